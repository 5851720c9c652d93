"""Paper task 2 (Sec. V-D/E): one-cycle switching-time optimization, HS-DDP against the open-loop method
of Xu & Antsaklis; Figs. 7 and 8.

Usage: python experiments/paper_task2_sto.py --out runs/task2 [--iterations 30] [--second-order]
           [--z-velocity paper|code] [--grf-tracking on|off] [--terminal-half on|off] [--max-touchdown-error M]
           [--periodic]
Writes summary.json (both methods, the variant recorded in each), fig7_durations.png and fig8_step_size.png.

       python experiments/paper_task2_sto.py --variants --out runs/task2_variants [--workers 2]
runs both methods on every cost / reference variant (z_velocity x grf_tracking x terminal_half), the two
reference variants with the max |g| <= 1 mm stop, and the periodic task; writes variants.json and prints the
README's table.
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import fig8_study, run_sto, sto_problem
from hsddp_gym.reports.store import machine_info, write_record
from hsddp_gym.util.io import write_json
from hsddp_gym.viz.plotting import plot_step_size, plot_sto_durations

PAPER = {"initial_total_time": 0.296, "hsddp": {"total_time": 0.2335, "reduction": 0.211},
         "open-loop": {"reduction": 0.063}}


def _variant_kwargs(args) -> dict:
    return {"z_velocity": args.z_velocity, "grf_tracking": args.grf_tracking == "on",
            "terminal_half": args.terminal_half == "on", "periodic": args.periodic,
            "max_touchdown_error": args.max_touchdown_error}


def _run(job: tuple) -> dict:
    """One (method, variant) run; the variant dict as in :func:`_variant_kwargs`."""
    method, variant, iterations, second_order = job
    v = dict(variant)
    tol = v.pop("max_touchdown_error")
    _, s = run_sto(method, iterations=iterations, second_order=second_order,
                   solver_options=SolverOptions(al_max_abs_tolerance=tol), **v)
    s.pop("cost_history")
    return s


def _label(v: dict) -> str:
    parts = [f"z_velocity={v['z_velocity']}", f"grf {'on' if v['grf_tracking'] else 'off'}",
             f"1/2 {'on' if v['terminal_half'] else 'off'}"]
    if v["max_touchdown_error"] is not None:
        parts.append(f"max|g| <= {1e3 * v['max_touchdown_error']:g} mm")
    if v["periodic"]:
        parts.append("periodic")
    return ", ".join(parts)


def run_variants(args) -> int:
    variants = [{"z_velocity": z, "grf_tracking": g, "terminal_half": t, "periodic": False,
                 "max_touchdown_error": None}
                for z, g, t in itertools.product(("paper", "code"), (True, False), (True, False))]
    variants += [{"z_velocity": z, "grf_tracking": True, "terminal_half": True, "periodic": False,
                  "max_touchdown_error": 1e-3} for z in ("paper", "code")]
    variants += [{"z_velocity": z, "grf_tracking": True, "terminal_half": True, "periodic": True,
                  "max_touchdown_error": None} for z in ("paper", "code")]
    machine = machine_info()
    jobs = [(m, v, args.iterations, args.second_order) for v in variants for m in ("hsddp", "open-loop")]
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        results = pool.map(_run, jobs, chunksize=1)
    rows = []
    for k, v in enumerate(variants):
        hs, ol = results[2 * k], results[2 * k + 1]
        ratio = hs["reduction"] / ol["reduction"] if ol["reduction"] > 0 else None  # None: open loop lengthened
        rows.append({"variant": v, "label": _label(v), "hsddp": hs, "open-loop": ol, "reduction_ratio": ratio})
    out = Path(args.out)
    write_json(out / "variants.json", {"rows": rows, "paper": PAPER, "iterations": args.iterations,
                                       "command": " ".join(["python", "experiments/paper_task2_sto.py",
                                                            *(args.argv or [])])})
    print("| variant | HS-DDP total [s] | HS-DDP reduction | open-loop total [s] | open-loop reduction | ratio "
          "| HS-DDP durations [ms] | HS-DDP iters | max abs g HS-DDP / OL [mm] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        hs, ol = r["hsddp"], r["open-loop"]
        print(f"| {r['label']} | {hs['total_time']:.4f} | {100 * hs['reduction']:.1f} % | {ol['total_time']:.4f} | "
              f"{100 * ol['reduction']:.1f} % | "
              f"{'n/a' if r['reduction_ratio'] is None else format(r['reduction_ratio'], '.1f') + 'x'} | "
              f"{' / '.join(f'{1e3 * d:.1f}' for d in hs['mode_durations'])} | {hs['iterations']} ({hs['stopped']}) "
              f"| {1e3 * hs['max_touchdown_error']:.2f} / {1e3 * ol['max_touchdown_error']:.2f} |", flush=True)
    print(f"wrote {out / 'variants.json'}")
    if args.record:
        write_record(args.record, {"rows": rows, "paper": PAPER, "iterations": args.iterations},
                     "Paper task 2: one-cycle STO, HS-DDP and the open-loop method on every cost and reference variant",
                     machine=machine)
        print(f"wrote {args.record}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/task2", help="output directory (default: %(default)s)")
    parser.add_argument("--iterations", type=int, default=30, help="STO iterations (default: %(default)s)")
    parser.add_argument("--second-order", action="store_true", help="exact V_zz (see hsddp-gym sto --help)")
    parser.add_argument("--z-velocity", choices=("paper", "code"), default="paper",
                        help="vertical-velocity references (see hsddp-gym sto --help; default: %(default)s)")
    parser.add_argument("--grf-tracking", choices=("on", "off"), default="on",
                        help="ground-force tracking term (default: %(default)s)")
    parser.add_argument("--terminal-half", choices=("on", "off"), default="on",
                        help="1/2 in the terminal costs (default: %(default)s)")
    parser.add_argument("--max-touchdown-error", type=float, default=None, metavar="METRES",
                        help="Algorithm 1 also needs max |g| <= this to stop (default: sum g^2 only, as the paper)")
    parser.add_argument("--periodic", action="store_true", help="the periodic task (see hsddp-gym sto --help)")
    parser.add_argument("--variants", action="store_true", help="run every variant (see the usage above)")
    parser.add_argument("--workers", type=int, default=2, help="--variants: worker processes (default: %(default)s)")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the results as a record of the results store (e.g. results/paper/sto.json, "
                             "with --variants results/paper/sto_variants.json)")
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    if args.iterations < 0:
        parser.error(f"--iterations must be >= 0, got {args.iterations}")
    if args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    if args.max_touchdown_error is not None and not args.max_touchdown_error > 0:
        parser.error(f"--max-touchdown-error must be > 0 [m], got {args.max_touchdown_error}")
    if args.variants:
        return run_variants(args)
    out = Path(args.out)
    machine = machine_info()
    variant = _variant_kwargs(args)
    summary = {"variant": variant}
    for method in ("hsddp", "open-loop"):
        summary[method] = _run((method, variant, args.iterations, args.second_order))
        s = summary[method]
        print(f"{method:<10} total {s['initial_total_time']:.4f} -> {s['total_time']:.4f} s "
              f"({100 * s['reduction']:.1f} %), {s['iterations']} iterations, cost {s['initial_cost']:.1f} -> "
              f"{s['final_cost']:.1f}, sum g^2 {s['switching_violation']:.1e}, max |g| "
              f"{1e3 * s['max_touchdown_error']:.2f} mm", flush=True)
    ratio = summary["hsddp"]["reduction"] / summary["open-loop"]["reduction"] \
        if summary["open-loop"]["reduction"] > 0 else None  # None: the open-loop method lengthened the cycle
    summary["reduction_ratio"] = ratio
    summary["initial_total_time"] = summary["hsddp"]["initial_total_time"]
    summary["paper"] = PAPER
    # Fig. 8: a tenth of the first duration step after Algorithm 1, before Algorithm 1 re-optimizes the control
    problem = sto_problem(z_velocity=variant["z_velocity"], grf_tracking=variant["grf_tracking"],
                          terminal_half=variant["terminal_half"], periodic=variant["periodic"])
    study = fig8_study(problem, np.linspace(0.0, 0.4, 21),
                       solver_options=SolverOptions(al_max_abs_tolerance=variant["max_touchdown_error"]))
    summary["fig8"] = study
    write_json(out / "summary.json", summary)
    if not variant["periodic"]:
        plot_sto_durations(summary, out / "fig7_durations.png")
    plot_step_size(study, out / "fig8_step_size.png")
    if args.record:
        write_record(args.record, summary, "Paper task 2: one-cycle STO with HS-DDP and the open-loop method, with the "
                     "data of Figs. 7 and 8", machine=machine)
    ratio_text = "n/a (the open-loop method lengthened the cycle)" if ratio is None else f"{ratio:.2f}"
    print(f"HS-DDP / open-loop reduction ratio: {ratio_text} (paper: {0.211 / 0.063:.2f}); wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
