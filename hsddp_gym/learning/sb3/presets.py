"""What a baseline run is set up with: the envs and algorithms [`train_sb3`][hsddp_gym.learning.sb3.training.train_sb3]
trains, the RL-Zoo hyperparameter presets ([`PRESETS`][PRESETS]), the overrides the front-ends offer
([`hyperparameters`][hyperparameters]: layer widths, gSDE, the exploration noise, the learning rate and its ``lin_``
notation) and the SB3 constructor arguments made from them ([`model_kwargs`][model_kwargs]). NumPy only at import (the
front-ends read `OPTION_HELP` to build their parsers).
"""

from __future__ import annotations

import json

import numpy as np

ENV_ID = "hsddp_gym/Bounding-v0"
ENV_IDS = (ENV_ID, "hsddp_gym/Pronking-v0", "hsddp_gym/Backflip-v0", "hsddp_gym/GapJump-v0", "hsddp_gym/BoxJump-v0",
           "hsddp_gym/StandToBound-v0", "hsddp_gym/BoundPronkBound-v0", "hsddp_gym/BoundToStop-v0")
"""The envs [`train_sb3`][hsddp_gym.learning.sb3.training.train_sb3] trains in (``env_id``): Bounding-v0 (the default)
and every task with a plan-tracking expert: the pronk, the backflip, the jumps and the three gait transitions (each
has a compiled vector env and the robustness conditions; ``tests/test_learning.py`` checks that these are the
registry's)."""
ALGOS = ("ppo", "sac")

PPO_HYPERPARAMS: dict = {
    "normalize": True,
    "n_envs": 1,
    "n_steps": 512,
    "batch_size": 64,
    "gamma": 0.98,
    "gae_lambda": 0.92,
    "learning_rate": 2.0633e-5,
    "clip_range": 0.1,
    "n_epochs": 20,
    "ent_coef": 4.0e-4,
    "max_grad_norm": 0.8,
    "vf_coef": 0.58,
    "policy_kwargs": {"log_std_init": -2.0, "ortho_init": False, "activation_fn": "ReLU",
                      "net_arch": {"pi": [256, 256], "vf": [256, 256]}},
}
"""RL-Zoo ``hyperparams/ppo.yml`` HalfCheetah-v3 (tuned): VecNormalize on observations and rewards, one env."""

PPO_HOPPER_HYPERPARAMS: dict = {
    "normalize": True,
    "n_envs": 1,
    "n_steps": 512,
    "batch_size": 32,
    "gamma": 0.999,
    "gae_lambda": 0.99,
    "learning_rate": 9.80828e-5,
    "clip_range": 0.2,
    "n_epochs": 5,
    "ent_coef": 0.00229519,
    "max_grad_norm": 0.7,
    "vf_coef": 0.835671,
    "policy_kwargs": {"log_std_init": -2.0, "ortho_init": False, "activation_fn": "ReLU",
                      "net_arch": {"pi": [256, 256], "vf": [256, 256]}},
}
"""RL-Zoo ``hyperparams/ppo.yml`` Hopper-v3 (tuned): the family of terminating locomotion tasks (an episode ends
on a fall, as here), unlike HalfCheetah, which never terminates; VecNormalize on observations and rewards."""

SAC_HYPERPARAMS: dict = {
    "normalize": False,
    "n_envs": 1,
    "learning_starts": 10_000,
}
"""RL-Zoo ``hyperparams/sac.yml`` HalfCheetah-v3: SB3 defaults (lr 3e-4, buffer 1e6, batch 256, tau 0.005,
gamma 0.99, train_freq 1, auto entropy, [256, 256] ReLU) plus ``learning_starts`` 10000."""

PPO_PARALLEL_HYPERPARAMS: dict = {
    "normalize": True,
    "n_envs": 64,
    "n_steps": 128,
    "batch_size": 2048,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "learning_rate": 3.0e-4,
    "clip_range": 0.2,
    "n_epochs": 5,
    "ent_coef": 0.0,
    "max_grad_norm": 1.0,
    "vf_coef": 1.0,
    "target_kl": 0.02,
    "policy_kwargs": {"log_std_init": -1.0, "ortho_init": True, "activation_fn": "ELU",
                      "net_arch": {"pi": [512, 256, 128], "vf": [512, 256, 128]}},
}
"""Massively parallel PPO for legged robots (legged_gym / rsl_rl, Rudin et al., CoRL 2021: many envs, short
rollouts, 4 large minibatches, 5 epochs, ELU 512-256-128, gamma 0.99, lambda 0.95, clip 0.2, value coefficient 1,
gradient norm 1) scaled to a CPU: 64 robots (meant for the compiled vector env, ``--vector-env``) x 128 steps =
8192 samples per update; a fixed step 3e-4 with SB3's ``target_kl`` early stop in place of rsl_rl's adaptive step
(desired KL 0.01); VecNormalize on observations and rewards. Not an RL-Zoo set."""

PRESETS: dict = {"ppo": {"hopper": PPO_HOPPER_HYPERPARAMS, "halfcheetah": PPO_HYPERPARAMS,
                         "parallel": PPO_PARALLEL_HYPERPARAMS},
                 "sac": {"hopper": SAC_HYPERPARAMS, "halfcheetah": SAC_HYPERPARAMS}}
"""The hyperparameter sets by algorithm and task: RL-Zoo's Hopper-v3 and HalfCheetah-v3 (SAC's Hopper-v3 entry is
its HalfCheetah-v3 one), and PPO's ``"parallel"`` (many robots at once,
[`PPO_PARALLEL_HYPERPARAMS`][PPO_PARALLEL_HYPERPARAMS])."""
DEFAULT_PRESET = "hopper"
"""Bounding-v0 terminates on falls like Hopper/Walker2d: their settings are the default."""


def _policy_kwargs(kwargs: dict) -> dict:
    import torch.nn as nn

    kw = dict(kwargs)
    if isinstance(kw.get("activation_fn"), str):
        kw["activation_fn"] = getattr(nn, kw["activation_fn"])
    return kw


def hyperparameters(algo: str, overrides: dict | None = None, preset: str = DEFAULT_PRESET) -> dict:
    """The documented hyperparameters of ``algo`` (``"ppo"`` or ``"sac"``) for ``preset`` ([`PRESETS`][PRESETS]) with
    ``overrides`` applied (e.g. ``{"n_envs": 4}``). ``{"net_arch": [128, 128]}`` sets the hidden layers of every
    network (actor and critic alike) in ``policy_kwargs``, keeping the preset's other policy settings;
    ``{"sde": True}`` (PPO) switches to gSDE exploration (`SDE_HYPERPARAMS`); ``{"log_std_init": x}`` (PPO)
    sets the initial log standard deviation of the exploration noise (gSDE: of its weights)."""
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    if preset not in PRESETS[algo]:
        raise ValueError(f"preset must be one of {tuple(PRESETS[algo])}, got {preset!r}")
    hp = json.loads(json.dumps(PRESETS[algo][preset]))
    overrides = dict(overrides or {})
    if "sde" in overrides:  # first, so that an explicit log_std_init wins whatever the order given
        overrides = {"sde": overrides.pop("sde"), **overrides}
    for k, v in overrides.items():
        if v is None:
            continue
        if k == "log_std_init":
            if algo != "ppo":
                raise ValueError(f"log_std_init is offered for ppo only (SAC learns a state-dependent std), got "
                                 f"algo {algo!r}")
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not np.isfinite(v):
                raise ValueError(f"log_std_init must be a finite number, got {v!r}")
            hp.setdefault("policy_kwargs", {})["log_std_init"] = float(v)
            continue
        if k == "net_arch":
            if (isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) == 0
                    or any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1 for n in v)):
                raise ValueError(f"net_arch must be a non-empty list of layer widths >= 1, got {v!r}")
            widths = [int(n) for n in v]
            hp.setdefault("policy_kwargs", {})["net_arch"] = (
                {"pi": widths, "vf": widths} if algo == "ppo" else {"pi": widths, "qf": widths})
            continue
        if k == "learning_rate":
            learning_rate_schedule(v)  # validates
        if k == "sde":
            if not isinstance(v, (bool, np.bool_)):
                raise ValueError(f"sde must be True or False, got {v!r}")
            if v:
                if algo != "ppo":
                    raise ValueError(f"sde (gSDE exploration) is offered for ppo only, got algo {algo!r}")
                hp.update(SDE_HYPERPARAMS)
                hp.setdefault("policy_kwargs", {})["log_std_init"] = SDE_LOG_STD_INIT
            continue
        hp[k] = v
    return hp


SDE_HYPERPARAMS: dict = {"use_sde": True, "sde_sample_freq": 4}
SDE_LOG_STD_INIT = -2.0
"""``{"sde": True}`` (PPO): generalized state-dependent exploration (gSDE, Raffin et al., CoRL 2021) as RL-Zoo's
PPO on the PyBullet locomotion tasks sets it: the exploration noise is a linear function of the policy's last
hidden features, its weights drawn anew every 4 steps, and ``log_std_init`` -2. With SB3's default white Gaussian
noise the parallel preset's mean action bounds differently from the draws it was trained with (its mean action
fell where its draws did not; docs/results/what-did-not-work.md); with gSDE the mean action is sound. SB3 redraws
the weights every 4 steps of its rollouts; [`SB3ModelPolicy`][hsddp_gym.learning.sb3.runs.SB3ModelPolicy]'s own draws
every 4 steps of the episode."""


#: The help of the RL options both front-ends offer (``hsddp-gym train`` and ``experiments/train_rl.py``).
OPTION_HELP = {
    "learning_rate": "the optimizer's step: a number, or lin_<number> for a step that falls linearly to 0 over "
                     "--steps (RL-Zoo's notation; default: the preset's)",
    "sde": "PPO: generalized state-dependent exploration (gSDE; RL-Zoo's PyBullet settings: noise weights drawn "
           "every 4 steps, log_std_init -2), whose mean action bounds as its draws do "
           "(hsddp_gym.learning.sb3.SDE_HYPERPARAMS)",
    "log_std_init": "PPO: initial log standard deviation of the exploration noise (with --sde: of the noise weights, "
                    "whose action noise is the features times them; default: the preset's, -2 with --sde)",
}


def parse_learning_rate(text: str) -> float | str:
    """A learning rate as a command line gives it: ``"3e-4"`` -> 3e-4, ``"lin_3e-4"`` stays a string (RL-Zoo's
    linear decay, see [`learning_rate_schedule`][learning_rate_schedule]); ``ValueError`` for anything else (the
    front-ends name their option)."""
    if not isinstance(text, str):
        raise TypeError(f"learning rate text must be a str, got {type(text).__name__}")
    value = text if text.startswith("lin_") else _float_or_text(text)
    learning_rate_schedule(value)  # validates
    return value


def _float_or_text(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text


def learning_rate_schedule(value):
    """SB3's ``learning_rate`` from a hyperparameter: a number (constant) or RL-Zoo's ``"lin_<number>"``, a step
    that falls linearly from ``<number>`` to 0 over the run's ``steps`` (SB3's ``progress_remaining``; with a
    ``time_limit`` that stops the run earlier, the step has not reached 0 there)."""
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError:
            start = float("nan")
        if not (np.isfinite(start) and start > 0):
            raise ValueError(f"learning_rate 'lin_<number>' needs a number > 0, got {value!r}")
        return lambda progress_remaining: progress_remaining * start
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(value) and value > 0):
        raise ValueError(f"learning_rate must be a number > 0 or 'lin_<number>', got {value!r}")
    return float(value)


TRAINER_KEYS = ("normalize", "n_envs")
"""Hyperparameters the trainer applies around the SB3 model rather than passing to its constructor:
``normalize`` (VecNormalize) and ``n_envs`` (robots stepped together)."""


def model_kwargs(hp: dict) -> dict:
    """The keyword arguments of an SB3 model's constructor from hyperparameters ``hp``
    ([`hyperparameters`][hyperparameters]): without [`TRAINER_KEYS`][TRAINER_KEYS], the learning rate as SB3 takes it
    ([`learning_rate_schedule`][learning_rate_schedule]) and the activation named in ``policy_kwargs`` as its torch
    class."""
    kw = {k: v for k, v in hp.items() if k not in TRAINER_KEYS}
    if "learning_rate" in kw:
        kw["learning_rate"] = learning_rate_schedule(kw["learning_rate"])
    if "policy_kwargs" in kw:
        kw["policy_kwargs"] = _policy_kwargs(kw["policy_kwargs"])
    return kw
