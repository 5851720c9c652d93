"""Stable-Baselines3 glue: any policy as an SB3 ``BasePolicy``, and the PPO / SAC baselines on ``Bounding-v0`` (and
``Pronking-v0``, ``env_id``).

**Adapter.** :func:`as_sb3_policy` wraps a :class:`~hsddp_gym.planners.policies.base.Policy` (or any callable
``obs (obs_dim,) -> action (act_dim,)``) into a ``stable_baselines3.common.policies.BasePolicy`` whose
``predict(observation, state, episode_start, deterministic)`` and ``_predict(obs_tensor)`` return exactly the
callable's actions (float32, clipped to the action box, which leaves a policy's in-box actions unchanged).
A :class:`Policy` keeps one independent copy per vectorized env and resets the copy whose ``episode_start``
is true, so planners with memory (gait clock, plan cursor, MPC warm start) work with ``evaluate_policy``
and with ``imitation``'s rollout / DAgger tooling. A plain callable is applied row by row and has no memory.

**Baselines.** :func:`train_sb3` trains PPO or SAC with RL-Zoo hyperparameters (:data:`PRESETS`): by default
those of Hopper-v3 (:data:`PPO_HOPPER_HYPERPARAMS`; SAC's are its HalfCheetah-v3 defaults, :data:`SAC_HYPERPARAMS`),
a task that ends on a fall like this one; ``preset="halfcheetah"`` gives the HalfCheetah-v3 set
(:data:`PPO_HYPERPARAMS`; ``user_needs.md`` §2.2). It writes into ``out``:

* ``model.zip``: the SB3 model (``PPO.load`` / ``SAC.load``, or :func:`load_trained_policy`, which reads only
  the weights, never unpickles);
* ``vecnormalize.pkl`` (SB3's format, PPO only) and ``vecnormalize.npz`` (the same running statistics as
  plain arrays);
* ``train.monitor.csv`` (SB3 ``Monitor``: return, length, time of every training episode),
  ``evaluations.npz`` (``EvalCallback``: deterministic evaluations during training);
* ``curve.csv`` (training episodes: ``env_step, episode_return, episode_length``), ``eval_curve.csv``
  (``env_step, mean_return, std_return``) and ``curve.png`` (needs matplotlib);
* ``summary.json``: algorithm, hyperparameters, seed, steps, wall time, final evaluation.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.io import atomic_path, read_npz, write_json, write_npz
from hsddp_gym.util.validation import check_int, check_positive

ENV_ID = "hsddp_gym/Bounding-v0"
ENV_IDS = (ENV_ID, "hsddp_gym/Pronking-v0", "hsddp_gym/Backflip-v0", "hsddp_gym/GapJump-v0", "hsddp_gym/BoxJump-v0")
"""The envs :func:`train_sb3` trains in (``env_id``): Bounding-v0 (the default), the pronking task Pronking-v0, the
backflip task Backflip-v0 and the jumps GapJump-v0 and BoxJump-v0, which offer no compiled vector env and no
robustness conditions."""
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
its HalfCheetah-v3 one), and PPO's ``"parallel"`` (many robots at once, :data:`PPO_PARALLEL_HYPERPARAMS`)."""
DEFAULT_PRESET = "hopper"
"""Bounding-v0 terminates on falls like Hopper/Walker2d: their settings are the default."""


# ================================================================================================ adapter
def _as_batch_fn(policy) -> Callable:
    """``(obs (n, d) float32, episode_start (n,) bool or None) -> actions (n, m)``."""
    if isinstance(policy, Policy):
        def batch(obs, episode_start):
            acts, _ = policy.predict(obs, episode_start=episode_start, deterministic=True)
            return np.asarray(acts, dtype=np.float32)
        return batch
    if not callable(policy):
        raise TypeError(f"policy must be a hsddp_gym.planners.policies.base.Policy or a callable obs -> action, "
                        f"got {type(policy).__name__}")

    def batch(obs, episode_start):
        return np.stack([np.asarray(policy(o), dtype=np.float32) for o in obs])
    return batch


def as_sb3_policy(policy, observation_space, action_space):
    """Wrap ``policy`` into an SB3 ``BasePolicy`` (see the module docstring).

    Args:
        policy: a :class:`~hsddp_gym.planners.policies.base.Policy` (memory handled per env through
            ``episode_start``) or a callable ``obs (obs_dim,) -> action (act_dim,)`` (no memory).
        observation_space: the env's observation space (a ``gymnasium.spaces.Box``).
        action_space: the env's action space (a ``gymnasium.spaces.Box``).

    Returns:
        A ``CallableSB3Policy`` (an ``stable_baselines3.common.policies.BasePolicy``) with no parameters; it
        runs on the CPU and cannot be saved (the callable is arbitrary Python).
    """
    from gymnasium import spaces

    if not isinstance(observation_space, spaces.Box) or not isinstance(action_space, spaces.Box):
        raise TypeError(f"observation_space and action_space must be gymnasium Box spaces, got "
                        f"{type(observation_space).__name__} and {type(action_space).__name__}")
    return _adapter_class()(policy, observation_space, action_space)


_ADAPTER = None


def _adapter_class():
    """The adapter class, defined on first use so that importing this module does not import torch."""
    global _ADAPTER
    if _ADAPTER is not None:
        return _ADAPTER
    import torch as th
    from stable_baselines3.common.policies import BasePolicy

    class CallableSB3Policy(BasePolicy):
        """An SB3 ``BasePolicy`` that delegates to a planner policy or callable (see :func:`as_sb3_policy`)."""

        def __init__(self, policy, observation_space, action_space) -> None:
            super().__init__(observation_space, action_space)
            self.wrapped = policy
            self._batch = _as_batch_fn(policy)

        def _predict(self, observation, deterministic: bool = False):
            obs = observation.detach().cpu().numpy().astype(np.float32, copy=False)
            return th.as_tensor(self._batch(obs.reshape(len(obs), -1), None))

        def predict(self, observation, state=None, episode_start=None, deterministic: bool = False):
            """SB3 protocol; unlike ``BasePolicy.predict`` it passes ``episode_start`` to the wrapped policy
            so that each env's copy is reset at the start of its episode."""
            obs = np.asarray(observation, dtype=np.float32)
            shape = self.observation_space.shape
            single = obs.shape == shape
            if not single and obs.shape[1:] != shape:
                raise ValueError(f"observation must have shape {shape} or (n_envs, *{shape}), got {obs.shape}")
            batch = obs[None] if single else obs
            starts = None if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(len(batch))
            acts = self._batch(batch, starts).reshape((-1, *self.action_space.shape))
            acts = np.clip(acts, self.action_space.low, self.action_space.high)
            return (acts[0] if single else acts), state

        def forward(self, obs, deterministic: bool = False):
            return self._predict(obs, deterministic)

        def save(self, path) -> None:  # noqa: D102
            raise NotImplementedError("a CallableSB3Policy wraps arbitrary Python and cannot be saved; save the "
                                      "underlying planner (e.g. its Solution) instead")

    _ADAPTER = CallableSB3Policy
    return _ADAPTER


# ================================================================================================ training
@dataclasses.dataclass
class TrainResult:
    """What :func:`train_sb3` wrote: ``out`` and the ``summary`` dict (also in ``out/summary.json``)."""

    out: Path
    summary: dict


def _policy_kwargs(kwargs: dict) -> dict:
    import torch.nn as nn

    kw = dict(kwargs)
    if isinstance(kw.get("activation_fn"), str):
        kw["activation_fn"] = getattr(nn, kw["activation_fn"])
    return kw


def hyperparameters(algo: str, overrides: dict | None = None, preset: str = DEFAULT_PRESET) -> dict:
    """The documented hyperparameters of ``algo`` (``"ppo"`` or ``"sac"``) for ``preset`` (:data:`PRESETS`) with
    ``overrides`` applied (e.g. ``{"n_envs": 4}``). ``{"net_arch": [128, 128]}`` sets the hidden layers of every
    network (actor and critic alike) in ``policy_kwargs``, keeping the preset's other policy settings;
    ``{"sde": True}`` (PPO) switches to gSDE exploration (:data:`SDE_HYPERPARAMS`); ``{"log_std_init": x}`` (PPO)
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
the weights every 4 steps of its rollouts; :class:`SB3ModelPolicy`'s own draws every 4 steps of the episode."""


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
    linear decay, see :func:`learning_rate_schedule`); ``ValueError`` for anything else (the front-ends name their
    option)."""
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


def _model_kwargs(hp: dict) -> dict:
    kw = {k: v for k, v in hp.items() if k not in TRAINER_KEYS}
    if "learning_rate" in kw:
        kw["learning_rate"] = learning_rate_schedule(kw["learning_rate"])
    if "policy_kwargs" in kw:
        kw["policy_kwargs"] = _policy_kwargs(kw["policy_kwargs"])
    return kw


def check_env_id(env_id, vector_env: bool = False, train_condition=None) -> str:
    """``env_id`` (None: :data:`ENV_ID`) if :func:`train_sb3` trains in it, else ``ValueError`` naming it; the
    compiled vector env (``vector_env``) and the robustness conditions (``train_condition``) are Bounding-v0's."""
    if env_id is None:
        return ENV_ID
    if not isinstance(env_id, str) or env_id not in ENV_IDS:
        raise ValueError(f"env_id must be one of {ENV_IDS}, got {env_id!r}")
    if env_id != ENV_ID and vector_env:
        raise ValueError(f"env_id {env_id!r} has no compiled vector env (vector_env is {ENV_ID}'s only)")
    if env_id != ENV_ID and train_condition is not None:
        raise ValueError(f"env_id {env_id!r} takes no train_condition (the conditions perturb {ENV_ID}), got "
                         f"{train_condition!r}")
    return env_id


def check_train_condition(name, env_kwargs: dict | None = None, vector_env: bool = False):
    """The :class:`~hsddp_gym.envs.perturbations.Condition` called ``name`` for training robots (None: none), with
    ``ValueError`` naming ``train_condition`` for an unknown name, for env arguments it sets that ``env_kwargs``
    sets too, and (``vector_env``) for observation noise or latency, which the compiled vector env does not offer."""
    if name is None:
        return None
    from hsddp_gym.envs.perturbations import CONDITIONS

    if not isinstance(name, str) or name not in CONDITIONS:
        raise ValueError(f"train_condition must be one of {list(CONDITIONS)} or None, got {name!r}")
    condition = CONDITIONS[name]
    both = sorted(set(condition.env_kwargs) & set(env_kwargs or {}))
    if both:
        raise ValueError(f"train_condition {name!r} sets {both} itself; do not give them in env_kwargs too")
    if vector_env and not condition.acts_through_env_arguments:
        raise ValueError(f"train_condition {name!r} has observation noise or latency, which the compiled vector "
                         "env does not offer: train without vector_env (--vector-env) for it")
    return condition


def _make_venv(n_envs: int, seed: int, env_kwargs: dict, max_episode_steps: int | None, monitor_path: Path | None,
               vector_env: bool = False, condition=None, env_id: str = ENV_ID):
    """The training (or evaluation) envs of ``env_id``; ``condition`` (a checked
    :class:`~hsddp_gym.envs.perturbations.Condition` or None) perturbs every one of them."""
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    import hsddp_gym  # noqa: F401  (registers the env)

    if vector_env:  # the compiled vector env: one call steps all robots; one monitor file for all
        from hsddp_gym.envs.bounding import DEFAULT_MAX_EPISODE_STEPS
        from hsddp_gym.learning.vector_sb3 import make_sb3_vec_env

        steps = DEFAULT_MAX_EPISODE_STEPS if max_episode_steps is None else int(max_episode_steps)
        extra = {} if condition is None else dict(condition.env_kwargs)
        if condition is not None and condition.push is not None:
            extra["push"] = dict(condition.push)
        return VecMonitor(make_sb3_vec_env(n_envs, seed=seed, max_episode_steps=steps, **env_kwargs, **extra),
                          filename=None if monitor_path is None else str(monitor_path))

    def make(i):
        def _init():
            kw = dict(env_kwargs)
            if max_episode_steps is not None:
                kw["max_episode_steps"] = int(max_episode_steps)
            env = gym.make(env_id, **kw) if condition is None else condition.make(**kw)
            filename = None
            if monitor_path is not None:
                filename = str(monitor_path) if n_envs == 1 else str(monitor_path).replace(".monitor.csv",
                                                                                          f"_{i}.monitor.csv")
            return Monitor(env, filename=filename)
        return _init

    venv = DummyVecEnv([make(i) for i in range(n_envs)])
    venv.seed(seed)
    return venv


def save_vecnormalize_npz(venv, path) -> Path:
    """The running observation/return statistics of a ``VecNormalize`` as plain arrays (no pickle)."""
    return write_npz(path, obs_mean=venv.obs_rms.mean, obs_var=venv.obs_rms.var, obs_count=np.array(venv.obs_rms.count),
                     ret_mean=np.array(venv.ret_rms.mean), ret_var=np.array(venv.ret_rms.var),
                     clip_obs=np.array(venv.clip_obs), clip_reward=np.array(venv.clip_reward),
                     epsilon=np.array(venv.epsilon), gamma=np.array(venv.gamma),
                     norm_obs=np.array(venv.norm_obs), norm_reward=np.array(venv.norm_reward))


def train_sb3(algo: str, steps: int, seed: int, out, env_kwargs: dict | None = None,
              max_episode_steps: int | None = None, overrides: dict | None = None, eval_freq: int | None = None,
              eval_episodes: int = 5, final_eval_episodes: int = 10, threads: int = 1, progress: bool = False,
              verbose: int = 0, time_limit: float | None = None, preset: str = DEFAULT_PRESET,
              vector_env: bool = False, train_condition: str | None = None,
              env_id: str | None = None) -> TrainResult:
    """Train PPO or SAC on ``Bounding-v0`` (or ``env_id``) and write the files of the module docstring into ``out``.

    Args:
        algo: ``"ppo"`` or ``"sac"``. steps: env steps. seed: seeds the model, the env and the evaluation env.
        env_kwargs: ``gym.make`` keyword arguments. max_episode_steps: time-limit override (None: 1000).
        overrides: hyperparameters replacing the documented ones (e.g. ``{"learning_starts": 100}``,
            ``{"n_envs": 4}``: that many envs in a ``DummyVecEnv``, stepped together).
        vector_env: step the ``n_envs`` training robots with the compiled vector env
            (:class:`hsddp_gym.envs.vector.BoundingVectorEnv` through :mod:`hsddp_gym.learning.vector_sb3`, one
            ``train.monitor.csv`` for all) instead of a ``DummyVecEnv`` of single envs; the evaluation env stays
            a single env. Same transitions up to round-off (``tests/test_vector_env.py``).
        preset: the RL-Zoo hyperparameter set (:data:`PRESETS`; default ``"hopper"``, a terminating task).
        eval_freq: env steps between deterministic evaluations of ``eval_episodes`` episodes (None:
            ``max(steps // 10, 1000)``; 0: none).
        final_eval_episodes: after training, evaluate the saved policy with the comparison protocol
            (:func:`hsddp_gym.learning.reporting.evaluate_policy_episodes`: seeds 0, 1, ..., deterministic) into
            ``summary["eval"]`` (0: skip).
        threads: ``torch.set_num_threads`` (1 by default: the machines are shared).
        train_condition: a condition of the robustness registry
            (:data:`hsddp_gym.envs.perturbations.CONDITIONS`, e.g. ``"push_x3"``) under which every training robot
            runs (domain randomization: pushes, env arguments; with ``vector_env`` observation noise and latency
            are refused); the evaluations, training-time and final, stay on the unperturbed task. None: none.
        time_limit: wall-clock budget of the training [s] (None: none). Training stops at the first env step
            after it, so ``summary["steps"]`` is the budget that fit (``"stopped_by_time_limit"`` says so).
            Such a run is not reproducible step for step; rerun it with ``steps = summary["steps"]`` for that.
        env_id: the env to train and evaluate in, one of :data:`ENV_IDS` (None: Bounding-v0); Pronking-v0 takes
            neither ``vector_env`` nor ``train_condition``. Stored in ``summary.json``, so
            :func:`load_trained_policy` rebuilds the run's env.
    """
    from hsddp_gym.util.extras import require

    require(["stable_baselines3", "torch"], f"train_sb3 ({algo})")
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback
    from stable_baselines3.common.vec_env import VecNormalize

    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    if int(steps) < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    if time_limit is not None and not float(time_limit) > 0:
        raise ValueError(f"time_limit must be > 0 seconds or None, got {time_limit!r}")
    env_kwargs = dict(env_kwargs or {})
    env_id = check_env_id(env_id, bool(vector_env), train_condition)
    condition = check_train_condition(train_condition, env_kwargs, bool(vector_env))
    torch.set_num_threads(int(threads))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    hp = hyperparameters(algo, overrides, preset)
    if not isinstance(vector_env, (bool, np.bool_)):
        raise TypeError(f"vector_env must be a bool, got {type(vector_env).__name__}")
    venv = _make_venv(hp["n_envs"], seed, env_kwargs, max_episode_steps, out / "train.monitor.csv",
                      vector_env=bool(vector_env), condition=condition, env_id=env_id)
    # the evaluation env is wrapped as the training env (SB3 copies VecNormalize's statistics wrapper by wrapper)
    eval_venv = _make_venv(1, seed + 10_000, env_kwargs, max_episode_steps, None, vector_env=bool(vector_env),
                           env_id=env_id)
    if hp["normalize"]:
        gamma = hp.get("gamma", 0.99)
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=gamma)
        eval_venv = VecNormalize(eval_venv, norm_obs=True, norm_reward=False, gamma=gamma, training=False)
    cls = PPO if algo == "ppo" else SAC
    model = cls("MlpPolicy", venv, seed=seed, device="cpu", verbose=verbose, **_model_kwargs(hp))
    callbacks = []
    eval_freq = max(int(steps) // 10, 1000) if eval_freq is None else int(eval_freq)
    best = None
    if eval_freq > 0:
        best = _save_best(out, venv if hp["normalize"] else None)
        # EvalCallback counts calls, one per step of all n_envs robots: eval_freq env steps are that many / n_envs
        callbacks.append(EvalCallback(eval_venv, n_eval_episodes=eval_episodes,
                                      eval_freq=max(eval_freq // int(hp["n_envs"]), 1),
                                      log_path=str(out), deterministic=True, verbose=0, callback_on_new_best=best))
    t0 = time.perf_counter()
    timer = None
    if time_limit is not None:
        timer = _wall_clock_limit(float(time_limit), t0)
        callbacks.append(timer)
    model.learn(total_timesteps=int(steps), callback=CallbackList(callbacks) if callbacks else None,
                progress_bar=progress)
    wall = time.perf_counter() - t0
    with atomic_path(out / "model.zip", suffix=".zip") as tmp:
        model.save(tmp)
    files = ["model.zip", "train.monitor.csv"]
    if hp["normalize"]:
        venv.save(str(out / "vecnormalize.pkl"))
        save_vecnormalize_npz(venv, out / "vecnormalize.npz")
        files += ["vecnormalize.pkl", "vecnormalize.npz"]
    if (out / "evaluations.npz").exists():
        files.append("evaluations.npz")
    if best is not None and best.record is not None:
        files += [BEST_MODEL] + ([BEST_VECNORMALIZE] if hp["normalize"] else [])
    files += write_curves(out, algo, env_id=env_id)
    summary = {
        "algo": algo, "env_id": env_id, "env_kwargs": env_kwargs, "max_episode_steps": max_episode_steps,
        "seed": int(seed), "steps": int(model.num_timesteps), "requested_steps": int(steps),
        "preset": preset, "hyperparameters": hp, "vector_env": bool(vector_env),
        "train_condition": None if condition is None else condition.as_dict(), "wall_time_s": wall,
        "threads": int(threads), "eval_freq": eval_freq,
        "time_limit_s": time_limit, "stopped_by_time_limit": bool(timer is not None and timer.stopped),
        "eval_episodes": eval_episodes, "files": files,
        "training_episodes": _count_monitor_episodes(out / "train.monitor.csv"),
        "best_checkpoint": best.record if best is not None else None,
    }
    venv.close()
    eval_venv.close()
    write_json(out / "summary.json", summary)
    if final_eval_episodes > 0:
        from hsddp_gym.learning.reporting import eval_brief, evaluate_policy_episodes

        summary["eval"] = eval_brief(evaluate_policy_episodes(load_trained_policy(out), final_eval_episodes, 0,
                                                               env_kwargs, max_episode_steps, env_id=env_id))
        # the policy as it acted in training: draws of its own distribution (seeded; a Gaussian PPO policy's mean
        # can fall where its draws bound, README "RL baselines")
        summary["eval_stochastic"] = eval_brief(evaluate_policy_episodes(
            load_trained_policy(out, deterministic=False), final_eval_episodes, 0, env_kwargs, max_episode_steps,
            env_id=env_id))
        if summary["best_checkpoint"] is not None:
            # the checkpoint chosen by the training-time evaluations (their own seeds), under the same protocol
            summary["eval_best"] = eval_brief(evaluate_policy_episodes(
                load_trained_policy(out, checkpoint="best"), final_eval_episodes, 0, env_kwargs, max_episode_steps,
                env_id=env_id))
        write_json(out / "summary.json", summary)
    return TrainResult(out, summary)


BEST_MODEL = "best_model.zip"
BEST_VECNORMALIZE = "best_vecnormalize.npz"
CHECKPOINTS = ("final", "best")
"""Which weights :func:`load_trained_policy` reads: the end of training (``model.zip``) or the checkpoint whose
training-time deterministic evaluation (``EvalCallback``, seeds 10000 + seed ..., apart from the protocol's 0, 1,
...) had the highest mean return (``best_model.zip``, with the observation statistics of that moment)."""


def _save_best(out: Path, venv):
    """An SB3 callback for ``EvalCallback(callback_on_new_best=...)``: writes the model (:data:`BEST_MODEL`) and,
    with ``VecNormalize`` (``venv``), its observation statistics of that moment (:data:`BEST_VECNORMALIZE`, which
    go on changing after), and keeps ``record`` = ``{"env_step", "mean_return"}`` of the evaluation."""
    from stable_baselines3.common.callbacks import BaseCallback

    class SaveBest(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.record = None

        def _on_step(self) -> bool:
            with atomic_path(out / BEST_MODEL, suffix=".zip") as tmp:
                self.model.save(tmp)
            if venv is not None:
                save_vecnormalize_npz(venv, out / BEST_VECNORMALIZE)
            self.record = {"env_step": int(self.model.num_timesteps),
                           "mean_return": float(self.parent.best_mean_reward)}
            return True

    return SaveBest()


def _wall_clock_limit(seconds: float, start: float):
    """An SB3 callback that stops ``learn`` once ``seconds`` have passed since ``start`` (``perf_counter``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class WallClockLimit(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.stopped = False

        def _on_step(self) -> bool:
            if time.perf_counter() - start >= seconds:
                self.stopped = True
            return not self.stopped

    return WallClockLimit()


def _read_monitor(path: Path) -> np.ndarray:
    """``(n, 3)`` rows ``[return, length, time]`` of an SB3 monitor file (empty if none)."""
    if not path.exists():
        return np.zeros((0, 3))
    rows = []
    with open(path) as fh:
        fh.readline()  # the JSON header line
        for row in csv.DictReader(fh):
            rows.append([float(row["r"]), float(row["l"]), float(row["t"])])
    return np.array(rows).reshape(-1, 3)


def _count_monitor_episodes(path: Path) -> int:
    return int(len(_read_monitor(path)))


def write_curves(out: Path, label: str, env_id: str = ENV_ID) -> list[str]:
    """``curve.csv`` (training episodes vs env steps), ``eval_curve.csv`` (from ``evaluations.npz``) and
    ``curve.png`` (titled with ``label`` and ``env_id``) from the files of a training run in ``out``; returns the
    names written."""
    out = Path(out)
    mon = _read_monitor(out / "train.monitor.csv")
    written = []
    steps = np.cumsum(mon[:, 1]) if len(mon) else np.zeros(0)
    with open(out / "curve.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["env_step", "episode_return", "episode_length"])
        for s, (r, n, _) in zip(steps, mon):
            w.writerow([int(s), f"{r:.6g}", int(n)])
    written.append("curve.csv")
    ev = None
    if (out / "evaluations.npz").exists():
        d = read_npz(out / "evaluations.npz")
        ev = (d["timesteps"], d["results"].mean(axis=1), d["results"].std(axis=1))
        with open(out / "eval_curve.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["env_step", "mean_return", "std_return"])
            for s, m, sd in zip(*ev):
                w.writerow([int(s), f"{m:.6g}", f"{sd:.6g}"])
        written.append("eval_curve.csv")
    from hsddp_gym.viz.plotting import _plt, _save

    try:
        plt = _plt()
    except ImportError:  # the viz extra is optional
        return written
    fig, ax = plt.subplots(figsize=(6, 3.5))
    if len(mon):
        ax.plot(steps, mon[:, 0], ".", ms=2, alpha=0.3, color="C0", label="training episodes")
        k = max(1, len(mon) // 50)
        if len(mon) >= k and k > 1:
            smooth = np.convolve(mon[:, 0], np.ones(k) / k, mode="valid")
            ax.plot(steps[k - 1:], smooth, color="C0", label=f"training (mean of {k})")
    if ev is not None:
        ax.errorbar(ev[0], ev[1], yerr=ev[2], color="C1", marker="o", ms=3, capsize=2,
                    label="deterministic evaluation")
    ax.set_xlabel("env steps")
    ax.set_ylabel("episode return")
    ax.set_title(f"{label} on {env_id}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, out / "curve.png")  # atomic
    written.append("curve.png")
    return written


# ================================================================================================ loading
class SB3ModelPolicy(Policy):
    """A trained SB3 model as a :class:`Policy`: normalizes the observation with the saved ``VecNormalize``
    statistics (if any) and returns the model's action, clipped to the action space.

    ``deterministic=True`` (the comparison protocol): the mean of PPO's Gaussian, SAC's squashed mean.
    ``deterministic=False``: a draw of the policy's own distribution, as in training (gSDE: noise weights held for
    ``sde_sample_freq`` steps), from a generator seeded with ``noise_seed`` at every :meth:`reset` (so an episode
    is the same whatever ran before it in the process); ``noise_scale`` (>= 0, default 1) multiplies the noise's
    standard deviation (0: the mean action; a diagnostic of how much the policy rests on its noise,
    ``experiments/rl_noise_scale.py``).

    Build it with :func:`load_trained_policy`.
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), model=None, obs_stats: dict | None = None,
                 deterministic: bool = True, noise_seed: int = 0, noise_scale: float = 1.0) -> None:
        super().__init__(interface)
        if model is None:
            raise ValueError("model must be a trained SB3 model")
        if not isinstance(deterministic, (bool, np.bool_)):
            raise TypeError(f"deterministic must be a bool, got {deterministic!r}")
        self.model = model
        self.obs_stats = obs_stats
        self.deterministic = bool(deterministic)
        self.noise_seed = check_int(noise_seed, "noise_seed")
        self.noise_scale = check_positive(noise_scale, "noise_scale", allow_zero=True)
        if self.deterministic and self.noise_scale != 1.0:
            raise ValueError(f"noise_scale scales the draws of deterministic=False; got noise_scale={noise_scale!r} "
                             "with deterministic=True")
        self._torch_gen = None
        self._sde_weights = None
        self._sde_steps = 0

    def reset(self) -> None:
        super().reset()
        self._torch_gen = None
        self._sde_weights = None
        self._sde_steps = 0

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if not self.obs_stats:
            return np.asarray(obs, dtype=np.float32)
        s = self.obs_stats
        z = (np.asarray(obs, dtype=np.float64) - s["obs_mean"]) / np.sqrt(s["obs_var"] + float(s["epsilon"]))
        return np.clip(z, -float(s["clip_obs"]), float(s["clip_obs"])).astype(np.float32)

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.deterministic:
            a, _ = self.model.predict(self.normalize(obs), deterministic=True)
            return np.clip(np.asarray(a, dtype=np.float32), -1.0, 1.0)
        import torch as th

        if self._torch_gen is None:
            self._torch_gen = th.Generator().manual_seed(self.noise_seed)
        # SB3 samples from torch's global generator; here the policy's own draw from its own seeded generator
        policy = self.model.policy
        x = th.as_tensor(self.normalize(obs)[None])
        with th.no_grad():
            if hasattr(policy, "actor"):  # SAC: a Gaussian squashed into the (normalized) action bounds by tanh
                mean, log_std, _ = policy.actor.get_action_dist_params(x)
                a = th.tanh(mean + self.noise_scale * th.exp(log_std) * th.randn(mean.shape,
                                                                                  generator=self._torch_gen))
            elif getattr(self.model, "use_sde", False):  # PPO with gSDE: the mean plus features @ noise weights
                a = self._gsde_draw(policy, x)
            else:  # PPO: a diagonal Gaussian, clipped to the bounds as SB3 does
                d = policy.get_distribution(x).distribution
                a = d.mean + self.noise_scale * d.stddev * th.randn(d.mean.shape, generator=self._torch_gen)
        return np.clip(a.numpy()[0].astype(np.float32), -1.0, 1.0)

    def _gsde_draw(self, policy, x):
        """A gSDE PPO policy's own draw as SB3 acts in training: the mean action plus the last hidden features
        times a noise matrix ``(features, actions)`` of N(0, exp(log_std)^2) weights, drawn anew every
        ``sde_sample_freq`` steps of the episode (and at its start)."""
        import torch as th

        features = policy.extract_features(x, policy.pi_features_extractor)
        latent = policy.mlp_extractor.forward_actor(features)
        mean = policy.action_net(latent)
        freq = int(self.model.sde_sample_freq)
        if self._sde_weights is None or (freq > 0 and self._sde_steps % freq == 0):
            std = self.noise_scale * policy.action_dist.get_std(policy.log_std)
            self._sde_weights = std * th.randn(std.shape, generator=self._torch_gen)
        self._sde_steps += 1
        return mean + latent @ self._sde_weights


def load_trained_policy(run_dir, env=None, deterministic: bool = True, noise_seed: int = 0,
                        checkpoint: str = "final", noise_scale: float = 1.0) -> SB3ModelPolicy:
    """The policy of a :func:`train_sb3` run in ``run_dir``, read without unpickling: the model is rebuilt
    from ``summary.json``'s hyperparameters and only the weights of ``model.zip`` are loaded
    (``set_parameters``); the observation statistics come from ``vecnormalize.npz``.

    Args:
        env: the env to act in (None: ``gym.make`` of the run's env, ``summary.json``'s ``env_id``, with its env
            kwargs).
        deterministic: the mean action (True) or draws of the policy's distribution (:class:`SB3ModelPolicy`).
        noise_seed: the seed of those draws.
        noise_scale: the factor on the draws' noise (1: the policy's own distribution).
        checkpoint: ``"final"`` or ``"best"`` (:data:`CHECKPOINTS`: ``best_model.zip`` and
            ``best_vecnormalize.npz``, the best training-time evaluation).
    """
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC

    import hsddp_gym  # noqa: F401

    if checkpoint not in CHECKPOINTS:
        raise ValueError(f"checkpoint must be one of {CHECKPOINTS}, got {checkpoint!r}")
    run_dir = Path(run_dir)
    weights, statistics = (("model.zip", "vecnormalize.npz") if checkpoint == "final" else
                           (BEST_MODEL, BEST_VECNORMALIZE))
    if not (run_dir / weights).exists():
        raise FileNotFoundError(f"checkpoint={checkpoint!r}: no {weights} in {run_dir} (a run without "
                                "training-time evaluations has no best checkpoint)")
    summary = json.loads((run_dir / "summary.json").read_text())
    algo = summary["algo"]
    if env is None:
        env = gym.make(summary.get("env_id", ENV_ID), **summary.get("env_kwargs", {}))
    hp = dict(summary["hyperparameters"])
    kw = _model_kwargs(hp)
    for name in ("learning_starts", "buffer_size", "n_steps", "batch_size"):  # training only: the weights do not
        kw.pop(name, None)  # depend on them (and a 2,048 batch over one env's 128 steps only raises SB3's warning)
    cls = PPO if algo == "ppo" else SAC
    extra = {"buffer_size": 1} if algo == "sac" else {}
    model = cls("MlpPolicy", env, device="cpu", **kw, **extra)
    model.set_parameters(str(run_dir / weights), exact_match=True, device="cpu")
    stats = read_npz(run_dir / statistics) if (run_dir / statistics).exists() else None
    return SB3ModelPolicy(EnvInterface.from_env(env), model=model, obs_stats=stats, deterministic=deterministic,
                          noise_seed=noise_seed, noise_scale=noise_scale)
