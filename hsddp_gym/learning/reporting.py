"""Evaluation of learned policies over seeded episodes, learning-curve plots and CSV tables."""

from __future__ import annotations


# ================================================================================================ evaluation
def evaluate_policy_episodes(policy, episodes: int = 10, seed: int = 0, env_kwargs: dict | None = None,
                             max_episode_steps: int | None = None, reset_options: dict | None = None) -> dict:
    """The comparison protocol: ``episodes`` episodes seeded ``seed, seed + 1, ...``, the policy's
    deterministic actions; returns :func:`hsddp_gym.planners.policies.evaluation.summarize` (mean/std return, falls,
    forward
    speed, episode length, ...)."""
    from hsddp_gym.datasets.collection import make_env
    from hsddp_gym.planners.policies.evaluation import run_episode, summarize

    env = make_env(env_kwargs, max_episode_steps)
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
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def eval_brief(summary: dict) -> dict:
    keys = ("episodes", "seeds", "mean_return", "std_return", "returns", "falls", "mean_forward_speed",
            "mean_episode_length")
    return {k: summary[k] for k in keys if k in summary}
