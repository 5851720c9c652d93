"""A baseline run's files read back: the learning curves from its monitor and evaluation files
([`write_curves`][write_curves]), and its trained policy ([`load_trained_policy`][load_trained_policy], an
[`SB3ModelPolicy`][SB3ModelPolicy]), rebuilt from ``summary.json`` and the weights of ``model.zip`` without
unpickling."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from hsddp_gym.learning.sb3.presets import ENV_ID, model_kwargs
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.io import read_npz
from hsddp_gym.util.validation import check_int, check_positive

BEST_MODEL = "best_model.zip"
BEST_VECNORMALIZE = "best_vecnormalize.npz"
CHECKPOINTS = ("final", "best")
"""Which weights [`load_trained_policy`][load_trained_policy] reads: the end of training (``model.zip``) or the
checkpoint whose training-time deterministic evaluation (``EvalCallback``, seeds 10000 + seed ..., apart from the
protocol's 0, 1, ...) had the highest mean return (``best_model.zip``, with the observation statistics of that
moment)."""


def read_monitor(path: Path) -> np.ndarray:
    """``(n, 3)`` rows ``[return, length, time]`` of an SB3 monitor file (empty if none)."""
    if not path.exists():
        return np.zeros((0, 3))
    rows = []
    with open(path) as fh:
        fh.readline()  # the JSON header line
        for row in csv.DictReader(fh):
            rows.append([float(row["r"]), float(row["l"]), float(row["t"])])
    return np.array(rows).reshape(-1, 3)


def write_curves(out: Path, label: str, env_id: str = ENV_ID) -> list[str]:
    """``curve.csv`` (training episodes vs env steps), ``eval_curve.csv`` (from ``evaluations.npz``) and
    ``curve.png`` (titled with ``label`` and ``env_id``) from the files of a training run in ``out``; returns the
    names written."""
    out = Path(out)
    mon = read_monitor(out / "train.monitor.csv")
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


class SB3ModelPolicy(Policy):
    """A trained SB3 model as a [`Policy`][Policy]: normalizes the observation with the saved ``VecNormalize``
    statistics (if any) and returns the model's action, clipped to the action space.

    ``deterministic=True`` (the comparison protocol): the mean of PPO's Gaussian, SAC's squashed mean.
    ``deterministic=False``: a draw of the policy's own distribution, as in training (gSDE: noise weights held for
    ``sde_sample_freq`` steps), from a generator seeded with ``noise_seed`` at every `reset` (so an episode
    is the same whatever ran before it in the process); ``noise_scale`` (>= 0, default 1) multiplies the noise's
    standard deviation (0: the mean action; a diagnostic of how much the policy rests on its noise,
    ``experiments/rl_noise_scale.py``).

    Build it with [`load_trained_policy`][load_trained_policy].
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
                        checkpoint: str = "final", noise_scale: float = 1.0) -> Policy:
    """The policy of a [`train_sb3`][hsddp_gym.learning.sb3.training.train_sb3] run in ``run_dir``, read without
    unpickling: the model is rebuilt from ``summary.json``'s hyperparameters and only the weights of ``model.zip`` are
    loaded (``set_parameters``); the observation statistics come from ``vecnormalize.npz``. A run with a residual
    (``summary["residual"]``) gives a [`ResidualPolicy`][hsddp_gym.learning.residual.ResidualPolicy]: the task's expert
    built for ``env`` plus the learner; any other an [`SB3ModelPolicy`][SB3ModelPolicy].

    Args:
        env: the env to act in (None: ``gym.make`` of the run's env, ``summary.json``'s ``env_id``, with its env
            kwargs).
        deterministic: the mean action (True) or draws of the policy's distribution
            ([`SB3ModelPolicy`][SB3ModelPolicy]).
        noise_seed: the seed of those draws.
        noise_scale: the factor on the draws' noise (1: the policy's own distribution).
        checkpoint: ``"final"`` or ``"best"`` ([`CHECKPOINTS`][CHECKPOINTS]: ``best_model.zip`` and
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
    residual = summary.get("residual")
    learner_env = env
    if residual is not None:  # the learner acts in the residual env: its input carries the expert's action
        from hsddp_gym.learning.residual import ResidualEnv

        learner_env = ResidualEnv(env, residual["scale"], residual["base"])
    hp = dict(summary["hyperparameters"])
    kw = model_kwargs(hp)
    for name in ("learning_starts", "buffer_size", "n_steps", "batch_size"):  # training only: the weights do not
        kw.pop(name, None)  # depend on them (and a 2,048 batch over one env's 128 steps only raises SB3's warning)
    cls = PPO if algo == "ppo" else SAC
    extra = {"buffer_size": 1} if algo == "sac" else {}
    model = cls("MlpPolicy", learner_env, device="cpu", **kw, **extra)
    model.set_parameters(str(run_dir / weights), exact_match=True, device="cpu")
    stats = read_npz(run_dir / statistics) if (run_dir / statistics).exists() else None
    policy = SB3ModelPolicy(EnvInterface.from_env(env), model=model, obs_stats=stats, deterministic=deterministic,
                            noise_seed=noise_seed, noise_scale=noise_scale)
    if residual is None:
        return policy
    from hsddp_gym.learning.residual import ResidualPolicy

    return ResidualPolicy(learner_env.base, policy, residual["scale"])
