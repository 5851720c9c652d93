"""generate_dataset: seeded, parallel, resumable generation of a demonstration dataset."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.datasets.collection import checkpoint_path, collect_episodes, make_env
from hsddp_gym.datasets.recording import ENV_ID, NONDETERMINISTIC_INFOS, check_env_id, solve_expert_plan
from hsddp_gym.datasets.storage import (
    check_dataset_id,
    check_target,
    default_dataset_id,
    package_version,
    parent_dir,
    write_dataset,
)
from hsddp_gym.rollout.policies import PolicySpec, task_policy_spec
from hsddp_gym.util.io import json_default, write_json
from hsddp_gym.util.parallel import check_backend
from hsddp_gym.util.validation import check_positive

REF_MIN_EPISODES = 5
"""Episodes of the random policy (seeds ``seed .. seed + 4``) averaged into ``ref_min_score``."""
REF_MAX_EPISODES = 5
"""With DART noise, clean (noise-free) episodes of the policy (seeds ``seed .. seed + 4``, at most
``episodes``) averaged into ``ref_max_score``; without noise it is the mean return of the dataset's episodes."""
CHECKPOINT_FORMAT = 1
"""Version of the checkpoint layout of an interrupted run (``.<name>.partial``, see
[`generate_dataset`][generate_dataset])."""


def mean_random_return(env_kwargs: dict | None = None, max_episode_steps: int | None = None, seed: int = 0,
                       episodes: int = REF_MIN_EPISODES, env_id: str | None = None) -> tuple[float, list[float]]:
    """Mean return of [`RandomPolicy`][hsddp_gym.planners.policies.random_policy.RandomPolicy] over ``episodes``
    episodes seeded ``seed, seed + 1, ...`` (the ``ref_min_score``) and the returns."""
    eps = collect_episodes(PolicySpec("random"), episodes, seed, 1, env_kwargs, max_episode_steps, progress=False,
                           env_id=env_id)
    returns = [e.episode_return for e in eps]
    return float(np.mean(returns)), returns


@dataclasses.dataclass
class DatasetResult:
    """What [`generate_dataset`][generate_dataset] wrote (``resumed_episodes``: episodes loaded from the checkpoints of
    an interrupted run instead of being recorded again)."""

    path: Path
    dataset_id: str
    episodes: int
    total_steps: int
    generation_time_s: float
    metadata: dict
    resumed_episodes: int = 0
    total_time_s: float = 0.0
    """Wall time of the whole call: the episodes, the reference-score episodes, the expert's plan, writing."""


# ================================================================================================ resume
def partial_dir(out) -> Path:
    """``<parent>/.<name>.partial``: where a run writing dataset ``out`` keeps its checkpoints."""
    out = Path(out)
    return out.resolve().parent / f".{out.name}.partial"


def _code_fingerprint() -> str:
    """SHA-256 of the source of the packages that produce the data (``hsddp_gym`` and the folders installed into it,
    ``hsddp_gym.planners`` and ``hsddp_gym.envs``): checkpoints recorded by other code are never resumed."""
    import hashlib
    import importlib.util

    h = hashlib.sha256()
    for pkg in ("hsddp_gym", "hsddp_gym.planners", "hsddp_gym.envs"):
        spec = importlib.util.find_spec(pkg)
        if spec is None or not spec.submodule_search_locations:
            continue
        root = Path(list(spec.submodule_search_locations)[0])
        for f in sorted(root.rglob("*.py")):
            h.update(f"{pkg}/{f.relative_to(root).as_posix()}\0".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _factory_id(factory) -> str:
    """A stable name of a policy factory (module-qualified class or function, plus dataclass fields)."""
    if dataclasses.is_dataclass(factory) and not isinstance(factory, type):
        fields = {f.name: getattr(factory, f.name) for f in dataclasses.fields(factory) if f.name != "plan_path"}
        return f"{type(factory).__module__}.{type(factory).__qualname__}{json.dumps(fields, default=str)}"
    target = factory if callable(factory) and hasattr(factory, "__qualname__") else type(factory)
    return f"{getattr(target, '__module__', '?')}.{getattr(target, '__qualname__', repr(target))}"


@contextlib.contextmanager
def _exclusive(partial: Path):
    """Create ``partial`` and hold an exclusive lock on ``partial/lock`` (released when the process ends,
    even when killed); refuse if another live run holds it. Then stale temporary siblings of the dataset
    (``.<name>.tmp-*`` / ``.old-*`` / ``.plan-*`` of a killed run) are removed."""
    partial.mkdir(parents=True, exist_ok=True)
    fh = open(partial / "lock", "a+")
    try:
        try:
            import fcntl
        except ImportError:  # pragma: no cover (not POSIX: no lock)
            fcntl = None
        if fcntl is not None:
            try:
                fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise FileExistsError(f"another run is generating this dataset (it holds {partial / 'lock'}); "
                                      "wait for it to finish") from None
        import re

        name = partial.name[1:-len(".partial")]
        pattern = re.compile(rf"\.{re.escape(name)}\.(tmp|old|plan)-[A-Za-z0-9_]{{8}}")
        for stale in partial.parent.iterdir():
            if stale.is_dir() and pattern.fullmatch(stale.name):
                shutil.rmtree(stale, ignore_errors=True)
        yield partial
    finally:
        fh.close()


def _has_checkpoints(partial: Path) -> bool:
    """Whether ``partial`` holds finished work (episodes, reference episodes, the expert's plan); hidden files
    are the temporaries of an interrupted atomic write."""
    return any(p.suffix == ".npz" and not p.name.startswith(".") for p in partial.iterdir())


def _prepare_checkpoints(partial: Path, settings: dict, resume: bool, overwrite: bool) -> int:
    """Check the checkpoints in ``partial`` against ``settings``; returns the number of episode checkpoints kept.

    Same settings (and code): resumed (``resume=True``). Otherwise they are discarded with ``resume=False``
    or ``overwrite=True`` and refused (`FileExistsError` naming the differences) without.
    """
    settings_file = partial / "settings.json"
    found = sorted(partial.glob("episode-*.npz"))
    current = json.loads(json.dumps(settings, default=json_default))
    stored = None
    if not _has_checkpoints(partial):
        stored = current  # nothing recorded yet (a fresh directory, or a run killed before its first episode)
    elif settings_file.exists():
        with contextlib.suppress(ValueError):
            stored = json.loads(settings_file.read_text())
    if stored == current and resume:
        write_json(settings_file, current)
        return len(found)
    if stored != current and not (overwrite or not resume):
        diff = sorted(k for k in set(stored or {}) | set(current) if (stored or {}).get(k) != current.get(k))
        what = [f"{k} (the source of hsddp_gym/planners/envs changed since)" if k == "code_sha256" else k
                for k in diff]
        raise FileExistsError(
            f"an interrupted run left {len(found)} episode checkpoint(s) in {partial} recorded with other "
            f"settings (differing: {', '.join(what) or 'unreadable settings'}); rerun with the same settings to "
            "resume it, or pass resume=False / overwrite=True (CLI: --no-resume / --overwrite) to discard them")
    for f in partial.iterdir():
        if f.name != "lock":
            shutil.rmtree(f) if f.is_dir() else f.unlink()
    write_json(settings_file, current)
    return 0


def generate_dataset(policy: str | PolicySpec | Callable, episodes: int, out, seed: int = 0, workers: int = 1,
                     dataset_id: str | None = None, overwrite: bool = False, env_kwargs: dict | None = None,
                     max_episode_steps: int | None = None, policy_options: dict | None = None,
                     include_gains: bool = False, progress: bool = True, policy_name: str | None = None,
                     policy_description: dict | None = None, action_noise: float = 0.0,
                     resume: bool = True, backend: str = "local", address: str | None = None,
                     conditions=None, env_id: str | None = None) -> DatasetResult:
    """Generate a demonstration dataset into ``out`` (see the module docstring).

    **Interrupted runs and reruns.** Every finished episode is checkpointed (atomically) into the hidden
    sibling directory ``.<name>.partial`` ([`partial_dir`][partial_dir], with the run's settings and, for ``expert``,
    its plan) and the dataset itself is written into a temporary directory renamed onto ``out`` only when
    complete, so an interrupted run (an exception, Ctrl-C, a kill) never leaves a half-written ``out``. A
    rerun with the same settings (policy and options, seed, env kwargs, time limit, gains, noise, dataset
    id, and the same source code; ``episodes`` and ``workers`` may differ) **resumes**: checkpointed
    episodes are loaded, the others recorded, the data identical to an uninterrupted run. A rerun with other
    settings **refuses** (`FileExistsError` naming the differing settings) unless ``resume=False`` or
    ``overwrite=True`` discards the checkpoints. An existing ``out`` is never replaced without
    ``overwrite=True``. The checkpoints are deleted once the dataset is published; one run at a time may
    write a given ``out`` (a lock in the checkpoint directory, released when the process dies).

    Args:
        policy: a name of `POLICIES`, a [`PolicySpec`][PolicySpec], or a picklable factory
            ``(env, episode_seed) -> (policy, reset_options)`` (then give ``policy_name``).
        episodes: number of episodes; episode ``i`` is seeded ``seed + i``.
        workers: worker processes, or the CPUs of a local Ray instance (the data do not depend on it).
        backend: ``"local"`` (this process or local worker processes) or ``"ray"`` (a local Ray instance,
            or the running cluster at ``address``); see
            [`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel]. The data do not depend on
            it; an episode whose worker dies is run again.
        address: Ray cluster address (``"auto"``, ``"ray://host:10001"``); None starts a local instance.
        dataset_id: Minari id (default ``hsddp_gym/<task>/<policy>-v0``, task ``bounding``, ``pronking``,
            ``backflip``, ``gap_jump``, ``box_jump``, ``terrain``, ``stand_to_bound``, ``bound_pronk_bound`` or
            ``bound_to_stop``).
        env_id: the env the episodes are recorded in, one of [`DATASET_ENVS`][hsddp_gym.datasets.recording.DATASET_ENVS]
            (None: ``hsddp_gym/Bounding-v0``); in ``hsddp_gym/Pronking-v0`` the ``expert`` tracks a pronk plan
            ([`pronking_expert`][hsddp_gym.planners.policies.experts.pronking_expert]), in ``hsddp_gym/Backflip-v0`` a
            backflip plan ([`backflip_expert`][hsddp_gym.planners.policies.experts.backflip_expert]); in
            ``hsddp_gym/Terrain-v0`` ``mpc`` is the terrain-aware MPC, given each episode's terrain (``MPCPolicy(...,
            terrain=env_terrain(env))``), and there is no ``expert``.
        overwrite: replace an existing ``out`` (and discard checkpoints recorded with other settings).
        env_kwargs: ``gym.make`` keyword arguments; max_episode_steps: time-limit override (default 1000).
        policy_options: ``MPCOptions`` fields for ``mpc``.
        include_gains: also store the plan's feedback gains (``expert_feedback_gain (4, 14)`` per step).
        action_noise: DART noise injection ([`record_episode`][hsddp_gym.datasets.recording.record_episode]): the
            executed actions (``actions``) are
            the policy's plus Gaussian noise of this standard deviation (normalized units), the policy's clean
            actions are in ``infos["expert_action"]`` (what
            [`hsddp_gym.learning.demonstrations.load_demonstrations`][hsddp_gym.learning.demonstrations.load_demonstrations]
            uses as labels). Recorded in the metadata; ``ref_max_score`` then comes from
            [`REF_MAX_EPISODES`][REF_MAX_EPISODES] clean episodes of the policy (the expert's score, not the noisy
            one's).
        resume: resume from the checkpoints of an interrupted run with the same settings (False: discard
            any checkpoints and start over).
        conditions: demonstrations under perturbations: names of
            [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS] (repeats
            allowed, as weights); episode ``i`` runs in ``conditions[i % len(conditions)]``, its perturbation seeded by
            its episode seed. The policy acts on the true state (under observation noise it sees the clean observation),
            the dataset's ``observations`` are the perturbed ones the learner will see
            (``record_episode(privileged=True)``). The metadata record ``conditions`` (names, definitions) and, per
            episode, ``episode_conditions`` and ``episode_target_speeds``. The reference episodes cycle through the same
            conditions (the random policy's run in the plain env). None: the plain env.
    Raises:
        FileExistsError: ``out`` exists and ``overwrite`` is False; checkpoints with other settings exist
            and neither ``resume=False`` nor ``overwrite``; another run is writing ``out``.
    """
    from hsddp_gym.util.extras import require

    require(["minari", "h5py"], "generate_dataset (writing a Minari dataset)")  # before any episode is recorded
    action_noise = check_positive(action_noise, "action_noise", allow_zero=True)
    if int(episodes) < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    check_backend(backend, address)
    out = Path(out)
    check_target(out, overwrite)
    env_kwargs = dict(env_kwargs or {})
    env_id = check_env_id(env_id)
    if conditions is not None:
        from hsddp_gym.datasets.collection import check_condition_kwargs, check_task_conditions

        conditions = list(check_task_conditions(conditions, env_id, "conditions"))
        check_condition_kwargs(conditions, env_kwargs)
    partial = partial_dir(out)
    plan_file = partial / "expert_plan.npz"
    if isinstance(policy, str):
        spec = task_policy_spec(policy, env_id, policy_options, plan_path=str(plan_file))
    else:
        spec = policy
    name = policy_name or (spec.name if isinstance(spec, PolicySpec) else type(spec).__name__)
    describe = policy_description or (spec.describe() if isinstance(spec, PolicySpec) else {"name": name})
    dataset_id = check_dataset_id(dataset_id or default_dataset_id(name, env_id), "dataset_id")
    settings = {"checkpoint_format": CHECKPOINT_FORMAT, "dataset_id": dataset_id, "policy": describe,
                "policy_factory": _factory_id(spec), "seed": int(seed), "env_kwargs": env_kwargs,
                "max_episode_steps": max_episode_steps, "include_gains": bool(include_gains),
                "action_noise": action_noise, "code_sha256": _code_fingerprint()}
    if conditions is not None:
        settings["conditions"] = conditions
    if env_id != ENV_ID:  # absent for Bounding-v0: the settings of runs recorded before env_id existed
        settings["env_id"] = env_id
    parent_dir(out)
    t_start = time.perf_counter()
    with _exclusive(partial):
        check_target(out, overwrite)  # again, under the lock
        _prepare_checkpoints(partial, settings, resume, overwrite)
        resumed = sum(checkpoint_path(partial, i).exists() for i in range(int(episodes)))
        if resumed and progress:
            print(f"resuming an interrupted run: {resumed} episode(s) checkpointed in {partial}", flush=True)
        try:
            eps, metadata, extra, gen_time = _generate(spec, name, describe, episodes, seed, workers, env_kwargs,
                                                       max_episode_steps, include_gains, progress, action_noise,
                                                       dataset_id, partial, plan_file, resumed,
                                                       {"backend": backend, "address": address,
                                                        "conditions": conditions, "env_id": env_id})
            env = make_env(env_kwargs, max_episode_steps, env_id=env_id)
            try:
                write_dataset(eps, out, dataset_id, env, metadata, ref_min_score=metadata["ref_min_score"],
                              ref_max_score=metadata["ref_max_score"], overwrite=overwrite, extra_files=extra,
                              description=f"{name} demonstrations on {env_id} ({len(eps)} episodes, seeds "
                                          f"{seed}..{seed + len(eps) - 1}); see the 'hsddp_gym' metadata entry")
            finally:
                env.close()
        except BaseException:
            if not _has_checkpoints(partial):  # nothing worth resuming
                shutil.rmtree(partial, ignore_errors=True)
            raise
        shutil.rmtree(partial, ignore_errors=True)
    return DatasetResult(out, dataset_id, len(eps), metadata["total_steps"], gen_time, metadata, resumed,
                         total_time_s=time.perf_counter() - t_start)


def _generate(spec, name, describe, episodes, seed, workers, env_kwargs, max_episode_steps, include_gains,
              progress, action_noise, dataset_id, partial, plan_file, resumed, where):
    """The episodes (checkpointed into ``partial``) and the metadata of [`generate_dataset`][generate_dataset]."""
    t0 = time.perf_counter()
    extra, plan_summary = {}, None
    if isinstance(spec, PolicySpec) and spec.name == "expert" and Path(spec.plan_path) == plan_file:
        summary_file = partial / "expert_plan.json"
        if plan_file.exists() and summary_file.exists():  # resumed: the plan the checkpoints were recorded with
            plan_summary = json.loads(summary_file.read_text())
        else:
            control_dt = float(env_kwargs.get("frame_skip", 5)) * float(env_kwargs.get("sim_timestep", 1e-3))
            plan_summary = solve_expert_plan(plan_file, where["env_id"],
                                             float(env_kwargs.get("target_speed", 1.0)),
                                             hold=max(1, int(control_dt / 1e-3 + 0.5)))
            write_json(summary_file, plan_summary)
        extra["expert_plan.npz"] = plan_file
    plan_time = time.perf_counter() - t0
    t1 = time.perf_counter()
    eps = collect_episodes(spec, episodes, seed, workers, env_kwargs, max_episode_steps, include_gains,
                           progress, desc=f"{name} episodes", action_noise=action_noise, checkpoint_dir=partial,
                           backend=where["backend"], address=where["address"], conditions=where["conditions"],
                           env_id=where["env_id"])
    gen_time = time.perf_counter() - t1
    t2 = time.perf_counter()
    where = dict(where)
    conditions = where.pop("conditions", None)
    env_id = where.pop("env_id", ENV_ID)
    ref_min, random_returns = mean_random_return(env_kwargs, max_episode_steps, seed, env_id=env_id)
    returns = [e.episode_return for e in eps]
    if action_noise > 0:
        n_ref = min(int(episodes), REF_MAX_EPISODES)
        ref_eps = collect_episodes(spec, n_ref, seed, workers, env_kwargs, max_episode_steps, progress=progress,
                                   desc=f"{name} reference episodes (no noise)", checkpoint_dir=partial,
                                   checkpoint_prefix="reference", conditions=conditions, env_id=env_id, **where)
        ref_returns = [e.episode_return for e in ref_eps]
        ref_source = (f"mean return of the {name} policy without action noise over {n_ref} episodes, seeds "
                      f"{seed}..{seed + n_ref - 1} (not in the dataset)")
    else:
        ref_returns = returns
        ref_source = f"mean return of the {name} episodes of this dataset"
    ref_max = float(np.mean(ref_returns))
    reference_time = time.perf_counter() - t2
    env = make_env(env_kwargs, max_episode_steps, env_id=env_id)
    spec_json, limit, control_dt = env.spec.to_json(), env.spec.max_episode_steps, float(env.unwrapped.dt)
    env.close()
    if plan_summary is not None:
        describe = {**describe, "plan_summary": plan_summary}
    metadata = {
        "dataset_id": dataset_id,
        "env_id": env_id,
        "env_spec": json.loads(spec_json),
        "env_kwargs": env_kwargs,
        "max_episode_steps": int(limit) if limit else None,
        "control_dt": control_dt,
        "policy": describe,
        "seed": int(seed),
        "action_noise": action_noise,
        "action_noise_note": "DART: actions = clip(policy action + action_noise * N(0, I), -1, 1) were executed; "
                             "the policy's clean actions (labels) are infos/expert_action" if action_noise > 0
                             else "none: actions are the policy's",
        "episode_seeds": [e.seed for e in eps],
        "episodes": len(eps),
        "total_steps": int(sum(e.length for e in eps)),
        "falls": int(sum(bool(e.terminations[-1]) for e in eps)),
        "episode_returns": returns,
        "mean_return": float(np.mean(returns)),
        "ref_max_score": ref_max,
        "ref_max_score_source": ref_source,
        "ref_max_returns": ref_returns,
        "ref_min_score": ref_min,
        "ref_min_score_source": f"mean return of RandomPolicy over {REF_MIN_EPISODES} episodes, seeds "
                                f"{seed}..{seed + REF_MIN_EPISODES - 1}",
        "random_returns": random_returns,
        **_condition_metadata(conditions, len(eps), env_kwargs),
        "infos_schema": {k: [list(v.shape[1:]), str(v.dtype)] for k, v in eps[0].infos.items()},
        "infos_alignment": "row t = observation t (reset info first) and the decision taken at it; the last "
                           "row repeats the last decision with replanned = planner_failed = False",
        "determinism": "the same seed, settings and code give identical data for any number of workers and "
                       f"across resumed runs, except the wall-clock times in infos/{', '.join(NONDETERMINISTIC_INFOS)}",
        "workers": int(workers),
        "backend": where["backend"],
        "resumed_episodes": int(resumed),
        "generation_time_s": gen_time,
        "generation_time_note": "wall time of the episodes recorded by this run (worker start-up included, the "
                                "expert's offline plan excluded: plan_time_s; resumed_episodes were loaded from "
                                "an interrupted run's checkpoints)",
        "plan_time_s": plan_time if plan_summary is not None else 0.0,
        "reference_time_s": reference_time,
        "reference_time_note": "wall time of the reference-score episodes (random policy, and the noise-free "
                               "policy with action_noise > 0), not in generation_time_s",
        "hsddp_gym_version": package_version(),
    }
    return eps, metadata, extra, gen_time


def _condition_metadata(conditions, episodes: int, env_kwargs: dict) -> dict:
    """The metadata entries of demonstrations under perturbations (``conditions``; none without)."""
    if conditions is None:
        return {}
    from hsddp_gym.datasets.collection import episode_conditions
    from hsddp_gym.envs.bounding import DEFAULT_TARGET_SPEED
    from hsddp_gym.envs.perturbations import get_condition

    names = episode_conditions(conditions, episodes)
    speeds = [float({**env_kwargs, **get_condition(c).env_kwargs}.get("target_speed", DEFAULT_TARGET_SPEED))
              for c in names]
    return {"conditions": {"names": list(conditions),
                           "definitions": {c: get_condition(c).as_dict() for c in dict.fromkeys(conditions)},
                           "rule": "episode i runs in names[i % len(names)], its perturbation seeded by its seed",
                           "expert_observation": "the policy acted on the true state (the observation without "
                                                 "observation noise); observations are the perturbed ones"},
            "episode_conditions": names, "episode_target_speeds": speeds}
