"""Robustness benchmark: the named perturbations of ``hsddp_gym.envs.perturbations.CONDITIONS`` x any policy.

Each (policy, condition, seed) is one episode of the condition's env (``make_env(condition)``: env kwargs and
wrappers, every random draw seeded from the episode seed) reset with ``seed``, run to the env's 1000-step
time limit (5 s) or a fall. Policies:

* ``mpc``: ``MPCPolicy`` with the default ``MPCOptions()`` (it reads the env's action delay, if any, from
  ``EnvInterface.from_env``); ``mpc-options``: ``MPCOptions().replace(**json)`` from ``--mpc-options`` (ablations; give
  ``--label`` to name it);
* ``heuristic``: the contact-event heuristic; ``random``;
* learned ones, ``--learned NAME=DIR`` (NAME ``bc`` / ``dagger``: ``DIR/policy.npz``; ``ppo`` / ``sac``:
  ``DIR/model.zip`` + ``summary.json``, ``--rl-checkpoint best`` for the best training-time evaluation's weights;
  ``NAME@TAG=DIR`` labels one of several of a kind, e.g. training seeds), skipped with a note when the files are
  missing; ``bc`` / ``dagger`` with several directories, ``NAME=DIR1,DIR2,...``, is their mean-action ensemble
  (:func:`hsddp_gym.learning.ensemble.load_mlp_ensemble`);
* ``--estimated LABEL ...``: those policies once more behind the MPC's own perception
  (:class:`~hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy`: the state filter under observation
  noise, the model's prediction over an action delay), labelled ``LABEL+est``.

**Contact models.** Beside the suite, ``--conditions`` takes the contact-model conditions, which always run in the
MuJoCo twin whatever ``--simulator`` says: ``contact_family`` draws a contact model per episode from the episode seed
(``ContactModel.sample``: friction cone, solref, solimp, foot radius, impratio, time step, friction) and
``contact_<corner>`` runs one named corner of ``hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`` (softest, stiffest,
pyramidal, large_feet, low_friction, coarse_step). Their rows also give the mean time to fall, and the episodes of
``contact_family`` record their model (``contact_model``), so falls can be read against the drawn parameters.

**Conditions of a real robot.** ``--conditions`` also takes the hardware conditions
(``hsddp_gym.envs.perturbations.HARDWARE_CONDITIONS``, not in the suite): a latency other than the one the policies are
told (``delay_5ms_announced_0ms``, ``delay_10ms_announced_5ms``, ``delay_5ms_announced_10ms``,
``delay_15ms_announced_10ms``: executed, then announced; ``delay_jitter``: 10 ms announced, 5, 10 or 15 ms executed,
drawn per episode), a constant sensor bias (``sensor_bias``: +0.03 rad pitch, +0.05 m/s forward velocity, -0.02 m
height; ``sensor_bias_random``: a bias drawn per episode; ``sensor_bias_x2``: ``sensor_bias`` twice over), a push timed
by the contact phase (``push_flight``, ``push_stance``: at the first control step in flight, resp. in stance, after
t ~ U(1, 4) s, dv up to 1.0 m/s, 1.0 m/s, 7 rad/s) and several at once (``noise_bias_latency``: ``obs_noise``'s noise,
``sensor_bias_random``'s bias, 10 ms of latency announced as 5 ms). Each of their episodes records what was drawn
(``perturbation``: the executed and announced delay, the bias, the applied push).

**Every task.** ``--env ID [ID ...]`` runs in tasks' envs instead of Bounding-v0 (``hsddp_gym/Backflip-v0``,
``hsddp_gym/GapJump-v0``, ...; the contact conditions in their MuJoCo twins), one after the other (several:
``OUT/TASK/``): by default the task-generic suite (``hsddp_gym.envs.perturbations.TASK_SUITE``, those of its
conditions that apply to the task) with the task's plan-tracking expert (``--policies expert``, starting from its
``reset_options``; Terrain-v0 has none: ``--policies mpc``, given each episode's terrain). Pushes come in the task's
window with the task's sizes (``Task.push_window``, ``Task.push_size``); a condition that cannot apply to a task (a
target speed where the task fixes its own, a twin it does not have) is refused. Each episode records the task's
success (its rule at the last step) beside its fall; per cell: successes / episodes and falls / episodes. ``--record``
then puts the tasks' cells into a record of several tasks (e.g. ``results/robustness/tasks.json``: per task, policy
and condition the successes and falls; every episode is in ``OUT/robustness.json``), keeping its other tasks and
policies.

**Seeds.** The default evaluation seeds are 7000-7019 (``--first-seed 7000 --seeds 20``); they were not used to
develop or tune anything, with one exception: the scuff rule of the MPC's gait clock (a contact counts as a landing
only after a swing of at least ``min_flight`` of the flight) was found on seed 7012 of the ``obs_noise`` condition.
Development used seeds 500-899.
``--seed-list S [S ...]`` runs exactly those seeds (e.g. an earlier run's ``fall_seeds``, or a subset of pushes
chosen by their draw).

Per cell: falls / episodes, mean return (all episodes), mean forward speed of the episodes that did not fall
(and its error to the target), real-time factor (simulated / wall time, policy + simulation), and for the MPC the
planner failures and mean re-plan time. Writes ``OUT/robustness.json`` (every episode), ``OUT/robustness.md``
(the table) and ``OUT/robustness.png`` (falls and speed per condition). Episodes are independent:
``--workers`` runs them in parallel with the same results (timings aside).

Usage::

    python experiments/robustness.py --out runs/robustness --policies mpc heuristic --seeds 20 --workers 2
        [--conditions default obs_noise ...] [--learned bc=runs/train/bc]
    python experiments/robustness.py --out runs/contact --policies mpc heuristic --seeds 5 --first-seed 9000
        --conditions contact_family contact_softest contact_stiffest contact_pyramidal contact_large_feet
        contact_low_friction contact_coarse_step
    python experiments/robustness.py --out runs/extra --policies mpc heuristic --seeds 20 --first-seed 9300
        --conditions delay_10ms_announced_5ms delay_jitter sensor_bias sensor_bias_random push_flight push_stance
        push_x3
    python experiments/robustness.py --out runs/robustness_table --combine runs/a/robustness.json runs/b/robustness.json
    python experiments/robustness.py --env hsddp_gym/Backflip-v0 hsddp_gym/GapJump-v0 --policies expert
        --first-seed 56000 --workers 2 --record results/robustness/tasks.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from hsddp_gym.benchmarks.robustness import (
    BUILTIN,
    EVAL_FIRST_SEED,
    LEARNED,
    benchmark_policy,
    combine,
    markdown,
    merge_task_record,
    run_benchmark,
    run_one,
    summarize_cell,
    task_record_entry,
)
from hsddp_gym.reports.store import machine_info, read_record, write_record
from hsddp_gym.util.io import atomic_path, write_json
from hsddp_gym.util.parallel import add_backend_arguments, check_backend
from hsddp_gym.viz.plotting import plot_robustness

__all__ = ["BUILTIN", "EVAL_FIRST_SEED", "LEARNED", "benchmark_policy", "combine", "markdown", "run_benchmark",
           "run_one", "summarize_cell", "main"]


def main(argv: list[str] | None = None) -> int:
    from hsddp_gym.envs.perturbations import CONDITIONS, SIMULATORS, SUITE, TASK_SUITE, condition_task
    from hsddp_gym.registry import TASKS

    bounding = TASKS["bounding"].env_id
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/robustness", help="output directory (default: %(default)s)")
    p.add_argument("--env", nargs="+", default=[bounding], choices=[t.env_id for t in TASKS.values()],
                   metavar="ID",
                   help="the tasks whose envs the conditions run in, one after the other (their MuJoCo twins for the "
                        "contact conditions): pushes in the task's window and sizes, each episode's success recorded; "
                        "several: OUT/TASK/ per task (default: %(default)s)")
    p.add_argument("--policies", nargs="*", default=None, choices=BUILTIN,
                   help="built-in policies (expert: the task's plan-tracking expert); '--policies' alone runs none "
                        "(only --learned ones) (default: mpc heuristic in Bounding-v0, the task's expert in another "
                        "task's env)")
    p.add_argument("--mpc-options", default=None, metavar="JSON",
                   help="the mpc-options policy's settings by their flat names (MPCOptions.replace), JSON (ablations)")
    p.add_argument("--label", default="mpc-options", help="name of the mpc-options policy (default: %(default)s)")
    p.add_argument("--learned", action="append", default=[], metavar="NAME=DIR",
                   help=f"a trained policy, NAME one of {list(LEARNED)}, or NAME@TAG to run several of a kind (e.g. "
                        "ppo@seed0=DIR0 ppo@seed1=DIR1); bc/dagger with comma-separated directories "
                        "(dagger@ens=DIR0,DIR1,DIR2) is the mean action of those learners (repeatable; skipped if "
                        "its files are missing)")
    p.add_argument("--rl-checkpoint", choices=("final", "best"), default="final",
                   help="ppo/sac: the final weights or the best training-time evaluation's (default: %(default)s)")
    p.add_argument("--estimated", nargs="+", default=[], metavar="LABEL",
                   help="policies (labels of --policies or --learned names, not the MPC) that also run behind the "
                        "MPC's state filter and latency compensation (EstimatedStatePolicy), labelled LABEL+est")
    p.add_argument("--conditions", nargs="+", default=None, choices=list(CONDITIONS),
                   help="conditions (default: the benchmark suite, hsddp_gym.envs.perturbations.SUITE: every condition "
                        "but push_x3 and the contact ones; with --env a task's env: TASK_SUITE, those of its "
                        "conditions that apply to the task). The contact-model conditions always run in the MuJoCo "
                        "twin (whatever --simulator says): contact_family draws a contact model per episode from the "
                        "episode seed (friction cone, solref, solimp, foot radius, impratio, time step, friction; "
                        "hsddp_gym.envs.mujoco_twin.ContactModel.sample), contact_<corner> runs one corner of "
                        "CONTACT_CORNERS (softest, stiffest, pyramidal, large_feet, low_friction, coarse_step); "
                        "the table then adds falls and mean time to fall per contact condition. The hardware "
                        "conditions (HARDWARE_CONDITIONS) test what a real robot has: a latency other than the one "
                        "announced to the policy (delay_<executed>_announced_<announced>, e.g. "
                        "delay_10ms_announced_5ms; delay_jitter: 10 ms announced, 5, 10 or 15 ms executed, drawn per "
                        "episode), a constant sensor bias (sensor_bias: +0.03 rad pitch, +0.05 m/s forward velocity, "
                        "-0.02 m height; sensor_bias_random: drawn per episode; sensor_bias_x2: sensor_bias twice "
                        "over), pushes timed by the contact phase (push_flight, push_stance: dv up to 1.0 m/s, "
                        "1.0 m/s, 7 rad/s at the first flight or stance step after t ~ U(1, 4) s) and several at once "
                        "(noise_bias_latency: obs_noise's noise, sensor_bias_random's bias, 10 ms of latency "
                        "announced as 5 ms); push_x3: three pushes")
    p.add_argument("--seeds", type=int, default=20, help="episodes per policy and condition (default: %(default)s)")
    p.add_argument("--first-seed", type=int, default=EVAL_FIRST_SEED,
                   help="first seed (default: %(default)s, the evaluation seeds; develop on others)")
    p.add_argument("--seed-list", type=int, nargs="+", default=None, metavar="SEED",
                   help="run exactly these seeds instead of --seeds/--first-seed (e.g. an earlier run's fall seeds)")
    p.add_argument("--max-steps", type=int, default=None,
                   help="stop episodes after this many control steps (default: the 1000-step limit; smoke tests)")
    p.add_argument("--workers", type=int, default=1,
                   help="parallel worker processes; results do not depend on it (default: %(default)s)")
    add_backend_arguments(p)
    p.add_argument("--simulator", default="bounding", choices=sorted(SIMULATORS),
                   help="the simulator every condition runs in (the contact ones: always mujoco): bounding "
                        "(hsddp_gym/Bounding-v0, exact LCP), mujoco "
                        "(its MuJoCo twin, soft contacts; needs the extra 'mujoco') or kkt (the planner's own model) "
                        "(default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--combine", nargs="+", default=None, metavar="JSON",
                   help="run nothing: merge these robustness.json files into one table in --out")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the table's cells (no per-episode rows) as a record of the results store, e.g. "
                        "results/robustness/suite.json")
    p.add_argument("--made-with", nargs="*", default=[], metavar="COMMAND",
                   help="with --env and --record: the commands that made the --learned policies, put in the record "
                        "before this one (default: none)")
    args = p.parse_args(argv)
    if args.combine:
        missing = [f for f in args.combine if not Path(f).is_file()]
        if missing:
            p.error(f"--combine: no such file(s) {missing}")
        combine(args.combine, Path(args.out))
        return 0
    if args.seeds < 1:
        p.error(f"--seeds must be >= 1, got {args.seeds}")
    if args.first_seed < 0:
        p.error(f"--first-seed must be >= 0, got {args.first_seed}")
    if args.seed_list is not None:
        if min(args.seed_list) < 0:
            p.error(f"--seed-list: seeds must be >= 0, got {min(args.seed_list)}")
        if len(set(args.seed_list)) != len(args.seed_list):
            p.error("--seed-list: a seed is given twice")
    if args.workers < 1:
        p.error(f"--workers must be >= 1, got {args.workers}")
    try:
        check_backend(args.backend, args.address)
    except (ImportError, ValueError) as exc:
        p.error(f"--backend {args.backend}: {exc}")
    if args.max_steps is not None and args.max_steps < 1:
        p.error(f"--max-steps must be >= 1, got {args.max_steps}")
    if len(set(args.env)) != len(args.env):
        p.error(f"--env: an env is given twice: {args.env}")
    if bounding in args.env and len(args.env) > 1:
        p.error(f"--env: {bounding} runs alone (its tables are the suite's)")
    tasks = {e: condition_task(e) for e in args.env}
    env_ids = {e: None if e == bounding else e for e in args.env}  # None: Bounding-v0, as before
    conditions = {}
    for e, task in tasks.items():
        if args.conditions is None:
            suite = SUITE if env_ids[e] is None else TASK_SUITE
            conditions[e] = [c for c in suite if CONDITIONS[c].applies_to(task, args.simulator)]
            left = [c for c in suite if c not in conditions[e]]
            if left:
                print(f"not applicable to {e}: {', '.join(left)}", flush=True)
        else:
            conditions[e] = list(args.conditions)
        for c in conditions[e]:
            reason = CONDITIONS[c].refusal(task, args.simulator)
            if reason is not None:
                p.error(f"--conditions: {c!r} does not apply to the task {task.name!r} ({e}): {reason}")
    if args.policies is None:
        args.policies = ["mpc", "heuristic"] if env_ids[args.env[0]] is None else ["expert"]
    lacking = [e for e, task in tasks.items() if task.expert is None]
    if "expert" in args.policies and lacking:
        p.error(f"--policies expert: {', '.join(lacking)} has no plan-tracking expert (use --policies mpc)")
    policies: dict = {}
    for name in args.policies:
        if name == "mpc-options":
            if args.mpc_options is None:
                p.error("the mpc-options policy needs --mpc-options")
            from hsddp_gym.planners.policies.mpc import MPCOptions

            try:
                opts = json.loads(args.mpc_options)
                if not isinstance(opts, dict):
                    raise ValueError("not a JSON object")
                MPCOptions().replace(**opts)
            except (ValueError, TypeError) as exc:
                p.error(f"--mpc-options must be a JSON object of MPC settings by their flat names: {exc}")
            policies[args.label] = {"kind": "mpc-options", "mpc_options": opts}
        else:
            policies[name] = {"kind": name}
    skipped = {}
    for item in args.learned:
        name, sep, path = item.partition("=")
        kind = name.split("@")[0]
        if not sep or kind not in LEARNED or name in policies or name in skipped:
            p.error(f"--learned must be NAME=DIR with NAME one of {list(LEARNED)}, optionally tagged NAME@TAG (e.g. "
                    f"ppo@seed1), each NAME once, got {item!r}")
        dirs = path.split(",")
        if len(dirs) > 1 and kind not in ("bc", "dagger"):
            p.error(f"--learned {item!r}: only bc and dagger learners form an ensemble of several directories")
        missing = [str(Path(d) / LEARNED[kind]) for d in dirs if not (Path(d) / LEARNED[kind]).exists()]
        if missing:
            skipped[name] = f"missing {', '.join(missing)}"
            print(f"skipping {name}: {skipped[name]}", flush=True)
            continue
        policies[name] = {"kind": kind, "dir": path} if len(dirs) == 1 else {"kind": kind, "dirs": dirs}
        if kind in ("ppo", "sac"):
            policies[name]["checkpoint"] = args.rl_checkpoint
    for label in args.estimated:
        if label in skipped:
            continue
        if label not in policies:
            p.error(f"--estimated: {label!r} is not one of the policies run ({sorted(policies)})")
        if policies[label]["kind"] in ("mpc", "mpc-options", "expert"):
            p.error(f"--estimated: {label!r} is an MPC, which filters and predicts itself, or the expert, built for "
                    "its env")
        policies[f"{label}+est"] = {**policies[label], "estimator": True}
    if not policies:
        p.error("no policy to run: give --policies or a --learned policy whose files exist")
    seeds = list(args.seed_list) if args.seed_list is not None else list(range(args.first_seed,
                                                                                 args.first_seed + args.seeds))
    machine = machine_info()
    record: dict = {}
    for e, task in tasks.items():
        out = Path(args.out) if len(tasks) == 1 else Path(args.out) / task.name
        results = _run(args, policies, skipped, conditions[e], seeds, env_ids[e], task, out)
        if env_ids[e] is not None:
            record[task.name] = ({"push_window": list(task.push_window), "push_size": list(task.push_size),
                                  "results": task_record_entry(results, conditions[e])}, conditions[e])
        elif args.record:
            cells = {pol: {c: {k: v for k, v in cell.items() if k != "runs"} for c, cell in by_cond.items()}
                     for pol, by_cond in results.items()}
            write_record(args.record, {"seeds": seeds, "max_steps": args.max_steps, "simulator": args.simulator,
                                       "policies": policies, "conditions": {c: CONDITIONS[c].as_dict()
                                                                            for c in conditions[e]},
                                       "results": cells},
                         f"Falls, returns and speeds of {', '.join(results)} under the perturbation conditions "
                         f"({len(seeds)} seeds each, {args.simulator})", machine=machine)
            print(f"wrote {args.record}")
    if args.record and record:
        _record_tasks(args.record, record, seeds, machine, argv, args.made_with)
    return 0


def _run(args, policies: dict, skipped: dict, conditions: list, seeds: list, env_id: str | None, task,
         out: Path) -> dict:
    """Run the benchmark in one env (``env_id``, None: Bounding-v0) and write ``OUT/robustness.{json,md,png}``."""
    from hsddp_gym.envs.perturbations import CONDITIONS

    t0 = time.perf_counter()
    results = run_benchmark(policies, conditions, seeds, args.max_steps, args.workers, not args.quiet,
                            args.backend, args.address, args.simulator, env_id)
    task_fields = {} if env_id is None else {"env_id": env_id, "push_window": list(task.push_window),
                                             "push_size": list(task.push_size)}
    write_json(out / "robustness.json", {
        "command": " ".join(["python", *sys.argv]), "seeds": seeds, "max_steps": args.max_steps,
        "simulator": args.simulator, **task_fields,
        "policies": policies, "skipped": skipped, "wall_time_s": time.perf_counter() - t0,
        "conditions": {c: CONDITIONS[c].as_dict() for c in conditions}, "results": results})
    table = markdown(results, conditions)
    with atomic_path(out / "robustness.md") as tmp:
        tmp.write_text(table)
    plot_robustness(results, conditions, out / "robustness.png")
    print("\n" + (f"{task.env_id}\n" if env_id is not None else "") + table)
    return results


def _record_tasks(path: str, entries: dict, seeds, machine: dict, argv, made_with=()) -> None:
    """Put the tasks' entries (``{task: (entry, conditions)}``) into the tasks' record at ``path``: kept are its
    other tasks and, per task, its other policies, and its other commands (``made_with``, the commands that made the
    learned policies, then this command, ``argv`` without them, each once)."""
    from hsddp_gym.reports.store import invoked_command, without_option

    data, commands = None, []
    if Path(path).is_file():
        record = read_record(path)
        data, commands = record.data, list(record.commands)
    for name, (entry, conditions) in entries.items():
        data = merge_task_record(data, name, entry, conditions, seeds)
    command = invoked_command(without_option(argv, "--made-with"))
    new = [*made_with, command]
    commands = [c for c in commands if c not in new] + new
    write_record(path, data, f"Successes and falls of the tasks under the perturbation conditions ({len(seeds)} "
                 "seeds)", command=commands if len(commands) > 1 else command, machine=machine)
    print(f"wrote {path} ({', '.join(entries)})")


if __name__ == "__main__":
    sys.exit(main())
