"""Issue "planner as a policy": the MPC, the plan-tracking expert, the heuristic and random policies in
hsddp_gym/Bounding-v0 with its default reset noise and time limit; a push; other target speeds.

Usage: python experiments/mpc_evaluation.py --out runs/mpc_eval [--episodes 10] [--quick]
Writes summary.json with one block per experiment (the fields of `hsddp-gym rollout`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.cli import run_rollouts
from hsddp_gym.io import write_json


def expert_tracking(out: Path) -> dict:
    """Track the 5-cycle al-reb plan in the env from its initial state; state tracking error."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401
    from planners.evaluation import run_episode
    from planners.policies import PlanTrackingExpert
    from planners.tasks import plan_bounding

    sol = plan_bounding("al-reb", cycles=5).solution
    env = gym.make("hsddp_gym/Bounding-v0", reset_noise_scale=0.0)
    policy = PlanTrackingExpert.from_env(env, solution=sol)
    steps = int(round(sol.times[-1] / env.unwrapped.dt))
    res = run_episode(env, policy, 0, options={"state": sol.X[0]}, max_steps=steps)
    t = env.unwrapped.dt * np.arange(res.states.shape[0])
    plan = np.array([np.interp(t, sol.times, sol.X[:, j]) for j in range(14)]).T
    err = res.states - plan
    return {"plan_duration_s": float(sol.times[-1]), "steps": res.length, "fell": res.fell,
            "max_abs_error_q": np.abs(err[:, :7]).max(axis=0).tolist(),
            "rms_error_q": np.sqrt(np.mean(err[:, :7] ** 2, axis=0)).tolist(),
            "final_x_env": float(res.states[-1, 0]), "final_x_plan": float(sol.X[-1, 0]),
            "mean_forward_speed": res.forward_speed}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/mpc_eval", help="output directory (default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per policy (default: %(default)s)")
    parser.add_argument("--push", type=float, nargs=4, default=(1.0, -0.6, 0.0, 0.0),
                        metavar=("T", "DVX", "DVZ", "DPITCH"), help="the push (default: %(default)s)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    summary = {}
    for policy in ("mpc", "heuristic", "random"):
        print(f"== {policy}: {args.episodes} episodes", flush=True)
        summary[policy] = run_rollouts(policy, args.episodes, 0, out / policy, video=policy == "mpc")
    print("== expert tracking the 5-cycle al-reb plan", flush=True)
    summary["expert_tracking"] = expert_tracking(out)
    t, dvx, dvz, dw = args.push
    push = {"delta_v": [dvx, dvz, dw], "time": t}
    for policy in ("mpc", "heuristic"):
        print(f"== push {push} with {policy}", flush=True)
        summary[f"push_{policy}"] = run_rollouts(policy, 3, 100, out / f"push_{policy}", push=push)
    for speed in (0.5, 1.5):
        print(f"== mpc at target speed {speed}", flush=True)
        summary[f"mpc_speed_{speed}"] = run_rollouts("mpc", 3, 200, out / f"mpc_speed_{speed}",
                                                     env_kwargs={"target_speed": speed})
    summary["command"] = " ".join(["python", *sys.argv])
    write_json(out / "summary.json", summary)
    for name, s in summary.items():
        if isinstance(s, dict) and "mean_return" in s:
            print(f"{name:<16} return {s['mean_return']:8.1f} ± {s['std_return']:6.1f}  falls {s['falls']}/"
                  f"{s['episodes']}  speed {s['mean_forward_speed']:.3f}  RTF {s['real_time_factor']:.2f}")
    print("expert tracking:", summary["expert_tracking"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
