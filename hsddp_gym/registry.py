"""The task registry: one [`Task`][Task] entry per task defines everything the package knows of it.

An entry holds the task's env and its twins (ids, entry points, keyword arguments, time limit, vector entry point),
the start state, the HS-DDP plan the expert tracks (a function, its fixed arguments and the ones read from the env),
the plan-tracking expert (its class and how its episodes start), the dataset expert, the success rule (words; the
env computes ``info["success"]``), the per-episode measures of its evaluation, the evaluation seeds and the
description. Everything else reads it: ``import hsddp_gym`` registers every env ([`register_envs`][register_envs]), the
policy factory ([`hsddp_gym.rollout.policies.make_policy`][hsddp_gym.rollout.policies.make_policy]) builds the expert,
datasets and DAgger find the expert and its plan, the task evaluations
([`hsddp_gym.benchmarks.tasks`][hsddp_gym.benchmarks.tasks]) their measures and seeds.

Light on purpose: this module imports only [`hsddp_gym.core.task_constants`][hsddp_gym.core.task_constants] (pure
Python); entry points, plans, experts and measures are ``"module:attr"`` strings, imported when used
([`resolve`][resolve]), as Gymnasium's entry points.

**Pushes.** A task's pushes (the conditions ``push`` and ``push_x3``, and the earliest time of ``push_flight`` and
``push_stance``, [`hsddp_gym.envs.perturbations.conditions`][hsddp_gym.envs.perturbations.conditions]) come in its
``push_window`` and are as large as its ``push_size``. The steady gaits of 5 s keep the bound's window, ``t ~ U(1, 4)``
s: past the start, with a second left to recover (bounding, terrain, and the pronk, whose cycle repeats all episode).
The planned motions are over within about a second, so their windows span the motion itself, read from their plans'
phase durations ([`PUSH_WINDOWS`][PUSH_WINDOWS]): a push later than the motion tests only the hold after it, an earlier
one only the start. The bound's pushes keep their size (bounding and terrain, where the MPC re-plans); the motions'
experts track one plan and get half the bound's speed changes and 3/5 of its pitch rate
([`hsddp_gym.core.task_constants.MOTION_PUSH_SIZE`][hsddp_gym.core.task_constants.MOTION_PUSH_SIZE]).

Adding a task: one [`Task`][Task] in [`TASKS`][TASKS] (see ``docs/architecture.md``, "Adding a task").
"""

from __future__ import annotations

import dataclasses
import importlib
import math

from hsddp_gym.core import task_constants as tc

_HOLD = "control period / 1 ms (5 by default)"
_NO_RESET = "none (the env starts at the plan's start, with reset noise)"
_HELD_LAW = "the plan's held-input feedback law, touchdowns counted for feet seen 2 cm clear; after the plan "


@dataclasses.dataclass(frozen=True)
class EnvEntry:
    """One registered env: ``gym.register(id=env_id, entry_point=..., kwargs=..., max_episode_steps=...,
    vector_entry_point=...)``."""

    env_id: str
    entry_point: str
    max_episode_steps: int
    kwargs: dict = dataclasses.field(default_factory=dict)
    vector_entry_point: str | None = None


@dataclasses.dataclass(frozen=True)
class Task:
    """Everything the package knows of one task (one place; new concerns become new fields).

    Attributes:
        name: the task's key in [`TASKS`][TASKS] (``--task`` of ``experiments/tasks.py``).
        env: the task's env.
        twins: the same task in other simulators, ``{"mujoco": EnvEntry, "kkt": EnvEntry}`` (those it has).
        description: one sentence (the records' description of the task's evaluation).
        start: how an episode starts (words).
        plan: ``"module:attr"`` of the HS-DDP plan the expert tracks: a function returning a
            [`PlanResult`][hsddp_gym.planners.tasks.PlanResult] or a
            [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] (None: the task has no plan).
        plan_kwargs: the plan function's fixed keyword arguments.
        plan_inputs: the plan function's keyword arguments read from the env: ``"hold"`` (plan knots of 1 ms per
            control period) and ``"speed"`` (the env's target speed); one plan is solved per task and values of these
            per process ([`hsddp_gym.rollout.plans.task_plan`][hsddp_gym.rollout.plans.task_plan]).
        expert: ``"module:attr"`` of the plan-tracking expert's factory
            ([`hsddp_gym.planners.policies.experts`][hsddp_gym.planners.policies.experts]), built as
            ``factory(EnvInterface.from_env(env), plan, **expert_kwargs)``.
        expert_kwargs: the expert's further keyword arguments.
        expert_starts_at_plan: the expert's episodes start at its plan's first state (reset options
            ``{"state": plan.X[0]}``, no reset noise); else the env starts there itself.
        expert_record: what a dataset's metadata says of the expert's options (``PolicySpec.describe``).
        dataset_expert: the policy a dataset of the task is recorded with by default (``"mpc"`` or ``"expert"``).
        terrain_aware_mpc: the task's ``mpc`` is given each episode's terrain (``env_terrain(env)``).
        motion: the planned motion the task's ``mpc`` re-plans online (a key of
            [`MOTION_PROBLEMS`][hsddp_gym.planners.motions.references.MOTION_PROBLEMS]; its ``mpc`` is then a
            [`MotionMPCPolicy`][hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy]), or None: the bounding MPC.
        success_rule: the success rule in words (the env computes ``info["success"]``), or None.
        measures: ``"module:attr"`` of the per-episode measures of the task's evaluation
            ([`hsddp_gym.rollout.measures.Measures`][hsddp_gym.rollout.measures.Measures]), or None.
        first_seed: the first evaluation seed (seeds no dataset uses), or None.
        episode_start: the posture episodes start in, for help texts (``"standing"``, ``"bounding"``).
        push_window: ``(low, high)`` [s] of episode time in which the task's pushes come (see the module docstring).
        push_size: ``(3,)`` the largest trunk-velocity change of the task's push, ``[dvx, dvz, dpitch_rate]`` [m/s,
            m/s, rad/s]; the perturbation conditions scale their own push sizes (given for Bounding-v0) by it.
        speed_range: ``(low, high)`` [m/s] of the target speeds the task's env may be set to (the target-speed
            conditions), or None: the task fixes its own speed.
    """

    name: str
    env: EnvEntry
    twins: dict = dataclasses.field(default_factory=dict)
    description: str = ""
    start: str = ""
    plan: str | None = None
    plan_kwargs: dict = dataclasses.field(default_factory=dict)
    plan_inputs: tuple = ()
    expert: str | None = None
    expert_kwargs: dict = dataclasses.field(default_factory=dict)
    expert_starts_at_plan: bool = False
    expert_record: dict = dataclasses.field(default_factory=dict)
    dataset_expert: str = "expert"
    terrain_aware_mpc: bool = False
    motion: str | None = None
    success_rule: str | None = None
    measures: str | None = None
    first_seed: int | None = None
    episode_start: str = "bounding"
    push_window: tuple = tc.BOUND_PUSH_WINDOW
    push_size: tuple = tc.BOUND_PUSH_SIZE
    speed_range: tuple | None = None

    @property
    def env_id(self) -> str:
        """The task's env id."""
        return self.env.env_id

    @property
    def twin_id(self) -> str | None:
        """The MuJoCo twin's env id (None without one)."""
        twin = self.twins.get("mujoco")
        return twin.env_id if twin is not None else None

    @property
    def max_episode_steps(self) -> int:
        """The registered time limit of the task's env [control steps]."""
        return self.env.max_episode_steps

    def entries(self) -> tuple:
        """The task's env and its twins ([`EnvEntry`][EnvEntry])."""
        return (self.env, *self.twins.values())


# ------------------------------------------------------------------------------------------------ the entries
def _twin(env_id: str, entry_point: str, steps: int, kwargs: dict | None = None) -> dict:
    return {"mujoco": EnvEntry(env_id.replace("-v0", "MuJoCo-v0"), entry_point, steps, dict(kwargs or {}))}


_TASK_VECTOR = "hsddp_gym.envs.task_vector:"
"""The module of the task envs' vector entry points (the physics of N robots in one compiled call)."""
_BOUNDING = EnvEntry("hsddp_gym/Bounding-v0", "hsddp_gym.envs.bounding:BoundingEnv", tc.BOUNDING_MAX_EPISODE_STEPS,
                     vector_entry_point="hsddp_gym.envs.vector:BoundingVectorEnv")
_BOUNDING_PLAN = {"method": "al-reb", "cycles": 5}

_JUMP_RULE = ("no fall (the trunk centre never below 0.12 m over the ground under it, a gap bridged at its rims' "
              "level; no foot 2 cm into the gap), and for the last 50 steps (0.25 s) the trunk 0.3 m past the far "
              "edge with both feet past it, |pitch| <= 0.6 rad, the trunk centre at least 0.15 m above the ground "
              "(hsddp_gym.envs.jumps.JumpTask.success)")
_BOUNDING_RULE = ("bounding over the last 60 steps (0.3 s): back stance alone and front stance alone at least 4 steps "
                  "each, both feet down at most 20 % of them, mean forward speed within 0.3 m/s of 1 m/s")
_TRANSITION_RULES = {
    "stand_to_bound": f"no fall, past the plan (0.84 s), and {_BOUNDING_RULE}",
    "bound_pronk_bound": (f"no fall, past the plan (1.59 s), at least 2 double stances of 30 ms or more (the pronk), "
                          f"and {_BOUNDING_RULE}"),
    "bound_to_stop": ("no fall, past the plan (0.99 s), both feet down over the last 60 steps (0.3 s) and at the end "
                      "trunk speed <= 0.1 m/s, |pitch rate| <= 0.5 rad/s, |pitch| <= 0.3 rad, trunk centre >= 0.15 m"),
}
_TRANSITION_CYCLES = {"stand_to_bound": 3, "bound_pronk_bound": 2, "bound_to_stop": 2}
"""Per gait transition, the plan's cycles per gait segment (``plan_transition_held(task, hold, cycles=...)``): stand
to bound plans a third cycle at 1 m/s so that the looped cycle (phases 5-8) is not the plan's last (its schedule and
speed profile are those of the two-cycle plan with its last cycle repeated, what the env rewards)."""
"""Cycles of bounding around each transition in its expert's plan."""
_TRANSITION_AFTER = {"stand_to_bound": "its bounding cycle (phases 5-8), looped",
                     "bound_pronk_bound": "its bounding cycle (phases 13-16), looped",
                     "bound_to_stop": "its last control plus a joint PD to its last knot's joint angles"}
"""What the transition expert plays after its plan (``hsddp_gym.planners.policies.experts.TRANSITION_LOOPS``)."""


PUSH_WINDOWS = {
    "backflip": (0.1, 1.05),
    "gap_jump": (0.3, 1.07), "box_jump": (0.3, 1.07),
    "stand_to_bound": (0.1, 0.55),
    "bound_pronk_bound": (0.45, 1.15),
    "bound_to_stop": (0.3, 0.8),
}
"""The push windows of the planned motions [s], from their plans' phases (bound cycles of 0.296 s):

* backflip: the push (double stance, 0-0.25 s) from 0.1 s, the take-off (0.25-0.35 s), the flight (0.35-0.75 s) and
  the landing (0.75-1.05 s);
* the jumps: the second approach cycle (0.296-0.592 s), the take-off back stance (to 0.672 s), the 0.25 s jump flight
  and the landing cycle (to 1.066 s);
* stand to bound: the end of the accelerating double stance (0-0.25 s), the switch into the bound and its first cycle
  (to 0.546 s);
* bound, pronk, bound: the end of the bound (to 0.592 s), the two pronk cycles, the double stance that returns to the
  bound (0.952-1.002 s) and its first flight;
* bound to stop: the cycle that slows to 0.4 m/s (0.296-0.592 s), the landing on both feet and the first half of the
  stopping double stance (to 0.992 s)."""


def _jump(name: str, env_id: str, what: str) -> Task:
    steps = tc.JUMP_MAX_EPISODE_STEPS
    return Task(
        name=name, env=EnvEntry(env_id, "hsddp_gym.envs.jumps:JumpEnv", steps, {"task": name},
                     _TASK_VECTOR + "JumpVectorEnv"),
        twins=_twin(env_id, "hsddp_gym.envs.jumps:MuJoCoJumpEnv", steps, {"task": name}),
        description=(f"The jump {what}: the HS-DDP jump expert ({env_id.split('/')[-1]} and its MuJoCo twin) and BC "
                     "from its demonstrations on unseen seeds."),
        start=f"bounding at 1 m/s, {tc.JUMP_APPROACH_CYCLES} cycles before the obstacle (the plan's start)",
        plan="hsddp_gym.planners.motions:plan_jump_held", plan_kwargs={"motion": name}, plan_inputs=("hold",),
        expert="hsddp_gym.planners.policies.experts:jump_expert",
        expert_record={"plan": {"motion": name, "speed": 1.0, "cycles": 2, "hold": _HOLD},
                       "plan_file": "expert_plan.npz",
                       "tracking": _HELD_LAW + "its first cycle after the jump, looped", "reset_options": _NO_RESET},
        success_rule=_JUMP_RULE, measures="hsddp_gym.rollout.measures:JUMP", first_seed=9650,
        push_window=PUSH_WINDOWS[name], push_size=tc.MOTION_PUSH_SIZE, motion=name)


def _transition(name: str, env_id: str, what: str, start: str) -> Task:
    steps = tc.TRANSITION_MAX_EPISODE_STEPS[name]
    cycles = _TRANSITION_CYCLES[name]
    return Task(
        name=name, env=EnvEntry(env_id, "hsddp_gym.envs.transitions:TransitionEnv", steps, {"task": name},
                     _TASK_VECTOR + "TransitionVectorEnv"),
        twins=_twin(env_id, "hsddp_gym.envs.transitions:MuJoCoTransitionEnv", steps, {"task": name}),
        description=(f"The gait transition {what}: the HS-DDP transition expert ({env_id.split('/')[-1]} and its "
                     "MuJoCo twin) and BC from its demonstrations on unseen seeds."),
        start=f"{start} (the plan's start)",
        plan="hsddp_gym.planners.motions:plan_transition_held", plan_kwargs={"motion": name, "cycles": cycles},
        plan_inputs=("hold",), expert="hsddp_gym.planners.policies.experts:transition_expert",
        expert_kwargs={"task": name},
        expert_record={"plan": {"motion": name, "speed": 1.0, "cycles": cycles, "hold": _HOLD},
                       "plan_file": "expert_plan.npz",
                       "tracking": ("the plan's held-input feedback law, touchdowns counted for feet seen clear (2 cm, "
                                    "or half the plan's lowest landing-foot peak if lower); after the plan "
                                    + _TRANSITION_AFTER[name]),
                       "reset_options": _NO_RESET},
        success_rule=f"{_TRANSITION_RULES[name]} (hsddp_gym.envs.transitions.TransitionTask.success)",
        measures="hsddp_gym.rollout.measures:GAIT", first_seed=9700, episode_start=start,
        push_window=PUSH_WINDOWS[name], push_size=tc.MOTION_PUSH_SIZE, motion=name)


TASKS: dict[str, Task] = {
    "bounding": Task(
        name="bounding", env=_BOUNDING,
        twins={"mujoco": EnvEntry("hsddp_gym/BoundingMuJoCo-v0", "hsddp_gym.envs.mujoco_twin:MuJoCoBoundingEnv",
                                  tc.BOUNDING_MAX_EPISODE_STEPS),
               "kkt": EnvEntry("hsddp_gym/BoundingKKT-v0", "hsddp_gym.envs.kkt_twin:KKTBoundingEnv",
                               tc.BOUNDING_MAX_EPISODE_STEPS)},
        description="Bounding at the target speed (1 m/s by default) on flat ground.",
        start="the paper's initial state with reset noise (the expert: its plan's first state, no noise)",
        plan="hsddp_gym.planners.tasks:plan_bounding", plan_kwargs=_BOUNDING_PLAN,
        expert="hsddp_gym.planners.policies.experts:bounding_expert", expert_starts_at_plan=True,
        expert_record={"plan": dict(_BOUNDING_PLAN), "plan_file": "expert_plan.npz",
                       "reset_options": "{'state': plan.X[0]} (no reset noise)",
                       "fallback_after_plan": "hsddp_gym.planners.policies.mpc.MPCPolicy (default options)"},
        dataset_expert="mpc", first_seed=0, speed_range=(0.0, math.inf)),
    "pronking": Task(
        name="pronking",
        env=EnvEntry("hsddp_gym/Pronking-v0", "hsddp_gym.envs.pronking:PronkingEnv", tc.PRONKING_MAX_EPISODE_STEPS,
                     vector_entry_point=_TASK_VECTOR + "PronkingVectorEnv"),
        twins=_twin("hsddp_gym/Pronking-v0", "hsddp_gym.envs.pronking:MuJoCoPronkingEnv",
                    tc.PRONKING_MAX_EPISODE_STEPS),
        description=("The pronking task: the HS-DDP pronk expert (Pronking-v0 and its MuJoCo twin), BC from its "
                     "demonstrations, DAgger labelled by it and SAC on unseen seeds."),
        start="the pronk plan's start at the target speed (mid double stance), with reset noise",
        plan="hsddp_gym.planners.motions:plan_pronk", plan_kwargs={"cycles": 4}, plan_inputs=("speed",),
        expert="hsddp_gym.planners.policies.experts:pronking_expert",
        expert_record={"plan": {"motion": "pronk", "cycles": 4}, "plan_file": "expert_plan.npz",
                       "tracking": "periodic: after the plan's last touchdown the cursor returns to phase 2",
                       "reset_options": _NO_RESET},
        success_rule=("no fall, mean forward speed within 20 % of the target, >= 80 % of control steps with matching "
                      "contact flags (hsddp_gym.envs.pronking.pronking_success)"),
        measures="hsddp_gym.rollout.measures:PRONK", first_seed=9500, push_size=tc.MOTION_PUSH_SIZE,
        speed_range=tc.SPEED_RANGE, motion="pronk"),
    "backflip": Task(
        name="backflip",
        env=EnvEntry("hsddp_gym/Backflip-v0", "hsddp_gym.envs.backflip:BackflipEnv", tc.BACKFLIP_MAX_EPISODE_STEPS,
                     vector_entry_point=_TASK_VECTOR + "BackflipVectorEnv"),
        twins=_twin("hsddp_gym/Backflip-v0", "hsddp_gym.envs.backflip:MuJoCoBackflipEnv",
                    tc.BACKFLIP_MAX_EPISODE_STEPS),
        description=("The backflip task: the HS-DDP backflip expert (Backflip-v0 and its MuJoCo twin) and BC (and "
                     "DAgger) from its demonstrations on unseen seeds."),
        start="standing at rest (the plan's start), with reset noise",
        plan="hsddp_gym.planners.motions:plan_backflip_held", plan_inputs=("hold",),
        expert="hsddp_gym.planners.policies.experts:backflip_expert",
        expert_record={"plan": {"motion": "backflip", "hold": _HOLD}, "plan_file": "expert_plan.npz",
                       "tracking": _HELD_LAW + "a joint PD on its last posture", "reset_options": _NO_RESET},
        success_rule=("no fall (the trunk never touched the ground), a full turn, and at the end upright (pitch within "
                      "0.3 rad of -2 pi, trunk at least 0.15 m high) on both feet and still (trunk speed <= 0.3 m/s, "
                      "pitch rate <= 1 rad/s) (hsddp_gym.envs.backflip.backflip_success)"),
        measures="hsddp_gym.rollout.measures:FLIP", first_seed=9600, episode_start="standing", motion="backflip",
        push_window=PUSH_WINDOWS["backflip"], push_size=tc.MOTION_PUSH_SIZE),
    "gap_jump": _jump("gap_jump", "hsddp_gym/GapJump-v0", "over a 0.3 m gap"),
    "box_jump": _jump("box_jump", "hsddp_gym/BoxJump-v0", "onto a 0.1 m box"),
    "terrain": Task(
        name="terrain",
        env=EnvEntry("hsddp_gym/Terrain-v0", "hsddp_gym.envs.bounding:BoundingEnv", tc.BOUNDING_MAX_EPISODE_STEPS,
                     {"terrain": "random_mixed"}, _TASK_VECTOR + "TaskVectorEnv"),
        description="Bounding on a seeded random terrain of steps and slopes per episode.",
        start="the paper's initial state with reset noise, on the episode's terrain",
        dataset_expert="mpc", terrain_aware_mpc=True, speed_range=(0.0, math.inf)),
    "stand_to_bound": _transition("stand_to_bound", "hsddp_gym/StandToBound-v0",
                                  "from standing into a bound at 1 m/s", "standing"),
    "bound_pronk_bound": _transition("bound_pronk_bound", "hsddp_gym/BoundPronkBound-v0",
                                     "from a bound into a pronk and back", "bounding"),
    "bound_to_stop": _transition("bound_to_stop", "hsddp_gym/BoundToStop-v0", "from a bound to rest standing",
                                 "bounding"),
}
"""The tasks, by name (the order of ``hsddp-gym dataset --env``'s choices)."""

ENV_TASKS: dict[str, Task] = {e.env_id: task for task in TASKS.values() for e in task.entries()}
"""Every registered env id (tasks and twins) -> its task."""
DATASET_ENVS = tuple(task.env_id for task in TASKS.values())
"""The envs datasets are recorded in (``hsddp-gym dataset --env``): every task's env."""
MPC_ENVS = tuple(task.env_id for task in TASKS.values() if task.dataset_expert == "mpc")
"""The envs whose dataset expert is the MPC (the others' is their task's plan tracker, ``expert``)."""


def register_envs() -> None:
    """``gym.register`` every env of [`TASKS`][TASKS] not registered yet (imports gymnasium, not the envs)."""
    import gymnasium as gym

    for task in TASKS.values():
        for e in task.entries():
            if e.env_id not in gym.registry:
                gym.register(id=e.env_id, entry_point=e.entry_point, kwargs=dict(e.kwargs) or None,
                             max_episode_steps=e.max_episode_steps, vector_entry_point=e.vector_entry_point)


def resolve(ref: str):
    """The object a ``"module:attr"`` string names (the module imported now)."""
    if not isinstance(ref, str) or ref.count(":") != 1:
        raise ValueError(f"ref must be a 'module:attr' string, got {ref!r}")
    module, attr = ref.split(":")
    return getattr(importlib.import_module(module), attr)


def get_task(name: str) -> Task:
    """The task ``name`` (a key of [`TASKS`][TASKS]), else ``ValueError`` naming it."""
    if name not in TASKS:
        raise ValueError(f"task must be one of {tuple(TASKS)}, got {name!r}")
    return TASKS[name]


def task_of_env_id(env_id: str) -> Task:
    """The task of a registered env id (a task's env or one of its twins), else ``ValueError`` naming it."""
    if env_id not in ENV_TASKS:
        raise ValueError(f"env_id must be one of {tuple(ENV_TASKS)}, got {env_id!r}")
    return ENV_TASKS[env_id]


def task_of_env(env) -> Task:
    """The task of ``env`` (wrapped or not): by its registered id (``env.spec.id``), else by its class and keyword
    arguments among the entry points (an env built without ``gym.make``); ``ValueError`` for an env of no task."""
    spec = getattr(env, "spec", None)
    env_id = getattr(spec, "id", None)
    if env_id in ENV_TASKS:
        return ENV_TASKS[env_id]
    u = getattr(env, "unwrapped", env)
    cls = f"{type(u).__module__}:{type(u).__name__}"
    matches = [(len(e.kwargs), task) for task in TASKS.values() for e in task.entries()
               if e.entry_point == cls and all(getattr(u, k, None) == v for k, v in e.kwargs.items())]
    if not matches:
        raise ValueError(f"env must be an env of a registered task ({tuple(ENV_TASKS)}), got {type(u).__name__} "
                         f"(spec id {env_id!r})")
    return max(matches, key=lambda m: m[0])[1]
