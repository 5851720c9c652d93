"""Paper task 2 (Sec. V-D/E): one-cycle switching-time optimization, HS-DDP against the open-loop method
of Xu & Antsaklis; Figs. 7 and 8.

Usage: python experiments/paper_task2_sto.py --out runs/task2 [--iterations 30] [--second-order]
Writes summary.json, fig7_durations.png and fig8_step_size.png.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.tasks import fig8_study, run_sto

from hsddp_gym.util.io import write_json
from hsddp_gym.viz.plotting import _plt, _save

PAPER = {"initial_total_time": 0.296, "hsddp": {"total_time": 0.2335, "reduction": 0.211},
         "open-loop": {"reduction": 0.063}}


def fig7(summary: dict, path) -> None:
    plt = _plt()
    labels = ["BS", "FL1", "FS", "FL2"]
    init = 1e3 * np.array(summary["hsddp"]["initial_durations"])
    bars = {"initial": init, "HS-DDP": 1e3 * np.array(summary["hsddp"]["mode_durations"]),
            "open loop [24]": 1e3 * np.array(summary["open-loop"]["mode_durations"])}
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.27
    for j, (name, vals) in enumerate(bars.items()):
        ax.bar(np.arange(4) + (j - 1) * width, vals, width, label=name)
    ax.set_xticks(np.arange(4), labels)
    ax.set_ylabel("mode duration [ms]")
    ax.set_title(f"total: initial {init.sum():.1f} ms, HS-DDP {bars['HS-DDP'].sum():.1f} ms, "
                 f"open loop {bars['open loop [24]'].sum():.1f} ms", fontsize=9)
    ax.legend()
    _save(fig, path)


def fig8(study: dict, path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    s = np.array(study["steps"])
    colors = {"durations": ("r", r"$\epsilon=0,\ \epsilon_z=s$"), "control": ("m", r"$\epsilon=s,\ \epsilon_z=0$"),
              "both": ("b", r"$\epsilon=\epsilon_z=s$")}
    for case, (c, label) in colors.items():
        ax.plot(s, study[case]["actual"], "-", color=c, label=f"{label} actual")
        ax.plot(s, study[case]["predicted"], "--", color=c, label=f"{label} predicted")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_yscale("symlog", linthresh=1.0)  # the duration step's actual change grows by orders of magnitude
    ax.set_xlabel("step size s")
    ax.set_ylabel("change of the objective (symlog)")
    ax.legend(fontsize=8)
    _save(fig, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/task2", help="output directory (default: %(default)s)")
    parser.add_argument("--iterations", type=int, default=30, help="STO iterations (default: %(default)s)")
    parser.add_argument("--second-order", action="store_true", help="exact V_zz (see hsddp-gym sto --help)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    summary = {}
    for method in ("hsddp", "open-loop"):
        _, summary[method] = run_sto(method, iterations=args.iterations, second_order=args.second_order)
        s = summary[method]
        print(f"{method:<10} total {s['initial_total_time']:.4f} -> {s['total_time']:.4f} s "
              f"({100 * s['reduction']:.1f} %), {s['iterations']} iterations, cost {s['initial_cost']:.1f} -> "
              f"{s['final_cost']:.1f}, sum g^2 {s['switching_violation']:.1e}", flush=True)
    ratio = summary["hsddp"]["reduction"] / summary["open-loop"]["reduction"] \
        if summary["open-loop"]["reduction"] > 0 else float("inf")
    summary["reduction_ratio"] = ratio
    summary["initial_total_time"] = summary["hsddp"]["initial_total_time"]
    summary["paper"] = PAPER
    # Fig. 8: a tenth of the first duration step after Algorithm 1, before Algorithm 1 re-optimizes the control
    study = fig8_study(HybridProblem.bounding(1), np.linspace(0.0, 0.4, 21))
    summary["fig8"] = study
    write_json(out / "summary.json", summary)
    fig7(summary, out / "fig7_durations.png")
    fig8(study, out / "fig8_step_size.png")
    print(f"HS-DDP / open-loop reduction ratio: {ratio:.2f} (paper: {0.211 / 0.063:.2f}); wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
