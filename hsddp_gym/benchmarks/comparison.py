"""The policy comparison's policies (``experiments/compare_policies.py``, ``experiments/two_simulators.py``): every
policy of the comparison protocol by name, with what it learned from."""

from __future__ import annotations

import json
import time
from pathlib import Path

TRAINED = {"bc": ("policy.npz", "summary.json"), "dagger": ("policy.npz", "summary.json"),
           "ppo": ("model.zip", "summary.json"), "sac": ("model.zip", "summary.json")}
"""The trained kinds and the files of a run each needs."""


def build(name: str, run_dir: Path | None, rl_actions: str = "deterministic", rl_checkpoint: str = "final"):
    """``(policy, info)`` of policy ``name`` for the default ``hsddp_gym/Bounding-v0`` (the policy's
    ``reset_options``: the expert starts at its plan's first state; ``info``: the samples it learned from and its
    training time), or ``FileNotFoundError`` for a trained kind whose ``run_dir`` lacks its files."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401
    from hsddp_gym.rollout.policies import PolicySpec, make_policy

    env = gym.make("hsddp_gym/Bounding-v0")  # only its public settings are read (the default env)
    if name in ("mpc", "heuristic", "random"):
        return make_policy(PolicySpec(name), env), {"samples": "-", "train_time_s": None}
    if name == "expert":
        t = time.perf_counter()
        policy = make_policy("expert", env)
        return policy, {"samples": "-", "train_time_s": time.perf_counter() - t,
                        "train_time_note": "offline HS-DDP plan"}
    missing = [f for f in TRAINED[name] if run_dir is None or not (run_dir / f).exists()]
    if missing:
        raise FileNotFoundError(f"{name}: missing {', '.join(missing)} in {run_dir}")
    summary = json.loads((run_dir / "summary.json").read_text())
    if name in ("bc", "dagger"):
        policy = make_policy(f"{name}:{run_dir}", env)  # behind the MPC's perception if trained behind it
        if name == "bc":
            count, unit = summary["transitions"], f"transitions ({summary['demonstrations']} demos, " \
                                                  f"{summary.get('dataset_policy')})"
        else:
            count, unit = summary["expert_labels"], f"expert labels ({summary['expert']['name']} expert)"
    else:
        policy = make_policy(PolicySpec(f"{name}:{run_dir}", options={"deterministic": rl_actions == "deterministic",
                                                                      "checkpoint": rl_checkpoint}), env)
        count, unit = summary["steps"], "env steps"
    return policy, {"samples": f"{count:,} {unit}", "samples_count": int(count), "samples_unit": unit,
                    "train_time_s": summary.get("wall_time_s"), "summary": summary}
