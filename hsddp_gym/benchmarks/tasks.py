"""The task evaluations (``experiments/tasks.py``, ``experiments/backflip.py``, ``experiments/pronking.py``): a task's
expert in its env and twin, and learners from its demonstrations, on the task's unseen evaluation seeds.

Each policy plays one episode per seed of the task's env
([`hsddp_gym.rollout.episodes.run_episode`][hsddp_gym.rollout.episodes.run_episode]); per episode the return, the
length, a fall, the task's measures (``Task.measures`` of the task registry,
[`TaskEpisodes`][hsddp_gym.rollout.measures.TaskEpisodes]) and its success. A row sums them. """

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from hsddp_gym.registry import Task, resolve


def task_measures(task: Task):
    """The [`Measures`][hsddp_gym.rollout.measures.Measures] of ``task`` (``Task.measures``)."""
    if task.measures is None:
        raise ValueError(f"task {task.name!r} has no per-episode measures")
    return resolve(task.measures)


def run_task_episodes(task: Task, env, policy, seeds) -> list[dict]:
    """Play one episode per seed; per episode: seed, return, length, fell, the task's measures, success."""
    from hsddp_gym.rollout.episodes import run_episode
    from hsddp_gym.rollout.measures import TaskEpisodes

    seen = TaskEpisodes(task_measures(task))
    out = []
    for seed in seeds:
        run_episode(env, policy, int(seed), observers=(seen,))
        out.append(seen.episode(int(seed)))
    return out


def task_summary(task: Task, episodes: list[dict]) -> dict:
    """A row's statistics: episodes, mean and std return, successes, falls and the task's row measures."""
    r = np.array([e["return"] for e in episodes])
    return {"episodes": len(episodes), "mean_return": float(r.mean()), "std_return": float(r.std()),
            "successes": int(sum(e["success"] for e in episodes)), "falls": int(sum(e["fell"] for e in episodes)),
            **task_measures(task).summarize(episodes)}


def episode_columns(episodes: list[dict], keys=None) -> dict:
    """What a record keeps of a row's episodes: ``{key: [value per episode]}`` for ``keys`` (None: every key of the
    first episode), in the episodes' order (columns: a record stays small and each column reads on one line)."""
    keys = list(episodes[0]) if keys is None and episodes else list(keys or ())
    return {k: [e[k] for e in episodes] for k in keys}


TWIN = "mujoco_twin"
"""The key of a row's ``conditions`` that counts its episodes in the task's MuJoCo twin."""


def evaluate_task_policy(task: Task, label: str, env_id: str, spec, seeds, quiet: bool, conditions=(),
                         twin: bool = False, episodes: bool = True) -> dict:
    """The row of policy ``spec`` (a name or [`PolicySpec`][hsddp_gym.rollout.policies.PolicySpec],
    [`make_policy`][hsddp_gym.rollout.policies.make_policy]) in ``env_id`` (the task's env or a twin) on ``seeds``;
    with ``conditions`` (names of
    [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS]) or ``twin``, the
    row's ``conditions`` holds the policy's successes on the same seeds in each condition and (key
    [`TWIN`][TWIN]) in the task's MuJoCo twin ([`condition_counts`][condition_counts]). ``episodes``: the row keeps
    the task's per-episode measures ([`episode_columns`][episode_columns]); else (a learner's row) only the seeds of
    the episodes that failed and that fell (``failed_seeds``, ``fell_seeds``)."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.rollout.policies import make_policy

    measures = task_measures(task)
    env = gym.make(env_id)
    policy = make_policy(spec, env)
    t = time.perf_counter()
    eps = run_task_episodes(task, env, policy, seeds)
    env.close()
    row = {"label": label, "env_id": env_id, **task_summary(task, eps), "wall_time_s": time.perf_counter() - t}
    if episodes:
        row["per_episode"] = episode_columns(eps, measures.per_episode)
    else:
        row.update(failed_seeds=[e["seed"] for e in eps if not e["success"]],
                   fell_seeds=[e["seed"] for e in eps if e["fell"]])
    if conditions or twin:
        row["conditions"] = condition_counts(task, spec, seeds, conditions, twin)
    if not quiet:
        extra = "".join(f"  {k} {c['successes']}/{c['episodes']}" for k, c in row.get("conditions", {}).items())
        print(f"{label:28s} {env_id:30s} return {row['mean_return']:8.1f} ± {row['std_return']:6.1f}  success "
              f"{row['successes']}/{row['episodes']}  falls {row['falls']}  {measures.describe(row)}{extra}",
              flush=True)
    return row


def condition_counts(task: Task, spec, seeds, conditions=(), twin: bool = False) -> dict:
    """``{name: {"successes", "falls", "episodes"}}`` of policy ``spec`` playing one episode per seed in each
    condition of ``conditions`` (built for the task's env,
    [`make_env`][hsddp_gym.envs.perturbations.conditions.make_env]; a fresh policy per condition, told the
    condition's env) and, with ``twin``, in the task's MuJoCo twin (key [`TWIN`][TWIN]); ``ValueError`` for a
    condition that does not apply to the task
    ([`check_task_conditions`][hsddp_gym.datasets.collection.check_task_conditions]) or a task without a MuJoCo
    twin."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.datasets.collection import check_task_conditions
    from hsddp_gym.envs.perturbations import make_env
    from hsddp_gym.rollout.policies import make_policy

    names = check_task_conditions(conditions, task.env_id) if len(conditions) else ()
    if twin and task.twin_id is None:
        raise ValueError(f"twin: the task {task.name!r} has no MuJoCo twin")
    builders = [(n, lambda n=n: make_env(n, env_id=task.env_id)) for n in dict.fromkeys(names)]
    if twin:
        builders.append((TWIN, lambda: gym.make(task.twin_id)))
    out = {}
    for name, build in builders:
        env = build()
        try:
            eps = run_task_episodes(task, env, make_policy(spec, env), seeds)
        finally:
            env.close()
        out[name] = {"successes": int(sum(e["success"] for e in eps)), "falls": int(sum(e["fell"] for e in eps)),
                     "episodes": len(eps)}
    return out


def check_learner_runs(error, task: Task, runs_by_flag: dict, env_checked=("bc", "dagger", "sac")) -> None:
    """Call ``error(message)`` for a run of ``runs_by_flag`` (``{flag: (runs, algo)}``) that is no finished
    ``hsddp-gym train`` run of its algorithm in ``task``'s env (the env checked for the algorithms of
    ``env_checked``)."""
    for flag, (runs, algo) in runs_by_flag.items():
        for run in runs:
            f = Path(run) / "summary.json"
            if not f.exists():
                error(f"{flag}: {run} has no summary.json (not a finished hsddp-gym train run)")
            train = json.loads(f.read_text())
            if train.get("algo") != algo or (algo in env_checked and train.get("env_id") != task.env_id):
                error(f"{flag}: {run} is a {train.get('algo')} run in {train.get('env_id')}, not {algo} in "
                      f"{task.env_id}")


def imitation_rows(task: Task, runs, algo: str, seeds, quiet: bool, rounds_word: str = "iteration", conditions=(),
                   twin: bool = False) -> list[dict]:
    """The rows of the ``hsddp-gym train --algo bc|dagger`` runs ``runs`` (final weights), each with what the
    record keeps of its run
    ([`hsddp_gym.learning.reporting.imitation_run_fields`][hsddp_gym.learning.reporting.imitation_run_fields]) and its
    successes in ``conditions`` and the ``twin`` ([`evaluate_task_policy`][evaluate_task_policy]); DAgger's label
    counts its rounds as ``rounds_word``."""
    from hsddp_gym.learning.reporting import imitation_run_fields

    rows = []
    for run in runs:
        fields = imitation_run_fields(run, algo)
        if algo == "bc":
            label = f"BC (training seed {fields['training_seed']})"
        else:
            n = fields["rounds"]
            by = ", MPC labels" if fields.get("labeller") == "mpc" else ""
            if fields.get("keep") == "best":
                by += f", best round ({fields['selected_round']})"
            label = f"DAgger, {n} {rounds_word}{'s' if n != 1 else ''}{by} (training seed {fields['training_seed']})"
        rows.append({**evaluate_task_policy(task, label, task.env_id, f"{algo}:{run}", seeds, quiet, conditions, twin,
                                            episodes=False), **fields})
    return rows


RL_ALGOS = ("sac", "ppo")
"""The reinforcement-learning algorithms a task evaluation takes runs of (``--sac``, ``--ppo``)."""


def rl_rows(task: Task, runs, seeds, quiet: bool, conditions=(), twin: bool = False, algo: str = "sac") -> list[dict]:
    """The rows of the ``hsddp-gym train --algo sac|ppo`` runs ``runs`` (``algo``): each with its final weights and its
    best checkpoint (when it has one), both with the mean action (and their successes in ``conditions`` and the
    ``twin``)."""
    from hsddp_gym.learning.reporting import rl_label
    from hsddp_gym.rollout.policies import PolicySpec

    if algo not in RL_ALGOS:
        raise ValueError(f"algo must be one of {RL_ALGOS}, got {algo!r}")
    rows = []
    for run in runs:
        train = json.loads((Path(run) / "summary.json").read_text())
        for checkpoint in ("final", "best"):
            if checkpoint == "best" and not train.get("best_checkpoint"):
                continue
            name = "final weights" if checkpoint == "final" else "best checkpoint"
            row = evaluate_task_policy(task, f"{rl_label(algo, train)} (training seed {train['seed']}, {name})",
                                       task.env_id, PolicySpec(f"{algo}:{run}", options={"checkpoint": checkpoint}),
                                       seeds, quiet, conditions, twin, episodes=False)
            best = train.get("best_checkpoint") or {}
            row.update(run=str(run), algo=algo, residual=train.get("residual"), training_seed=int(train["seed"]),
                       checkpoint=checkpoint,
                       env_steps=int(train["steps"]) if checkpoint == "final" else int(best["env_step"]),
                       total_env_steps=int(train["steps"]), train_wall_time_s=float(train["wall_time_s"]))
            if checkpoint == "final":  # the run's settings, once per run
                row.update(time_limit_s=train.get("time_limit_s"), preset=train.get("preset"),
                           hyperparameters=train["hyperparameters"])
            rows.append(row)
    return rows


def expert_rows(task: Task, seeds, quiet: bool, mujoco: bool, conditions=()) -> list[dict]:
    """The expert's rows: in the task's env (with its successes in ``conditions``) and, with ``mujoco``, in its
    MuJoCo twin."""
    rows = [evaluate_task_policy(task, "expert", task.env_id, "expert", seeds, quiet, conditions)]
    if mujoco:
        rows.append(evaluate_task_policy(task, "expert", task.twin_id, "expert", seeds, quiet))
    return rows


def task_evaluation_main(argv, description: str, task: str | None = None,
                         record_settings: dict | None = None, rounds_word: str = "iteration",
                         env_checked=("bc", "dagger")) -> int:
    """The command line of a task evaluation: the expert (and, with ``--mujoco``, in the twin), ``--bc`` and
    ``--dagger``, ``--sac`` and ``--ppo`` runs on ``--episodes`` seeds from ``--seed`` (default: the task's
    ``first_seed``), each also in the ``--conditions`` (and the learners, with ``--mujoco``, in the twin), and the
    record ``--record``.

    Args:
        description: the script's help text.
        task: a fixed task (a name of the task registry), else ``--task`` chooses among the plan-tracking tasks.
        record_settings: the settings the record stores after the seeds (default: the task's time limit,
            ``{"max_episode_steps": ...}``).
        rounds_word: how DAgger's rows count its rounds.
        env_checked: the imitation algorithms whose runs must be of the task's env (RL runs always must).
    """
    import argparse

    from hsddp_gym.registry import TASKS

    choices = sorted(n for n, t in TASKS.items() if t.measures is not None and n != "pronking")
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    if task is None:
        p.add_argument("--task", choices=choices, required=True)
    p.add_argument("--seed", type=int, default=None,
                   help="first evaluation seed (default: the task's, 9500 for the pronk, 9600 for the backflip, 9650 "
                        "for the jumps, 9700 for the gait transitions)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per policy (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR) on a dataset "
                                                       "of the task's env, one per training seed")
    p.add_argument("--dagger", nargs="*", default=[], help="DAgger runs (hsddp-gym train --algo dagger --env "
                                                           "TASK_ENV --out DIR), one per training seed")
    for algo in RL_ALGOS:
        p.add_argument(f"--{algo}", nargs="*", default=[],
                       help=f"{algo.upper()} runs (hsddp-gym train --algo {algo} --env TASK_ENV --out DIR, from "
                            "scratch or --residual on the expert), one per training seed; final weights and best "
                            "checkpoint")
    p.add_argument("--mujoco", action="store_true",
                   help="also run the expert (a row of its own) and every learner (its successes) in the task's "
                        "MuJoCo twin")
    p.add_argument("--conditions", nargs="*", default=[], metavar="NAME",
                   help="conditions of the perturbation suite (e.g. push obs_noise; names: experiments/robustness.py "
                        "--help) every policy also plays on the same seeds; the record keeps its successes in each")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/TASK.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the learners' runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    spec = TASKS[task if task is not None else args.task]
    learners = {"--bc": (args.bc, "bc"), "--dagger": (args.dagger, "dagger"),
                **{f"--{algo}": (getattr(args, algo), algo) for algo in RL_ALGOS}}
    check_learner_runs(p.error, spec, learners, tuple(env_checked) + RL_ALGOS)
    first = spec.first_seed if args.seed is None else args.seed
    seeds = list(range(first, first + args.episodes))
    conditions = tuple(args.conditions)
    try:
        condition_counts(spec, "expert", [], conditions)  # checks the names and that each applies, plays nothing
    except ValueError as exc:
        p.error(f"--conditions: {exc}")
    rows = expert_rows(spec, seeds, args.quiet, args.mujoco, conditions)
    bc = imitation_rows(spec, args.bc, "bc", seeds, args.quiet, conditions=conditions, twin=args.mujoco)
    dagger = imitation_rows(spec, args.dagger, "dagger", seeds, args.quiet, rounds_word, conditions, args.mujoco)
    rl_part = {algo: rl_rows(spec, getattr(args, algo), seeds, args.quiet, conditions, args.mujoco, algo)
               for algo in RL_ALGOS if getattr(args, algo)}
    if args.record:
        from hsddp_gym.reports.store import invoked_command, without_option, write_record

        settings = record_settings if record_settings is not None else {"max_episode_steps": spec.max_episode_steps}
        data = {"env_id": spec.env_id, "seeds": seeds, **settings, "rows": rows, "bc": bc, "dagger": dagger,
                **rl_part, "success_rule": spec.success_rule}
        write_record(args.record, data, spec.description,
                     command=list(args.made_with) + [invoked_command(without_option(argv, "--made-with"))])
        print(f"wrote {args.record}")
    return 0
