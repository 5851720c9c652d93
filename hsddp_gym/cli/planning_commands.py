"""``hsddp-gym plan``, ``sto`` and ``demo``: the paper's planning tasks (HS-DDP plans, switching-time optimization)
and the main job, each writing ``summary.json`` and its files into ``--out``."""

from __future__ import annotations

import sys
from pathlib import Path

from hsddp_gym.cli.parsing import positive_float, positive_int, print_values
from hsddp_gym.util.extras import require
from hsddp_gym.util.io import write_json
from hsddp_gym.util.validation import UsageError, check_output_dir
from hsddp_gym.workflows import write_plan_outputs


# ----------------------------------------------------------------------------------------------- plan
def cmd_plan(args) -> int:
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.tasks import WarmStartDivergedError, plan_bounding

    out = check_output_dir(args.out, "--out")
    if not args.no_plots:
        require(["matplotlib"], "hsddp-gym plan (its figures; or pass --no-plots)")
    options = SolverOptions(max_al_iterations=args.max_al_iterations, max_ddp_iterations=args.max_ddp_iterations)
    try:
        result = plan_bounding(args.method, cycles=args.cycles, speed=args.speed, options=options,
                               verbose=not args.quiet)
    except WarmStartDivergedError as exc:  # e.g. --method heuristic on a long horizon: the rollout tumbles
        print(f"error: {exc}", file=sys.stderr)
        return 1
    summary = dict(result.summary)
    summary["files"] = write_plan_outputs(result, out, not args.no_plots)
    summary["command"] = args.command_line
    write_json(out / "summary.json", summary)
    _print_summary(summary)
    print(f"wrote {out / 'summary.json'}")
    return 0


def _print_summary(summary: dict) -> None:
    print_values(summary, ("method", "status", "al_iterations", "ddp_iterations", "switching_violation",
                           "max_abs_torque", "min_normal_grf", "max_friction_violation", "avg_forward_speed", "cost",
                           "solve_time_s"), 24, 6)


# ----------------------------------------------------------------------------------------------- sto
def cmd_sto(args) -> int:
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.tasks import run_sto

    out = check_output_dir(args.out, "--out")
    _check_duration_bounds(args)
    if args.periodic and args.cycles != 1:
        raise UsageError("--cycles", f"{args.cycles} with --periodic", "1: the periodic task optimizes one cycle")
    if args.periodic_weight is not None and not args.periodic:
        raise UsageError("--periodic-weight", "given without --periodic", "only with --periodic")

    def progress(rec):
        if not args.quiet:
            tt = rec.get("total_time")
            print(f"  STO iteration {rec['iteration']:>3d}: {rec['status']:<12} "
                  + (f"total time {tt:.4f} s, cost {rec['cost']:.4g}, sum g^2 {rec['switching_violation']:.2e}"
                     if tt is not None else ""), flush=True)

    periodic = {"periodic": True} if args.periodic else {}
    if args.periodic_weight is not None:
        periodic["periodic_weight"] = args.periodic_weight
    res, summary = run_sto(args.method, iterations=args.iterations, cycles=args.cycles,
                           second_order=args.second_order, callback=progress, min_duration=args.min_duration,
                           max_duration=args.max_duration, z_velocity=args.z_velocity,
                           grf_tracking=args.grf_tracking == "on", terminal_half=args.terminal_half == "on",
                           solver_options=SolverOptions(al_max_abs_tolerance=args.max_touchdown_error), **periodic)
    res.solution.save(out / "solution.npz")
    summary["command"] = args.command_line
    write_json(out / "summary.json", summary)
    print(f"{args.method}: total time {summary['initial_total_time']:.4f} s -> {summary['total_time']:.4f} s "
          f"({100 * summary['reduction']:.1f} % reduction) in {summary['iterations']} iterations; "
          f"durations [ms] {[round(1e3 * d, 1) for d in summary['mode_durations']]}; max |g| "
          f"{1e3 * summary['max_touchdown_error']:.2f} mm")
    print(f"wrote {out / 'summary.json'}")
    return 0


def _check_duration_bounds(args) -> None:
    """``--min-duration`` < ``--max-duration`` (an omitted one is STOOptions' default)."""
    import dataclasses

    from hsddp_gym.planners.optimizer.sto import STOOptions

    defaults = {f.name: f.default for f in dataclasses.fields(STOOptions)}
    lo = args.min_duration if args.min_duration is not None else defaults["min_duration"]
    hi = args.max_duration if args.max_duration is not None else defaults["max_duration"]
    if not lo < hi:
        option = "--min-duration" if args.min_duration is not None else "--max-duration"
        raise UsageError(option, f"min duration {lo} s >= max duration {hi} s"
                         + ("" if args.min_duration is not None and args.max_duration is not None
                            else " (the other bound is the default)"), "--min-duration < --max-duration")
    from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS

    start = getattr(args, "durations", None) or PAPER_BOUNDING_DURATIONS  # the optimization starts from them
    allowed = f"--min-duration <= {min(start):g} s and --max-duration >= {max(start):g} s (the initial durations)"
    if lo > min(start):
        raise UsageError("--min-duration", f"{lo} s is above the initial mode duration {min(start):g} s", allowed)
    if hi < max(start):
        raise UsageError("--max-duration", f"{hi} s is below the initial mode duration {max(start):g} s", allowed)


# ----------------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from hsddp_gym.workflows import run_demo

    check_output_dir(args.out, "--out")
    require(["matplotlib"] + ([] if args.no_video else ["PIL"]),
            "hsddp-gym demo (its figures" + (")" if args.no_video else " and GIF; or pass --no-video)"))
    summary = run_demo(Path(args.out), cycles=args.cycles, episodes=args.episodes, video=not args.no_video,
                       quiet=args.quiet, max_episode_steps=args.max_episode_steps)
    for name in ("warm_start", "hsddp_plan"):
        print(f"{name}:")
        _print_summary(summary[name])
    print("mpc_in_env:")
    print_values(summary["mpc_in_env"], ("mean_return", "falls", "mean_forward_speed", "real_time_factor",
                                         "mean_replan_ms"), 24)
    print(f"wrote {args.out}/summary.json and figures")
    return 0


# ----------------------------------------------------------------------------------------------- parsers
def add_parsers(sub) -> None:
    """Add ``demo``, ``plan`` and ``sto`` to the subparsers ``sub``."""
    p = sub.add_parser("demo", help="plan a 5-cycle bound with HS-DDP from the heuristic warm start; write "
                                    "figures and a summary",
                       description="The main job: the HS-DDP (al-reb) plan of the paper's bounding task "
                                   "beside its warm start (the heuristic controller up to 5 cycles, a repeated "
                                   "cycle of the solved 5-cycle plan beyond), figures (motion.png, states.png, "
                                   "convergence.png), "
                                   "solution.npz, then the HS-DDP MPC bounding in hsddp_gym/Bounding-v0 "
                                   "(mpc/summary.json, mpc/episode0.gif) and summary.json in --out.")
    p.add_argument("--out", default="runs/demo", help="output directory (default: %(default)s)")
    p.add_argument("--cycles", type=positive_int, default=5, help="gait cycles to plan (default: %(default)s)")
    p.add_argument("--episodes", type=positive_int, default=1,
                   help="MPC episodes to run in the env, seeds 0, 1, ... (default: %(default)s)")
    p.add_argument("--max-episode-steps", type=positive_int, default=None,
                   help="time limit of the MPC episodes in control steps of 5 ms (default: the env's 1000)")
    p.add_argument("--no-video", action="store_true", help="skip the GIF of the first MPC episode")
    p.add_argument("--quiet", action="store_true", help="do not print the solver's iteration table")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("plan", help="paper task 1: plan a bounding gait with a given method",
                       description="Plan --cycles bounding cycles (80/72/72/72 ms, h = 1 ms, the paper's initial "
                                   "state; warm start: the heuristic controller up to 5 cycles, beyond them the "
                                   "solved 5-cycle plan with its 4th cycle repeated) and write summary.json, the "
                                   "solution and figures.")
    p.add_argument("--method", choices=("heuristic", "ddp", "al", "al-reb"), default="al-reb",
                   help="heuristic: the heuristic controller's rollout alone (it diverges in cycle 10); ddp: "
                        "impact-aware DDP ignoring switching constraints; al: + augmented Lagrangian on them; "
                        "al-reb: + relaxed barriers on torque, normal force and friction (default: %(default)s)")
    p.add_argument("--cycles", type=positive_int, default=5, help="gait cycles (default: %(default)s)")
    p.add_argument("--speed", type=positive_float, default=1.0,
                   help="desired forward speed [m/s] (default: %(default)s)")
    p.add_argument("--max-al-iterations", type=positive_int, default=6,
                   help="outer AL iterations at most (default: %(default)s)")
    p.add_argument("--max-ddp-iterations", type=positive_int, default=10,
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
    p.add_argument("--iterations", type=positive_int, default=30, help="STO iterations at most (default: %(default)s)")
    p.add_argument("--cycles", type=positive_int, default=1, help="gait cycles (default: %(default)s)")
    p.add_argument("--min-duration", type=positive_float, default=None,
                   help="shortest mode duration the optimization may reach [s] (default: STOOptions' 0.02)")
    p.add_argument("--max-duration", type=positive_float, default=None,
                   help="longest mode duration [s] (default: STOOptions' 0.2)")
    p.add_argument("--second-order", action="store_true",
                   help="exact V_zz with the dynamics' second-order terms (slower); default: iLQR's, as the paper")
    p.add_argument("--z-velocity", choices=("paper", "code"), default="paper",
                   help="vertical-velocity references at the phase ends: paper = 0 (the paper's text), code = the "
                        "authors' +1 m/s after a stance, -1 m/s before a touchdown (default: %(default)s)")
    p.add_argument("--grf-tracking", choices=("on", "off"), default="on",
                   help="the authors' ground-force tracking term in the running cost; the paper has none "
                        "(default: %(default)s)")
    p.add_argument("--terminal-half", choices=("on", "off"), default="on",
                   help="the authors' 1/2 in the terminal costs; the paper's eq. 33 has none (default: %(default)s)")
    p.add_argument("--max-touchdown-error", type=positive_float, default=None, metavar="METRES",
                   help="Algorithm 1 also stops only when every landing foot is within this height of the ground "
                        "(max |g|; the authors' later code: 0.001); default: sum g^2 <= 1e-4 only, as the paper")
    p.add_argument("--periodic", action="store_true",
                   help="the periodic task: back stance, flight, front stance, flight, back stance, ending in the "
                        "start state up to x (a gait that can be repeated); needs --cycles 1")
    p.add_argument("--periodic-weight", type=positive_float, default=None,
                   help="scale of the periodic terminal penalty (default: 1e5; needs --periodic)")
    p.add_argument("--out", default="runs/sto", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no per-iteration lines")
    p.set_defaults(func=cmd_sto)
