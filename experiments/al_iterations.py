"""Why Algorithm 1 needs the AL iterations it needs: sum g^2 and max |g| at the end of every AL iteration of
paper task 1 (5 cycles), for the default options and for variations of the outer loop.

Usage: python experiments/al_iterations.py [--method al] [--cycles 5] [--set sigma0=35.36 --set beta=20 ...]
       [--out runs/al_iterations.json]
Each ``--set name=value`` overrides one SolverOptions field (a number); without any, the default options run.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import plan_bounding
from hsddp_gym.util.io import write_json

FIELDS = {f.name for f in dataclasses.fields(SolverOptions)}


def parse_set(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or name not in FIELDS or name == "method":
        raise argparse.ArgumentTypeError(f"--set needs name=value with a SolverOptions field, got {text!r}")
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--set {name}: value must be a number, got {value!r}") from None
    return name, int(number) if name.startswith("max_") and number.is_integer() else number


def al_table(method: str, cycles: int, overrides: dict) -> dict:
    """One solve; per AL iteration: DDP iterations so far, sum g^2, max |g| at its end (from the log)."""
    res = plan_bounding(method, cycles=cycles, options=SolverOptions(**overrides))
    sol = res.solution
    robot = res.problem.dynamics.robot
    last = {}
    for rec in sol.log:
        last[rec.al_iteration] = rec
    rows = [{"al_iteration": a + 1, "ddp_iterations": rec.ddp_iteration, "sum_g2": rec.switching_violation}
            for a, rec in sorted(last.items())]
    g = [float(robot.foot_heights(sol.X_pre[i, :7])[f]) for i, f in enumerate(res.problem.touchdown) if f >= 0]
    return {"method": method, "cycles": cycles, "overrides": overrides, "al_iterations": sol.al_iterations,
            "ddp_iterations": sol.ddp_iterations, "status": sol.status, "rows": rows,
            "final_max_abs_g": float(np.max(np.abs(g)))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--method", choices=("al", "al-reb"), default="al", help="(default: %(default)s)")
    parser.add_argument("--cycles", type=int, default=5, help="gait cycles (default: %(default)s)")
    parser.add_argument("--set", type=parse_set, action="append", default=[], metavar="NAME=VALUE",
                        help="override a SolverOptions field (repeatable)")
    parser.add_argument("--out", default=None, help="write the table as JSON here")
    args = parser.parse_args(argv)
    if args.cycles < 1:
        parser.error(f"--cycles must be >= 1, got {args.cycles}")
    t = al_table(args.method, args.cycles, dict(args.set))
    print(f"{args.method} {t['overrides'] or 'defaults'}: {t['al_iterations']} AL iterations, "
          f"{t['ddp_iterations']} DDP iterations, {t['status']}, final max |g| {1e3 * t['final_max_abs_g']:.2f} mm")
    for r in t["rows"]:
        print(f"  AL {r['al_iteration']}: DDP iterations so far {r['ddp_iterations']:>3d}, sum g^2 {r['sum_g2']:.2e}")
    if args.out:
        write_json(args.out, t)
    return 0


if __name__ == "__main__":
    sys.exit(main())
