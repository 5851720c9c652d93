"""Push robustness of the policies on hsddp_gym/Bounding-v0: falls after a body-velocity change mid-episode.

Every push ``[dvx, dvz, dpitch_rate]`` (m/s, m/s, rad/s; positive pitch rate is nose-down) is applied through
the env's documented reset option ``{"push": {"delta_v": ..., "time": T}}`` at ``T`` seconds of episode time
(default 1 s, mid-gait); each (policy, push) pair runs ``--seeds`` seeded episodes of ``--steps`` control
steps (default reset noise). An episode counts as a fall when it terminates (unhealthy) before its last step.

Writes ``OUT/push_robustness.json`` (per policy and push: falls, seeds, fall times) and ``push_robustness.md``
(a table of falls / episodes). The default grid holds pushes along each axis of growing size.

Usage::

    python experiments/push_robustness.py --out runs/push [--policies mpc heuristic] [--seeds 3] [--time 1.0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from envs.bounding import DEFAULT_FRAME_SKIP, DEFAULT_SIM_TIMESTEP
from hsddp_gym.io import atomic_path, write_json

DEFAULT_PUSHES = [
    (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (-1.5, 0.0, 0.0), (1.5, 0.0, 0.0), (3.0, 0.0, 0.0),
    (0.0, -1.0, 0.0), (0.0, -1.5, 0.0), (0.0, -2.5, 0.0),
    (0.0, 0.0, 6.0), (0.0, 0.0, -6.0), (0.0, 0.0, 8.0), (0.0, 0.0, -10.0), (0.0, 0.0, 10.0),
]


POLICIES = ("mpc", "mpc-recovery", "mpc-handover", "heuristic", "random")
"""``mpc-recovery``: the MPC with ``MPCOptions(recovery=True)`` (immediate re-plan, more iterations, the
heuristic only after a failed re-plan); ``mpc-handover``: also ``recovery_handover=True`` (the heuristic acts
for the whole recovery window)."""


def make_policy(name: str, env):
    from planners.mpc import MPCOptions, MPCPolicy
    from planners.policies import HeuristicPolicy, RandomPolicy

    if name == "mpc-recovery":
        return MPCPolicy.from_env(env, options=MPCOptions(recovery=True))
    if name == "mpc-handover":
        return MPCPolicy.from_env(env, options=MPCOptions(recovery=True, recovery_handover=True))
    factories = {"mpc": MPCPolicy, "heuristic": HeuristicPolicy, "random": RandomPolicy}
    if name not in factories:
        raise ValueError(f"policy must be one of {list(POLICIES)}, got {name!r}")
    return factories[name].from_env(env)


def run_grid(policies, pushes, seeds: int, first_seed: int, push_time: float, steps: int, progress: bool = True
             ) -> dict:
    """``{policy: {push label: {"falls", "episodes", "fall_times_s"}}}``."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)
    from planners.evaluation import run_episode

    results: dict = {}
    for name in policies:
        results[name] = {}
        for dv in pushes:
            falls, times = 0, []
            for seed in range(first_seed, first_seed + seeds):
                env = gym.make("hsddp_gym/Bounding-v0")
                policy = make_policy(name, env)
                res = run_episode(env, policy, seed, options={"push": {"delta_v": list(dv), "time": push_time}},
                                  max_steps=steps)
                if res.fell:
                    falls += 1
                    times.append(res.length * env.unwrapped.dt)
                env.close()
            label = "[" + ", ".join(f"{v:+g}" for v in dv) + "]"
            results[name][label] = {"delta_v": list(dv), "falls": falls, "episodes": seeds, "fall_times_s": times}
            if progress:
                print(f"{name:<10} push {label:<18} falls {falls}/{seeds}", flush=True)
    return results


def markdown(results: dict, push_time: float, steps: int, dt: float) -> str:
    policies = list(results)
    labels = list(results[policies[0]])
    lines = [f"Falls / episodes after a push at t = {push_time:g} s ({steps} steps = {steps * dt:g} s per episode)",
             "", "| push [dvx, dvz, dpitch_rate] | " + " | ".join(policies) + " |",
             "|---|" + "---|" * len(policies)]
    for label in labels:
        cells = [f"{results[p][label]['falls']}/{results[p][label]['episodes']}" for p in policies]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/push", help="output directory (default: %(default)s)")
    p.add_argument("--policies", nargs="+", default=["mpc", "heuristic"], choices=POLICIES,
                   help="policies to test (default: %(default)s)")
    p.add_argument("--seeds", type=int, default=3, help="episodes per policy and push (default: %(default)s)")
    p.add_argument("--first-seed", type=int, default=100, help="seed of the first episode (default: %(default)s)")
    p.add_argument("--time", type=float, default=1.0, help="push time [s] (default: %(default)s)")
    p.add_argument("--steps", type=int, default=500,
                   help="control steps per episode, push included (default: %(default)s = 2.5 s)")
    p.add_argument("--push", type=float, nargs=3, action="append", metavar=("DVX", "DVZ", "DPITCH"),
                   help="a push to test (repeatable; default: the built-in grid)")
    args = p.parse_args(argv)
    if args.seeds < 1:
        p.error("--seeds must be >= 1")
    if args.steps < 1:
        p.error("--steps must be >= 1")
    if not args.time >= 0:
        p.error("--time must be >= 0")
    pushes = [tuple(v) for v in args.push] if args.push else DEFAULT_PUSHES
    results = run_grid(args.policies, pushes, args.seeds, args.first_seed, args.time, args.steps)
    out = Path(args.out)
    dt = DEFAULT_FRAME_SKIP * DEFAULT_SIM_TIMESTEP  # the env's default control period
    write_json(out / "push_robustness.json", {"push_time_s": args.time, "steps": args.steps,
                                              "first_seed": args.first_seed, "results": results,
                                              "command": " ".join(["python", *sys.argv])})
    table = markdown(results, args.time, args.steps, dt)
    with atomic_path(out / "push_robustness.md") as tmp:
        tmp.write_text(table)
    print("\n" + table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
