"""The ``hsddp-gym`` command line.

Every subcommand writes into ``--out DIR``: a ``summary.json`` with the numbers, plus figures and data.
Run ``hsddp-gym SUBCOMMAND --help`` for the options of each.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.io import write_json


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


# ----------------------------------------------------------------------------------------------- plan
def _plan_outputs(result, out: Path, plots: bool) -> dict:
    files = {}
    pr = result.problem
    if result.solution is not None:
        result.solution.save(out / "solution.npz")
        files["solution"] = "solution.npz"
    else:
        from hsddp_gym.io import write_npz

        write_npz(out / "trajectory.npz", X=result.X, X_pre=result.X_pre, U=result.U, GRF=result.GRF)
        files["trajectory"] = "trajectory.npz"
    if plots:
        from hsddp_gym import plotting

        robot = pr.dynamics.robot
        td = [tuple(float(c) for c in robot.foot_positions(result.X_pre[i, :7])[f])
              for i, f in enumerate(pr.touchdown) if f >= 0]
        plotting.plot_motion_strips(robot, {result.method: result.X}, out / "motion.png",
                                    touchdowns={result.method: td})
        plotting.plot_states({result.method: result.X}, pr.dt, out / "states.png", target_speed=None)
        plotting.plot_forces_torques(pr.dt, result.U, result.GRF, pr.constraints.torque_limit,
                                     pr.constraints.friction, out / "forces_torques.png", stance=pr.stance, foot=0,
                                     title=f"{result.method}: front foot GRF and joint torques")
        files.update(motion="motion.png", states="states.png", forces_torques="forces_torques.png")
        if result.solution is not None:
            plotting.plot_convergence({result.method: result.solution}, out / "convergence.png")
            files["convergence"] = "convergence.png"
    return files


def cmd_plan(args) -> int:
    from planners.solution import SolverOptions
    from planners.tasks import plan_bounding

    out = Path(args.out)
    options = SolverOptions(max_al_iterations=args.max_al_iterations, max_ddp_iterations=args.max_ddp_iterations)
    result = plan_bounding(args.method, cycles=args.cycles, speed=args.speed, options=options,
                           verbose=not args.quiet)
    summary = dict(result.summary)
    summary["files"] = _plan_outputs(result, out, not args.no_plots)
    summary["command"] = " ".join(["hsddp-gym", *sys.argv[1:]]) if sys.argv else ""
    write_json(out / "summary.json", summary)
    _print_summary(summary)
    print(f"wrote {out / 'summary.json'}")
    return 0


def _print_summary(summary: dict) -> None:
    keys = ("method", "status", "al_iterations", "ddp_iterations", "switching_violation", "max_abs_torque",
            "min_normal_grf", "max_friction_violation", "avg_forward_speed", "cost", "solve_time_s")
    for k in keys:
        if k in summary:
            v = summary[k]
            print(f"  {k:<24} {v:.6g}" if isinstance(v, float) else f"  {k:<24} {v}")


# ----------------------------------------------------------------------------------------------- sto
def cmd_sto(args) -> int:
    from planners.tasks import run_sto

    out = Path(args.out)

    def progress(rec):
        if not args.quiet:
            tt = rec.get("total_time")
            print(f"  STO iteration {rec['iteration']:>3d}: {rec['status']:<12} "
                  + (f"total time {tt:.4f} s, cost {rec['cost']:.4g}, sum g^2 {rec['switching_violation']:.2e}"
                     if tt is not None else ""), flush=True)

    res, summary = run_sto(args.method, iterations=args.iterations, cycles=args.cycles,
                           second_order=args.second_order, callback=progress)
    res.solution.save(out / "solution.npz")
    summary["command"] = " ".join(["hsddp-gym", *sys.argv[1:]]) if sys.argv else ""
    write_json(out / "summary.json", summary)
    print(f"{args.method}: total time {summary['initial_total_time']:.4f} s -> {summary['total_time']:.4f} s "
          f"({100 * summary['reduction']:.1f} % reduction) in {summary['iterations']} iterations; "
          f"durations [ms] {[round(1e3 * d, 1) for d in summary['mode_durations']]}")
    print(f"wrote {out / 'summary.json'}")
    return 0


# ----------------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from planners.tasks import plan_bounding

    out = Path(args.out)
    print("[1/2] heuristic bounding controller (the warm start), 5 cycles of 80/72/72/72 ms ...")
    heur = plan_bounding("heuristic", cycles=args.cycles)
    print("[2/2] HS-DDP (impact-aware DDP + AL switching constraints + relaxed barriers) ...")
    plan = plan_bounding("al-reb", cycles=args.cycles, verbose=not args.quiet)
    summary = {"heuristic": heur.summary, "al-reb": plan.summary}
    from hsddp_gym import plotting

    robot = plan.problem.dynamics.robot
    plotting.plot_motion_strips(robot, {"heuristic warm start": heur.X, "HS-DDP (al-reb)": plan.X},
                                out / "motion.png")
    plotting.plot_states({"heuristic": heur.X, "HS-DDP": plan.X}, plan.problem.dt, out / "states.png",
                         target_speed=1.0)
    plotting.plot_convergence({"al-reb": plan.solution}, out / "convergence.png")
    plan.solution.save(out / "solution.npz")
    summary["files"] = ["motion.png", "states.png", "convergence.png", "solution.npz"]
    write_json(out / "summary.json", summary)
    for name in ("heuristic", "al-reb"):
        print(f"{name}:")
        _print_summary(summary[name])
    print(f"wrote {out}/summary.json and figures")
    return 0


# ----------------------------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hsddp-gym",
        description="HS-DDP (Li & Wensing, RA-L 2020) for the planar MIT Mini Cheetah: plan bounding gaits, "
                    "optimize switching times, run the planner as MPC in the Gymnasium env.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="plan a 5-cycle bound with HS-DDP from the heuristic warm start; write "
                                    "figures and a summary",
                       description="The main job: heuristic warm start, HS-DDP (al-reb) plan of the paper's "
                                   "bounding task, figures (motion.png, states.png, convergence.png), "
                                   "solution.npz and summary.json in --out.")
    p.add_argument("--out", default="runs/demo", help="output directory (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=5, help="gait cycles to plan (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="do not print the solver's iteration table")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("plan", help="paper task 1: plan a bounding gait with a given method",
                       description="Plan --cycles bounding cycles (80/72/72/72 ms, h = 1 ms, the paper's initial "
                                   "state, heuristic warm start) and write summary.json, the solution and figures.")
    p.add_argument("--method", choices=("heuristic", "ddp", "al", "al-reb"), default="al-reb",
                   help="heuristic: the warm start alone; ddp: impact-aware DDP ignoring switching constraints; "
                        "al: + augmented Lagrangian on them; al-reb: + relaxed barriers on torque, normal force and "
                        "friction (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=5, help="gait cycles (default: %(default)s)")
    p.add_argument("--speed", type=_positive_float, default=1.0,
                   help="desired forward speed [m/s] (default: %(default)s)")
    p.add_argument("--max-al-iterations", type=_positive_int, default=6,
                   help="outer AL iterations at most (default: %(default)s)")
    p.add_argument("--max-ddp-iterations", type=_positive_int, default=10,
                   help="DDP iterations per AL iteration at most (default: %(default)s)")
    p.add_argument("--out", default="runs/plan", help="output directory (default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--quiet", action="store_true", help="do not print the solver's iteration table")
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("sto", help="paper task 2: switching-time optimization (HS-DDP Algorithm 2 or the "
                                   "open-loop baseline)",
                       description="Optimize the mode durations of --cycles bounding cycles (start 80/72/72/72 ms, "
                                   "task-1 costs, AL parameters and warm start). hsddp: Newton steps on the "
                                   "durations rolled out with the feedback policy (the paper); open-loop: the "
                                   "control held open loop (Xu & Antsaklis). Writes summary.json and solution.npz.")
    p.add_argument("--method", choices=("hsddp", "open-loop"), default="hsddp",
                   help="hsddp: feedback policy in the duration update; open-loop: Xu & Antsaklis baseline "
                        "(default: %(default)s)")
    p.add_argument("--iterations", type=_positive_int, default=30, help="STO iterations at most (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=1, help="gait cycles (default: %(default)s)")
    p.add_argument("--second-order", action="store_true",
                   help="exact V_zz with the dynamics' second-order terms (slower); default: iLQR's, as the paper")
    p.add_argument("--out", default="runs/sto", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no per-iteration lines")
    p.set_defaults(func=cmd_sto)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
