"""Push robustness of the policies on hsddp_gym/Bounding-v0: falls after a body-velocity change mid-episode.

Every push ``[dvx, dvz, dpitch_rate]`` (m/s, m/s, rad/s; positive pitch rate is nose-down) is applied through
the env's documented reset option ``{"push": {"delta_v": ..., "time": T}}`` at each of the ``--times`` (env
time, default 1 s; several times spread over a gait cycle push at different gait phases); each (policy,
push, time) runs ``--seeds`` seeded episodes of ``--steps`` control steps (default reset noise). An episode
counts as a fall when it terminates (unhealthy) before its last step.

Writes ``OUT/push_robustness.json`` (per policy and push: falls, episodes, and per episode the seed, push
time, fall, fall time and, for the MPC policies, the planner failures) and ``push_robustness.md`` (a table of
falls / episodes). The default grid holds pushes along each axis of growing size. Episodes are independent:
``--workers`` runs them in parallel processes with the same results.

Usage::

    python experiments/push_robustness.py --out runs/push [--policies mpc heuristic] [--seeds 3] [--times 1.0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.benchmarks.pushes import DEFAULT_PUSHES, POLICIES, markdown, push_label, push_policy, run_grid, run_one
from hsddp_gym.envs.bounding import DEFAULT_FRAME_SKIP, DEFAULT_SIM_TIMESTEP
from hsddp_gym.util.io import atomic_path, write_json
from hsddp_gym.util.parallel import add_backend_arguments, check_backend

__all__ = ["DEFAULT_PUSHES", "POLICIES", "markdown", "push_label", "push_policy", "run_grid", "run_one", "main"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/push", help="output directory (default: %(default)s)")
    p.add_argument("--policies", nargs="+", default=["mpc", "heuristic"], choices=POLICIES,
                   help="policies to test (default: %(default)s)")
    p.add_argument("--seeds", type=int, default=3, help="episodes per policy and push (default: %(default)s)")
    p.add_argument("--first-seed", type=int, default=100, help="seed of the first episode (default: %(default)s)")
    p.add_argument("--times", type=float, nargs="+", default=[1.0],
                   help="push times [s] of env time; each is run with every seed (default: %(default)s)")
    p.add_argument("--steps", type=int, default=500,
                   help="control steps per episode, push included (default: %(default)s = 2.5 s)")
    p.add_argument("--mpc-options", default=None, metavar="JSON",
                   help='settings of the mpc-options policy by their flat names (MPCOptions.replace) as JSON, e.g. '
                        '\'{"planner_dt": 0.005, "speed_integral_gain": null}\' (default: none)')
    p.add_argument("--workers", type=int, default=1,
                   help="parallel worker processes (or the CPUs of the local Ray instance); the results do not "
                        "depend on it (default: %(default)s)")
    add_backend_arguments(p)
    p.add_argument("--push", type=float, nargs=3, action="append", metavar=("DVX", "DVZ", "DPITCH"),
                   help="a push to test (repeatable; default: the built-in grid)")
    args = p.parse_args(argv)
    if args.seeds < 1:
        p.error("--seeds must be >= 1")
    if args.steps < 1:
        p.error("--steps must be >= 1")
    if not all(t >= 0 for t in args.times):
        p.error("--times must be >= 0")
    if args.workers < 1:
        p.error("--workers must be >= 1")
    try:
        check_backend(args.backend, args.address)
    except (ImportError, ValueError) as exc:
        p.error(f"--backend {args.backend}: {exc}")
    mpc_options = None
    if args.mpc_options is not None:
        import json

        from hsddp_gym.planners.policies.mpc import MPCOptions

        try:
            mpc_options = json.loads(args.mpc_options)
            if not isinstance(mpc_options, dict):
                raise ValueError("not a JSON object")
            MPCOptions().replace(**mpc_options)
        except (ValueError, TypeError) as exc:
            p.error(f"--mpc-options must be a JSON object of MPC settings by their flat names: {exc}")
    if "mpc-options" in args.policies and mpc_options is None:
        p.error("the mpc-options policy needs --mpc-options")
    pushes = [tuple(v) for v in args.push] if args.push else DEFAULT_PUSHES
    results = run_grid(args.policies, pushes, args.seeds, args.first_seed, args.times, args.steps, args.workers,
                       mpc_options=mpc_options, backend=args.backend, address=args.address)
    out = Path(args.out)
    dt = DEFAULT_FRAME_SKIP * DEFAULT_SIM_TIMESTEP  # the env's default control period
    write_json(out / "push_robustness.json", {"push_times_s": args.times, "steps": args.steps,
                                              "mpc_options": mpc_options,
                                              "first_seed": args.first_seed, "results": results,
                                              "command": " ".join(["python", *sys.argv])})
    table = markdown(results, args.times, args.steps, dt)
    with atomic_path(out / "push_robustness.md") as tmp:
        tmp.write_text(table)
    print("\n" + table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
