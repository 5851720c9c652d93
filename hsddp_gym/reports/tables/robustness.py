"""The robustness tables: falls per perturbation of the suite, per simulator, per contact model, over the conditions
the MPC was not built on (generality), the fall rates under pushes on many seeds, and the tasks' successes and falls
per condition."""

from __future__ import annotations

from collections.abc import Callable

from hsddp_gym.core.task_constants import MOTION_PUSH_SIZE
from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import NA, fmt, machine_note, markdown_table, source_line

SUITE_LABELS = {"mpc": "MPC", "heuristic": "heuristic", "heuristic+est": "heuristic + estimator",
                "dagger@ensemble_a": "DAgger ensemble A", "dagger@ensemble_b": "DAgger ensemble B",
                "dagger@ensemble_c": "DAgger ensemble C"}
ENSEMBLES = ("dagger@ensemble_a", "dagger@ensemble_b", "dagger@ensemble_c")


def suite_columns(store: Store) -> tuple[list[str], dict, dict]:
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
    conds, columns, desc = suite_columns(store)
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
    conds, columns, _ = suite_columns(store)
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
                 f"on {machine_note(store, CONTACT_RECORDS[0])}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, *CONTACT_RECORDS)])


def generality_groups() -> tuple:
    """The groups of the generality table: (title, condition names), in order."""
    from hsddp_gym.envs.perturbations.conditions import CONTACT_CONDITIONS, HARDWARE_CONDITIONS, SUITE

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
    for title, members in generality_groups():
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
                 f"on {machine_note(store, 'robustness/generality')}).")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "robustness/generality")])


def robustness_generality_summary(store: Store) -> str:
    """The generality table in one row per group of conditions: falls of the MPC and of the heuristic, and each
    one's most falls in a single condition (``robustness/generality``)."""
    d = store.data("robustness/generality")
    conds = list(d["conditions"])
    res = d["results"]
    rows = []
    for title, members in generality_groups():
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
    rate with its 95 % Wilson interval, and in how many blocks of [`PUSH_BLOCK`][PUSH_BLOCK] consecutive seeds (a cell
    of the generality table) the MPC fell more often than the heuristic."""
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
            + f". Two episodes at a time on {machine_note(store, 'robustness/pushes')}.")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, "robustness/pushes")])


TASK_RECORD = "robustness/tasks"
"""The tasks' robustness record (``experiments/robustness.py --env ID --record results/robustness/tasks.json``)."""
TASK_RL_RECORD = "robustness/tasks_rl"
"""The record of the learners that use the plan (residual RL) beside RL from scratch and the expert."""
TASK_MPC_RECORD = "robustness/task_mpc"
"""Each motion's MPC beside its plan-tracking expert on the same seeds, and the MPC with online landing timing on the
push and latency cells."""
TASK_POLICY_LABELS = {"expert": "expert", "mpc": "MPC", "mpc-retimed": "MPC, online landing timing",
                      "ppo@residual_push": "PPO residual, trained under push",
                      "ppo@residual_obs_noise_s0": "PPO residual, trained under obs. noise, seed 0",
                      "ppo@residual_obs_noise_s1": "PPO residual, trained under obs. noise, seed 1",
                      "ppo@scratch_push": "PPO from scratch, trained under push"}


def task_robustness(store: Store, tasks: tuple | None, record: str = TASK_RECORD) -> str:
    """Successes and falls per condition of the tasks ``tasks`` (names of the task registry, one column per task and
    policy; None: every task of the record) from a tasks' robustness record (``record``), with each task's push
    window and size; the record's command is shown once, on the perturbations page (``record`` other than the tasks'
    own: under the table)."""
    if record not in store.ids():
        return (f"No `{record}` record yet: run `python experiments/robustness.py --env ENV --policies expert "
                f"--first-seed 56000 --record results/{record}.json`.")
    d = store.data(record)
    tasks = tuple(d["tasks"]) if tasks is None else tasks
    missing = [t for t in tasks if t not in d["tasks"]]
    if missing:
        raise ValueError(f"{record}: no entry for the task(s) {missing}")
    columns = [(t, label) for t in tasks for label in d["tasks"][t]["results"]]
    several = len({label for _, label in columns}) > 1
    header = ["condition"] + [t.replace("_", " ") + (f", {TASK_POLICY_LABELS.get(label, label)}" if several else "")
                              for t, label in columns]
    rows = []
    for i, c in enumerate(d["conditions"]):
        cells = [d["tasks"][t]["results"][label] for t, label in columns]
        if any(r["falls"][i] is not None for r in cells):  # None: not run
            rows.append([f"`{c}`"] + [NA if r["falls"][i] is None else f"{fmt(r['successes'][i], 'd')}, {r['falls'][i]}"
                                      for r in cells])
    windows = {tuple(d["tasks"][t]["push_window"]) for t in tasks}
    pushes = "; ".join(("" if len(windows) == 1 else f"{t.replace('_', ' ')} ")
                       + "t ~ U({:g}, {:g}) s".format(*d["tasks"][t]["push_window"])
                       for t in (tasks[:1] if len(windows) == 1 else tasks))
    sizes = {tuple(d["tasks"][t]["push_size"]) for t in tasks}
    size = "" if sizes == {MOTION_PUSH_SIZE} else ", Δv up to ±{:g} m/s, ±{:g} m/s, ±{:g} rad/s".format(
        *d["tasks"][tasks[0]]["push_size"])  # the motions' size is on the perturbations page
    note = (f"Cells: successes, falls of {len(d['seeds'])} episodes (seeds {d['seeds'][0]}-{d['seeds'][-1]}). Push: "
            f"{pushes}{size}.")
    return "\n".join([markdown_table(header, rows, ["l"] + ["r"] * len(columns)), "", note,
                      source_line(store, record, commands=record != TASK_RECORD)])


def robustness_tasks_rl_backflip(store: Store) -> str:
    """The backflip's learners that use the plan beside RL from scratch and the expert, per condition."""
    return task_robustness(store, ("backflip",), TASK_RL_RECORD)


def robustness_tasks_rl_jumps(store: Store) -> str:
    """The jumps' learners that use the plan beside RL from scratch and the expert, per condition (the jumps the
    record holds)."""
    d = store.data(TASK_RL_RECORD) if TASK_RL_RECORD in store.ids() else {"tasks": {}}
    jumps = tuple(t for t in ("gap_jump", "box_jump") if t in d["tasks"])
    if not jumps:
        return f"No jump in `{TASK_RL_RECORD}` yet."
    return task_robustness(store, jumps, TASK_RL_RECORD)


def task_mpc_table(task: str) -> Callable[[Store], str]:
    """The table of ``task``'s MPC beside its plan-tracking expert (and the MPC with online landing timing where it
    ran), per condition, from [`TASK_MPC_RECORD`][TASK_MPC_RECORD]."""
    def table(store: Store) -> str:
        return task_robustness(store, (task,), TASK_MPC_RECORD)
    table.__doc__ = f"The {task.replace('_', ' ')} MPC beside its plan-tracking expert, per condition."
    return table


TASK_MPC_TASKS = ("pronking", "backflip", "gap_jump", "box_jump", "stand_to_bound", "bound_pronk_bound",
                  "bound_to_stop")
"""The tasks whose motion MPC [`TASK_MPC_RECORD`][TASK_MPC_RECORD] holds (a table ``robustness/task_mpc_TASK``
each)."""


def robustness_task_mpc_summary(store: Store) -> str:
    """Per motion, the MPC against its plan-tracking expert: successes of 20 nominal, under a push, observation noise,
    the worst latency cell, the contact family, and the worst cell of all with its condition."""
    if TASK_MPC_RECORD not in store.ids():
        return f"No `{TASK_MPC_RECORD}` record yet."
    d = store.data(TASK_MPC_RECORD)
    conditions = d["conditions"]
    latency = [i for i, c in enumerate(conditions) if c.startswith("delay_")]

    def cell(results: dict, label: str, idx: list[int]) -> str:
        values = [results[label]["successes"][i] for i in idx if label in results]
        values = [v for v in values if v is not None]
        return NA if not values else str(min(values))

    def worst(results: dict, label: str) -> str:
        cells = [(v, conditions[i]) for i, v in enumerate(results[label]["successes"]) if v is not None]
        low = min(v for v, _ in cells)
        at = [c for v, c in cells if v == low]
        if len(at) == len(cells):
            return f"{low} (every cell)"
        return f"{low} (`{at[0]}`" + (f" and {len(at) - 1} more)" if len(at) > 1 else ")")

    header = ["motion", "nominal", "push", "obs. noise", "worst latency", "contact family", "worst cell"]
    rows = []
    index = {c: i for i, c in enumerate(conditions)}
    for t in [t for t in TASK_MPC_TASKS if t in d["tasks"]]:
        r = d["tasks"][t]["results"]
        rows.append([t.replace("_", " ")] + [
            f"{cell(r, 'mpc', idx)} / {cell(r, 'expert', idx)}"
            for idx in ([index["default"]], [index["push"]], [index["obs_noise"]], latency, [index["contact_family"]])
        ] + [f"{worst(r, 'mpc')} / {worst(r, 'expert')}"])
    note = (f"Cells: successes of {len(d['seeds'])} episodes (seeds {d['seeds'][0]}-{d['seeds'][-1]}), the MPC / the "
            "plan-tracking expert; worst latency: the least of the four latency cells.")
    return "\n".join([markdown_table(header, rows, ["l"] + ["r"] * 6), "", note, source_line(store, TASK_MPC_RECORD)])


def robustness_tasks_pronking(store: Store) -> str:
    """The pronk's expert under the perturbation conditions."""
    return task_robustness(store, ("pronking",))


def robustness_tasks_backflip(store: Store) -> str:
    """The backflip's expert under the perturbation conditions."""
    return task_robustness(store, ("backflip",))


def robustness_tasks_jumps(store: Store) -> str:
    """The jumps' expert under the perturbation conditions."""
    return task_robustness(store, ("gap_jump", "box_jump"))


def robustness_tasks_transitions(store: Store) -> str:
    """The gait transitions' expert under the perturbation conditions."""
    return task_robustness(store, ("stand_to_bound", "bound_pronk_bound", "bound_to_stop"))
