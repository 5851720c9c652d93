"""What each rule of the MPC buys: the default MPC beside the MPC without one rule at a time, on the same episodes.

The rules are the settings of the schedule estimator, the planner and the feedback law that act only when the robot
leaves the nominal gait (a late landing, a push, a biased sensor). Each arm is the default ``MPCOptions()`` with one
of them off (:data:`ABLATIONS`), and every arm plays the same episodes: the conditions (default: the 32 conditions of
the generality table, ``hsddp_gym.envs.perturbations``) times the seeds. Per arm: falls per condition, their seeds,
and the falls where the default did not fall and vice versa.

Usage::

    python experiments/rule_ablations.py --out runs/rule_ablations --seeds 10 --first-seed 53000 --workers 2 \\
        [--arms default no_restep ...] [--conditions push push_flight ...] \\
        [--record results/robustness/rule_ablations.json]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ABLATIONS = {
    "default": {},
    "no_late_landing": {"touchdown_height": None},
    "no_ground_search": {"ground_search_speed": None},
    "no_flight_reach": {"flight_reach": None},
    "no_restep": {"restep": False},
    "no_lost_stance": {"lost_stance_steps": 0},
    "no_double_stance": {"double_stance": None},
    "no_pushing_torques": {"min_stance_force": None},
    "no_feedback_replan": {"replan_feedback": None},
    "feedback_replan_one_iteration": {"feedback_iterations": None},
    "no_restart": {"restart_ratio": None},
    "no_speed_governor": {"speed_ramp": None},
    "filter_restart_at_once": {"filter_restart_steps": 1},
    "no_delay_search": {"delay_search": 0},
    "no_bias_estimate": {"bias_memory": None},
}
"""Each arm's settings by their flat names (``MPCOptions().replace(**settings)``); ``default`` is the default MPC."""
RULES = {
    "no_late_landing": "a late flight's landing foot at the ground has landed (`touchdown_height`)",
    "no_ground_search": "a late flight's plans search for the ground before the calibration (`ground_search_speed`)",
    "no_flight_reach": "a flight lasts until its landing hip can reach the ground (`flight_reach`)",
    "no_restep": "a second step of the other foot after a pitch kick (`restep`)",
    "no_lost_stance": "a stance whose foot left the ground is lost (`lost_stance_steps`)",
    "no_double_stance": "a landing on both feet starts a double stance (`double_stance`)",
    "no_pushing_torques": "the law's torques projected onto those that push (`min_stance_force`)",
    "no_feedback_replan": "re-plan at once when the feedback would saturate (`replan_feedback`)",
    "feedback_replan_one_iteration": "feedback re-plans solved further (`feedback_iterations`)",
    "no_restart": "a re-plan gone far off solved again from scratch (`restart_ratio`)",
    "no_speed_governor": "the speed reference within 0.5 m/s of the measured speed (`speed_ramp`)",
    "filter_restart_at_once": "the filter restarts on two outliers in a row, not one (`filter_restart_steps`)",
    "no_delay_search": "the executed delay estimated online (`delay_search`)",
    "no_bias_estimate": "the sensor-bias estimate from the feet on the ground (`bias_memory`)",
}
"""What each ablated arm takes away (the rule the default has)."""


def arm_spec(settings: dict) -> dict:
    """The robustness benchmark's policy spec of an arm (``hsddp_gym.benchmarks.robustness``)."""
    return {"kind": "mpc-options", "mpc_options": dict(settings)} if settings else {"kind": "mpc"}


def summarize(results: dict, conditions) -> dict:
    """``{arm: {"falls", "episodes", "fall_cells": {condition: [seeds]}, "extra": [(condition, seed)],
    "fewer": [(condition, seed)]}}``: ``extra`` the episodes the arm fell in and the default did not, ``fewer`` the
    reverse."""
    default = {(c, s) for c in conditions for s in results["default"][c]["fall_seeds"]}
    out = {}
    for arm, cells in results.items():
        falls = {(c, s) for c in conditions for s in cells[c]["fall_seeds"]}
        out[arm] = {"falls": len(falls), "episodes": sum(cells[c]["episodes"] for c in conditions),
                    "fall_cells": {c: cells[c]["fall_seeds"] for c in conditions if cells[c]["fall_seeds"]},
                    "extra": sorted(falls - default), "fewer": sorted(default - falls)}
    return out


def main(argv=None) -> int:
    from hsddp_gym.envs.perturbations import check_conditions
    from hsddp_gym.reports.tables.robustness import generality_groups
    from hsddp_gym.util.parallel import add_backend_arguments, check_backend

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="output folder (rule_ablations.json)")
    p.add_argument("--arms", nargs="+", default=list(ABLATIONS), choices=list(ABLATIONS), metavar="ARM",
                   help=f"the arms (default: all of {', '.join(ABLATIONS)}; 'default' is always run)")
    p.add_argument("--conditions", nargs="+", default=[c for _, group in generality_groups() for c in group],
                   help="condition names (default: the generality table's)")
    p.add_argument("--seeds", type=int, default=10, help="episodes per arm and condition (default %(default)s)")
    p.add_argument("--first-seed", type=int, default=53000, help="first episode seed (default %(default)s)")
    p.add_argument("--workers", type=int, default=1, help="parallel episodes (the results do not depend on it)")
    p.add_argument("--record", default=None, metavar="FILE.json", help="also write a record of the results store")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_backend_arguments(p)
    args = p.parse_args(argv)
    if args.seeds < 1 or args.workers < 1:
        p.error("--seeds and --workers must be >= 1")
    try:
        conditions = check_conditions(args.conditions, "--conditions")
        check_backend(args.backend, args.address)
    except (ImportError, ValueError) as exc:
        p.error(str(exc))
    from hsddp_gym.benchmarks.robustness import run_benchmark
    from hsddp_gym.reports.store import machine_info, write_record
    from hsddp_gym.util.io import write_json

    arms = ["default"] + [a for a in args.arms if a != "default"]
    machine = machine_info()
    t0 = time.perf_counter()
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    results = run_benchmark({a: arm_spec(ABLATIONS[a]) for a in arms}, conditions, seeds, workers=args.workers,
                            progress=not args.quiet, backend=args.backend, address=args.address)
    summary = summarize(results, conditions)
    data = {"arms": {a: {"settings": ABLATIONS[a], "rule": RULES.get(a), **summary[a]} for a in arms},
            "conditions": list(conditions), "seeds": seeds,
            "falls": {a: {c: results[a][c]["fall_seeds"] for c in conditions} for a in arms},
            "wall_time_s": time.perf_counter() - t0}
    write_json(args.out / "rule_ablations.json", {"command": " ".join(["python", *sys.argv]), **data})
    for a in arms:
        s = summary[a]
        print(f"{a:32s} {s['falls']:3d}/{s['episodes']}  extra {len(s['extra'])}  fewer {len(s['fewer'])}  "
              f"{s['fall_cells']}")
    if args.record:
        write_record(args.record, data, "The default MPC beside the MPC without one of its rules at a time, on the "
                     "same episodes of the generality conditions", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
