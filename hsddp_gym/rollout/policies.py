"""The policy factory: every policy by name, with one return convention.

[`make_policy`][make_policy] takes a name (``mpc``, ``expert``, ``heuristic``, ``random``, or a trained policy
``bc:DIR``, ``dagger:DIR``, ``sb3:DIR``, ``ppo:DIR``, ``sac:DIR``) or a picklable [`PolicySpec`][PolicySpec] (a name and
its options), and returns a [`Policy`][hsddp_gym.planners.policies.base.Policy]. The reset options a policy's episodes
need (the bounding expert starts at its plan's first state) are its ``reset_options`` attribute, which the episode loop
([`hsddp_gym.rollout.episodes.run_episode`][hsddp_gym.rollout.episodes.run_episode]) reads.

Trained policies are built by the learning layer, above this one: their loaders are ``"module:attr"`` strings
([`LEARNED_LOADERS`][LEARNED_LOADERS]), imported when used, so the import graph keeps pointing one way.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

from hsddp_gym.registry import TASKS, resolve, task_of_env, task_of_env_id

POLICIES = ("mpc", "expert", "heuristic", "random")
"""The built-in policies."""
LEARNED_POLICIES = ("bc", "dagger", "sb3", "ppo", "sac")
"""Prefixes of learned policies, ``KIND:DIR`` with ``DIR`` the ``--out`` of ``hsddp-gym train``: ``bc`` and
``dagger`` load its ``policy.npz`` (an [`MLPPolicy`][hsddp_gym.learning.bc.MLPPolicy], NumPy inference, no torch;
several directories ``DIR1,DIR2,...`` act as their mean-action ensemble), ``sb3`` (or ``ppo`` / ``sac``) its
``model.zip`` + ``vecnormalize.npz`` (needs stable-baselines3)."""
LEARNED_LOADERS = {"bc": "hsddp_gym.learning.ensemble:load_mlp_learner",
                   "dagger": "hsddp_gym.learning.ensemble:load_mlp_learner",
                   "sb3": "hsddp_gym.learning.sb3:load_trained_policy",
                   "ppo": "hsddp_gym.learning.sb3:load_trained_policy",
                   "sac": "hsddp_gym.learning.sb3:load_trained_policy"}
"""The loader of each learned kind (``"module:attr"``): ``load_mlp_learner(run_dirs, interface)`` for the MLP
learners, ``load_trained_policy(run_dir, env, **options)`` for SB3's."""
MOTION_MPC = "hsddp_gym.planners.motions.references:motion_mpc_policy"
"""The factory of the ``mpc`` of a task with a planned motion (``Task.motion``): a
[`MotionMPCPolicy`][hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy]."""
CLASSES = {"mpc": "hsddp_gym.planners.policies.mpc:MPCPolicy",
           "heuristic": "hsddp_gym.planners.policies.heuristic:HeuristicPolicy",
           "random": "hsddp_gym.planners.policies.random_policy:RandomPolicy"}
"""The class of each built-in policy but the expert (whose class is its task's, ``Task.expert``)."""
_POLICY_ALLOWED = ("mpc, expert, heuristic, random, or bc:DIR, dagger:DIR, sb3:DIR (also ppo:DIR, sac:DIR) with "
                   "DIR the --out of `hsddp-gym train`")
_RUN_FILES = {"bc": "policy.npz", "dagger": "policy.npz", "ppo": "model.zip", "sac": "model.zip"}
_KIND_ALGOS = {"bc": ("bc", "dagger"), "dagger": ("bc", "dagger"), "sb3": ("ppo", "sac"), "ppo": ("ppo",),
               "sac": ("sac",)}


def parse_policy_spec(spec: str, name: str = "policy") -> tuple[str, Path | None]:
    """``(kind, run_dir)`` of a policy name: one of [`POLICIES`][POLICIES] (``run_dir`` None) or ``KIND:DIR`` with
    ``KIND`` in [`LEARNED_POLICIES`][LEARNED_POLICIES] and ``DIR`` a finished ``hsddp-gym train`` run of a matching
    algorithm (``sb3`` matches ppo and sac, ``bc`` and ``dagger`` both MLP runs).

    Raises:
        UsageError: a ValueError naming ``name``: an unknown name, a missing or unfinished run directory, or a run
            of another algorithm.
    """
    import json

    from hsddp_gym.util.validation import UsageError, did_you_mean, parenthesized

    if not isinstance(spec, str):
        raise UsageError(name, f"{spec!r} is not a policy name", _POLICY_ALLOWED)
    if spec in POLICIES:
        return spec, None
    kind, sep, path = spec.partition(":")
    if not sep or kind not in LEARNED_POLICIES or not path:
        known = [*POLICIES, *(f"{k}:{path}" for k in LEARNED_POLICIES if path)]
        raise UsageError(name, f"unknown policy {spec!r}" + parenthesized(did_you_mean(spec, known)), _POLICY_ALLOWED)
    run = Path(path)
    summary_file = run / "summary.json"
    if not summary_file.is_file():
        problem = "does not exist" if not run.exists() else "has no summary.json (not a finished training run)"
        raise UsageError(name, f"{kind}:{path}: {str(run)!r} {problem}", _POLICY_ALLOWED)
    try:
        algo = json.loads(summary_file.read_text()).get("algo")
    except (ValueError, AttributeError):
        algo = None
    if algo not in _KIND_ALGOS[kind]:
        raise UsageError(name, f"{kind}:{path}: the run in {str(run)!r} is a {algo!r} run",
                         f"{kind}: runs of {' or '.join(_KIND_ALGOS[kind])}")
    if not (run / _RUN_FILES[algo]).is_file():
        raise UsageError(name, f"{kind}:{path}: {str(run / _RUN_FILES[algo])!r} is missing",
                         f"a finished `hsddp-gym train --algo {algo}` run directory")
    return kind, run


def required_modules(policy: str) -> list[str]:
    """The optional packages a policy name needs (see
    [`hsddp_gym.util.extras.require`][hsddp_gym.util.extras.require])."""
    kind = str(policy).partition(":")[0]
    return ["stable_baselines3", "torch"] if kind in ("sb3", "ppo", "sac") else []


@dataclasses.dataclass(frozen=True)
class PolicySpec:
    """A picklable recipe for a policy: its name and options (the ``policy_factory`` of datasets and DAgger).

    Args:
        name: one of [`POLICIES`][POLICIES], or a learned policy ``KIND:DIR`` ([`LEARNED_POLICIES`][LEARNED_POLICIES];
            ``bc`` and ``dagger`` take several directories ``DIR1,DIR2,...``, their mean-action ensemble).
        options: ``mpc``: an ``MPCOptions`` or a dict of its fields (JSON values, read with
            ``MPCOptions.from_record``); ``sb3`` / ``ppo`` / ``sac``: keyword arguments of ``load_trained_policy``
            (``checkpoint``, ``deterministic``, ...); unused otherwise.
        plan_path: the expert's plan (``.npz`` of
            [`hsddp_gym.planners.optimizer.solution.Solution.save`][hsddp_gym.planners.optimizer.solution.Solution.save];
            None: its task's plan, solved once per process,
            [`hsddp_gym.rollout.plans.task_plan`][hsddp_gym.rollout.plans.task_plan]).
        env_id: the task the policy is for (None: Bounding-v0): the expert is that task's plan tracker
            (``Task.expert``), and the ``mpc`` of a task with ``terrain_aware_mpc`` (``hsddp_gym/Terrain-v0``) is
            given each episode's terrain as privileged information.
    """

    name: str
    options: object = dataclasses.field(default_factory=dict)
    plan_path: str | None = None
    env_id: str | None = None

    def __post_init__(self) -> None:
        kind = self.name.partition(":")[0] if isinstance(self.name, str) else None
        if self.name not in POLICIES and (kind not in LEARNED_POLICIES or ":" not in self.name):
            raise ValueError(f"policy name must be one of {POLICIES} or KIND:DIR with KIND one of "
                             f"{LEARNED_POLICIES}, got {self.name!r}")
        task = self.task
        if self.name == "expert" and task.expert is None:
            raise ValueError(f"in {task.env_id} the expert is {task.dataset_expert!r} (the terrain-aware MPC), not a "
                             "plan tracker")

    @property
    def task(self):
        """The [`Task`][hsddp_gym.registry.Task] of `env_id`."""
        return task_of_env_id(self.env_id or TASKS["bounding"].env_id)

    def __call__(self, env, episode_seed: int):
        """The policy for an episode of ``env`` seeded ``episode_seed`` ([`make_policy`][make_policy])."""
        return make_policy(self, env, seed=int(episode_seed))

    def describe(self) -> dict:
        """JSON description (name and the full options in effect)."""
        task = self.task
        if self.name == "expert":
            return {"name": self.name, "class": task.expert.replace(":", "."), "options": dict(task.expert_record)}
        d = {"name": self.name, "class": CLASSES.get(self.name, self.name).replace(":", ".")}
        if self.name == "mpc":
            d["options"] = dataclasses.asdict(_mpc_options(self.options))
            if task.motion is not None:
                d["class"] = "hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy"
                d["motion"] = task.motion
            if task.terrain_aware_mpc:
                d["terrain"] = ("env_terrain(env): the episode's terrain (privileged information), read at every "
                                "reset")
        elif self.name == "random":
            d["options"] = {"seed": "episode seed"}
        else:
            d["options"] = {}
        return d


def task_policy_spec(name: str, env_id: str | None = None, options: dict | None = None,
                     plan_path: str | None = None) -> PolicySpec:
    """The [`PolicySpec`][PolicySpec] datasets and DAgger record for policy ``name`` (one of [`POLICIES`][POLICIES]) in
    the task of ``env_id`` (None: Bounding-v0): the expert of that task (its plan at ``plan_path``), the ``mpc`` given
    the terrain where the task's is (``Task.terrain_aware_mpc``), the other policies as in any task (``env_id`` None);
    ``options``: the ``mpc``'s."""
    task = task_of_env_id(env_id or TASKS["bounding"].env_id)
    if name == "expert":
        return PolicySpec("expert", plan_path=plan_path, env_id=None if task is TASKS["bounding"] else task.env_id)
    own = name == "mpc" and (task.terrain_aware_mpc or task.motion is not None)
    return PolicySpec(name, options=dict(options or {}), env_id=task.env_id if own else None)


def _mpc_options(options):
    from hsddp_gym.planners.policies.mpc import MPCOptions

    return options if isinstance(options, MPCOptions) else MPCOptions.from_record(dict(options or {}))


@functools.lru_cache(maxsize=4)
def load_plan(path: str):
    """The [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] saved at ``path`` (cached per path)."""
    from hsddp_gym.planners.optimizer.solution import Solution

    return Solution.load(path)


def make_policy(spec, env=None, seed: int = 0, interface=None):
    """The policy ``spec`` for ``env``: a [`Policy`][hsddp_gym.planners.policies.base.Policy] whose
    ``reset_options`` attribute (when present and not None) holds the reset options its episodes need.

    Args:
        spec: a name (one of [`POLICIES`][POLICIES] or ``KIND:DIR``, see [`parse_policy_spec`][parse_policy_spec];
            ``env``'s task
            decides the expert and whether the MPC is given the terrain) or a [`PolicySpec`][PolicySpec] (its ``env_id``
            decides them).
        env: the env the policy acts in (a trained policy's own env when None; needed by every other policy).
            A trained policy's directory with a ``summary.json`` is checked to be a finished run of its kind
            ([`parse_policy_spec`][parse_policy_spec]); one without is loaded from its weights alone.
        seed: the random policy's seed.
        interface: build the policy for this [`EnvInterface`][hsddp_gym.planners.policies.base.EnvInterface] instead of
            ``env``'s (e.g. the env without its action delay, behind the MPC's perception); not for the expert.
    """
    if isinstance(spec, str):
        kind = spec.partition(":")[0]
        task = task_of_env(env) if env is not None and kind not in LEARNED_POLICIES else TASKS["bounding"]
        spec = PolicySpec(spec, env_id=task.env_id)
    if not isinstance(spec, PolicySpec):
        raise TypeError(f"spec must be a policy name or a PolicySpec, got {type(spec).__name__}")
    if spec.name.partition(":")[0] in LEARNED_POLICIES:
        return _learned(spec, env, interface)
    if env is None:
        raise ValueError(f"env is needed to build the {spec.name!r} policy")
    if spec.name == "expert":
        from hsddp_gym.rollout.plans import make_expert

        solution = load_plan(str(spec.plan_path)) if spec.plan_path is not None else None
        return make_expert(env, solution, task=spec.task)
    cls = resolve(CLASSES[spec.name])
    kwargs = {"seed": int(seed)} if spec.name == "random" else {}
    if spec.name == "mpc" and spec.task.motion is not None:  # the task's motion, re-planned online
        from hsddp_gym.planners.policies.base import EnvInterface

        kwargs = {k: v for k, v in spec.task.plan_kwargs.items() if k != "motion"}  # e.g. the cycles before a stop
        interface = interface if interface is not None else EnvInterface.from_env(env)
        if "speed" in spec.task.plan_inputs:  # a motion planned at the env's target speed (the pronk)
            kwargs["speed"] = float(interface.target_speed)
        return resolve(MOTION_MPC)(interface, spec.task.motion, _mpc_options(spec.options), **kwargs)
    if spec.name == "mpc":
        from hsddp_gym.planners.policies.mpc import env_terrain

        kwargs = {"terrain": env_terrain(env) if spec.task.terrain_aware_mpc else None}
        if interface is None:
            return cls.from_env(env, options=_mpc_options(spec.options), **kwargs)
        return cls(interface, _mpc_options(spec.options), **kwargs)
    return cls.from_env(env, **kwargs) if interface is None else cls(interface, **kwargs)


def _learned(spec: PolicySpec, env, interface):
    from hsddp_gym.util.extras import require

    kind, _, paths = spec.name.partition(":")
    runs = [parse_policy_spec(f"{kind}:{p}", "policy")[1] if (Path(p) / "summary.json").exists() else Path(p)
            for p in paths.split(",")]  # a directory with only its weights (no training summary) loads as it is
    require(required_modules(spec.name), f"the policy {spec.name}")
    loader = resolve(LEARNED_LOADERS[kind])
    if kind in ("bc", "dagger"):  # behind the MPC's perception if trained behind it
        if interface is None:
            from hsddp_gym.planners.policies.base import EnvInterface

            interface = EnvInterface.from_env(env) if env is not None else EnvInterface()
        return loader(runs[0] if len(runs) == 1 else runs, interface)
    if len(runs) > 1:
        raise ValueError(f"policy {spec.name!r}: only bc and dagger learners form an ensemble of several directories")
    policy = loader(runs[0], env, **dict(spec.options or {}))
    if interface is not None:  # the model reads observations only; the interface says which env it acts for
        policy.interface = interface
    return policy
