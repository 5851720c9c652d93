"""HS-DDP motions beyond the bound: plan a pronk or a gait transition with AL + ReB, check every limit, and draw it.

Writes into --out: summary.json (schedule, solve time, iterations, the limits measured), <motion>_strips.png (the
motion as snapshots), <motion>_states.png (trunk height, pitch, forward speed) and, unless --no-gif, <motion>.gif
(real time). The motions and their schedules, references, costs and constraints are described in
docs/planner/motions.md and hsddp_gym.planners.motions.

Usage::

    python experiments/motions.py --motion pronk --out runs/motions [--speed 1.0] [--cycles 4]
        [--record results/motions/pronk.json] [--gif-out docs/figures/pronk.gif]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.planners.motions import MOTIONS, SPEED_RANGE


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--motion", required=True, choices=MOTIONS,
                        help="pronk (double stance / flight repeated), stand_to_bound (from rest into bounding), "
                             "bound_pronk_bound (bounding, pronking, bounding) or bound_to_stop (bounding, then a "
                             "landing on both feet and a double stance that ends at rest), gap_jump (bounding, a jump "
                             "over a 0.3 m gap, bounding on), box_jump (bounding, a jump onto a 0.1 m box, bounding on "
                             "it) or backflip (from standing, a flight through -2 pi of pitch, a landing at rest)")
    parser.add_argument("--out", default="runs/motions", help="output directory (default: %(default)s)")
    parser.add_argument("--speed", type=float, default=1.0,
                        help=f"target forward speed [m/s], in [{SPEED_RANGE[0]}, {SPEED_RANGE[1]}] "
                             "(default: %(default)s)")
    parser.add_argument("--cycles", type=int, default=None,
                        help="pronk cycles for --motion pronk (default 4); bounding and pronk cycles per gait segment "
                             "for a transition (default 2); bounding cycles before and after a jump (default 2); "
                             "none for the backflip")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the results as a record of the results store (results/motions/NAME.json)")
    parser.add_argument("--no-gif", action="store_true", help="skip the GIF")
    parser.add_argument("--gif-out", default=None, metavar="FILE.gif",
                        help="write the GIF here instead of --out/<motion>.gif (e.g. docs/figures/pronk.gif)")
    parser.add_argument("--gif-stride", type=int, default=20,
                        help="knots (1 ms each) per GIF frame, played in real time (default: %(default)s)")
    parser.add_argument("--gif-width", type=int, default=360, help="GIF width [px] (default: %(default)s)")
    parser.add_argument("--gif-height", type=int, default=200, help="GIF height [px] (default: %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no solver table")
    args = parser.parse_args(argv)
    if args.cycles is not None and args.cycles < 1:
        parser.error(f"--cycles must be >= 1, got {args.cycles}")
    if not SPEED_RANGE[0] <= args.speed <= SPEED_RANGE[1]:
        parser.error(f"--speed must be in [{SPEED_RANGE[0]}, {SPEED_RANGE[1]}] m/s, got {args.speed}")
    if args.gif_stride < 1:
        parser.error(f"--gif-stride must be >= 1, got {args.gif_stride}")

    from hsddp_gym.planners.motions import plan_motion
    from hsddp_gym.reports.figures import motion_figure_data, motion_figures
    from hsddp_gym.reports.store import machine_info, write_record
    from hsddp_gym.util.io import write_json

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    machine = machine_info()
    res = plan_motion(args.motion, args.speed, args.cycles, verbose=not args.quiet)
    s = res.summary
    lim = s["limits"]
    print(f"{args.motion}: {s['status']}, {s['al_iterations']} AL / {s['ddp_iterations']} DDP iterations, "
          f"{s['solve_time_s']:.2f} s; |u| <= {lim['max_abs_torque']:.2f} N m, min f_z {lim['min_normal_grf']:.1f} N, "
          f"max(|f_x| - mu f_z) {lim['max_friction_violation']:.2f} N, sum g^2 {lim['switching_violation']:.2e} m^2, "
          f"hips {lim['hip_range'][0]:.2f}..{lim['hip_range'][1]:.2f} rad, knees {lim['knee_range'][0]:.2f}.."
          f"{lim['knee_range'][1]:.2f} rad; limits {'met' if lim['ok'] else 'VIOLATED: ' + ', '.join(lim['violated'])}")
    summary = {k: v for k, v in s.items() if k != "timings"}
    write_json(out / "summary.json", summary)
    dt = res.problem.dt
    fig = motion_figure_data(res.X, dt)
    terrain = res.problem.terrain
    paths = motion_figures({args.motion.replace("_", " "): fig}, out, prefix=args.motion,
                           terrains={args.motion.replace("_", " "): terrain} if terrain is not None else None)
    if not args.no_gif:
        from hsddp_gym.viz.render import render_trajectory, save_gif

        frames = render_trajectory(res.X, every=args.gif_stride, width=args.gif_width, height=args.gif_height,
                                   text=args.motion)
        gif = Path(args.gif_out) if args.gif_out else out / f"{args.motion}.gif"
        gif.parent.mkdir(parents=True, exist_ok=True)
        save_gif(frames, gif, fps=1.0 / (dt * args.gif_stride))
        paths.append(gif)
    for p in paths:
        print(f"wrote {p}")
    if args.record:
        keep = ("motion", "method", "target_speed", "modes", "final_mode", "durations", "gaits", "status", "converged",
                "al_iterations", "ddp_iterations", "solve_time_s", "warm_start_time_s", "avg_forward_speed",
                "final_speed", "final_pitch", "final_max_abs_velocity", "min_body_height", "max_abs_pitch", "cost",
                "total_time", "limits")
        data = {k: s[k] for k in keep}
        data["cycles"] = args.cycles if args.cycles is not None else (
            4 if args.motion == "pronk" else 0 if args.motion == "backflip" else 2)
        if res.problem.terrain is not None:
            data["terrain"] = {"edges": list(res.problem.terrain.edges), "levels": list(res.problem.terrain.levels),
                               "gaps": list(res.problem.terrain.gaps)}
        data["figure"] = fig
        write_record(args.record, data, f"HS-DDP (AL + ReB) plan of the {args.motion.replace('_', ' ')} motion: "
                     "schedule, iterations, solve time and every limit measured.", machine=machine)
        print(f"wrote {args.record}")
    return 0 if lim["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
