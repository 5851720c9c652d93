"""The robustness benchmark (``experiments/robustness.py``): the named perturbations of
[`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS] x any policy, one
episode per (policy, condition, seed), run in parallel
([`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel]), summed per cell, tabled and plotted;
in Bounding-v0 or in any task's env (``env_id``), where an episode also records the task's success (its measures'
rule, [`hsddp_gym.rollout.measures.TaskEpisodes`][hsddp_gym.rollout.measures.TaskEpisodes]: ``info["success"]`` at the
last step).

A policy is a spec dict, as the benchmark's records store it: ``{"kind": ..., "mpc_options": {...}, "dir": ...,
"estimator": bool, "checkpoint": ...}`` (``"dirs": [...]`` for a bc/dagger ensemble), built by
[`benchmark_policy`][benchmark_policy] through the policy factory
([`hsddp_gym.rollout.policies.make_policy`][hsddp_gym.rollout.policies.make_policy]). """

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.util.io import atomic_path, write_json
from hsddp_gym.util.parallel import run_parallel
from hsddp_gym.viz.plotting import plot_robustness

BUILTIN = ("mpc", "mpc-options", "heuristic", "random", "expert")
"""The built-in kinds: ``mpc`` (the default ``MPCOptions()``; in Terrain-v0 given each episode's terrain),
``mpc-options`` (``MPCOptions`` from the spec's ``mpc_options``, ablations), ``heuristic``, ``random``, ``expert`` (the
task's plan-tracking expert, starting from its ``reset_options``)."""
LEARNED = {"bc": "policy.npz", "dagger": "policy.npz", "ppo": "model.zip", "sac": "model.zip"}
"""The learned kinds and the file of a run each needs."""
EVAL_FIRST_SEED = 7000
"""The first of the evaluation seeds (7000-7019 by default; development used 500-899)."""


def policy_spec(spec: dict, env_id: str | None = None):
    """The [`PolicySpec`][hsddp_gym.rollout.policies.PolicySpec] of a benchmark spec dict (its kind and options) in the
    task of ``env_id`` (None: Bounding-v0; [`task_policy_spec`][hsddp_gym.rollout.policies.task_policy_spec])."""
    from hsddp_gym.rollout.policies import PolicySpec, task_policy_spec

    kind = spec["kind"]
    if kind in ("mpc", "mpc-options"):
        return task_policy_spec("mpc", env_id, options=spec.get("mpc_options"))
    if kind in ("heuristic", "random", "expert"):
        return task_policy_spec(kind, env_id)
    if kind in ("bc", "dagger"):
        return PolicySpec(f"{kind}:{','.join(spec.get('dirs') or [spec['dir']])}")
    if kind in ("ppo", "sac"):
        return PolicySpec(f"{kind}:{spec['dir']}", options={"checkpoint": spec.get("checkpoint", "final")})
    raise ValueError(f"policy kind must be one of {BUILTIN + tuple(LEARNED)}, got {kind!r}")


def benchmark_policy(spec: dict, env, env_id: str | None = None):
    """The policy described by ``spec`` (see the module docstring) for ``env`` (of the task of ``env_id``, None:
    Bounding-v0), built for the env's interface (the random policy seeded 0); with ``estimator`` the policy, built for
    the env without its delay, acts behind
    [`EstimatedStatePolicy`][hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy] (the MPC's state filter
    and latency compensation)."""
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy
    from hsddp_gym.rollout.policies import make_policy

    kind = spec["kind"]
    interface = EnvInterface.from_env(env)
    recipe = policy_spec(spec, env_id)
    if kind == "expert":  # built from the env itself (its plan reads the env's control period and speed)
        if spec.get("estimator"):
            raise ValueError("estimator: the plan-tracking expert is built for its env; it runs without one")
        return make_policy(recipe, env)
    if kind in ("bc", "dagger"):  # a network or a mean-action ensemble, behind the estimator if trained behind it
        policy = make_policy(recipe, env, interface=interface)
        if not spec.get("estimator") or isinstance(policy, EstimatedStatePolicy):
            return policy
        return EstimatedStatePolicy.around(policy.with_interface, interface)
    if spec.get("estimator"):
        if kind in ("mpc", "mpc-options"):
            raise ValueError("estimator: the MPC has its own state estimator; wrap other policies")
        return EstimatedStatePolicy.around(lambda i: make_policy(recipe, env, interface=i), interface)
    return make_policy(recipe, env, interface=interface)


def run_one(task: tuple) -> dict:
    """One episode: ``task = (label, policy spec, condition name, seed, max_steps or None, simulator[, env_id])``
    (``env_id``: a task's env, None or absent: Bounding-v0). In a task with measures the episode's ``success`` (its
    rule, at the last step) is recorded beside its fall."""
    from hsddp_gym.benchmarks.tasks import task_measures
    from hsddp_gym.envs.perturbations import HardwareCondition, condition_task, episode_perturbation, get_condition
    from hsddp_gym.rollout.episodes import run_episode
    from hsddp_gym.rollout.measures import TaskEpisodes

    label, spec, condition, seed, max_steps, simulator = task[:6]
    env_id = task[6] if len(task) > 6 else None
    cond = get_condition(condition)
    env_task = condition_task(env_id)
    env = cond.make(simulator=cond.simulator_for(simulator), env_id=env_id)
    try:
        policy = benchmark_policy(spec, env, env_id)
        seen = TaskEpisodes(task_measures(env_task)) if env_task.measures is not None else None
        res = run_episode(env, policy, seed, max_steps=max_steps, observers=() if seen is None else (seen,))
        stats = res.policy_stats or {}
        solve_ms = stats.get("solve_ms") or []
        run = {"seed": int(seed), "return": res.episode_return, "fell": bool(res.fell), "length": res.length,
               "fall_time_s": res.simulated_time if res.fell else None, "speed": res.forward_speed,
               "wall_time_s": res.wall_time, "simulated_time_s": res.simulated_time,
               "replans": int(stats.get("replans", 0)), "planner_failures": int(stats.get("planner_failures", 0)),
               "mean_replan_ms": float(np.mean(solve_ms)) if solve_ms else None,
               "target_speed": float(env.unwrapped.target_speed)}
        if seen is not None:
            run["success"] = bool(seen.episode(seed)["success"])
        if isinstance(cond, HardwareCondition):  # the delay, bias or phase-timed push of this episode
            run["perturbation"] = episode_perturbation(env)
        if cond.SIMULATOR is not None:  # a contact condition: the simulator and the model of this episode
            run["simulator"] = cond.SIMULATOR
            run["contact_model"] = env.unwrapped.contact_model.as_dict()
        return run
    finally:
        env.close()


def summarize_cell(runs: list[dict]) -> dict:
    """A cell's statistics from its episodes (``run_one``'s): episodes, falls and their seeds, returns, speeds, the
    real-time factor, the planner's failures and re-plan time; in a task, also the successes and the seeds without
    one."""
    alive = [r for r in runs if not r["fell"]]
    target = runs[0]["target_speed"]
    speed = float(np.mean([r["speed"] for r in alive])) if alive else None
    ms = [r["mean_replan_ms"] for r in runs if r["mean_replan_ms"] is not None]
    success = {"successes": sum(r["success"] for r in runs),
               "failed_seeds": [r["seed"] for r in runs if not r["success"]]} if "success" in runs[0] else {}
    return {"episodes": len(runs), "falls": sum(r["fell"] for r in runs), **success,
            "fall_seeds": [r["seed"] for r in runs if r["fell"]],
            "mean_return": float(np.mean([r["return"] for r in runs])),
            "std_return": float(np.std([r["return"] for r in runs])),
            "mean_speed": speed, "target_speed": target,
            "speed_error": None if speed is None or target == 0.0 else (speed - target) / target,
            "real_time_factor": sum(r["simulated_time_s"] for r in runs) / max(sum(r["wall_time_s"] for r in runs),
                                                                              1e-12),
            "planner_failures": sum(r["planner_failures"] for r in runs),
            "mean_replan_ms": float(np.mean(ms)) if ms else None,
            "mean_fall_time_s": float(np.mean([r["fall_time_s"] for r in runs if r["fell"]]))
            if len(alive) < len(runs) else None}


def run_benchmark(policies: dict, conditions, seeds, max_steps=None, workers: int = 1, progress: bool = True,
                  backend: str = "local", address: str | None = None, simulator: str = "bounding",
                  env_id: str | None = None) -> dict:
    """``{label: {condition: cell summary + "runs"}}`` for ``policies = {label: spec}``; the episodes run on
    [`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel] (``backend`` "local" or "ray",
    ``address`` a Ray cluster) in ``simulator`` (a key of ``hsddp_gym.envs.perturbations.SIMULATORS``) of the task of
    ``env_id`` (None: Bounding-v0)."""
    from tqdm import tqdm

    tasks = [(label, spec, c, s, max_steps, simulator) + (() if env_id is None else (env_id,)) for c in conditions
             for label, spec in policies.items() for s in seeds]
    with tqdm(total=len(tasks), desc="episodes", disable=not progress, smoothing=0.05) as bar:
        runs = run_parallel(run_one, tasks, workers=workers, backend=backend, address=address,
                            on_result=lambda i, r: bar.update(1))
    out: dict = {label: {} for label in policies}
    for task, run in zip(tasks, runs):
        out[task[0]].setdefault(task[2], []).append(run)
    return {label: {c: {**summarize_cell(r), "runs": r} for c, r in cells.items()} for label, cells in out.items()}


def markdown(results: dict, conditions) -> str:
    from hsddp_gym.envs.perturbations import get_condition

    labels = list(results)
    tasks = "successes" in next(iter(results[labels[0]].values()))  # a task's cells: successes first
    lines = [("Successes / episodes, falls / episodes, mean return, mean speed of the episodes that did not fall, "
              "real-time factor" if tasks else
              "Falls / episodes, mean return, mean speed of the episodes that did not fall (error to the target), "
              "real-time factor"), "",
             "| condition | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for c in conditions:
        cells = []
        for label in labels:
            s = results[label][c]
            error = "" if s["speed_error"] is None else f" ({100 * s['speed_error']:+.0f} %)"
            speed = "-" if s["mean_speed"] is None else f"{s['mean_speed']:.2f} m/s{error}"
            success = f"{s['successes']}/{s['episodes']} successes, " if tasks else ""
            cells.append(f"{success}**{s['falls']}/{s['episodes']}**{' falls' if tasks else ''}, "
                         f"{s['mean_return']:.0f}, {speed}, RTF {s['real_time_factor']:.1f}")
        lines.append(f"| {c}: {get_condition(c).description} | " + " | ".join(cells) + " |")
    totals = [f"{sum(results[lb][c]['falls'] for c in conditions)}/"
              f"{sum(results[lb][c]['episodes'] for c in conditions)}" for lb in labels]
    lines.append("| total falls | " + " | ".join(totals) + " |")
    contact = [c for c in conditions if get_condition(c).SIMULATOR is not None]
    if contact:
        lines += ["", "Contact models (MuJoCo twin): falls / episodes, mean time to fall of the episodes that fell [s]",
                  "", "| condition | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
        for c in contact:
            cells = []
            for label in labels:
                s = results[label][c]
                t = s.get("mean_fall_time_s")
                cells.append(f"**{s['falls']}/{s['episodes']}**" + ("" if t is None else f", {t:.2f} s"))
            lines.append(f"| {c} | " + " | ".join(cells) + " |")
        c_totals = [f"{sum(results[lb][c]['falls'] for c in contact)}/"
                    f"{sum(results[lb][c]['episodes'] for c in contact)}" for lb in labels]
        lines.append("| contact falls | " + " | ".join(c_totals) + " |")
    return "\n".join(lines) + "\n"


def combine(paths, out: Path) -> dict:
    """One table from several ``robustness.json`` files (e.g. a baseline, the current default, ablations): every
    policy of every file, labelled ``NAME`` or, when two files hold the same name, ``NAME@DIRNAME``; only the
    conditions common to all. Writes ``OUT/robustness.md``, ``.png`` and ``.json``."""
    loaded = [(Path(p), json.loads(Path(p).read_text())) for p in paths]
    names = [name for _, d in loaded for name in d["results"]]
    results, sources = {}, {}
    for path, d in loaded:
        for name, cells in d["results"].items():
            label = name if names.count(name) == 1 else f"{name}@{path.parent.name}"
            results[label] = cells
            sources[label] = {"file": str(path), "command": d.get("command"), "seeds": d.get("seeds")}
    common = [c for c in loaded[0][1]["conditions"] if all(c in cells for cells in results.values())]
    write_json(out / "robustness.json", {"command": " ".join(["python", *sys.argv]), "sources": sources,
                                         "conditions": loaded[0][1]["conditions"], "results": results})
    table = markdown(results, common)
    with atomic_path(out / "robustness.md") as tmp:
        tmp.write_text(table)
    plot_robustness(results, common, out / "robustness.png")
    print(table)
    return results


def task_record_entry(results: dict, conditions) -> dict:
    """What a task's record keeps of its cells, per policy: the ``successes`` (None in a task without a success rule,
    Terrain-v0) and the ``falls`` per condition (in ``conditions``' order). Lean on purpose (the results store's size
    budget); every episode (seed, success, fall and its time) is in the run's ``robustness.json``."""
    return {label: {"successes": [cells[c].get("successes") for c in conditions],
                    "falls": [cells[c]["falls"] for c in conditions]} for label, cells in results.items()}


def merge_task_record(previous: dict | None, task: str, entry: dict, conditions, seeds) -> dict:
    """The data of the tasks' robustness record with ``task``'s ``entry`` (its settings and its policies'
    [`task_record_entry`][task_record_entry] ``results`` over ``conditions``) put in: ``previous`` (the record's data,
    None: a new record) keeps its other tasks and the task's other policies; its ``conditions`` gain the new ones
    (every per-condition list follows that order, None where a policy did not run a condition). ``ValueError`` when
    ``previous`` was measured on other seeds."""
    data = {"seeds": list(seeds), "conditions": [], "tasks": {}} if previous is None else dict(previous)
    if data["seeds"] != list(seeds):
        raise ValueError(f"the record holds seeds {data['seeds'][0]}-{data['seeds'][-1]} ({len(data['seeds'])}); "
                         f"got {len(seeds)} seeds from {seeds[0]}: use its seeds or another record")
    old = list(data["conditions"])
    order = old + [c for c in conditions if c not in old]

    def aligned(lists: dict, have: list) -> dict:
        return {k: [v[have.index(c)] if c in have else None for c in order] for k, v in lists.items()}

    tasks = {name: {**e, "results": {label: aligned(r, old) for label, r in e["results"].items()}}
             for name, e in data["tasks"].items()}
    results = {**tasks.get(task, {}).get("results", {}),
               **{label: aligned(r, list(conditions)) for label, r in entry["results"].items()}}
    tasks[task] = {**entry, "results": results}
    return {**data, "conditions": order, "tasks": {name: tasks[name] for name in sorted(tasks)}}
