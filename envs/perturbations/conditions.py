"""The named test conditions of the robustness benchmark: a [`Condition`][Condition] is env arguments plus the wrappers
of [`hsddp_gym.envs.perturbations.wrappers`][hsddp_gym.envs.perturbations.wrappers], and [`CONDITIONS`][CONDITIONS]
names them all:

* model mismatch through env arguments: ``friction`` (Coulomb coefficient) and ``trunk_mass_scale`` (the
  simulated trunk is heavier or lighter than the model every policy uses); reset noise and target speeds;
* observation noise, latency and random pushes; [`SUITE`][SUITE] is the benchmark's set;
* contact models the policies were not built on ([`ContactCondition`][ContactCondition], always in the MuJoCo twin): a
corner
  of [`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`][hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS] (``contact_<corner>``),
  or [`RandomContactModel`][hsddp_gym.envs.perturbations.wrappers.RandomContactModel], a
  [`ContactModel`][hsddp_gym.envs.mujoco_twin.ContactModel] drawn per episode from the episode seed
  (``contact_family``). They are extra conditions, not in [`SUITE`][SUITE];
* conditions a real robot has ([`HardwareCondition`][HardwareCondition], [`HARDWARE_CONDITIONS`][HARDWARE_CONDITIONS]):
a latency other than the announced one, a sensor bias, a push in flight or in stance. Extra conditions too.

**Every task.** A condition is built for Bounding-v0 by default and for any task of the registry with
``make(env_id=...)`` ([`hsddp_gym.registry.TASKS`][hsddp_gym.registry.TASKS]): the same env arguments and wrappers on
the task's env, or on its twin of the condition's simulator (the contact conditions: the MuJoCo twin). The pushes'
descriptions give Bounding-v0's window and sizes; in a task the pushes come in its ``push_window`` and their sizes are
scaled per component by its ``push_size`` over the bound's ([`task_push`][task_push]). A condition that cannot apply
to a task is refused ([`Condition.refusal`][Condition.refusal]): a target speed where the task fixes its own speed (the
backflip, the jumps, the transitions) or outside its range (the pronk: 0.5-1.5 m/s), a simulator the task has no twin in
(Terrain-v0 has no MuJoCo twin, only Bounding-v0 a KKT twin). [`TASK_SUITE`][TASK_SUITE] is the set a task's
robustness table runs.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import gymnasium as gym

from hsddp_gym.core.task_constants import BOUND_PUSH_SIZE
from hsddp_gym.envs.perturbations.wrappers import (
    ActionDelay,
    ObservationBias,
    ObservationNoise,
    PhasePush,
    RandomContactModel,
    RandomPush,
)
from hsddp_gym.registry import TASKS, Task, get_task, task_of_env_id

ENV_ID = "hsddp_gym/Bounding-v0"
SIMULATORS = {"bounding": "hsddp_gym/Bounding-v0", "mujoco": "hsddp_gym/BoundingMuJoCo-v0",
              "kkt": "hsddp_gym/BoundingKKT-v0"}
"""The simulators a condition runs in (``Condition.make(simulator=...)``): the exact-LCP env (default), its MuJoCo
twin (soft contacts; the optional extra ``mujoco``) and the planner's own hybrid model (pinned feet). In another task
(``make(env_id=...)``): the task's env and its twins of the same keys ([`simulator_env_id`][simulator_env_id])."""


def condition_task(env_id: str | None = None) -> Task:
    """The task whose env ``env_id`` is (a task's own env id, not a twin's; None: Bounding-v0's task), else
    ``ValueError`` naming the task envs."""
    if env_id is None:
        return TASKS["bounding"]
    allowed = [t.env_id for t in TASKS.values()]
    if not isinstance(env_id, str) or env_id not in allowed:
        raise ValueError(f"env_id must be a task's env id, one of {allowed} (its twins through simulator=), got "
                         f"{env_id!r}")
    return task_of_env_id(env_id)


def simulator_env_id(task: Task, simulator: str) -> str | None:
    """The env id of ``task`` in ``simulator`` (a key of [`SIMULATORS`][SIMULATORS]): the task's env for
    ``"bounding"``, its twin of that key otherwise; None when the task has no such twin."""
    if simulator not in SIMULATORS:
        raise ValueError(f"simulator must be one of {sorted(SIMULATORS)}, got {simulator!r}")
    if simulator == "bounding":
        return task.env_id
    twin = task.twins.get(simulator)
    return None if twin is None else twin.env_id


def task_push(push: dict, task: Task, default_size=BOUND_PUSH_SIZE) -> dict:
    """The keyword arguments of a push wrapper ([`RandomPush`][RandomPush], [`PhasePush`][PhasePush]) for ``task``:
    ``push`` (a condition's, its ``max_delta_v`` given for Bounding-v0, ``default_size`` when it has none) with the
    task's ``push_window`` as ``time_range`` (unless ``push`` sets one) and ``max_delta_v`` scaled per component by
    ``task.push_size / BOUND_PUSH_SIZE`` (Bounding-v0's and Terrain-v0's sizes: unscaled)."""
    size = tuple(push.get("max_delta_v", default_size))
    if tuple(task.push_size) != BOUND_PUSH_SIZE:
        size = tuple(round(v * t / b, 9) for v, t, b in zip(size, task.push_size, BOUND_PUSH_SIZE))
    return {"time_range": tuple(task.push_window), **push, "max_delta_v": size}


def _as_task(task) -> Task:
    return task if isinstance(task, Task) else get_task(task)


@dataclasses.dataclass(frozen=True)
class Condition:
    """A named test condition: env arguments plus wrappers.

    Attributes:
        name: the registry key. description: one line for tables.
        env_kwargs: arguments of ``gym.make("hsddp_gym/Bounding-v0", ...)`` (reset noise, friction, trunk mass,
            target speed).
        observation_noise: ``(position_std, velocity_std)`` of [`ObservationNoise`][ObservationNoise], or None.
        action_delay: control steps of [`ActionDelay`][ActionDelay] (0: none).
        push: the keyword arguments of [`RandomPush`][RandomPush] (``{}``: its defaults), or None (no push).
    """

    name: str
    description: str
    env_kwargs: dict = dataclasses.field(default_factory=dict)
    observation_noise: tuple | None = None
    action_delay: int = 0
    push: dict | None = None

    SIMULATOR: ClassVar[str | None] = None
    """The simulator the condition always runs in (None: any, the one asked for)."""

    def simulator_for(self, requested: str = "bounding") -> str:
        """The simulator the condition runs in when ``requested`` is asked for: ``requested``, or the condition's
        own (`SIMULATOR`) if it has one (``experiments/robustness.py --simulator`` asks for one)."""
        return self.SIMULATOR or requested

    def refusal(self, task, simulator: str | None = None) -> str | None:
        """Why the condition cannot run in ``task`` (a [`Task`][hsddp_gym.registry.Task] or its name) when
        ``simulator`` is asked for (None: the condition's own or ``"bounding"``), or None when it can: the task has no
        twin in the simulator, or the condition sets a target speed and the task fixes its own speed or does not
        reach that one (``Task.speed_range``)."""
        task = _as_task(task)
        simulator = self.simulator_for("bounding" if simulator is None else simulator)
        if simulator_env_id(task, simulator) is None:
            return f"the task has no {simulator} twin"
        speed = self.env_kwargs.get("target_speed")
        if speed is not None:
            if task.speed_range is None:
                return "the task fixes its own speed"
            lo, hi = task.speed_range
            if not lo <= speed <= hi:
                return f"its target speeds are {lo:g}-{hi:g} m/s, the condition's {speed:g} m/s"
        return None

    def applies_to(self, task, simulator: str | None = None) -> bool:
        """The condition can run in ``task`` (a [`Task`][hsddp_gym.registry.Task] or its name) with ``simulator``
        asked for ([`refusal`][refusal] is None)."""
        return self.refusal(task, simulator) is None

    def make(self, simulator: str | None = None, env_id: str | None = None, **make_kwargs) -> gym.Env:
        """``gym.make`` the env of ``simulator`` (a key of [`SIMULATORS`][SIMULATORS]; None: the condition's own,
        `SIMULATOR`, or ``"bounding"``) for the task of ``env_id`` (a task's env id, None: Bounding-v0; the task's env
        or its twin in that simulator, [`simulator_env_id`][simulator_env_id]) with `env_kwargs` (``make_kwargs`` may
        add others, e.g. ``render_mode``, ``max_episode_steps``; a key of both raises ``ValueError``) and wrap it; the
        pushes come in the task's window with the task's sizes ([`task_push`][task_push]). A condition with its own
        simulator raises ``ValueError`` for another one, a condition that cannot apply to the task
        ([`refusal`][refusal]) ``ValueError`` naming both."""
        import hsddp_gym  # noqa: F401  (registers the env)

        task = condition_task(env_id)
        if simulator is None:
            simulator = self.simulator_for("bounding")
        if simulator not in SIMULATORS:
            raise ValueError(f"simulator must be one of {sorted(SIMULATORS)}, got {simulator!r}")
        if self.SIMULATOR is not None and simulator != self.SIMULATOR:
            raise ValueError(f"condition {self.name!r} runs in the {self.SIMULATOR!r} simulator only, got "
                             f"simulator={simulator!r}")
        reason = self.refusal(task, simulator)
        if reason is not None:
            raise ValueError(f"condition {self.name!r} does not apply to the task {task.name!r} ({task.env_id}): "
                             f"{reason}")
        both = sorted(set(make_kwargs) & set(self.env_kwargs))
        if both:
            raise ValueError(f"condition {self.name!r} sets {both} itself; do not pass them to make()")
        env = gym.make(simulator_env_id(task, simulator), **self.env_kwargs, **make_kwargs)
        if self.push is not None:
            env = RandomPush(env, **task_push(self.push, task))
        env = self._wrap_inner(env, task)
        env = self._wrap_delay(env)
        if self.observation_noise is not None:
            env = ObservationNoise(env, *self.observation_noise)
        return self._wrap(env)

    def _wrap_inner(self, env: gym.Env, task: Task) -> gym.Env:
        """Wrappers right above the pushes (a subclass's own), for ``task``."""
        return env

    def _wrap_delay(self, env: gym.Env) -> gym.Env:
        return ActionDelay(env, self.action_delay) if self.action_delay else env

    def _wrap(self, env: gym.Env) -> gym.Env:
        """The outermost wrappers (a subclass's own)."""
        return env

    @property
    def announced_delay(self) -> int:
        """The action delay [control steps] a policy is told (``EnvInterface.from_env(env).action_delay_steps``):
        `action_delay` here; a [`HardwareCondition`][HardwareCondition] may announce another one."""
        return self.action_delay

    @property
    def acts_through_env_arguments(self) -> bool:
        """True when the condition is env arguments and pushes only (no observation noise, no latency): what the
        compiled vector env can run without wrappers."""
        return self.observation_noise is None and not self.action_delay

    def as_dict(self) -> dict:
        """A JSON-serializable description."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class ContactCondition(Condition):
    """A condition of the contact model, run in the MuJoCo twin whatever simulator is asked for
    (`SIMULATOR` ``"mujoco"``): a fixed model through `env_kwargs` (``{"contact_model":
    ContactModel(...)}``, e.g. a corner of
    [`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`][hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS]), or with `family` a
    model drawn per episode from the episode seed ([`RandomContactModel`][RandomContactModel]).

    Attributes:
        family: draw the contact model per episode ([`RandomContactModel`][RandomContactModel], the outermost wrapper).
    """

    family: bool = False
    SIMULATOR: ClassVar[str | None] = "mujoco"

    def _wrap(self, env: gym.Env) -> gym.Env:
        return RandomContactModel(env) if self.family else env

    @property
    def acts_through_env_arguments(self) -> bool:
        """False: the compiled vector env (exact LCP) has no MuJoCo contact model."""
        return False


@dataclasses.dataclass(frozen=True)
class HardwareCondition(Condition):
    """A condition a real robot has and the policies are not told about exactly: a latency other than the announced
    one, a constant sensor bias, or a push timed by the contact phase. Extra conditions, not in [`SUITE`][SUITE]; the
    compiled vector env cannot run them ([`acts_through_env_arguments`][acts_through_env_arguments] is False).

    Attributes:
        announced_action_delay: the delay [control steps] [`ActionDelay`][ActionDelay] announces (None: the executed
            one, `action_delay`).
        delay_jitter: per-episode executed delay uniform in ``action_delay +- delay_jitter``
            ([`ActionDelay`][ActionDelay]'s ``jitter``).
        observation_bias: the keyword arguments of [`ObservationBias`][ObservationBias] (``bias``, ``random_bias``), or
            None.
        phase_push: the keyword arguments of [`PhasePush`][PhasePush] (``phase``, ``time_range``, ``max_delta_v``), or
            None.
    """

    announced_action_delay: int | None = None
    delay_jitter: int = 0
    observation_bias: dict | None = None
    phase_push: dict | None = None

    @property
    def announced_delay(self) -> int:
        return self.action_delay if self.announced_action_delay is None else self.announced_action_delay

    def _wrap_inner(self, env: gym.Env, task: Task) -> gym.Env:
        if self.phase_push is None:
            return env
        return PhasePush(env, **task_push(self.phase_push, task, PHASE_PUSH_DELTA_V))

    def _wrap_delay(self, env: gym.Env) -> gym.Env:
        if not (self.action_delay or self.announced_action_delay or self.delay_jitter):
            return env
        return ActionDelay(env, self.action_delay, announced=self.announced_action_delay, jitter=self.delay_jitter)

    def _wrap(self, env: gym.Env) -> gym.Env:
        return env if self.observation_bias is None else ObservationBias(env, **self.observation_bias)

    @property
    def acts_through_env_arguments(self) -> bool:
        """False: the compiled vector env has no latency, observation or phase-timed-push wrappers."""
        return False


SENSOR_BIAS = {"pitch": 0.03, "dx": 0.05, "z": -0.02}
"""The fixed bias of ``sensor_bias`` ([`ObservationBias`][ObservationBias]'s ``bias``): +0.03 rad pitch (nose-down),
+0.05 m/s forward velocity, -0.02 m trunk height."""
SENSOR_BIAS_RANGE = {"z": 0.02, "pitch": 0.03, "hip_front": 0.02, "knee_front": 0.02, "hip_back": 0.02,
                     "knee_back": 0.02, "dx": 0.05, "dz": 0.05}
"""The half-widths of ``sensor_bias_random`` ([`ObservationBias`][ObservationBias]'s ``random_bias``): each episode a
bias uniform in +-0.02 m height, +-0.03 rad pitch, +-0.02 rad on each joint angle, +-0.05 m/s on the trunk's forward and
vertical velocities (the rates are unbiased)."""
SENSOR_BIAS_X2 = {name: 2.0 * value for name, value in SENSOR_BIAS.items()}
"""The fixed bias of ``sensor_bias_x2``: [`SENSOR_BIAS`][SENSOR_BIAS] twice over, +0.06 rad pitch, +0.1 m/s forward
velocity,
-0.04 m trunk height."""
PHASE_PUSH_DELTA_V = (1.0, 1.0, 7.0)
"""``max_delta_v`` of ``push_flight`` and ``push_stance``: ``U(+-1.0 m/s, +-1.0 m/s, +-7 rad/s)``, larger than
``push``'s (0.8, 0.8, 5.0)."""


def _hardware_conditions() -> tuple:
    h = HardwareCondition
    return (
        h("delay_5ms_announced_0ms", "actions executed 1 control step (5 ms) late, no delay announced",
          action_delay=1, announced_action_delay=0),
        h("delay_10ms_announced_5ms", "actions executed 2 control steps (10 ms) late, 1 step (5 ms) announced",
          action_delay=2, announced_action_delay=1),
        h("delay_5ms_announced_10ms", "actions executed 1 control step (5 ms) late, 2 steps (10 ms) announced",
          action_delay=1, announced_action_delay=2),
        h("delay_15ms_announced_10ms", "actions executed 3 control steps (15 ms) late, 2 steps (10 ms) announced",
          action_delay=3, announced_action_delay=2),
        h("delay_jitter", "10 ms announced; each episode executes 5, 10 or 15 ms (uniform, from the episode seed)",
          action_delay=2, delay_jitter=1),
        h("sensor_bias", "constant observation bias: +0.03 rad pitch, +0.05 m/s forward velocity, -0.02 m height",
          observation_bias={"bias": dict(SENSOR_BIAS)}),
        h("sensor_bias_random", "observation bias drawn per episode: U(+-0.02 m) height, U(+-0.03 rad) pitch, "
          "U(+-0.02 rad) joints, U(+-0.05 m/s) vx and vz", observation_bias={"random_bias": dict(SENSOR_BIAS_RANGE)}),
        h("sensor_bias_x2", "constant observation bias twice sensor_bias's: +0.06 rad pitch, +0.1 m/s forward "
          "velocity, -0.04 m height", observation_bias={"bias": dict(SENSOR_BIAS_X2)}),
        h("noise_bias_latency", "observation noise as obs_noise, a bias drawn as sensor_bias_random's and actions "
          "executed 2 control steps (10 ms) late with 1 step (5 ms) announced, together", observation_noise=(0.01, 0.1),
          action_delay=2, announced_action_delay=1, observation_bias={"random_bias": dict(SENSOR_BIAS_RANGE)}),
        h("push_flight", "one push at the first flight step (no foot in contact) after t ~ U(1, 4) s, "
          "dv ~ U(+-1.0 m/s, +-1.0 m/s, +-7 rad/s)",
          phase_push={"phase": "flight", "max_delta_v": PHASE_PUSH_DELTA_V}),
        h("push_stance", "one push at the first stance step (a foot in contact) after t ~ U(1, 4) s, "
          "dv ~ U(+-1.0 m/s, +-1.0 m/s, +-7 rad/s)",
          phase_push={"phase": "stance", "max_delta_v": PHASE_PUSH_DELTA_V}),
    )


def _conditions(*conds: Condition) -> dict:
    return {c.name: c for c in conds}


def _corner_conditions() -> tuple:
    from hsddp_gym.envs.mujoco_twin import CONTACT_CORNERS

    what = {"softest": "solref (20 ms, 0.5): the softest, least damped contact",
            "stiffest": "solref (2 ms, 1): the stiffest contact",
            "pyramidal": "pyramidal friction cone", "large_feet": "20 mm foot spheres (they roll)",
            "low_friction": "friction mu = 0.4 (model: 0.6)", "coarse_step": "5/3 ms MuJoCo step (3 per action)"}
    return tuple(ContactCondition(f"contact_{name}", f"MuJoCo twin, contact corner {name}: {what[name]}",
                                  {"contact_model": model}) for name, model in CONTACT_CORNERS.items())


CONDITIONS: dict[str, Condition] = _conditions(
    Condition("default", "default env (reset noise 0.01)"),
    Condition("reset_noise_x4", "reset noise x4 (reset_noise_scale=0.04)", {"reset_noise_scale": 0.04}),
    Condition("obs_noise", "observation noise: sigma 0.01 on positions, 0.1 on velocities",
              observation_noise=(0.01, 0.1)),
    Condition("delay_5ms", "actions executed 1 control step (5 ms) late", action_delay=1),
    Condition("delay_10ms", "actions executed 2 control steps (10 ms) late", action_delay=2),
    Condition("push", "random push: t ~ U(1, 4) s, dv ~ U(+-0.8 m/s, +-0.8 m/s, +-5 rad/s)", push={}),
    Condition("push_x3", "three random pushes, one in each second of 1-4 s, each dv as in push",
              push={"count": 3}),
    Condition("friction_0.4", "friction mu = 0.4 (model: 0.6)", {"friction": 0.4}),
    Condition("mass_+15", "trunk mass +15 % (env only)", {"trunk_mass_scale": 1.15}),
    Condition("mass_-15", "trunk mass -15 % (env only)", {"trunk_mass_scale": 0.85}),
    Condition("speed_0.5", "target speed 0.5 m/s", {"target_speed": 0.5}),
    Condition("speed_1.25", "target speed 1.25 m/s", {"target_speed": 1.25}),
    Condition("speed_1.5", "target speed 1.5 m/s", {"target_speed": 1.5}),
    Condition("speed_2.0", "target speed 2.0 m/s", {"target_speed": 2.0}),
    ContactCondition("contact_family", "MuJoCo twin, a contact model drawn per episode from the family "
                     "(ContactModel.sample, seeded by the episode seed)", family=True),
    *_corner_conditions(),
    *_hardware_conditions(),
)
"""Every named condition: the robustness benchmark's ([`SUITE`][SUITE]), ``push_x3`` (three pushes an episode: a
harder test, and a training condition that gives a learner's rollouts three push recoveries each), the contact
conditions ([`CONTACT_CONDITIONS`][CONTACT_CONDITIONS], in the MuJoCo twin) and the hardware ones
([`HARDWARE_CONDITIONS`][HARDWARE_CONDITIONS])."""
CONTACT_CONDITIONS: tuple[str, ...] = tuple(n for n, c in CONDITIONS.items() if isinstance(c, ContactCondition))
"""The contact-model conditions: ``contact_family`` and one ``contact_<corner>`` per corner of
[`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`][hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS]; not in [`SUITE`][SUITE]."""
HARDWARE_CONDITIONS: tuple[str, ...] = tuple(n for n, c in CONDITIONS.items() if isinstance(c, HardwareCondition))
"""The conditions of a real robot ([`HardwareCondition`][HardwareCondition]): latencies other than the announced one
(``delay_<executed>_announced_<announced>``, ``delay_jitter``), sensor biases (``sensor_bias``,
``sensor_bias_random``, ``sensor_bias_x2``), phase-timed pushes (``push_flight``, ``push_stance``) and noise, a bias and
a wrongly announced latency together (``noise_bias_latency``); not in [`SUITE`][SUITE]."""
SUITE: tuple[str, ...] = tuple(name for name in CONDITIONS if name != "push_x3" and name not in CONTACT_CONDITIONS
                               and name not in HARDWARE_CONDITIONS)
"""The robustness benchmark's conditions (every condition of [`CONDITIONS`][CONDITIONS] but ``push_x3``, the contact
conditions and the hardware ones, target speeds 0.5 and 1.5 m/s included): the default of
``experiments/robustness.py`` and ``experiments/imitation_robustness.py``."""

TASK_SUITE: tuple[str, ...] = ("default", "reset_noise_x4", "push", "obs_noise", "delay_5ms", "delay_10ms",
                               "delay_10ms_announced_5ms", "delay_5ms_announced_10ms", "sensor_bias", "friction_0.4",
                               "mass_+15", "mass_-15", *CONTACT_CONDITIONS)
"""The conditions of a task's robustness table (``experiments/robustness.py --env ID``'s default, those that apply):
nominal, reset noise x4, a push in the task's window, observation noise, 5 and 10 ms of latency announced, latency one
step longer and one step shorter than announced, a constant sensor bias, friction 0.4, trunk mass +-15 %, and the
contact models of the MuJoCo twin (the family and its corners). No target speeds: most tasks fix their own."""


def get_condition(name: str) -> Condition:
    """The [`Condition`][Condition] called ``name`` (ValueError naming the known ones otherwise)."""
    if not isinstance(name, str) or name not in CONDITIONS:
        raise ValueError(f"condition must be one of {list(CONDITIONS)}, got {name!r}")
    return CONDITIONS[name]


def check_conditions(names, argument: str = "conditions") -> tuple[str, ...]:
    """``names`` (a non-empty sequence of [`CONDITIONS`][CONDITIONS] names, repeats allowed) as a tuple; ``ValueError``
    naming ``argument`` and the allowed names otherwise."""
    if isinstance(names, str) or not isinstance(names, (list, tuple)) or not names:
        raise ValueError(f"{argument} must be a non-empty list of condition names, got {names!r}")
    bad = [n for n in names if not isinstance(n, str) or n not in CONDITIONS]
    if bad:
        raise ValueError(f"{argument}: unknown condition(s) {bad}; allowed: {list(CONDITIONS)}")
    return tuple(names)


def make_env(condition: str | Condition, **make_kwargs) -> gym.Env:
    """The env of a condition (a name of [`CONDITIONS`][CONDITIONS] or a [`Condition`][Condition]), see
    [`Condition.make`][Condition.make]."""
    if isinstance(condition, Condition):
        return condition.make(**make_kwargs)
    return get_condition(condition).make(**make_kwargs)
