"""The tables of the motions beyond the bound: every planned motion's plan, and per task (pronking, terrain,
backflip, jumps, transitions) its expert and the learners trained from its demonstrations."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import fmt, load_average, markdown_table, source_line

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
            f"({store[rids[0]].machine.get('cpus')} cores, load average {load_average(store[rids[0]].machine)}), "
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
    for (rounds, suffix), group in _dagger_groups(d):
        for r in group:
            rollouts = r["rounds"] * r["episodes_per_round"]
            first = (f"{r['initial_demonstrations']} demos" if r.get("initial_demonstrations") is not None else
                     f"{r['episodes_per_round']} expert episodes")
            rows.append(cells(r, f"{r['expert_labels']:,} {_labeller(r)} labels ({first} + {rollouts} relabelled "
                                 f"rollout{'s' if rollouts != 1 else ''})", f"{r['train_wall_time_s']:.0f} s"))
        rows.append(seeds_row(f"DAgger, {rounds} {dagger_unit}{'s' if rounds != 1 else ''}{suffix}", group))
    return rows


def _labeller(row: dict) -> str:
    """Who labelled a DAgger row's rollouts, as a table names it: ``"MPC"`` or ``"expert"`` (the records before
    the labeller was kept: the expert)."""
    return "MPC" if row.get("labeller") == "mpc" else "expert"


def _dagger_groups(d: dict) -> list[tuple[tuple[int, str], list]]:
    """A task record's DAgger rows grouped by ``(rounds, suffix)`` ([`_dagger_suffix`][_dagger_suffix]), one row per
    training seed, the groups in the record's order."""
    groups: dict = {}
    for r in d.get("dagger", []):
        groups.setdefault((r["rounds"], _dagger_suffix(r)), []).append(r)
    return list(groups.items())


def _dagger_suffix(row: dict) -> str:
    """What a DAgger learner's name adds to its iterations: ``, MPC labels`` (labelled by the task's MPC) and
    ``, best round`` (the run kept its best round, ``--keep best``)."""
    return (", MPC labels" if _labeller(row) == "MPC" else "") + (", best round" if row.get("keep") == "best" else "")


def _by(labeller: str) -> str:
    """The DAgger label's suffix of a [`_labeller`][_labeller] value."""
    return ", " + labeller.replace("MPC", "MPC labels").removeprefix("expert").lstrip(", ") if labeller != "expert" \
        else ""


def _rl_name(row: dict) -> str:
    """How the tables name an RL row's learner
    ([`hsddp_gym.learning.reporting.rl_label`][hsddp_gym.learning.reporting.rl_label]; the records before the algorithm
    was kept: SAC)."""
    from hsddp_gym.learning.reporting import rl_label

    return rl_label(row.get("algo", "sac"), row)


def rl_groups(d: dict) -> list[tuple[str, list]]:
    """A task record's RL runs (``d["sac"]``, ``d["ppo"]``) as ``(name, rows)`` per learner and checkpoint, one row
    per training seed."""
    rows = [r for algo in ("sac", "ppo") for r in d.get(algo, [])]
    groups = {}
    for r in rows:
        name = "final weights" if r["checkpoint"] == "final" else "best checkpoint"
        groups.setdefault(f"{_rl_name(r)} ({name})", []).append(r)
    return list(groups.items())


def _rl_rows(d: dict, cells, seeds_row) -> list:
    """A task record's RL rows, one per training seed and checkpoint, then one summing the seeds per learner and
    checkpoint (when there are several)."""
    out = []
    for _, group in rl_groups(d):
        for r in group:
            steps = (f"{r['env_steps']:,} env steps" if r["checkpoint"] == "final" else
                     f"{r['env_steps']:,} of {r['total_env_steps']:,} env steps")
            out.append(cells(r, steps, f"{r['train_wall_time_s']:.0f} s"))
    for name, group in rl_groups(d):
        if len(group) > 1:
            out.append(seeds_row(name, group))
    return out


def _rl_note(d: dict) -> str:
    """The note on a record's RL runs: their wall-clock budgets and how they act."""
    rl = [r for algo in ("sac", "ppo") for r in d.get(algo, [])]
    limits = sorted({r["time_limit_s"] for r in rl if r.get("time_limit_s")})
    if not limits:
        return ""
    residual = (" A residual learner adds its action, scaled, to the plan-tracking expert's."
                if any(r.get("residual") for r in rl) else "")
    return (f" RL trained for a wall-clock budget of {', '.join(f'{t:g}' for t in limits)} s (RL-Zoo settings, "
            "`hsddp-gym train --algo sac|ppo --time-limit`); both its final weights and its best checkpoint act with "
            f"the mean action.{residual}")


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
    rows += _rl_rows(d, cells, seeds_row)
    seeds = d["seeds"]
    note = (f"{len(seeds)} episodes, seeds {seeds[0]}-{seeds[-1]} (used by no dataset or training run), target speed "
            f"{d['target_speed']:g} m/s, 1000 steps (5 s); return: mean ± std over the episodes. Success: "
            f"{d['success_rule']}. Samples: the expert's labelled (observation, action) pairs BC and DAgger learned "
            "from (DAgger's include BC's demonstrations, its round 0), or RL's env steps (of its best checkpoint: "
            "the steps when it was saved). Training time: wall-clock seconds on the shared 2-core machine.")
    note += _rl_note(d)
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
    rows += _rl_rows(d, cells, seeds_row)
    seeds = d["seeds"]
    note = (f"{len(seeds)} episodes, seeds {seeds[0]}-{seeds[-1]} (used by no dataset or training run), "
            f"{d['max_episode_steps']} steps ({d['max_episode_steps'] * 0.005:g} s) {episodes_note}. "
            f"Success: {d['success_rule']}. "
            "Samples: the expert's labelled (observation, action) pairs BC and DAgger learned from (DAgger's include "
            "BC's demonstrations), or RL's env steps. Training time: wall-clock seconds on the shared 2-core "
            "machine." + _rl_note(d))
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


TASK_TABLE_ORDER = (("tasks/pronking", "pronk"), ("tasks/backflip", "backflip from standing"),
                    ("tasks/gap_jump", "jump over a 0.3 m gap"), ("tasks/box_jump", "jump onto a 0.1 m box"),
                    ("tasks/stand_to_bound", "stand to bound"), ("tasks/bound_pronk_bound", "bound, pronk, bound"),
                    ("tasks/bound_to_stop", "bound to stop"))
"""The task records of the task x learner table, in its order, with how the table names each task."""
TWIN_KEY = "mujoco_twin"
"""The key of a row's ``conditions`` that counts its episodes in the MuJoCo twin
([`hsddp_gym.benchmarks.tasks.TWIN`][hsddp_gym.benchmarks.tasks.TWIN])."""


def learner_groups(d: dict) -> list[tuple[str, list]]:
    """A task record's learners as ``(name, rows)``, one row per training seed: BC, DAgger per number of iterations
    and labeller, RL per algorithm, residual and checkpoint ([`rl_groups`][rl_groups])."""
    groups = [("BC", d.get("bc", []))] if d.get("bc") else []
    for (rounds, suffix), group in sorted(_dagger_groups(d), key=lambda g: g[0]):
        groups.append((f"DAgger, {rounds} iterations{suffix}", group))
    return groups + rl_groups(d)


def success_cell(group: list) -> str:
    """Successes summed over a learner's training seeds, with the 95 % Student-t interval of the success rate over
    the seeds (one rate per seed; clipped to 0-100 %) when there are at least two."""
    from hsddp_gym.learning.reporting import mean_ci95

    ok, n = sum(r["successes"] for r in group), sum(r["episodes"] for r in group)
    if len(group) < 2:
        return f"{ok}/{n}"
    mean, half = mean_ci95([r["successes"] / r["episodes"] for r in group])
    lo, hi = round(100 * max(mean - half, 0.0)), round(100 * min(mean + half, 1.0))
    return f"{ok}/{n} ({lo} % every seed)" if lo == hi else f"{ok}/{n} ({lo}-{hi} %)"


def condition_cell(group: list, name: str) -> str:
    """Successes in condition ``name`` summed over the rows (``–`` unless every row was run in it)."""
    cells = [r.get("conditions", {}).get(name) for r in group]
    if not group or any(c is None for c in cells):
        return "–"
    return f"{sum(c['successes'] for c in cells)}/{sum(c['episodes'] for c in cells)}"


def _mean_int(values) -> str:
    return f"{round(sum(values) / len(values)):,}"


def tasks_summary(store: Store) -> str:
    """Every task beyond bounding, task x learner: the plan-tracking expert and each learner from its demonstrations
    (BC, DAgger per iterations and labeller, SAC) on unseen seeds, under a push and observation noise and in the MuJoCo
    twin, with the expert labels, env steps, training time and training seeds each used (the task records
    ``tasks/*``)."""
    header = ["task", "policy", "success", "push", "obs. noise", "MuJoCo twin", "expert labels", "env steps",
              "training time", "training seeds"]
    rows, used = [], []
    for rid, what in TASK_TABLE_ORDER:
        if rid not in store.ids():
            continue
        used.append(rid)
        d = store.data(rid)
        env_id = d["env_id"]
        if "target_speed" in d:
            what = f"{what} at {d['target_speed']:g} m/s"
        task = f"{what} (`{env_id.split('/')[-1]}`, seeds {d['seeds'][0]}-{d['seeds'][-1]})"
        expert = {r["env_id"]: r for r in d["rows"] if r["label"] == "expert"}
        own = expert.get(env_id)
        twin = [r for e, r in expert.items() if e != env_id]
        if own is not None:
            rows.append([task, "expert (plan tracking)", f"{own['successes']}/{own['episodes']}",
                         condition_cell([own], "push"), condition_cell([own], "obs_noise"),
                         f"{twin[0]['successes']}/{twin[0]['episodes']}" if twin else "–", "–", "–", "–", "–"])
        for name, group in learner_groups(d):
            if "checkpoint" in group[0]:  # RL: no expert labels (a residual learner's expert acts, labels none)
                labels, steps = "0", _mean_int([r["env_steps"] for r in group])
            else:
                labels = _mean_int([r.get("expert_labels", r["transitions"]) for r in group])
                steps = _mean_int([r["transitions"] for r in group])
            rows.append(["" if any(row[0] == task for row in rows) else task, name, success_cell(group),
                         condition_cell(group, "push"), condition_cell(group, "obs_noise"),
                         condition_cell(group, TWIN_KEY), labels, steps,
                         f"{sum(r['train_wall_time_s'] for r in group) / len(group):.0f} s", str(len(group))])
    if not rows:
        return "No task record yet: run `python experiments/tasks.py --task backflip`."
    note = ("Successes / episodes on seeds used by no dataset or training run (push, observation noise and the "
            "MuJoCo twin: the same seeds; – where the record has no such run); each task's success rule and the "
            "per-seed rows are on its page (Pronking-v0, Backflip-v0, the jumps, the gait transitions). Learners: "
            "summed over their training seeds, with the 95 % interval of the success rate over the seeds (Student "
            "t); expert labels (the labelled pairs learned from; DAgger's include its first demonstrations) and env "
            "steps (the states visited: demonstrations and rollouts, or RL's steps) and training time (wall clock, "
            "2-core machine): means per training seed. DAgger's labeller: the plan-tracking expert, or the task's "
            "MPC. The expert tracks the task's HS-DDP plan with the plan's feedback gains (the pronk: a periodic "
            "plan).")
    return "\n".join([markdown_table(header, rows, ["l", "l"] + ["r"] * (len(header) - 2)), "", note,
                      source_line(store, *used)])
