"""Evaluation of learned policies over seeded episodes, learning-curve plots and CSV tables."""

from __future__ import annotations

import numpy as np


# ================================================================================================ evaluation
def imitation_run_fields(run, algo: str) -> dict:
    """What a task record keeps of a finished ``hsddp-gym train --algo bc|dagger --out run`` (its
    ``summary.json``): the run, its training seed, its samples and wall time (and DAgger's configuration, its
    labeller: ``"expert"``, ``"mpc"`` or ``"heuristic"``, and the round it kept)."""
    import json
    from pathlib import Path

    if algo not in ("bc", "dagger"):
        raise ValueError(f"algo must be 'bc' or 'dagger', got {algo!r}")
    train = json.loads((Path(run) / "summary.json").read_text())
    fields = {"run": str(run), "training_seed": int(train["seed"]), "transitions": int(train["transitions"]),
              "train_wall_time_s": float(train["wall_time_s"])}
    if algo == "bc":
        fields.update(demonstrations=int(train["demonstrations"]), dataset_id=train.get("dataset_id"))
    else:
        cfg = train["config"]
        fields.update(expert_labels=int(train["expert_labels"]),
                      initial_demonstrations=train.get("initial_demonstrations"), rounds=int(cfg["rounds"]),
                      episodes_per_round=int(cfg["episodes_per_round"]), beta_decay=float(cfg["beta_decay"]),
                      initial_dataset=train.get("initial_dataset"), rollout_noise=float(cfg.get("rollout_noise", 0.0)),
                      labeller=(train.get("expert") or {}).get("name", "expert"), keep=cfg.get("keep", "last"),
                      selected_round=train.get("selected_round", int(cfg["rounds"])))
    return fields


def rl_label(algo: str, train: dict) -> str:
    """How the task tables name an ``hsddp-gym train --algo sac|ppo`` run (``train``: its ``summary.json`` or a record's
    row of it, ``residual`` read from either): ``SAC`` / ``PPO``, with ``residual on the expert (scale s)`` for a run
    with ``--residual``."""
    residual = train.get("residual")
    return algo.upper() + (f", residual on the expert (scale {residual['scale']:g})" if residual else "")


def evaluate_policy_episodes(policy, episodes: int = 10, seed: int = 0, env_kwargs: dict | None = None,
                             max_episode_steps: int | None = None, reset_options: dict | None = None,
                             env_id: str | None = None) -> dict:
    """The comparison protocol: ``episodes`` episodes seeded ``seed, seed + 1, ...``, the policy's
    deterministic actions; returns [`hsddp_gym.rollout.episodes.summarize`][hsddp_gym.rollout.episodes.summarize]
    (mean/std return, falls, forward speed, episode length, ...); ``env_id``: the env (None: Bounding-v0)."""
    from hsddp_gym.datasets.collection import make_env
    from hsddp_gym.rollout.episodes import run_episode, summarize

    env = make_env(env_kwargs, max_episode_steps, env_id=env_id)
    try:
        results = [run_episode(env, policy, seed + i, options=reset_options) for i in range(int(episodes))]
    finally:
        env.close()
    return summarize(results)


# ================================================================================================ runs
def plot_curve(path, x, y, yerr=None, xlabel: str = "", ylabel: str = "mean return", title: str = "",
               reference: dict | None = None) -> bool:
    """A line plot with error bars saved to ``path`` (False when matplotlib is missing)."""
    from hsddp_gym.viz.plotting import _plt, _save

    try:
        plt = _plt()
    except ImportError:  # the viz extra is optional
        return False
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.errorbar(x, y, yerr=yerr, marker="o", ms=4, capsize=3)
    for i, (name, value) in enumerate((reference or {}).items()):
        if value is not None:
            ax.axhline(value, ls="--", lw=1, color=f"C{i + 1}", label=name)
    if reference:
        ax.legend(fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _save(fig, path)  # atomic
    return True


def write_csv(path, header, rows) -> None:
    """A CSV file with a header row, written atomically."""
    import csv

    from hsddp_gym.util.io import atomic_path

    with atomic_path(path, suffix=".csv") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def eval_brief(summary: dict) -> dict:
    keys = ("episodes", "seeds", "mean_return", "std_return", "returns", "falls", "mean_forward_speed",
            "mean_episode_length")
    return {k: summary[k] for k in keys if k in summary}


# ================================================================================================ seeds
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
         2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042)
"""Two-sided 95 % Student-t critical values for 1..30 degrees of freedom (1.96 beyond)."""


def mean_ci95(values) -> tuple[float, float]:
    """``(mean, half-width)`` of the two-sided 95 % Student-t confidence interval of the mean of ``values``
    (independent samples, e.g. one number per training seed); the half-width is NaN for fewer than 2 values."""
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        raise ValueError("values must not be empty")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"values must be finite, got {v.tolist()}")
    if v.size < 2:
        return float(v[0]), float("nan")
    t = _T975[v.size - 2] if v.size - 1 <= len(_T975) else 1.96
    return float(v.mean()), float(t * v.std(ddof=1) / np.sqrt(v.size))


def curve_band(curves, points: int = 50) -> dict:
    """Mean and 95 % interval across seeds of learning curves ``[(x (n_i,), y (n_i,)), ...]`` (x increasing),
    linearly interpolated onto ``points`` common x values from the largest first x to the smallest last x (the
    range every curve covers). Returns ``{"x", "mean", "low", "high", "seeds"}`` (arrays; low/high = mean -+
    half-width, equal to the mean for a single curve)."""
    curves = [(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)) for x, y in curves]
    curves = [(x, y) for x, y in curves if len(x) >= 2]
    if not curves:
        raise ValueError("curves must hold at least one curve of >= 2 points")
    lo_x, hi_x = max(x[0] for x, _ in curves), min(x[-1] for x, _ in curves)
    if not hi_x > lo_x:
        raise ValueError(f"the curves share no x range (they start at {lo_x:g} and the first ends at {hi_x:g})")
    grid = np.linspace(lo_x, hi_x, int(points))
    Y = np.stack([np.interp(grid, x, y) for x, y in curves])
    mean = Y.mean(axis=0)
    if len(curves) == 1:
        half = np.zeros_like(mean)
    else:
        t = _T975[len(curves) - 2] if len(curves) - 1 <= len(_T975) else 1.96
        half = t * Y.std(axis=0, ddof=1) / np.sqrt(len(curves))
    return {"x": grid, "mean": mean, "low": mean - half, "high": mean + half, "seeds": len(curves)}
