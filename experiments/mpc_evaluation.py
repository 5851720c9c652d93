"""Issue "planner as a policy", the measured claims in one run: the MPC, the heuristic and random policies in
hsddp_gym/Bounding-v0 with its default reset noise and time limit; a push, for the heuristic and the MPC; other
target speeds.

* policies: ``--episodes`` episodes each from seed 0 (the MPC's with a GIF);
* push: ``--push T DVX DVZ DPITCH`` (default: +10 rad/s nose-down pitch rate at t = 1 s) for the heuristic and the
  MPC (its default options), ``--episodes`` episodes from seed 100;
* target speeds 0.5 and 1.5 m/s: the MPC, ``--episodes`` episodes from seed 0.

The expert's tracking of the 5-cycle plan is ``experiments/expert_tracking.py``; the push grid over directions
and gait phases is ``experiments/push_robustness.py``.

Usage: python experiments/mpc_evaluation.py --out runs/mpc_eval [--episodes 10] [--push 1.0 0 0 10]
Writes OUT/summary.json with one block per experiment (the fields of ``hsddp-gym rollout``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.util.io import write_json
from hsddp_gym.workflows import run_rollouts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/mpc_eval", help="output directory (default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=10,
                        help="episodes per policy and experiment (default: %(default)s)")
    parser.add_argument("--push", type=float, nargs=4, default=(1.0, 0.0, 0.0, 10.0),
                        metavar=("T", "DVX", "DVZ", "DPITCH"),
                        help="the push: time [s], velocity change (m/s, m/s, rad/s) (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    out = Path(args.out)
    n = args.episodes
    summary = {}
    for policy in ("mpc", "heuristic", "random"):
        print(f"== {policy}: {n} episodes", flush=True)
        summary[policy] = run_rollouts(policy, n, 0, out / policy, video=policy == "mpc")
    t, dvx, dvz, dw = args.push
    push = {"delta_v": [dvx, dvz, dw], "time": t}
    for policy in ("heuristic", "mpc"):
        print(f"== push {push} with {policy}", flush=True)
        summary[f"push_{policy}"] = run_rollouts(policy, n, 100, out / f"push_{policy}", push=push)
    for speed in (0.5, 1.5):
        print(f"== mpc at target speed {speed}", flush=True)
        summary[f"mpc_speed_{speed}"] = run_rollouts("mpc", n, 0, out / f"mpc_speed_{speed}",
                                                     env_kwargs={"target_speed": speed})
    summary["command"] = " ".join(["python", *sys.argv])
    write_json(out / "summary.json", summary)
    for name, s in summary.items():
        if isinstance(s, dict) and "mean_return" in s:
            print(f"{name:<18} return {s['mean_return']:8.1f} ± {s['std_return']:6.1f}  falls {s['falls']}/"
                  f"{s['episodes']}  speed {s['mean_forward_speed']:.3f}  RTF {s['real_time_factor']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
