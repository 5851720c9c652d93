"""Paper task 1 (Sec. V-B/C): five-cycle bounding with heuristic / DDP / AL / AL+ReB; Figs. 4, 5 and 6.

Usage: python experiments/paper_task1.py --out runs/task1 [--cycles 5] [--record results/paper/task1.json]
Writes summary.json (one entry per method), fig4_convergence.png, fig5_motion.png, fig6_forces_torques.png
and each method's solution.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.planners.tasks import PLAN_METHODS, plan_bounding
from hsddp_gym.reports import figures
from hsddp_gym.reports.figures import FIG5_SNAPSHOTS
from hsddp_gym.reports.store import compact, machine_info, write_record
from hsddp_gym.util.io import write_json
from hsddp_gym.viz import plotting
from hsddp_gym.viz.plotting import convergence_series

PAPER = {"al": {"al_iterations": 3}, "al-reb": {"al_iterations": 4}}


FIG5_LABELS = {"heuristic": "heuristic controller (warm start)", "ddp": "DDP, switching constraints ignored",
               "al": "AL, switching constraints enforced"}


def task1_figure_data(results: dict) -> dict:
    """What Figs. 4-6 draw (:func:`hsddp_gym.reports.figures.paper_task1`), small enough for the results store:
    the convergence logs, 14 snapshots of each Fig. 5 motion with its touchdown points, and the AL + ReB front-foot
    forces and torques (4 significant digits)."""
    pr = results["al-reb"].problem
    robot = pr.dynamics.robot
    fig5 = {}
    for m, label in FIG5_LABELS.items():
        r = results[m]
        idx = np.linspace(0, r.X.shape[0] - 1, FIG5_SNAPSHOTS).astype(int)
        fig5[label] = {"snapshots": compact(r.X[idx, :7]), "touchdowns": [
            [float(c) for c in robot.foot_positions(r.X_pre[i, :7])[f]] for i, f in enumerate(pr.touchdown) if f >= 0]}
    r = results["al-reb"]
    return {"dt": pr.dt, "duration": pr.dt * (r.X.shape[0] - 1),
            "fig4": {m: convergence_series(results[m].solution) for m in ("ddp", "al", "al-reb")},
            "fig5": fig5,
            "fig6": {"U": compact(r.U), "GRF": compact(r.GRF), "stance": pr.stance.astype(int),
                     "torque_limit": pr.constraints.torque_limit, "friction": pr.constraints.friction}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/task1", help="output directory (default: %(default)s)")
    parser.add_argument("--cycles", type=int, default=5, help="gait cycles (default: %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no solver tables")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the results as a record of the results store (results/paper/task1.json)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    machine = machine_info()
    results = {}
    for method in PLAN_METHODS:
        print(f"== {method}", flush=True)
        results[method] = plan_bounding(method, cycles=args.cycles, verbose=not args.quiet)
        if results[method].solution is not None:
            results[method].solution.save(out / f"solution_{method}.npz")
    summary = {m: r.summary for m, r in results.items()}
    summary["paper"] = PAPER
    summary["command"] = " ".join([sys.executable.split("/")[-1], *sys.argv])
    write_json(out / "summary.json", summary)
    data = {"methods": {m: results[m].summary for m in PLAN_METHODS}, "paper": PAPER, "cycles": args.cycles,
            "figures": task1_figure_data(results)}
    if args.record:
        write_record(args.record, data, "Paper task 1: five-cycle bounding planned with the heuristic, DDP, AL and "
                     "AL + ReB, with the data of Figs. 4-6", machine=machine)
        print(f"wrote {args.record}")
    for path in figures.paper_task1(data, out):
        print(f"wrote {path}")
    pr = results["al-reb"].problem
    plotting.plot_states({m: results[m].X for m in PLAN_METHODS}, pr.dt, out / "states.png", target_speed=1.0)
    print(f"{'method':<10} {'AL it':>5} {'DDP it':>6} {'sum g^2':>9} {'max|u|':>7} {'min fz':>7} {'fric viol':>9} "
          f"{'speed':>6} {'cost':>8} {'time s':>7}")
    for m in PLAN_METHODS:
        s = summary[m]
        print(f"{m:<10} {s['al_iterations']:>5} {s['ddp_iterations']:>6} {s['switching_violation']:>9.2e} "
              f"{s['max_abs_torque']:>7.2f} {s['min_normal_grf']:>7.2f} {s['max_friction_violation']:>9.3f} "
              f"{s['avg_forward_speed']:>6.3f} {s['cost']:>8.1f} {s['solve_time_s']:>7.2f}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
