"""A fingerprint of the package's behaviour, for refactors that must not change results.

Usage: python experiments/behaviour_fingerprint.py OUT.json [--compare OTHER.json]

Hashes (SHA-256 of the float64 bytes) of paper task 1's trajectories and controls for every method and its
summary, the paper task 2 STO summaries of both methods, and the actions and states of 10 seeded default-MPC
episodes (seeds 0-9) in ``hsddp_gym/Bounding-v0``; wall-clock fields are left out. Two runs of the same code give
the same file; ``--compare`` lists the entries that differ from another run (exit code 1 if any).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np


def _hash(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
    return h.hexdigest()[:16]


def _no_times(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if "time" not in k and k != "timings"}


def fingerprint(mpc_seeds: int = 10, progress: bool = True) -> dict:
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.planners.policies.mpc import MPCPolicy
    from hsddp_gym.planners.tasks import PLAN_METHODS, plan_bounding, run_sto
    from hsddp_gym.rollout.episodes import run_episode

    out = {}
    for method in PLAN_METHODS:
        r = plan_bounding(method, cycles=5, verbose=False)
        out[f"task1/{method}"] = {"X": _hash(r.X), "U": _hash(r.U), "summary": _no_times(r.summary)}
        if progress:
            print(f"task 1 {method}: X {out[f'task1/{method}']['X']}", flush=True)
    for method in ("hsddp", "open-loop"):
        _, summary = run_sto(method=method)
        out[f"sto/{method}"] = _no_times(summary)
    env = gym.make("hsddp_gym/Bounding-v0")
    policy = MPCPolicy.from_env(env)
    for seed in range(mpc_seeds):
        res = run_episode(env, policy, seed)
        out[f"mpc/{seed}"] = {"actions": _hash(res.actions), "states": _hash(res.states),
                              "return": float(np.sum(res.rewards))}
        if progress:
            print(f"mpc seed {seed}: return {out[f'mpc/{seed}']['return']:.4f}", flush=True)
    env.close()
    return json.loads(json.dumps(out, default=float))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", help="where to write the fingerprint (JSON)")
    p.add_argument("--compare", default=None, help="a fingerprint of another run to compare with")
    p.add_argument("--mpc-seeds", type=int, default=10, help="MPC episodes (seeds 0..N-1; default: %(default)s)")
    args = p.parse_args(argv)
    if args.mpc_seeds < 0:
        p.error(f"--mpc-seeds must be >= 0, got {args.mpc_seeds}")
    from hsddp_gym.util.io import write_json

    fp = fingerprint(args.mpc_seeds)
    write_json(args.out, fp)
    if args.compare is None:
        return 0
    with open(args.compare) as fh:
        other = json.load(fh)
    differ = sorted(k for k in set(fp) | set(other) if fp.get(k) != other.get(k))
    print("identical" if not differ else "differ: " + ", ".join(differ))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
