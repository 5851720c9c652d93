"""The tables that set the results beside the paper's: task 1 (Algorithm 1) and task 2 (switching-time
optimization), every cost and reference variant and the periodic cycle."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import NA, fmt, load_average, markdown_table, source_line


def paper_task1(store: Store) -> str:
    """Task 1 side by side with the paper: iterations, constraint satisfaction, speed, cost, solve time."""
    d = store.data("paper/task1")
    header = ["method", "AL it.", "DDP it.", "Σ g² [m²]", "max \\|u\\| [N m]", "min f_z [N]",
              "max (\\|f_x\\| − μ f_z) [N]", "speed [m/s]", "cost (eq. 18)", "solve [s]"]
    rows = []
    for m, s in d["methods"].items():
        planned = m != "heuristic"
        rows.append([m, s["al_iterations"] if planned else NA, s["ddp_iterations"] if planned else NA,
                     fmt(s["switching_violation"], ".2e"), fmt(s["max_abs_torque"], ".2f"),
                     fmt(s["min_normal_grf"], ".1f"), fmt(s["max_friction_violation"], ".2f"),
                     fmt(s["avg_forward_speed"], ".3f"), fmt(s["cost"], ".0f"),
                     fmt(s["solve_time_s"], ".2f") if planned else NA])
    paper = d["paper"]
    rows.append(["*paper*", f"*al: {paper['al']['al_iterations']}, al-reb: {paper['al-reb']['al_iterations']}*", "",
                 "*≤ 1e-4*", "*≤ 33*", "*≥ 0*", "*≤ 0*", "*1.0*", "", "*(MATLAB)*"])
    note = (f"{d['cycles']} cycles, 80/72/72/72 ms phases, h = 1 ms. Solve times are wall-clock on the recording "
            f"machine ({store['paper/task1'].machine.get('cpus')} cores, load average "
            f"{load_average(store['paper/task1'].machine)}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "paper/task1")])


def _zref(v: dict) -> str:
    return "0" if v["z_velocity"] == "paper" else "±1 m/s"


def _on(flag: bool) -> str:
    return "on" if flag else "off"


def _ms(durations) -> str:
    return " / ".join(f"{1e3 * d:.1f}" for d in durations)


def paper_sto_variants(store: Store) -> str:
    """Task 2: every cost/reference variant, HS-DDP against the open-loop method, and the paper's numbers."""
    d = store.data("paper/sto_variants")
    header = ["ż_ref", "GRF term", "½ in Φ", "max \\|g\\| stop", "HS-DDP total [s]", "HS-DDP", "open loop total [s]",
              "open loop", "ratio", "HS-DDP BS/FL1/FS/FL2 [ms]", "max \\|g\\| HS-DDP / OL [mm]"]
    rows = []
    for r in d["rows"]:
        v, hs, ol = r["variant"], r["hsddp"], r["open-loop"]
        if v["periodic"]:
            continue
        ratio = r["reduction_ratio"]
        stop = NA if v["max_touchdown_error"] is None else f"{1e3 * v['max_touchdown_error']:g} mm"
        rows.append([_zref(v), _on(v["grf_tracking"]), _on(v["terminal_half"]), stop, f"{hs['total_time']:.4f}",
                     f"{100 * hs['reduction']:.1f} %", f"{ol['total_time']:.4f}", f"{100 * ol['reduction']:.1f} %",
                     NA if ratio is None else f"{ratio:.1f}×", _ms(hs["mode_durations"]),
                     f"{1e3 * hs['max_touchdown_error']:.2f} / {1e3 * ol['max_touchdown_error']:.2f}"])
    p = d["paper"]
    rows.append(["*paper*", "", "", "", f"*{p['hsddp']['total_time']}*", f"*{100 * p['hsddp']['reduction']:.1f} %*",
                 "", f"*{100 * p['open-loop']['reduction']:.1f} %*",
                 f"*{p['hsddp']['reduction'] / p['open-loop']['reduction']:.1f}×*", "*FL1 and FS shortened*", ""])
    note = (f"One cycle from 80/72/72/72 ms ({1e3 * d['rows'][0]['hsddp']['initial_total_time']:.0f} ms), "
            f"{d['iterations']} STO iterations at most. Reduction = 1 − total / initial total (negative: the cycle "
            "got longer); ratio = HS-DDP's reduction over the open-loop method's (– where the open loop lengthened "
            "the cycle).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "paper/sto_variants")])


def paper_sto_periodic(store: Store) -> str:
    """Task 2 on the periodic cycle: durations, periodicity residual, vertical velocity and mean normal force."""
    d = store.data("paper/sto_variants")
    header = ["ż_ref", "method", "total [s]", "reduction", "BS/FL1/FS/FL2/BS [ms]",
              "end − start, max: positions / velocities", "v_z start → end [m/s]", "mean normal force [N]"]
    rows = []
    for r in d["rows"]:
        if not r["variant"]["periodic"]:
            continue
        for method, label in (("hsddp", "HS-DDP"), ("open-loop", "open loop")):
            s = r[method]
            rows.append([_zref(r["variant"]), label, f"{s['total_time']:.4f}", f"{100 * s['reduction']:.1f} %",
                         _ms(s["mode_durations"]),
                         f"{1e3 * s['max_periodicity_error_position']:.1f} mm / "
                         f"{s['max_periodicity_error_velocity']:.3f} m/s",
                         f"{s['initial_vertical_velocity']:+.2f} → {s['final_vertical_velocity']:+.2f}",
                         f"{s['mean_normal_grf']:.1f} (weight {s['weight']:.1f})"])
    return "\n".join([markdown_table(header, rows), "", source_line(store, "paper/sto_variants")])
