"""Running many seeded episodes, in this process or in spawn-started workers, with per-episode checkpoints."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.datasets.recording import ENV_ID, Episode, check_env_id, record_episode
from hsddp_gym.util.io import read_npz
from hsddp_gym.util.parallel import check_backend, run_parallel


@dataclasses.dataclass(frozen=True)
class EpisodeTask:
    """Everything a worker needs for one episode (picklable)."""

    index: int
    seed: int
    policy_factory: Callable
    env_kwargs: dict
    max_episode_steps: int | None
    include_gains: bool = False
    action_noise: float = 0.0
    condition: str | None = None
    """A name of [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS] (None:
    the plain env); the policy then acts on the true state (``record_episode(privileged=True)``)."""
    env_id: str | None = None
    """The registered env (None: [`ENV_ID`][hsddp_gym.datasets.recording.ENV_ID], Bounding-v0)."""


def make_env(env_kwargs: dict | None = None, max_episode_steps: int | None = None, condition: str | None = None,
             env_id: str | None = None):
    """``gym.make(env_id, **env_kwargs)`` (``env_id`` None: ``"hsddp_gym/Bounding-v0"``, else one of
    [`DATASET_ENVS`][hsddp_gym.datasets.recording.DATASET_ENVS]) with an optional time-limit override; with
    ``condition`` (a name of
    [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS]) that condition's
    env (its env arguments and wrappers,
    [`hsddp_gym.envs.perturbations.make_env`][hsddp_gym.envs.perturbations.conditions.make_env]) with ``env_kwargs``
    added (a key both set raises ``ValueError``): in a task's env, the condition built for that task (its push window
    and sizes; a condition that does not apply to the task raises ``ValueError``)."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)

    kw = dict(env_kwargs or {})
    if max_episode_steps is not None:
        kw["max_episode_steps"] = int(max_episode_steps)
    env_id = check_env_id(env_id)
    if condition is not None:
        from hsddp_gym.envs.perturbations import make_env as make_condition_env

        return make_condition_env(condition, env_id=None if env_id == ENV_ID else env_id, **kw)
    return gym.make(env_id, **kw)


def episode_conditions(conditions, episodes: int) -> list:
    """The condition of each of ``episodes`` episodes: episode ``i`` runs in ``conditions[i % len(conditions)]``
    (the named conditions in turn); ``[None] * episodes`` without conditions."""
    if not conditions:
        return [None] * int(episodes)
    return [conditions[i % len(conditions)] for i in range(int(episodes))]


def check_task_conditions(conditions, env_id: str | None, argument: str = "conditions") -> tuple:
    """``conditions`` (names of
    [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS], repeats allowed)
    as a tuple, each one that applies to the task of ``env_id`` (None: Bounding-v0); ``ValueError`` naming
    ``argument`` for an unknown name or one the task refuses
    ([`Condition.refusal`][hsddp_gym.envs.perturbations.conditions.Condition.refusal])."""
    from hsddp_gym.envs.perturbations import check_conditions, get_condition
    from hsddp_gym.registry import TASKS, task_of_env_id

    names = check_conditions(list(conditions) if isinstance(conditions, (list, tuple)) else conditions, argument)
    task = TASKS["bounding"] if env_id in (None, ENV_ID) else task_of_env_id(env_id)
    for name in dict.fromkeys(names):
        reason = get_condition(name).refusal(task)
        if reason is not None:
            raise ValueError(f"{argument}: condition {name!r} does not apply to {task.env_id}: {reason}")
    return names


def check_condition_kwargs(conditions, env_kwargs: dict | None) -> None:
    """``ValueError`` if an env argument of ``env_kwargs`` is also set by one of ``conditions`` (e.g. a target
    speed given twice)."""
    from hsddp_gym.envs.perturbations import get_condition

    for name in dict.fromkeys(conditions or ()):
        both = sorted(set(env_kwargs or {}) & set(get_condition(name).env_kwargs))
        if both:
            raise ValueError(f"condition {name!r} sets {both} itself; do not also give them as env arguments")


def run_episode_task(task: EpisodeTask) -> Episode:
    """Worker entry point (top level, spawn-safe): a fresh env and policy, one recorded episode."""
    env = make_env(task.env_kwargs, task.max_episode_steps, task.condition, task.env_id)
    try:
        policy = task.policy_factory(env, task.seed)
        return record_episode(env, policy, task.seed, index=task.index, include_gains=task.include_gains,
                              action_noise=task.action_noise, privileged=task.condition is not None)
    finally:
        env.close()


def checkpoint_path(directory, index: int, prefix: str = "episode") -> Path:
    """``directory/<prefix>-<index:06d>.npz``: the checkpoint of one finished episode."""
    return Path(directory) / f"{prefix}-{int(index):06d}.npz"


def save_episode(path, episode: Episode) -> Path:
    """Write one [`Episode`][Episode] to ``.npz`` atomically (uncompressed, no pickle)."""
    from hsddp_gym.util.io import atomic_path

    arrays = {"index": np.array(episode.index), "seed": np.array(episode.seed),
              "wall_time": np.array(episode.wall_time), "observations": episode.observations,
              "actions": episode.actions, "rewards": episode.rewards, "terminations": episode.terminations,
              "truncations": episode.truncations, **{f"infos/{k}": v for k, v in episode.infos.items()}}
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return Path(path)


def load_episode(path) -> Episode:
    """Read an [`Episode`][Episode] written by [`save_episode`][save_episode] (never unpickles)."""
    d = read_npz(path)
    return Episode(index=int(d["index"]), seed=int(d["seed"]), observations=d["observations"],
                   actions=d["actions"], rewards=d["rewards"], terminations=d["terminations"],
                   truncations=d["truncations"],
                   infos={k[len("infos/"):]: v for k, v in d.items() if k.startswith("infos/")},
                   wall_time=float(d["wall_time"]))


def collect_episodes(policy_factory: Callable, episodes: int, seed: int = 0, workers: int = 1,
                     env_kwargs: dict | None = None, max_episode_steps: int | None = None,
                     include_gains: bool = False, progress: bool = True, desc: str = "episodes",
                     action_noise: float = 0.0, checkpoint_dir=None, checkpoint_prefix: str = "episode",
                     backend: str = "local", address: str | None = None, conditions=None,
                     env_id: str | None = None) -> list[Episode]:
    """Record ``episodes`` episodes (episode ``i`` seeded ``seed + i``) with ``workers`` workers.

    Args:
        policy_factory: picklable ``(env, episode_seed) -> policy`` (e.g. a
            [`PolicySpec`][hsddp_gym.rollout.policies.PolicySpec]; the policy's ``reset_options`` attribute, when it has
            one, gives the episode's reset options); called once per episode, in the worker.
        workers: with ``backend="local"``, 1 runs in this process and more use ``spawn``-started worker
            processes (one BLAS/OpenMP thread each); with ``"ray"``, the CPUs of the local Ray instance.
        backend: where the episodes run
            ([`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel]): ``"local"`` or ``"ray"``.
            An episode whose worker dies is run again; the data do not depend on the backend or the number of
            workers.
        address: with ``"ray"``, the cluster to connect to (None: a local Ray instance).
        action_noise: DART noise on the executed actions (see [`record_episode`][record_episode]).
        checkpoint_dir: if given, every finished episode is saved there ([`checkpoint_path`][checkpoint_path], written
            atomically as it arrives) and episodes already saved there are loaded instead of being run again
            (the caller makes sure they were recorded with the same settings;
            [`generate_dataset`][hsddp_gym.datasets.generation.generate_dataset] does).
        checkpoint_prefix: file-name prefix of the checkpoints.
        conditions: names of
            [`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS] (None: the
            plain env): episode ``i``
            runs in ``conditions[i % len(conditions)]`` ([`episode_conditions`][episode_conditions]), every random draw
            of its perturbation seeded by its episode seed; the policy acts on the true state, the recorded
            observations are the perturbed ones (``record_episode(privileged=True)``).
        env_id: the registered env (None: Bounding-v0; one of
            [`DATASET_ENVS`][hsddp_gym.datasets.recording.DATASET_ENVS]).
    Returns:
        The episodes in index order (identical for any ``workers``, and whether loaded or recorded).
    """
    episodes, workers = int(episodes), int(workers)
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    check_backend(backend, address)
    if conditions is not None:
        from hsddp_gym.envs.perturbations import check_conditions

        conditions = check_conditions(conditions, "conditions")
        check_condition_kwargs(conditions, env_kwargs)
    from tqdm import tqdm

    tasks = [EpisodeTask(i, int(seed) + i, policy_factory, dict(env_kwargs or {}), max_episode_steps, include_gains,
                         float(action_noise), cond, env_id)
             for i, cond in enumerate(episode_conditions(conditions, episodes))]
    results: list[Episode | None] = [None] * episodes
    if checkpoint_dir is not None:
        Path(checkpoint_dir).mkdir(parents=True, exist_ok=True)
        for t in tasks:
            path = checkpoint_path(checkpoint_dir, t.index, checkpoint_prefix)
            if path.exists():
                ep = load_episode(path)
                if ep.seed != t.seed or ep.index != t.index:
                    raise ValueError(f"checkpoint {path} holds episode {ep.index} (seed {ep.seed}), expected "
                                     f"episode {t.index} (seed {t.seed})")
                results[t.index] = ep
    todo = [t for t in tasks if results[t.index] is None]
    steps = sum(ep.length for ep in results if ep is not None)
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc=desc, unit="ep", disable=not progress)

    def done(_, ep: Episode) -> None:
        nonlocal steps
        if checkpoint_dir is not None:
            save_episode(checkpoint_path(checkpoint_dir, ep.index, checkpoint_prefix), ep)
        results[ep.index] = ep
        steps += ep.length
        bar.update(1)
        bar.set_postfix(steps=steps)

    try:
        run_parallel(run_episode_task, todo, workers=min(workers, max(len(todo), 1)), backend=backend,
                     address=address, on_result=done)
    finally:
        bar.close()
    return results  # type: ignore[return-value]
