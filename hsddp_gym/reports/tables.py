"""Every results table of the README and the documentation site, rendered from the records of the results store.

:data:`TABLES` maps a table id (the ``ID`` of ``<!-- results: ID -->``) to a function of the
:class:`~hsddp_gym.reports.store.Store` that returns the table as Markdown, followed by a line naming the records it
comes from and the commands that made them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from hsddp_gym.reports.store import Store

NA = "–"


def fmt(value, spec: str = ".3g", none: str = NA) -> str:
    """``value`` formatted with ``spec`` (``none`` for None or NaN)."""
    if value is None or (isinstance(value, float) and value != value):
        return none
    return format(value, spec)


def markdown_table(header: list[str], rows: Iterable[list], align: list[str] | None = None) -> str:
    """A GitHub-flavoured Markdown table (``align``: one of ``"l"``, ``"r"`` per column; default left)."""
    rows = [[str(c) for c in r] for r in rows]
    for r in rows:
        if len(r) != len(header):
            raise ValueError(f"row {r} has {len(r)} cells, the header {len(header)}")
    align = align or ["l"] * len(header)
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(rule) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def source_line(store: Store, *rids: str) -> str:
    """The provenance line under a table: the records and the commands that made them."""
    parts = []
    for rid in rids:
        rec = store[rid]
        if len(rec.commands) > 2:
            cmds = f"{len(rec.commands)} commands, listed in the record"
        else:
            cmds = "; ".join(f"`{c}`" for c in rec.commands)
        parts.append(f"`results/{rid}.json` ({cmds})")
    return "Generated from " + ", ".join(parts) + " by `python -m hsddp_gym.reports`."


# -- paper ---------------------------------------------------------------------------------------------------------

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
            f"{_load(store['paper/task1'].machine)}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "paper/task1")])


def _load(machine: dict) -> str:
    before, after = machine.get("load_average_before"), machine.get("load_average_after")
    if not before:
        return "unknown"
    return f"{before[0]:.2f} before, {after[0]:.2f} after" if after else f"{before[0]:.2f}"


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


# -- env ---------------------------------------------------------------------------------------------------------

def env_physics(store: Store) -> str:
    """The env's physical claims: the energy-consistent scheme (default) beside the legacy one and the MuJoCo twin."""
    d = store.data("env/physics")
    names = [k for k in ("energy_consistent", "legacy", "mujoco") if k in d["schemes"]]
    schemes = [d["schemes"][k] for k in names]
    n = 4 * d["states_per_combination"]

    def cells(fn):
        return [fn(rec) for rec in schemes]

    def energy(key):
        return cells(lambda rec: f"{rec['energy_excess_J'][key]:+.1e} J" if "energy_excess_J" in rec else "–")

    def joined(values, fmt):
        return " / ".join("blow-up" if v is None else format(v, fmt) for v in values)

    e = schemes[0]
    rates = " / ".join(e["free_flight_drift"])
    speeds = " / ".join(e["landing_depth_mm"])
    seconds = f"{d['flight_seconds']:g} s"
    rows = [
        [f"largest ΔE per 1 ms step, zero torque, g = 9.81 ({n} states in all contact combinations × "
         f"{d['steps']} steps)", *energy("g=9.81, zero torque")],
        ["the same, g = 0", *energy("g=0, zero torque")],
        ["largest ΔE − τ·Δq per step, random constant torques", *energy("g=9.81, random torques")],
    ]
    for key, what in (("energy", "energy"), ("linear_momentum", "linear momentum"),
                      ("angular_momentum", "angular momentum about the CoM")):
        rows.append([f"free flight, g = 0, zero torque, joints up to {rates} rad/s: relative drift of the {what} "
                     f"over {seconds}",
                     *cells(lambda rec, key=key: joined([v[key] for v in rec["free_flight_drift"].values()], ".1e"))])
    rows.append(["sticking foot, largest motion in one step (rocking double stance)",
                 *cells(lambda rec: f"{rec['stick_drift_m']:.1e} m" if "stick_drift_m" in rec else "–")])
    rows.append([f"deepest foot after landings at {speeds} m/s [mm]",
                 *cells(lambda rec: joined(rec["landing_depth_mm"].values(), ".3g"))])
    for key in e["tunnelling_mm"]:
        rows.append([f"deepest foot at the end of any 1 ms step, {d['bound_states']} start states at the reset "
                     f"bounds, 1 s of {key.replace('bang_bang', 'bang-bang torque').replace('zero,', 'zero torque,')}"
                     " [mm]", *cells(lambda rec, key=key: joined([rec["tunnelling_mm"][key]], ".3g"))])
    header = ["claim", "default scheme", "legacy scheme (`energy_consistent=False`)",
              "MuJoCo twin (soft contacts)"][:1 + len(names)]
    lines = [markdown_table(header, rows), ""]
    t = d.get("throughput")
    if t:
        lines += [f"Throughput (default frame skip, random actions, timed interleaved in the same run): Bounding-v0 "
                  f"{t['bounding_env_steps_per_s']:,.0f} env steps/s, HalfCheetah-v5 "
                  f"{t['halfcheetah_env_steps_per_s']:,.0f}: **{t['ratio']:.2f}×** HalfCheetah-v5.", ""]
    lines.append(source_line(store, "env/physics"))
    return "\n".join(lines)


# -- speed -------------------------------------------------------------------------------------------------------

def _machine_note(store: Store, rid: str) -> str:
    m = store[rid].machine
    return f"{m.get('cpus')} cores, load average {_load(m)}"


def _env_rows(d: dict) -> dict:
    return {(r["scheme"], r["frame_skip"], r["actions"]): r for r in d["rows"]}


def speed_env(store: Store) -> str:
    """Bounding-v0's env steps per second (single process) and HalfCheetah-v5's in the same run."""
    d = store.data("speed/env")
    hc = d["halfcheetah"]
    rows = []
    for r in d["rows"]:
        ratio = fmt(r["env_steps_per_s"] / hc["env_steps_per_s"], ".2f") if hc else NA
        rows.append([r["scheme"], r["frame_skip"], r["actions"], f"{r['env_steps_per_s']:,.0f}",
                     f"{r['sim_steps_per_s']:,.0f}", ratio])
    if hc:
        rows.append(["HalfCheetah-v5 (MuJoCo)", hc["frame_skip"], "random", f"{hc['env_steps_per_s']:,.0f}",
                     f"{hc['sim_steps_per_s']:,.0f}", "1.00"])
    table = markdown_table(["scheme", "frame_skip", "actions", "env steps/s", "simulated steps/s",
                            "× HalfCheetah-v5"], rows, ["l", "r", "l", "r", "r", "r"])
    inter = "; ".join(f"{r['actions']}: energy-consistent / legacy = {r['ratio']:.2f}" for r in d["interleaved"])
    return "\n".join([table, "", f"Timed interleaved in the same run: {inter}. Machine: "
                      f"{_machine_note(store, 'speed/env')}.", source_line(store, "speed/env")])


def speed_vector_env(store: Store) -> str:
    """The vector env against N, the single env and HalfCheetah-v5 (env steps per CPU second)."""
    d = store.data("speed/vector_env")
    rate = {r["configuration"]: r for r in d["rows"]}
    single = rate["single"]["env_steps_per_cpu_s"]
    hc = rate.get("halfcheetah", {}).get("env_steps_per_cpu_s")
    names = {"single": "single env `gym.make(\"hsddp_gym/Bounding-v0\")`", "halfcheetah": "HalfCheetah-v5 (MuJoCo)"}
    rows = []
    for name, r in rate.items():
        v = r["env_steps_per_cpu_s"]
        rows.append([names.get(name, name.replace("vector N=", "vector env, N = ")), f"{v:,.0f}",
                     f"{v / single:.2f}", fmt(v / hc if hc else None, ".2f"), f"{r['env_steps_per_wall_s']:,.0f}"])
    table = markdown_table(["configuration", "env steps per CPU second", "× single env", "× HalfCheetah-v5",
                            "env steps per wall second"], rows, ["l", "r", "r", "r", "r"])
    return "\n".join([table, "", f"{d['seconds']:g} s per row in {d['rounds']} interleaved rounds, one thread each. "
                      f"Machine: {_machine_note(store, 'speed/vector_env')}.", source_line(store, "speed/vector_env")])


def speed_dynamics(store: Store) -> str:
    """Microseconds per call by contact mode, and the compiled linearization against Pinocchio's calls."""
    d = store.data("speed/dynamics")
    modes = ["FL", "FS", "BS", "DS"]
    label = {"FL": "flight", "FS": "front stance", "BS": "back stance", "DS": "double stance"}
    rows = [[name] + [f"{by_mode[m]:.1f}" for m in modes] for name, by_mode in d["per_call_us"].items()]
    pin = d["pinocchio_derivatives_per_knot_us"]
    lin = d["per_call_us"][d["linearize_key"]]
    rows.append(["Pinocchio's derivative calls (reference, same run)"] + [f"{pin[m]:.1f}" for m in modes])
    rows.append(["**compiled linearize / Pinocchio**"] + [f"**{lin[m] / pin[m]:.2f}**" for m in modes])
    table = markdown_table(["µs per call"] + [label[m] for m in modes], rows, ["l", "r", "r", "r", "r"])
    fused = d["fused_per_knot_us"]
    return "\n".join([table, "", f"On the {d['knots']}-knot bounding trajectory a rollout that linearizes every "
                      f"knot on the way costs {fused:.1f} µs per knot (the solver's path). Machine: "
                      f"{_machine_note(store, 'speed/dynamics')}.", source_line(store, "speed/dynamics")])


def speed_solver(store: Store) -> str:
    """The time per DDP iteration and its breakdown."""
    d = store.data("speed/solver")
    keep = ("line search", "backward pass", "cost derivatives", "reset-map Jacobians (19 per linearization)",
            "warm-start rollout + linearization", "other (objective values, AL updates, logging)", "TOTAL")
    rows = []
    for r in d["breakdown"]:
        if r["name"] in keep:
            name = "**total**" if r["name"] == "TOTAL" else r["name"]
            rows.append([name, f"{r['ms_per_iteration']:.2f}", f"{1e3 * r['ms_per_iteration'] / d['knots']:.2f}"])
    table = markdown_table(["per DDP iteration", "ms", "µs per knot"], rows, ["l", "r", "r"])
    return "\n".join([table, "", f"Paper task 1 ({d['cycles']} cycles, {d['knots']} knots, `{d['method']}`): "
                      f"{d['ddp_iterations']} DDP iterations in {d['solve_s']['best']:.2f} s (best of "
                      f"{d['repeats']}). Machine: {_machine_note(store, 'speed/solver')}.",
                      source_line(store, "speed/solver")])


def speed_solver_horizons(store: Store) -> str:
    """The time per DDP iteration, the iterations and the constraints against the horizon (1 to 20 cycles)."""
    rec = store["speed/solver_horizons"]
    d = rec.data
    rows = []
    for r in d["rows"]:
        rows.append([r["cycles"], r["knots"], r["warm_start"], f"{r['ddp_iterations']} ({r['al_iterations']})",
                     f"{r['ms_per_ddp_iteration']['best']:.1f}", f"**{r['us_per_knot']:.2f}**",
                     f"{r['max_abs_torque']:.1f}", f"{r['min_normal_grf']:.1f}", f"{r['max_friction_violation']:.2f}",
                     f"{1e3 * r['max_touchdown_error']:.2f}", f"{r['solve_s']['best']:.2f}",
                     f"{r['warm_start_s']:.2f}"])
    table = markdown_table(["cycles", "knots", "warm start", "DDP it. (AL it.)", "ms per DDP it.", "µs per knot",
                            "max \\|u\\| [N m]", "min f_z [N]", "max (\\|f_x\\| − μ f_z) [N]", "max \\|g\\| [mm]",
                            "solve [s]", "warm start [s]"], rows, ["r", "r", "l"] + ["r"] * 9)
    limit = d["rows"][0]["torque_limit"] if d["rows"] else None
    fit = d.get("fit")
    fit_text = (f" A least-squares line through the rows: {fit['intercept_ms']:.2f} ms + {fit['us_per_knot']:.2f} µs "
                "per knot per DDP iteration." if fit else "")
    m = rec.machine
    load = max((m.get("load_average_before") or [0.0])[0], (m.get("load_average_after") or [0.0])[0])
    loaded = (" — a loaded machine: other jobs shared the cores, so the times are upper bounds"
              if m.get("cpus") and load >= 0.5 * m["cpus"] else "")
    note = (f"`{d['method']}` on `HybridProblem.bounding(cycles)` (296 knots of 1 ms per cycle), the best of "
            f"{d['repeats']} solves with fresh solvers; the warm start is timed apart (*repeated plan*: it includes "
            f"the 5-cycle solve). Limits: \\|u\\| ≤ {fmt(limit, 'g')} N m, f_z ≥ 0, friction violation ≤ 0.{fit_text} "
            f"Machine: {_machine_note(store, 'speed/solver_horizons')}{loaded}.")
    return "\n".join([table, "", note, source_line(store, "speed/solver_horizons")])


def speed_mpc(store: Store) -> str:
    """The MPC's re-plan time and real-time factor, beside the Pinocchio reference of the same knots."""
    d = store.data("speed/mpc")
    rows = [
        ["re-plan (one DDP iteration over the horizon), mean", f"{d['replan_ms']['mean']:.2f} ms"],
        [f"Pinocchio's derivative calls over the same {d['knots']} knots (reference)",
         f"{d['pinocchio_reference_ms']:.2f} ms"],
        ["**re-plan / reference**", f"**{d['replan_ms']['mean'] / d['pinocchio_reference_ms']:.2f}**"],
        ["the compiled dynamics' pass over those knots", f"{d['compiled_pass_ms']:.2f} ms"],
        ["re-plan period (the real-time budget)", f"{d['replan_period_ms']:.0f} ms"],
        ["**real-time factor** (simulated / wall time of the closed loop, env included)",
         f"**{d['real_time_factor']:.2f}**"],
    ]
    table = markdown_table(["MPC at its defaults", "measured"], rows, ["l", "r"])
    return "\n".join([table, "", f"{d['seconds']:.1f} s of bounding, {d['replans']} re-plans, "
                      f"{d['planner_failures']} failed. Machine: {_machine_note(store, 'speed/mpc')}.",
                      source_line(store, "speed/mpc")])


def speed_summary(store: Store) -> str:
    """One row per benchmark: the figure and its ratio to a reference measured in the same run (README)."""
    env = store.data("speed/env")
    vec = {r["configuration"]: r["env_steps_per_cpu_s"] for r in store.data("speed/vector_env")["rows"]}
    dyn = store.data("speed/dynamics")
    sol = store.data("speed/solver")
    mpc = store.data("speed/mpc")
    ours = next(r for r in env["rows"] if r["scheme"] == "energy" and r["frame_skip"] == 5
                and r["actions"] == "random")
    rows = []
    if env["halfcheetah"]:
        rows.append(["`Bounding-v0`, single env, random actions", f"{ours['env_steps_per_s']:,.0f} env steps/s",
                     f"{ours['env_steps_per_s'] / env['halfcheetah']['env_steps_per_s']:.2f}× HalfCheetah-v5"])
    big = max((k for k in vec if k.startswith("vector")), key=lambda k: int(k.split("=")[1]))
    n64 = "vector N=64" if "vector N=64" in vec else big
    rows.append([f"vector env, N = {n64.split('=')[1]}", f"{vec[n64]:,.0f} env steps per CPU second",
                 f"{vec[n64] / vec['single']:.1f}× the single env"])
    lin = dyn["per_call_us"][dyn["linearize_key"]]
    pin = dyn["pinocchio_derivatives_per_knot_us"]
    rows.append(["dynamics + derivatives per knot (compiled), double stance", f"{lin['DS']:.1f} µs",
                 f"{lin['DS'] / pin['DS']:.2f}× Pinocchio's derivative calls"])
    rows.append([f"HS-DDP, paper task 1 ({sol['knots']} knots)", f"{sol['ms_per_ddp_iteration']['best']:.1f} ms per "
                 f"DDP iteration, {sol['solve_s']['best']:.2f} s per solve",
                 f"{1e3 * sol['ms_per_ddp_iteration']['best'] / sol['knots']:.1f} µs per knot"])
    rows.append(["MPC re-plan", f"{mpc['replan_ms']['mean']:.1f} ms",
                 f"{mpc['replan_ms']['mean'] / mpc['pinocchio_reference_ms']:.2f}× Pinocchio's derivative calls of "
                 "the same knots"])
    rows.append(["MPC closed loop", f"real-time factor {mpc['real_time_factor']:.2f}", "simulated / wall time"])
    table = markdown_table(["what", "measured", "ratio"], rows)
    return "\n".join([table, "", "More rows and the machines' loads: the speed page of the docs.",
                      source_line(store, "speed/env", "speed/vector_env", "speed/dynamics", "speed/solver",
                                  "speed/mpc")])


# -- robustness --------------------------------------------------------------------------------------------------

SUITE_LABELS = {"mpc": "MPC", "heuristic": "heuristic", "heuristic+est": "heuristic + estimator",
                "dagger@ensemble_a": "DAgger ensemble A", "dagger@ensemble_b": "DAgger ensemble B",
                "dagger@ensemble_c": "DAgger ensemble C"}
ENSEMBLES = ("dagger@ensemble_a", "dagger@ensemble_b", "dagger@ensemble_c")


def _suite_columns(store: Store) -> tuple[list[str], dict, dict]:
    """(condition order, {label: {condition: cell}}, {condition: description}) of the suite table: the model-based
    policies of ``robustness/suite`` and the DAgger ensembles of ``robustness/learners``."""
    suite = store.data("robustness/suite")
    learners = store.data("robustness/learners")
    conds = list(suite["conditions"])
    columns = dict(suite["results"])
    for label in ENSEMBLES:
        columns[label] = learners["learners"][label]
    desc = {c: suite["conditions"][c]["description"] for c in conds}
    return conds, columns, desc


def _falls(cell: dict | None) -> str:
    return NA if cell is None else f"{cell['falls']}/{cell['episodes']}"


def robustness_suite(store: Store) -> str:
    """Falls per condition of the suite for the model-based policies and the DAgger ensembles."""
    conds, columns, desc = _suite_columns(store)
    header = ["condition"] + [SUITE_LABELS.get(k, k) for k in columns]
    rows = []
    for c in conds:
        row = [f"`{c}`: {desc[c]}"]
        for cells in columns.values():
            cell = cells.get(c)
            if cell is None:
                row.append(NA)
                continue
            speed = "" if cell.get("mean_speed") is None else f", {cell['mean_speed']:.2f} m/s"
            row.append(f"**{_falls(cell)}**, {cell['mean_return']:.0f}{speed}")
        rows.append(row)
    totals = ["**falls, total**"]
    for cells in columns.values():
        have = [cells[c] for c in conds if c in cells]
        totals.append(f"**{sum(x['falls'] for x in have)}/{sum(x['episodes'] for x in have)}**")
    rows.append(totals)
    seeds = store.data("robustness/suite")["seeds"]
    note = (f"Cells: falls / episodes, mean return, mean forward speed of the episodes that did not fall. Evaluation "
            f"seeds {seeds[0]}-{seeds[-1]}, one 1000-step episode (5 s) per seed and condition. The DAgger ensembles "
            "(the mean action of three networks trained with different seeds) were evaluated with version "
            f"{store['robustness/learners'].version}.")
    return "\n".join([markdown_table(header, rows), "", note,
                      source_line(store, "robustness/suite", "robustness/learners")])


def robustness_summary(store: Store) -> str:
    """One line per policy: falls over the suite and the worst condition (for the README)."""
    conds, columns, _ = _suite_columns(store)
    rows = []
    for label, cells in columns.items():
        have = {c: cells[c] for c in conds if c in cells}
        falls = sum(x["falls"] for x in have.values())
        eps = sum(x["episodes"] for x in have.values())
        worst = max(have, key=lambda c: have[c]["falls"])
        worst_text = NA if have[worst]["falls"] == 0 else f"`{worst}` ({_falls(have[worst])})"
        rows.append([SUITE_LABELS.get(label, label), f"{falls}/{eps}", worst_text])
    table = markdown_table(["policy", f"falls over the {len(conds)} conditions", "worst condition"], rows)
    return "\n".join([table, "", source_line(store, "robustness/suite", "robustness/learners")])


def robustness_simulators(store: Store) -> str:
    """Each policy in the three simulators."""
    d = store.data("robustness/simulators")
    envs = list(d["envs"])
    rows = []
    for name, by_env in d["results"].items():
        row = [name]
        for label in envs:
            s = by_env[label]
            cell = f"{s['mean_return']:.1f} ± {s['std_return']:.1f}, {s['falls']}/{s['episodes']} falls, " \
                   f"{s['mean_forward_speed']:.2f} m/s"
            if "friction_over_mu" in s:
                cell += f"; \\|f_x\\|/f_z > μ in {100 * s['friction_over_mu']:.1f} % of control steps"
            row.append(cell)
        kept = by_env[d["mujoco"]]["mean_return"] / by_env[d["reference"]]["mean_return"]
        row.append(f"{100 * kept:.1f} %")
        rows.append(row)
    table = markdown_table(["policy"] + envs + ["return kept in MuJoCo"], rows)
    return "\n".join([table, "", f"{d['episodes']} episodes per policy and simulator (seeds 0-{d['episodes'] - 1}).",
                      source_line(store, "robustness/simulators")])


CONTACT_RECORDS = ("robustness/contact_models", "robustness/contact_models_late_landing_only",
                   "robustness/contact_models_filter_only")
"""The MPC, the MPC before both rules and the heuristic; then the MPC with one of the two rules each."""
CONTACT_LABELS = {"mpc": "MPC", "mpc-before": "MPC before (neither rule)", "heuristic": "heuristic",
                  "mpc-late-landing-only": "late landing only", "mpc-filter-only": "persistent restart only"}


def robustness_contact_models(store: Store) -> str:
    """Falls and mean time to fall per contact condition of the MuJoCo twin: the MPC, the MPC before its two rules
    for contacts it was not built on (``touchdown_height=None, filter_restart_steps=1``), each rule alone, and the
    heuristic (``robustness/contact_models`` and the records of the single rules)."""
    main = store.data(CONTACT_RECORDS[0])
    conds = list(main["conditions"])
    columns = {}
    for rid in CONTACT_RECORDS:
        d = store.data(rid)
        if d["seeds"] != main["seeds"] or list(d["conditions"]) != conds:
            raise ValueError(f"{rid}: seeds or conditions differ from {CONTACT_RECORDS[0]}'s")
        columns.update(d["results"])
    order = [p for p in ("mpc", "mpc-before", "mpc-late-landing-only", "mpc-filter-only", "heuristic")
             if p in columns]
    order += [p for p in columns if p not in order]
    header = ["condition"] + [CONTACT_LABELS.get(p, p) for p in order]
    rows = []
    for c in conds:
        row = [f"`{c}`"]
        for p in order:
            cell = columns[p].get(c)
            if cell is None:
                row.append(NA)
                continue
            text = f"**{_falls(cell)}**"
            if cell["falls"]:
                text += f" ({cell['mean_fall_time_s']:.2f} s)"
            row.append(text)
        rows.append(row)
    totals = ["**falls, total**"]
    for p in order:
        cells = [columns[p][c] for c in conds if c in columns[p]]
        totals.append(f"**{sum(x['falls'] for x in cells)}/{sum(x['episodes'] for x in cells)}**")
    rows.append(totals)
    rtf = [main["results"]["mpc"][c]["real_time_factor"] for c in conds] if "mpc" in main["results"] else []
    seeds = main["seeds"]
    note = (f"Cells: falls / episodes (mean time to fall). Seeds {seeds[0]}-{seeds[-1]}, one 1000-step episode (5 s) "
            "per seed and condition, in the MuJoCo twin.")
    if rtf:
        note += (f" The MPC's real-time factor per condition: {min(rtf):.1f}-{max(rtf):.1f} (two episodes at a time "
                 f"on {_machine_note(store, CONTACT_RECORDS[0])}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, *CONTACT_RECORDS)])


# -- policies and learning -----------------------------------------------------------------------------------------

def _suite_total(cells: dict) -> int:
    """Falls over the suite's conditions (a record may hold more conditions, e.g. ``push_x3``)."""
    from hsddp_gym.envs.perturbations import SUITE

    return sum(cells[c]["falls"] for c in SUITE if c in cells)


def _learner_suite(learners: dict, policy: str) -> str:
    """The suite falls of each training seed of a protocol row (``bc``, ``sac``, ``ppo@sde``, ...)."""
    prefix = {"dagger@speed_est": "dagger@speed_est@"}.get(policy, f"{policy}@")
    totals = [str(_suite_total(v)) for k, v in learners.items() if k.startswith(prefix) and "ensemble" not in k
              and k[len(prefix):].startswith("seed")]
    text = ", ".join(totals) if totals else NA
    if policy == "dagger@speed_est":
        ens = ", ".join(str(_suite_total(learners[e])) for e in ENSEMBLES if e in learners)
        text += f"; three acting together: {ens}"
    return text


ROW_NAMES = {"mpc": "HS-DDP MPC (the expert)", "expert": "plan-tracking expert (5-cycle plan)",
             "heuristic": "contact-event heuristic", "random": "random", "bc": "BC, 24 DART demonstrations",
             "dagger@speed_est": "DAgger (speed input, perturbed rollouts, behind the estimator)",
             "sac": "SAC `--hidden 128,128`, 1 h", "ppo@push_x3": "PPO `parallel`, trained under `push_x3`, 1 h",
             "ppo@sde": "PPO `parallel --sde` (gSDE), 1 h"}
READING = {"best": "best checkpoint", "final": "final weights", "stochastic": "own draws (final weights)"}


def policies_protocol(store: Store) -> str:
    """Every policy under one protocol, with its suite falls."""
    model = store.data("policies/model_based")
    learned = store.data("policies/learned")
    learners = store.data("robustness/learners")["learners"]
    suite = store.data("robustness/suite")["results"]
    mpc = next(r for r in model["rows"] if r["policy"] == "mpc")["mean_return"]
    header = ["policy", "reading", "training seeds", "return", "of the MPC's", "falls", "speed [m/s]",
              "learned from (per seed)", "training wall time (per seed)", "suite: falls of 260 (per seed)"]
    rows = []
    for r in model["rows"]:
        cells = suite.get(r["policy"])
        rows.append([ROW_NAMES.get(r["policy"], r["policy"]), NA, NA,
                     f"{r['mean_return']:.1f} ± {r['std_return']:.1f} (std)", f"{100 * r['mean_return'] / mpc:.0f} %",
                     f"{r['falls']}/{r['episodes']}", f"{r['mean_forward_speed']:.2f}", NA, NA,
                     str(_suite_total(cells)) if cells else NA])
    order = ["bc", "dagger@speed_est", "sac", "ppo@push_x3", "ppo@sde"]
    for policy in order:
        for reading in ("best", "final", "stochastic"):
            r = next((x for x in learned["readings"][reading] if x["policy"] == policy), None)
            if r is None or (reading != "best" and policy in ("bc", "dagger@speed_est")):
                continue
            first = reading == "best"
            tt = NA if r.get("train_time_s") is None else f"{r['train_time_s']:.0f} s"
            rows.append([ROW_NAMES[policy] if first else "", READING[reading] if policy.startswith(("sac", "ppo"))
                         else NA, r["training_seeds"], f"{r['mean_return']:.1f} ± {r['ci95']:.1f}",
                         f"{100 * r['mean_return'] / mpc:.0f} %", f"{r['falls']}/{r['episodes']}",
                         f"{r['mean_forward_speed']:.2f}", r["samples"] if first else "", tt if first else "",
                         _learner_suite(learners, policy) if first else ""])
    p = learned["protocol"]
    note = (f"{p['episodes']} episodes, seeds {p['seeds']}, the default env, the mean action of learned policies "
            "unless the reading says otherwise. Learned rows: the mean over training seeds of each seed's mean "
            "return ± the 95 % Student-t interval of that mean, falls summed over seeds; model-based rows: mean ± "
            f"std over the episodes. The learned policies were trained and evaluated with version "
            f"{store['policies/learned'].version}, their demonstrations and labels from that version's MPC "
            f"(return {learned['mpc_return_at_evaluation']:.1f} then). Suite: the perturbation suite's 13 "
            "conditions × 20 evaluation seeds.")
    return "\n".join([markdown_table(header, rows), "", note,
                      source_line(store, "policies/model_based", "policies/learned", "robustness/suite",
                                  "robustness/learners")])


SHORT = {"default": "default", "reset_noise_x4": "reset ×4", "obs_noise": "obs. noise", "delay_5ms": "5 ms",
         "delay_10ms": "10 ms", "push": "push", "friction_0.4": "μ 0.4", "mass_+15": "mass +15 %",
         "mass_-15": "mass −15 %", "speed_0.5": "0.5 m/s", "speed_1.25": "1.25 m/s", "speed_1.5": "1.5 m/s",
         "speed_2.0": "2 m/s"}


def learning_imitation(store: Store) -> str:
    """Every learned policy under the suite: falls of 20 per condition."""
    d = store.data("robustness/learners")
    conds = d["suite_conditions"]
    rows = []
    for label, cells in d["learners"].items():
        rows.append([f"`{label}`"] + [str(cells[c]["falls"]) if c in cells else NA for c in conds]
                    + [f"**{_suite_total({c: cells[c] for c in conds if c in cells})}**"])
    table = markdown_table(["policy"] + [SHORT.get(c, c) for c in conds] + ["total of 260"], rows,
                           ["l"] + ["r"] * (len(conds) + 1))
    ens = "; ".join(f"`{k}`: {v}" for k, v in d["ensembles"].items())
    return "\n".join([table, "", f"Falls of 20 per condition (evaluation seeds {d['seeds']}). {ens}. Recorded with "
                      f"version {store['robustness/learners'].version}.", source_line(store, "robustness/learners")])


# -- motions beyond the bound ----------------------------------------------------------------------------------------

MOTION_ORDER = ("pronk", "stand_to_bound", "bound_pronk_bound", "bound_to_stop", "gap_jump", "box_jump", "backflip")


def motions_summary(store: Store) -> str:
    """Every planned motion of the ``motions/*`` records: schedule size, speed, iterations, solve time and every limit
    measured on the plan (``experiments/motions.py``)."""
    rids = [f"motions/{m}" for m in MOTION_ORDER if f"motions/{m}" in store.ids()]
    header = ["motion", "phases", "T [s]", "v target / mean / end [m/s]", "AL / DDP it.", "solve [s]", "Σ g² [m²]",
              "max \\|g\\| [m]", "max \\|u\\| [N m]", "min f_z [N]", "max (\\|f_x\\| − μ f_z) [N]", "hips [rad]",
              "knees [rad]", "limits"]
    rows = []
    for rid in rids:
        d = store.data(rid)
        lim = d["limits"]
        rows.append([d["motion"].replace("_", " "), f"{len(d['modes'])} → {d['final_mode']}",
                     fmt(d["total_time"], ".3f"),
                     f"{d['target_speed']:.2f} / {d['avg_forward_speed']:.2f} / {d['final_speed']:.2f}",
                     f"{d['al_iterations']} / {d['ddp_iterations']}", fmt(d["solve_time_s"], ".2f"),
                     fmt(lim["switching_violation"], ".1e"), fmt(lim["max_touchdown_error"], ".1e"),
                     fmt(lim["max_abs_torque"], ".2f"), fmt(lim["min_normal_grf"], ".1f"),
                     fmt(lim["max_friction_violation"], ".2f"),
                     f"{lim['hip_range'][0]:.2f} … {lim['hip_range'][1]:.2f}",
                     f"{lim['knee_range'][0]:.2f} … {lim['knee_range'][1]:.2f}",
                     "met" if lim["ok"] else "violated: " + ", ".join(lim["violated"])])
    if not rids:
        return "No `motions/*` records yet: run `python experiments/motions.py --motion pronk --record ...`."
    first = store.data(rids[0])["limits"]
    (h_lo, h_hi), (k_lo, k_hi) = first["joint_limits"]
    note = (f"Limits: \\|u\\| ≤ {first['torque_limit']:g} N m, f_z ≥ 0, \\|f_x\\| ≤ {first['friction']:g} f_z (stance "
            f"feet), hips in [{h_lo:g}, {h_hi:g}] rad, knees in [{k_lo:g}, {k_hi:g}] rad, Σ g² ≤ 1e-4 m² (the paper's "
            f"stop rule). h = 1 ms. Solve times are wall-clock on the recording machine "
            f"({store[rids[0]].machine.get('cpus')} cores, load average {_load(store[rids[0]].machine)}), "
            "after the warm start's rollout.")
    return "\n".join([markdown_table(header, rows, ["l"] + ["r"] * (len(header) - 1)), "", note,
                      source_line(store, *rids)])


def _seeds_row(label: str, group: list, env_name: str, blanks: int) -> list:
    """The row that sums a learner's training seeds: successes and falls over all of them, the mean of their mean
    returns, then ``blanks`` empty cells."""
    ok, n = sum(r["successes"] for r in group), sum(r["episodes"] for r in group)
    mean = sum(r["mean_return"] for r in group) / len(group)
    return [f"{label}, {len(group)} training seed{'s' if len(group) > 1 else ''}", env_name,
            f"{mean:.1f} (mean of the seeds)", f"{ok}/{n}", f"{sum(r['falls'] for r in group)}/{n}", *[""] * blanks]


def _imitation_rows(d: dict, cells, seeds_row, dagger_unit: str) -> list:
    """A task record's BC and DAgger rows (``d["bc"]``, ``d["dagger"]``), one per training seed and one summing
    them per learner: ``cells(row, samples, training time)`` and ``seeds_row(label, group)`` make the cells;
    ``dagger_unit`` names DAgger's iterations in its label."""
    rows = []
    for r in d["bc"]:
        rows.append(cells(r, f"{r['transitions']:,} expert labels ({r['demonstrations']} demos)",
                          f"{r['train_wall_time_s']:.0f} s"))
    if d["bc"]:
        rows.append(seeds_row("BC", d["bc"]))
    for rounds in dict.fromkeys(r["rounds"] for r in d.get("dagger", [])):
        group = [r for r in d["dagger"] if r["rounds"] == rounds]
        for r in group:
            rollouts = r["rounds"] * r["episodes_per_round"]
            first = (f"{r['initial_demonstrations']} demos" if r.get("initial_demonstrations") is not None else
                     f"{r['episodes_per_round']} expert episodes")
            rows.append(cells(r, f"{r['expert_labels']:,} expert labels ({first} + {rollouts} relabelled "
                                 f"rollout{'s' if rollouts != 1 else ''})", f"{r['train_wall_time_s']:.0f} s"))
        rows.append(seeds_row(f"DAgger, {rounds} {dagger_unit}{'s' if rounds != 1 else ''}", group))
    return rows


def tasks_pronking(store: Store) -> str:
    """The pronking task: the expert (Pronking-v0 and its MuJoCo twin), BC and DAgger per training seed and SAC per
    training seed and checkpoint on unseen seeds, with the samples and training time each learner used
    (``experiments/pronking.py``)."""
    rid = "tasks/pronking"
    if rid not in store.ids():
        return ("No `tasks/pronking` record yet: run `python experiments/pronking.py --record "
                "results/tasks/pronking.json`.")
    d = store.data(rid)
    header = ["policy", "env", "return", "success", "falls", "speed [m/s]", "matching contacts", "samples",
              "training time"]

    def cells(r, samples, train_time):
        return [r["label"], f"`{r['env_id'].split('/')[-1]}`", f"{r['mean_return']:.1f} ± {r['std_return']:.1f}",
                f"{r['successes']}/{r['episodes']}", f"{r['falls']}/{r['episodes']}", f"{r['mean_speed']:.3f}",
                f"{100 * r['mean_match_fraction']:.1f} % (min {100 * r['min_match_fraction']:.1f} %)", samples,
                train_time]

    def seeds_row(label, group):
        return _seeds_row(label, group, "`Pronking-v0`", 4)

    rows = [cells(r, "–", "–") for r in d["rows"]] + _imitation_rows(d, cells, seeds_row, "round")
    for r in d.get("sac", []):
        steps = (f"{r['env_steps']:,} env steps" if r["checkpoint"] == "final" else
                 f"{r['env_steps']:,} of {r['total_env_steps']:,} env steps")
        rows.append(cells(r, steps, f"{r['train_wall_time_s']:.0f} s"))
    for checkpoint, name in (("final", "final weights"), ("best", "best checkpoint")):
        group = [r for r in d.get("sac", []) if r["checkpoint"] == checkpoint]
        if len(group) > 1:
            rows.append(seeds_row(f"SAC ({name})", group))
    seeds = d["seeds"]
    note = (f"{len(seeds)} episodes, seeds {seeds[0]}-{seeds[-1]} (used by no dataset or training run), target speed "
            f"{d['target_speed']:g} m/s, 1000 steps (5 s); return: mean ± std over the episodes. Success: "
            f"{d['success_rule']}. Samples: the expert's labelled (observation, action) pairs BC and DAgger learned "
            "from (DAgger's include BC's demonstrations, its round 0), or SAC's env steps (of its best checkpoint: "
            "the steps when it was saved). Training time: wall-clock seconds on the shared 2-core machine.")
    sac = d.get("sac", [])
    if sac:
        limits = sorted({r["time_limit_s"] for r in sac if r.get("time_limit_s")})
        if limits:
            note += (f" SAC trained for a wall-clock budget of {', '.join(f'{t:g}' for t in limits)} s (RL-Zoo "
                     "settings, `hsddp-gym train --algo sac --time-limit`); both its final weights and its best "
                     "checkpoint act with the mean action.")
    return "\n".join([markdown_table(header, rows, ["l", "l"] + ["r"] * (len(header) - 2)), "", note,
                      source_line(store, rid)])


def _plan_task_table(store: Store, rid: str, command: str, measures: list, measure_cells, episodes_note: str) -> str:
    """The table of a plan-tracking task record (``experiments/tasks.py``): the expert (env and MuJoCo twin), BC and
    DAgger per training seed, the task's ``measures`` columns (``measure_cells(row)`` their cells) and the note."""
    if rid not in store.ids():
        return f"No `{rid}` record yet: run `{command}`."
    d = store.data(rid)
    env_name = f"`{d['env_id'].split('/')[-1]}`"
    header = ["policy", "env", "return", "success", "falls", *measures, "samples", "training time"]

    def cells(r, samples, train_time):
        return [r["label"], f"`{r['env_id'].split('/')[-1]}`", f"{r['mean_return']:.1f} ± {r['std_return']:.1f}",
                f"{r['successes']}/{r['episodes']}", f"{r['falls']}/{r['episodes']}", *measure_cells(r), samples,
                train_time]

    def seeds_row(label, group):
        return _seeds_row(label, group, env_name, len(measures) + 2)

    rows = [cells(r, "–", "–") for r in d["rows"]] + _imitation_rows(d, cells, seeds_row, "iteration")
    seeds = d["seeds"]
    note = (f"{len(seeds)} episodes, seeds {seeds[0]}-{seeds[-1]} (used by no dataset or training run), "
            f"{d['max_episode_steps']} steps ({d['max_episode_steps'] * 0.005:g} s) {episodes_note}. "
            f"Success: {d['success_rule']}. "
            "Samples: the expert's labelled (observation, action) pairs BC and DAgger learned from (DAgger's include "
            "BC's demonstrations). Training time: wall-clock seconds on the shared 2-core machine.")
    return "\n".join([markdown_table(header, rows, ["l", "l"] + ["r"] * (len(header) - 2)), "", note,
                      source_line(store, rid)])


def tasks_terrain(store: Store) -> str:
    """The terrain task: the terrain-aware MPC (the episode's terrain as privileged information), the flat-ground MPC
    and the heuristic on ``hsddp_gym/Terrain-v0``, per block of seeds, and BC / DAgger from the terrain-aware MPC's
    demonstrations beside it on unseen seeds, with their samples and training time (``experiments/terrain.py``)."""
    rid = "tasks/terrain"
    if rid not in store.ids():
        return ("No `tasks/terrain` record yet: run `python experiments/terrain.py --record "
                "results/tasks/terrain.json`.")
    d = store.data(rid)
    learned = any("training_seed" in r for r in d["rows"])
    header = ["seeds", "policy", "falls", "fell on seeds", "return", "speed [m/s]", "failed re-plans"]
    rows = []
    for r in d["rows"]:
        fell = ", ".join(str(s) for s in r["fell_seeds"]) or "–"
        failures = str(r["planner_failures"]) if "planner_failures" in r else "–"
        label = r["label"] if "training_seed" in r else f"`{r['label']}`"
        rows.append([f"{r['seeds'][0]}-{r['seeds'][1]}", label, f"{r['falls']}/{r['episodes']}", fell,
                     f"{r['mean_return']:.1f} ± {r['std_return']:.1f}", f"{r['mean_speed']:.3f}", failures])
        if learned and "expert_labels" in r:
            rollouts = r["rounds"] * r["episodes_per_round"]
            first = (f"{r['initial_demonstrations']} demos" if r.get("initial_demonstrations") is not None else
                     f"{r['episodes_per_round']} expert episodes")
            rows[-1] += [f"{r['expert_labels']:,} expert labels ({first} + {rollouts} relabelled rollouts)",
                         f"{r['train_wall_time_s']:.0f} s"]
        elif learned and "training_seed" in r:
            rows[-1] += [f"{r['transitions']:,} expert labels ({r['demonstrations']} demos)",
                         f"{r['train_wall_time_s']:.0f} s"]
        elif learned:
            rows[-1] += ["–", "–"]
    uses = " ".join(f"Seeds {b['seeds'][0]}-{b['seeds'][1]}: {b['use']}." for b in d["seed_blocks"])
    note = (f"`{d['env_id']}`, one 5 s episode per seed ({d['episode_steps']} steps, target speed "
            f"{d['target_speed']:g} m/s, a new random terrain per seed); return: mean ± std over the episodes. {uses} "
            "Failed re-plans: re-plans whose solve failed (the previous plan kept acting), summed over the episodes.")
    if learned:
        header += ["samples", "training time"]
        note += (" BC and DAgger: learned from the terrain-aware MPC (their expert, the record's commands), acting "
                 "on the observation alone (no terrain). Samples: the expert's labelled (observation, action) pairs "
                 "they learned from (DAgger's include BC's demonstrations). Training time: wall-clock seconds on the "
                 "shared 2-core machine.")
    return "\n".join([markdown_table(header, rows, ["l", "l", "r", "l", "r", "r", "r"] + ["l", "r"] * learned), "",
                      note, source_line(store, rid)])


def tasks_backflip(store: Store) -> str:
    """The backflip task: the HS-DDP backflip expert (Backflip-v0 and its MuJoCo twin), BC and DAgger per training
    seed on unseen seeds, with the samples and training time each learner used (``experiments/backflip.py``)."""
    return _plan_task_table(
        store, "tasks/backflip", "python experiments/backflip.py --record results/tasks/backflip.json",
        ["lowest pitch [rad]", "final pitch [rad]", "lowest trunk clearance [m]"],
        lambda r: [f"{r['mean_min_pitch']:.2f}", f"{r['mean_final_pitch']:.2f}", f"{r['min_trunk_clearance']:.3f}"],
        "from standing, reset noise 0.01; return: mean ± std over the episodes; lowest and final pitch: means over "
        "the episodes (a full turn is -6.28 rad); lowest trunk clearance: over every step of every episode (a fall "
        "below 0.05 m)")


def _tasks_jump(store: Store, task: str) -> str:
    return _plan_task_table(
        store, f"tasks/{task}", f"python experiments/tasks.py --task {task} --record results/tasks/{task}.json",
        ["final trunk x [m]", "final pitch [rad]", "lowest trunk height [m]"],
        lambda r: [f"{r['mean_final_x']:.2f}", f"{r['mean_final_pitch']:.2f}", f"{r['min_trunk_height']:.3f}"],
        "from bounding at 0.9 m/s, reset noise 0.01; return: mean ± std over the episodes; final trunk x and pitch: "
        "means over the episodes; lowest trunk height: the trunk centre over the ground under it, over every step of "
        "every episode (a fall below 0.12 m)")


def tasks_gap_jump(store: Store) -> str:
    """The jump over a 0.3 m gap: the HS-DDP jump expert (GapJump-v0 and its MuJoCo twin), BC and DAgger per training
    seed on unseen seeds (``experiments/tasks.py --task gap_jump``)."""
    return _tasks_jump(store, "gap_jump")


def tasks_box_jump(store: Store) -> str:
    """The jump onto a 0.1 m box: the HS-DDP jump expert (BoxJump-v0 and its MuJoCo twin), BC and DAgger per training
    seed on unseen seeds (``experiments/tasks.py --task box_jump``)."""
    return _tasks_jump(store, "box_jump")


def _tasks_transition(store: Store, task: str, start: str) -> str:
    return _plan_task_table(
        store, f"tasks/{task}",
        f"python experiments/tasks.py --task {task} --mujoco --record results/tasks/{task}.json",
        ["mean speed [m/s]", "final speed [m/s]", "lowest trunk height [m]"],
        lambda r: [f"{r['mean_speed']:.2f}", f"{r['mean_final_speed']:.2f}", f"{r['min_trunk_height']:.3f}"],
        f"{start}, reset noise 0.01; return: mean ± std over the episodes; mean speed (the trunk's x over the "
        "episode's time) and final speed: means over the episodes; lowest trunk height: over every step of every "
        "episode (a fall below 0.12 m)")


def tasks_stand_to_bound(store: Store) -> str:
    """From standing into a bound: the HS-DDP transition expert (StandToBound-v0 and its MuJoCo twin) and BC per
    training seed on unseen seeds (``experiments/tasks.py --task stand_to_bound``)."""
    return _tasks_transition(store, "stand_to_bound", "from standing at rest")


def tasks_bound_pronk_bound(store: Store) -> str:
    """From a bound into a pronk and back: the HS-DDP transition expert (BoundPronkBound-v0 and its MuJoCo twin) and
    BC per training seed on unseen seeds (``experiments/tasks.py --task bound_pronk_bound``)."""
    return _tasks_transition(store, "bound_pronk_bound", "from bounding at 0.9 m/s")


def tasks_bound_to_stop(store: Store) -> str:
    """From a bound to rest: the HS-DDP transition expert (BoundToStop-v0 and its MuJoCo twin) and BC per training
    seed on unseen seeds (``experiments/tasks.py --task bound_to_stop``)."""
    return _tasks_transition(store, "bound_to_stop", "from bounding at 0.9 m/s")


def tasks_summary(store: Store) -> str:
    """Every task beyond bounding in one table: its expert's successes in the env and in the MuJoCo twin, and the
    learners' from its datasets, over all training seeds (the task records ``tasks/*``)."""
    tasks = [("tasks/pronking", "pronk"), ("tasks/backflip", "backflip from standing"),
             ("tasks/gap_jump", "jump over a 0.3 m gap"), ("tasks/box_jump", "jump onto a 0.1 m box"),
             ("tasks/stand_to_bound", "stand to bound"), ("tasks/bound_pronk_bound", "bound, pronk, bound"),
             ("tasks/bound_to_stop", "bound to stop")]
    header = ["task", "env", "expert", "expert in the MuJoCo twin", "BC", "DAgger", "seeds"]
    rows, used = [], []

    def total(group):
        return (f"{sum(r['successes'] for r in group)}/{sum(r['episodes'] for r in group)} "
                f"({len(group)} training seed{'s' if len(group) != 1 else ''})") if group else "–"

    for rid, what in tasks:
        if rid not in store.ids():
            continue
        used.append(rid)
        d = store.data(rid)
        env_id = d["env_id"]
        expert = {r["env_id"]: r for r in d["rows"] if r["label"] == "expert"}
        own = expert.get(env_id)
        twin = [r for e, r in expert.items() if e != env_id]
        dagger = d.get("dagger", [])
        by_iterations = {n: [r for r in dagger if r["rounds"] == n] for n in sorted({r["rounds"] for r in dagger})}
        dagger_cell = "; ".join(f"{total(group)[:-1]}, {n} iterations)" for n, group in by_iterations.items()) or "–"
        if "target_speed" in d:
            what = f"{what} at {d['target_speed']:g} m/s"
        rows.append([what, f"`{env_id.split('/')[-1]}`",
                     f"{own['successes']}/{own['episodes']}" if own else "–",
                     f"{twin[0]['successes']}/{twin[0]['episodes']}" if twin else "–",
                     total(d.get("bc", [])), dagger_cell, f"{d['seeds'][0]}-{d['seeds'][-1]}"])
    if not rows:
        return "No task record yet: run `python experiments/tasks.py --task backflip`."
    note = ("Successes / episodes on seeds used by no dataset or training run; each task's success rule, the learners' "
            "samples and training time are on the [tasks page](docs/env/tasks.md). BC and DAgger: summed over their "
            "training seeds, DAgger per number of iterations. The expert tracks the task's HS-DDP plan with the plan's "
            "feedback gains (the pronk: a periodic plan).")
    return "\n".join([markdown_table(header, rows, ["l", "l", "r", "r", "r", "r", "l"]), "", note,
                      source_line(store, *used)])


# -- generality of the MPC ---------------------------------------------------------------------------------------------

def _generality_groups() -> tuple:
    """The groups of the generality table: (title, condition names), in order."""
    from hsddp_gym.envs.perturbations import CONTACT_CONDITIONS, HARDWARE_CONDITIONS, SUITE

    pushes = ("push_flight", "push_stance", "push_x3")
    return (("the suite", tuple(SUITE)), ("contact models (MuJoCo twin)", tuple(CONTACT_CONDITIONS)),
            ("latency not known exactly", tuple(c for c in HARDWARE_CONDITIONS if c.startswith("delay_"))),
            ("sensor bias", tuple(c for c in HARDWARE_CONDITIONS if c.startswith("sensor_"))),
            ("pushes by phase, repeated pushes", pushes),
            ("noise, bias and latency together", ("noise_bias_latency",)))


def robustness_generality(store: Store) -> str:
    """Falls per condition, the MPC beside the heuristic, over the suite and every condition the MPC was not built
    on (``robustness/generality``): contact models, latencies announced wrongly, sensor biases, pushes by phase."""
    d = store.data("robustness/generality")
    conds = list(d["conditions"])
    policies = [p for p in ("mpc", "heuristic") if p in d["results"]] + \
        [p for p in d["results"] if p not in ("mpc", "heuristic")]
    labels = {"mpc": "MPC", "heuristic": "heuristic"}
    header = ["condition"] + [labels.get(p, p) for p in policies]
    rows, seen = [], set()
    for title, members in _generality_groups():
        group = [c for c in conds if c not in seen and c in members]
        if not group:
            continue
        seen.update(group)
        rows.append([f"*{title}*"] + [""] * len(policies))
        for c in group:
            row = [f"`{c}`"]
            for p in policies:
                cell = d["results"][p].get(c)
                text = f"**{_falls(cell)}**" if cell is not None else NA
                if cell is not None and cell["falls"] and cell.get("mean_fall_time_s") is not None:
                    text += f" ({cell['mean_fall_time_s']:.2f} s)"
                row.append(text)
            rows.append(row)
    rest = [c for c in conds if c not in seen]
    for c in rest:
        rows.append([f"`{c}`"] + [f"**{_falls(d['results'][p].get(c))}**" for p in policies])
    totals = ["**falls, total**"]
    worst = ["**most falls in one condition**"]
    for p in policies:
        cells = [d["results"][p][c] for c in conds if c in d["results"][p]]
        totals.append(f"**{sum(x['falls'] for x in cells)}/{sum(x['episodes'] for x in cells)}**")
        worst.append(str(max((x["falls"] for x in cells), default=0)))
    rows += [totals, worst]
    seeds = d["seeds"]
    rtf = [d["results"]["mpc"][c]["real_time_factor"] for c in conds] if "mpc" in d["results"] else []
    note = (f"Cells: falls / episodes (mean time to fall). Seeds {seeds[0]}-{seeds[-1]} (never used to develop or "
            "tune anything), one 1000-step episode (5 s) per seed and condition; the contact conditions run in the "
            "MuJoCo twin, the others in Bounding-v0.")
    if rtf:
        note += (f" The MPC's real-time factor per condition: {min(rtf):.1f}-{max(rtf):.1f} (two episodes at a time "
                 f"on {_machine_note(store, 'robustness/generality')}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "robustness/generality")])


def robustness_generality_summary(store: Store) -> str:
    """The generality table in one row per group of conditions: falls of the MPC and of the heuristic, and each
    one's most falls in a single condition (``robustness/generality``)."""
    d = store.data("robustness/generality")
    conds = list(d["conditions"])
    res = d["results"]
    rows = []
    for title, members in _generality_groups():
        group = [c for c in conds if c in members]
        if not group:
            continue
        row = [title, str(len(group))]
        for p in ("mpc", "heuristic"):
            cells = [res[p][c] for c in group] if p in res else []
            if not cells:
                row += [NA, NA]
                continue
            worst = max(cells, key=lambda x: x["falls"])
            name = group[cells.index(worst)]
            row += [f"{sum(x['falls'] for x in cells)}/{sum(x['episodes'] for x in cells)}",
                    f"{worst['falls']}/{worst['episodes']}" + (f" (`{name}`)" if worst["falls"] else "")]
        rows.append(row)
    header = ["conditions", "count", "MPC falls", "MPC worst cell", "heuristic falls", "heuristic worst cell"]
    seeds = d["seeds"]
    note = (f"Seeds {seeds[0]}-{seeds[-1]}, never used in development, one 5 s episode per seed and condition; "
            "per condition on the [robustness page](docs/results/robustness.md#conditions-the-mpc-was-not-built-on).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "robustness/generality")])


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval (default 95 %) of a rate from ``k`` events in ``n`` trials: ``(low, high)`` in
    [0, 1]. Unlike ``k/n ± z·se`` it stays inside [0, 1] and is not empty at ``k = 0``."""
    if n <= 0 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n > 0, got k={k!r}, n={n!r}")
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * (p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5
    return max(0.0, centre - half), min(1.0, centre + half)


def _rate(cell: dict) -> str:
    lo, hi = wilson_interval(cell["falls"], cell["episodes"])
    return f"{100 * cell['falls'] / cell['episodes']:.1f} % ({100 * lo:.1f}–{100 * hi:.1f})"


PUSH_BLOCK = 20
"""Seeds per cell of the generality table: the pushes record counts its blocks of this many seeds."""


def robustness_pushes(store: Store) -> str:
    """Falls under each push law on many fresh seeds (``robustness/pushes``), the MPC beside the heuristic: the fall
    rate with its 95 % Wilson interval, and in how many blocks of :data:`PUSH_BLOCK` consecutive seeds (a cell of the
    generality table) the MPC fell more often than the heuristic."""
    d = store.data("robustness/pushes")
    res, seeds = d["results"], list(d["seeds"])
    missing = [p for p in ("mpc", "heuristic") if p not in res]
    if missing:
        raise ValueError(f"robustness/pushes: the record needs the policies 'mpc' and 'heuristic', missing {missing}")
    blocks = [seeds[i:i + PUSH_BLOCK] for i in range(0, len(seeds) - PUSH_BLOCK + 1, PUSH_BLOCK)]
    header = ["condition", "MPC falls", "MPC fall rate (95 % interval)", "heuristic falls",
              "heuristic fall rate (95 % interval)", f"blocks of {PUSH_BLOCK} seeds with more MPC falls"]
    rows = []
    totals = {p: {"falls": 0, "episodes": 0} for p in ("mpc", "heuristic")}
    worse_total = 0
    for c in d["conditions"]:
        mpc, heur = res["mpc"][c], res["heuristic"][c]
        worse = sum(sum(s in blk for s in mpc["fall_seeds"]) > sum(s in blk for s in heur["fall_seeds"])
                    for blk in blocks)
        worse_total += worse
        for p, cell in (("mpc", mpc), ("heuristic", heur)):
            totals[p]["falls"] += cell["falls"]
            totals[p]["episodes"] += cell["episodes"]
        rows.append([f"`{c}`", _falls(mpc), _rate(mpc), _falls(heur), _rate(heur), f"{worse} of {len(blocks)}"])
    rows.append(["**all pushes**", f"**{_falls(totals['mpc'])}**", _rate(totals["mpc"]),
                 f"**{_falls(totals['heuristic'])}**", _rate(totals["heuristic"]),
                 f"{worse_total} of {len(blocks) * len(d['conditions'])}"])
    mpc_seeds = {c: res["mpc"][c]["fall_seeds"] for c in d["conditions"] if res["mpc"][c]["fall_seeds"]}
    note = (f"Seeds {seeds[0]}-{seeds[-1]} (never used to develop or tune anything), one 1000-step episode (5 s) per "
            f"seed and condition in Bounding-v0; the MPC fell on "
            + (", ".join(f"`{c}` {', '.join(map(str, v))}" for c, v in mpc_seeds.items()) or "no seed")
            + f". Two episodes at a time on {_machine_note(store, 'robustness/pushes')}.")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "robustness/pushes")])


TABLES: dict[str, Callable[[Store], str]] = {
    "paper/task1": paper_task1,
    "paper/sto_variants": paper_sto_variants,
    "paper/sto_periodic": paper_sto_periodic,
    "env/physics": env_physics,
    "speed/env": speed_env,
    "speed/vector_env": speed_vector_env,
    "speed/dynamics": speed_dynamics,
    "speed/solver": speed_solver,
    "speed/solver_horizons": speed_solver_horizons,
    "speed/mpc": speed_mpc,
    "speed/summary": speed_summary,
    "robustness/suite": robustness_suite,
    "robustness/summary": robustness_summary,
    "robustness/simulators": robustness_simulators,
    "robustness/contact_models": robustness_contact_models,
    "policies/protocol": policies_protocol,
    "learning/imitation": learning_imitation,
    "motions/summary": motions_summary,
    "tasks/pronking": tasks_pronking,
    "tasks/backflip": tasks_backflip,
    "tasks/terrain": tasks_terrain,
    "tasks/gap_jump": tasks_gap_jump,
    "tasks/box_jump": tasks_box_jump,
    "tasks/stand_to_bound": tasks_stand_to_bound,
    "tasks/bound_pronk_bound": tasks_bound_pronk_bound,
    "tasks/bound_to_stop": tasks_bound_to_stop,
    "tasks/summary": tasks_summary,
    "robustness/generality": robustness_generality,
    "robustness/generality_summary": robustness_generality_summary,
    "robustness/pushes": robustness_pushes,
}
"""``{table id: renderer}``."""


def render(store: Store, table_id: str) -> str:
    """The Markdown of table ``table_id``.

    Raises:
        KeyError: an unknown table id (naming the known ones).
    """
    if table_id not in TABLES:
        raise KeyError(f"unknown results table {table_id!r} (known: {', '.join(sorted(TABLES))})")
    return TABLES[table_id](store)
