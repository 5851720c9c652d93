"""Paper task 1 (Sec. V-B/C): five-cycle bounding with heuristic / DDP / AL / AL+ReB; Figs. 4, 5 and 6.

Usage: python experiments/paper_task1.py --out runs/task1 [--cycles 5]
Writes summary.json (one entry per method), fig4_convergence.png, fig5_motion.png, fig6_forces_torques.png
and each method's solution.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.planners.tasks import PLAN_METHODS, plan_bounding
from hsddp_gym.util.io import write_json
from hsddp_gym.viz import plotting

PAPER = {"al": {"al_iterations": 3}, "al-reb": {"al_iterations": 4}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/task1", help="output directory (default: %(default)s)")
    parser.add_argument("--cycles", type=int, default=5, help="gait cycles (default: %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no solver tables")
    args = parser.parse_args(argv)
    out = Path(args.out)
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
    pr = results["al-reb"].problem
    robot = pr.dynamics.robot

    def touchdowns(r):
        return [tuple(float(c) for c in robot.foot_positions(r.X_pre[i, :7])[f])
                for i, f in enumerate(pr.touchdown) if f >= 0]

    labels = {"heuristic": "heuristic controller (warm start)", "ddp": "DDP, switching constraints ignored",
              "al": "AL, switching constraints enforced"}
    plotting.plot_motion_strips(robot, {labels[m]: results[m].X for m in labels}, out / "fig5_motion.png",
                                touchdowns={labels[m]: touchdowns(results[m]) for m in labels}, dt=pr.dt)
    plotting.plot_convergence({m: results[m].solution for m in ("ddp", "al", "al-reb")}, out / "fig4_convergence.png")
    r = results["al-reb"]
    plotting.plot_forces_torques(pr.dt, r.U, r.GRF, pr.constraints.torque_limit, pr.constraints.friction,
                                 out / "fig6_forces_torques.png", stance=pr.stance, foot=0,
                                 title="AL + ReB: front-foot GRF (top) and joint torques (bottom)")
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
