"""The envs the commands run in, read from the task registry: every registered env (the tasks' envs and their
twins), which built-in policies each has, the env ``--simulator`` picks, the env a trained policy was trained in
(its run's ``summary.json``) and how two envs relate (a twin, another task)."""

from __future__ import annotations

import json
from pathlib import Path

from hsddp_gym.registry import ENV_TASKS, TASKS, task_of_env_id
from hsddp_gym.rollout.policies import POLICIES
from hsddp_gym.util.validation import UsageError

DEFAULT_ENV = TASKS["bounding"].env_id
"""The env of a command without ``--env`` (hsddp_gym/Bounding-v0)."""
ENVS = tuple(ENV_TASKS)
"""Every registered env id: each task's env, then its twins (``hsddp-gym rollout --env``'s choices)."""
SIMULATORS = {"lcp": None, "mujoco": "mujoco"}
"""``--simulator`` -> the twin it picks (None: the task's own env, exact-LCP contacts)."""


def built_in_policies(env_id: str) -> tuple[str, ...]:
    """The built-in policies ([`POLICIES`][hsddp_gym.rollout.policies.POLICIES]) that exist in ``env_id``: every one but
    the ``expert`` in a task without a plan-tracking expert (``Task.expert`` None, e.g. Terrain-v0)."""
    task = task_of_env_id(env_id)
    return tuple(p for p in POLICIES if p != "expert" or task.expert is not None)


def _policies_text(env_id: str, trained: bool) -> str:
    task = task_of_env_id(env_id)
    names = [f"{p} (the terrain-aware MPC, the task's expert)" if p == "mpc" and task.terrain_aware_mpc else p
             for p in built_in_policies(env_id)]
    if trained:
        names.append("a trained policy KIND:DIR")
    return ", ".join(names[:-1]) + " or " + names[-1]


def check_policy_exists(policy: str, env_id: str, trained: bool = True) -> None:
    """UsageError naming ``--policy`` when the built-in ``policy`` does not exist in ``env_id`` (the expert of a task
    without one), saying which exist there (``trained``: also the trained policies)."""
    if policy in POLICIES and policy not in built_in_policies(env_id):
        raise UsageError("--policy", f"{policy} in {env_id}: the {task_of_env_id(env_id).name} task has no "
                                     "plan-tracking expert", f"in {env_id}: {_policies_text(env_id, trained)}")


def simulator_env(env_id: str, simulator: str) -> str:
    """The env of ``env_id``'s task that ``--simulator`` names: the task's own env (``lcp``) or its MuJoCo twin
    (``mujoco``); UsageError naming ``--simulator`` when the task has no such twin or ``env_id`` is another twin."""
    task = task_of_env_id(env_id)
    twin = SIMULATORS[simulator]
    if twin is not None and twin not in task.twins:
        raise UsageError("--simulator", f"{simulator} for {env_id}: the {task.name} task has no {twin} twin",
                         "lcp, or an --env with a MuJoCo twin")
    picked = task.env.env_id if twin is None else task.twins[twin].env_id
    if env_id not in (task.env.env_id, picked):
        raise UsageError("--simulator", f"{simulator} for {env_id}, another simulator's env",
                         f"no --simulator, or --env {task.env.env_id}")
    return picked


def trained_env_id(run_dir) -> str:
    """The env a ``hsddp-gym train`` run was trained in: its ``summary.json``'s ``env_id`` (runs from before the
    field: hsddp_gym/Bounding-v0)."""
    summary = json.loads((Path(run_dir) / "summary.json").read_text())
    return summary.get("env_id") or DEFAULT_ENV


def relation(env_id: str, other: str) -> str:
    """How ``other`` relates to ``env_id``, in words: ``its MuJoCo twin``, ``its KKT twin``, ``the env of its
    task`` (from a twin) or ``the env of another task (NAME)``."""
    task, other_task = task_of_env_id(env_id), task_of_env_id(other)
    if other_task is not task:
        return f"the env of another task ({other_task.name})"
    for kind, entry in task.twins.items():
        if entry.env_id == other:
            return f"its {'MuJoCo' if kind == 'mujoco' else kind.upper()} twin"
    return "the env of its task"


def needs_mujoco(env_id: str) -> bool:
    """Whether ``env_id`` is a MuJoCo twin (it needs the extra ``mujoco``)."""
    task = task_of_env_id(env_id)
    return "mujoco" in task.twins and task.twins["mujoco"].env_id == env_id


def env_list_text() -> str:
    """The registered envs for help texts: the tasks' envs, then their twins."""
    twins = [e.env_id for task in TASKS.values() for e in task.twins.values()]
    return f"the tasks' envs {', '.join(t.env_id for t in TASKS.values())} and their twins {', '.join(twins)}"


def check_env_settings(env_id: str, env_kwargs: dict, push, max_episode_steps) -> None:
    """Build the env once with ``--target-speed`` and ``--max-episode-steps``: UsageError naming
    ``--target-speed`` when the env refuses it, or ``--push`` for a push outside the episode or not finite."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)

    limit = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
    try:
        env = gym.make(env_id, **env_kwargs, **limit)
    except (TypeError, ValueError) as exc:
        if not env_kwargs:
            raise
        speed = env_kwargs["target_speed"]
        if isinstance(exc, TypeError):  # the task fixes its target speed
            raise UsageError("--target-speed", f"{speed} with --env {env_id}, which takes no target speed",
                             f"no --target-speed with --env {env_id}") from None
        raise UsageError("--target-speed", f"{speed} with --env {env_id}: {exc}",
                         f"a target speed {env_id} takes") from None
    duration = env.spec.max_episode_steps * float(env.unwrapped.dt)
    env.close()
    if push is None:
        return
    t = push[0]
    if not 0.0 <= t < duration:
        raise UsageError("--push", f"T = {t} s", f"a push time 0 <= T < {duration:g} s, the episode length")
    for label, v in zip(("DVX", "DVZ", "DPITCH"), push[1:]):
        if not abs(v) < 1e300:
            raise UsageError("--push", f"{label} = {v}", "finite velocity changes [m/s, m/s, rad/s]")
