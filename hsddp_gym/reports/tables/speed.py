"""The speed tables: the env, the vector env, the compiled dynamics, the solver (one horizon and many) and the MPC,
each beside a reference measured in the same run."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import NA, fmt, machine_note, markdown_table, source_line


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
                      f"{machine_note(store, 'speed/env')}.", source_line(store, "speed/env")])


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
                      f"Machine: {machine_note(store, 'speed/vector_env')}.", source_line(store, "speed/vector_env")])


def speed_vector_env_tasks(store: Store) -> str:
    """Per task env: the single env, its vector env and a ``SyncVectorEnv`` of single envs at each N (env steps per
    CPU second, and the ratio to the single env of the same run)."""
    rid = "speed/vector_env_tasks"
    d = store.data(rid)
    by_env: dict = {}
    for r in d["rows"]:
        if "env_id" in r:
            by_env.setdefault(r["env_id"], {})[r["configuration"]] = r["env_steps_per_cpu_s"]
    sizes = sorted({int(c.split("=")[1]) for rates in by_env.values() for c in rates if c.startswith("vector")})
    has_sync = any(c.startswith("sync") for rates in by_env.values() for c in rates)
    header = ["env", "single env"]
    header += [f"vector env, N = {n}" for n in sizes]
    header += [f"SyncVectorEnv, N = {n}" for n in sizes] if has_sync else []
    rows = []
    for env_id, rates in by_env.items():
        single = rates["single"]
        row = [f"`{env_id}`", f"{single:,.0f}"]
        for kind in ("vector", "sync") if has_sync else ("vector",):
            for n in sizes:
                v = rates.get(f"{kind} N={n}")
                row.append(NA if v is None else f"{v:,.0f} ({v / single:.2f}×)")
        rows.append(row)
    table = markdown_table(header, rows, ["l"] + ["r"] * (len(header) - 1))
    return "\n".join([table, "", "Env steps per CPU second (summed over the robots), random actions with autoreset; "
                      f"in parentheses the ratio to the single env of the same run. {d['seconds']:g} s per row in "
                      f"{d['rounds']} interleaved rounds, one thread each. Machine: {machine_note(store, rid)}.",
                      source_line(store, rid)])


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
                      f"{machine_note(store, 'speed/dynamics')}.", source_line(store, "speed/dynamics")])


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
                      f"{d['repeats']}). Machine: {machine_note(store, 'speed/solver')}.",
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
            f"Machine: {machine_note(store, 'speed/solver_horizons')}{loaded}.")
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
                      f"{d['planner_failures']} failed. Machine: {machine_note(store, 'speed/mpc')}.",
                      source_line(store, "speed/mpc")])


def speed_task_mpc(store: Store) -> str:
    """Each task's MPC for one episode: real-time factor, re-plan time and cost per plan knot beside the bound's MPC
    in the same run (``bench_mpc.py --env``)."""
    record = "speed/task_mpc"
    if record not in store.ids():
        return f"No `{record}` record yet (`python experiments/bench_mpc.py --env ID ... --record FILE`)."
    d = store.data(record)
    rows = []
    for env_id, r in d["envs"].items():
        name = env_id.split("/")[-1] + (" (the reference)" if env_id == d["reference"] else "")
        rows.append([f"`{name}`", f"{r['seconds']:.2f}", f"{r['real_time_factor']:.2f}",
                     f"{r['replan_ms']['mean']:.1f}", f"{r['replan_ms']['max']:.0f}", f"{r['knots_mean']:.0f}",
                     f"{r['us_per_knot']:.1f}",
                     f"{r['per_knot_ratio_to_bound']:.2f}"])
    table = markdown_table(["env", "simulated s", "real-time factor", "re-plan ms, mean", "max", "knots per re-plan",
                            "us per knot", "per knot / the bound's"], rows, ["l"] + ["r"] * 7)
    return "\n".join([table, "", f"One episode per env (seed {d['seed']}), one after the other in one process; the "
                      f"bound's MPC runs 3 s. Machine: {machine_note(store, record)}.", source_line(store, record)])


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
