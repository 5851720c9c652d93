"""Seeded perturbations of ``hsddp_gym/Bounding-v0`` for robustness tests, usable with any policy.

Three Gymnasium wrappers and two env arguments, and one registry, :data:`CONDITIONS`, that names the
conditions of the robustness benchmark (:data:`SUITE`, ``experiments/robustness.py``) and a few more:

* :class:`ObservationNoise`: zero-mean Gaussian noise on the observed positions and velocities (the contact
  flags and the gait clock stay clean);
* :class:`ActionDelay`: every action is executed ``steps`` control steps after the policy returned it (the
  first ``steps`` executed actions are zero torques); the wrapper's ``action_delay_steps`` attribute tells a
  policy its latency (:class:`hsddp_gym.planners.policies.base.EnvInterface` reads it);
* :class:`RandomPush`: one push (or ``count``) per episode at a random time, a random trunk-velocity change
  ``[dvx, dvz, dpitch_rate]`` (a :class:`PushDistribution`) applied through the env's documented ``push`` reset
  option (the compiled vector env draws the same pushes for its robots with its ``push`` argument);
* model mismatch through env arguments: ``friction`` (Coulomb coefficient) and ``trunk_mass_scale`` (the
  simulated trunk is heavier or lighter than the model every policy uses);
* contact models the policies were not built on (:class:`ContactCondition`, always in the MuJoCo twin): a corner
  of :data:`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS` (``contact_<corner>``), or :class:`RandomContactModel`, a
  :class:`~hsddp_gym.envs.mujoco_twin.ContactModel` drawn per episode from the episode seed (``contact_family``).
  They are extra conditions, not in :data:`SUITE`.

**Seeding.** Each wrapper draws from its own generator, seeded at every ``reset(seed=s)`` from ``(s, salt)``
(a per-wrapper constant), so an episode's perturbation is a function of its seed alone, independent of the
policy and of the env's own reset noise; ``reset()`` without a seed continues the generator (seeded from
the env's ``np_random`` on first use).

Example::

    from hsddp_gym.envs.perturbations import make_env
    env = make_env("push")                    # gym.make("hsddp_gym/Bounding-v0") + RandomPush
    obs, info = env.reset(seed=3)             # info["push"]: the push of this episode
"""

from __future__ import annotations

import collections
import copy
import dataclasses
import math
import numbers
from typing import ClassVar

import gymnasium as gym
import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.util.validation import check_int, check_positive

ENV_ID = "hsddp_gym/Bounding-v0"
SIMULATORS = {"bounding": "hsddp_gym/Bounding-v0", "mujoco": "hsddp_gym/BoundingMuJoCo-v0",
              "kkt": "hsddp_gym/BoundingKKT-v0"}
"""The simulators a condition runs in (``Condition.make(simulator=...)``): the exact-LCP env (default), its MuJoCo
twin (soft contacts; the optional extra ``mujoco``) and the planner's own hybrid model (pinned feet)."""


def episode_generator(seed, salt: int, current: np.random.Generator | None, env_rng) -> np.random.Generator:
    """A perturbation's generator for an episode reset with ``seed``: ``SeedSequence([seed, salt])``; without a
    seed the ``current`` one continues, or (first use) one seeded from a draw of the env's generator ``env_rng()``
    (a callable, called only then)."""
    if seed is not None:
        return np.random.default_rng(np.random.SeedSequence([int(seed), salt]))
    if current is None:
        return np.random.default_rng(np.random.SeedSequence([int(env_rng().integers(2 ** 63)), salt]))
    return current


def _episode_rng(wrapper, seed, salt: int) -> np.random.Generator:
    """The wrapper's generator for an episode reset with ``seed`` (None: continue, or start from the env)."""
    return episode_generator(seed, salt, wrapper._rng, lambda: wrapper.env.unwrapped.np_random)


def _check_nonneg(value, name: str) -> float:
    return check_positive(value, name, allow_zero=True)


class ObservationNoise(gym.Wrapper):
    """Gaussian noise ``N(0, position_std^2)`` on every observed position (trunk height, pitch, joint angles;
    the trunk ``x`` too when it is observed) and ``N(0, velocity_std^2)`` on every observed velocity, drawn
    independently at every observation (reset included); contact flags and the gait clock are not perturbed.
    The noisy observation is clipped to the observation space. ``info`` is untouched (it holds the true
    state).

    Args:
        env: a (wrapped) ``Bounding-v0``.
        position_std: [m or rad] (>= 0). velocity_std: [m/s or rad/s] (>= 0).
    """

    SALT = 0x0B5E

    def __init__(self, env: gym.Env, position_std: float = 0.01, velocity_std: float = 0.1) -> None:
        super().__init__(env)
        self.position_std = _check_nonneg(position_std, "position_std")
        self.velocity_std = _check_nonneg(velocity_std, "velocity_std")
        layout = env.unwrapped.observation_layout
        self._std = np.zeros(layout.size)
        self._std[layout.qpos] = self.position_std
        self._std[layout.qvel] = self.velocity_std
        self._rng: np.random.Generator | None = None

    def _noisy(self, obs: np.ndarray) -> np.ndarray:
        noisy = obs + self._std * self._rng.standard_normal(obs.shape)
        space = self.observation_space
        return np.clip(noisy, space.low, space.high).astype(obs.dtype)

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._rng = _episode_rng(self, seed, self.SALT)
        return self._noisy(obs), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._noisy(obs), reward, terminated, truncated, info


class ActionDelay(gym.Wrapper):
    """Actions executed ``steps`` control steps late: ``step(a_t)`` executes ``a_{t - steps}`` (zero torques for
    the first ``steps`` steps after a reset). ``info["executed_action"]`` is the action the env executed.

    A bad action (wrong shape, non-finite) raises ``ValueError`` when it is given, not when it is executed.

    Args:
        env: a (wrapped) ``Bounding-v0``. steps: the delay in control steps (>= 0; 0 is the identity).

    Attributes:
        action_delay_steps: ``steps`` (policies that know their latency read it through
            ``env.get_wrapper_attr("action_delay_steps")``).
    """

    INFO_KEYS = ("executed_action",)
    """The ``info`` keys this wrapper adds (:func:`wrapper_info_keys`)."""

    def __init__(self, env: gym.Env, steps: int = 1) -> None:
        super().__init__(env)
        self.action_delay_steps = check_int(steps, "steps", minimum=0)
        self._queue: collections.deque = collections.deque()

    def reset(self, *, seed=None, options=None):
        self._queue = collections.deque(np.zeros(NU, dtype=np.float32) for _ in range(self.action_delay_steps))
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        try:
            a = np.array(action, dtype=np.float32)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"action must be an array of {NU} numbers, got {action!r}") from exc
        if a.shape != (NU,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be a finite array of shape ({NU},), got {action!r}")
        self._queue.append(a)
        executed = self._queue.popleft()
        obs, reward, terminated, truncated, info = self.env.step(executed)
        info = dict(info, executed_action=executed)
        return obs, reward, terminated, truncated, info


def _check_range(value, name: str, minimum: float | None = None) -> tuple[float, float]:
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise TypeError(f"{name} must be a pair (low, high), got {value!r}")
    lo, hi = value
    for v in (lo, hi):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
            raise ValueError(f"{name} must hold two finite numbers, got {value!r}")
    if not float(lo) <= float(hi):
        raise ValueError(f"{name} must satisfy low <= high, got {value!r}")
    if minimum is not None and float(lo) < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return float(lo), float(hi)


PUSH_SALT = 0x9054
"""The salt of the push generators (:class:`RandomPush`, the vector env's ``push``): an episode reset with seed ``s``
draws its pushes from ``SeedSequence([s, PUSH_SALT])``."""


@dataclasses.dataclass(frozen=True)
class PushDistribution:
    """The random pushes of an episode: ``count`` of them (default one) at random times, each a change of the
    trunk velocities by ``delta_v ~ U(-max_delta_v, max_delta_v)`` per component (``[dvx, dvz, dpitch_rate]``,
    m/s, m/s, rad/s, positive pitch rate nose-down). With one push its time is ``t ~ U(time_range)``; with
    ``count`` pushes ``time_range`` is cut into ``count`` equal slots and push ``j`` comes at a uniform time in
    slot ``j`` (so they come in order, one recovery apart on average). One definition for :class:`RandomPush`
    and :class:`hsddp_gym.envs.vector.BoundingVectorEnv`'s ``push`` argument, so both draw the same pushes.

    Args (validated, ``TypeError`` / ``ValueError`` naming the argument):
        time_range: ``(low, high)`` push times [s] (>= 0). max_delta_v: (3,) largest absolute velocity change per
        component (>= 0). count: pushes per episode (>= 1).
    """

    time_range: tuple = (1.0, 4.0)
    max_delta_v: tuple = (0.8, 0.8, 5.0)
    count: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_range", _check_range(self.time_range, "time_range", minimum=0.0))
        m = self.max_delta_v
        if not isinstance(m, (tuple, list, np.ndarray)) or len(m) != 3:
            raise TypeError(f"max_delta_v must be 3 numbers [m/s, m/s, rad/s], got {m!r}")
        object.__setattr__(self, "max_delta_v", tuple(_check_nonneg(v, f"max_delta_v[{i}]") for i, v in enumerate(m)))
        object.__setattr__(self, "count", check_int(self.count, "count", minimum=1))

    @classmethod
    def parse(cls, value, name: str = "push") -> PushDistribution:
        """``value`` as a distribution: a :class:`PushDistribution`, or a dict of its fields (``{}``: the
        defaults); anything else raises ``TypeError`` naming ``name``."""
        if isinstance(value, cls):
            return value
        if not isinstance(value, dict):
            raise TypeError(f"{name} must be a PushDistribution or a dict of its fields (time_range, max_delta_v, "
                            f"count), got {type(value).__name__}")
        unknown = sorted(set(value) - {f.name for f in dataclasses.fields(cls)})
        if unknown:
            raise ValueError(f"{name}: unknown field(s) {unknown}; allowed: time_range, max_delta_v, count")
        return cls(**value)

    def draw(self, rng: np.random.Generator) -> list:
        """The pushes of one episode from ``rng``: a list of ``count`` dicts ``{"delta_v": [3 floats], "time":
        t}`` in time order (per push its time, then its velocity change), the env's ``push`` reset option."""
        lo, hi = self.time_range
        slot = (hi - lo) / self.count
        m = np.asarray(self.max_delta_v)
        pushes = []
        for j in range(self.count):
            t = float(rng.uniform(lo + j * slot, hi if j == self.count - 1 else lo + (j + 1) * slot))
            pushes.append({"delta_v": (m * rng.uniform(-1.0, 1.0, size=3)).tolist(), "time": t})
        return pushes


class RandomPush(gym.Wrapper):
    """Random pushes of a :class:`PushDistribution` (``count`` per episode, default one, at random times, each a
    random change of the trunk velocities) through the env's ``push`` reset option (a scheduled push, or a schedule
    of them). The pushes of the episode are ``info["push"]`` at reset and :attr:`last_push`: the reset option
    given to the env, ``{"delta_v": [3 floats], "time": t}`` for one push, a list of such dicts for several.
    Giving the ``push`` reset option yourself as well raises ``ValueError``.

    Args:
        env: a (wrapped) ``Bounding-v0``. time_range, max_delta_v, count: the :class:`PushDistribution`.
    """

    SALT = PUSH_SALT
    INFO_KEYS = ("push",)
    """The ``info`` keys this wrapper adds (at reset; :func:`wrapper_info_keys`)."""

    def __init__(self, env: gym.Env, time_range=(1.0, 4.0), max_delta_v=(0.8, 0.8, 5.0), count: int = 1) -> None:
        super().__init__(env)
        self.distribution = PushDistribution(time_range, max_delta_v, count)
        self.time_range = self.distribution.time_range
        self.max_delta_v = self.distribution.max_delta_v
        self.count = self.distribution.count
        self._rng: np.random.Generator | None = None
        self.last_push: dict | list | None = None

    def reset(self, *, seed=None, options=None):
        options = {} if options is None else dict(options)
        if options.get("push") is not None:
            raise ValueError("RandomPush draws the push itself: do not also give the 'push' reset option")
        if seed is not None or self._rng is None:
            self._rng = _episode_rng(self, seed, self.SALT)
        pushes = self.distribution.draw(self._rng)
        self.last_push = pushes[0] if self.count == 1 else pushes
        options["push"] = copy.deepcopy(self.last_push)
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, dict(info, push=copy.deepcopy(self.last_push))


CONTACT_SALT = 0xC0A7
"""The salt of :class:`RandomContactModel`'s generator: an episode reset with seed ``s`` draws its contact model from
``SeedSequence([s, CONTACT_SALT])``."""


class RandomContactModel(gym.Wrapper):
    """A contact model of the MuJoCo twin drawn per episode: at every reset a
    :class:`~hsddp_gym.envs.mujoco_twin.ContactModel` is drawn with
    :meth:`ContactModel.sample <hsddp_gym.envs.mujoco_twin.ContactModel.sample>` from the episode's generator
    (seeded from ``(seed, CONTACT_SALT)``: the same seed gives the same model, whatever the policy) and set on the
    env (:meth:`~hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv.set_contact_model`) before the env's own reset. The
    control period stays 5 ms (the env's ``frame_skip`` follows the model's time step). The episode's model is
    ``info["contact_model"]`` at reset (a dict of its fields) and :attr:`last_contact_model`.

    Args:
        env: a (wrapped) ``hsddp_gym/BoundingMuJoCo-v0`` (``TypeError`` otherwise).
    """

    SALT = CONTACT_SALT
    INFO_KEYS = ("contact_model",)
    """The ``info`` keys this wrapper adds (at reset; :func:`wrapper_info_keys`)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        if not callable(getattr(env.unwrapped, "set_contact_model", None)):
            raise TypeError("RandomContactModel needs the MuJoCo twin (hsddp_gym/BoundingMuJoCo-v0), got "
                            f"{type(env.unwrapped).__name__}")
        self._rng: np.random.Generator | None = None
        self.last_contact_model = None

    def reset(self, *, seed=None, options=None):
        from hsddp_gym.envs.mujoco_twin import ContactModel

        if seed is not None or self._rng is None:
            self._rng = _episode_rng(self, seed, self.SALT)
        self.last_contact_model = ContactModel.sample(self._rng)
        self.env.unwrapped.set_contact_model(self.last_contact_model)
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, dict(info, contact_model=self.last_contact_model.as_dict())


# ------------------------------------------------------------------------------------------------ registry
@dataclasses.dataclass(frozen=True)
class Condition:
    """A named test condition: env arguments plus wrappers.

    Attributes:
        name: the registry key. description: one line for tables.
        env_kwargs: arguments of ``gym.make("hsddp_gym/Bounding-v0", ...)`` (reset noise, friction, trunk mass,
            target speed).
        observation_noise: ``(position_std, velocity_std)`` of :class:`ObservationNoise`, or None.
        action_delay: control steps of :class:`ActionDelay` (0: none).
        push: the keyword arguments of :class:`RandomPush` (``{}``: its defaults), or None (no push).
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
        own (:attr:`SIMULATOR`) if it has one (``experiments/robustness.py --simulator`` asks for one)."""
        return self.SIMULATOR or requested

    def make(self, simulator: str | None = None, **make_kwargs) -> gym.Env:
        """``gym.make`` the env of ``simulator`` (a key of :data:`SIMULATORS`; None: the condition's own,
        :attr:`SIMULATOR`, or ``"bounding"``) with :attr:`env_kwargs` (``make_kwargs`` may add others, e.g.
        ``render_mode``, ``max_episode_steps``; a key of both raises ``ValueError``) and wrap it. A condition with
        its own simulator raises ``ValueError`` for another one."""
        import hsddp_gym  # noqa: F401  (registers the env)

        if simulator is None:
            simulator = self.simulator_for("bounding")
        if simulator not in SIMULATORS:
            raise ValueError(f"simulator must be one of {sorted(SIMULATORS)}, got {simulator!r}")
        if self.SIMULATOR is not None and simulator != self.SIMULATOR:
            raise ValueError(f"condition {self.name!r} runs in the {self.SIMULATOR!r} simulator only, got "
                             f"simulator={simulator!r}")
        both = sorted(set(make_kwargs) & set(self.env_kwargs))
        if both:
            raise ValueError(f"condition {self.name!r} sets {both} itself; do not pass them to make()")
        env = gym.make(SIMULATORS[simulator], **self.env_kwargs, **make_kwargs)
        if self.push is not None:
            env = RandomPush(env, **self.push)
        if self.action_delay:
            env = ActionDelay(env, self.action_delay)
        if self.observation_noise is not None:
            env = ObservationNoise(env, *self.observation_noise)
        return self._wrap(env)

    def _wrap(self, env: gym.Env) -> gym.Env:
        return env

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
    (:attr:`SIMULATOR` ``"mujoco"``): a fixed model through :attr:`env_kwargs` (``{"contact_model":
    ContactModel(...)}``, e.g. a corner of :data:`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`), or with
    :attr:`family` a model drawn per episode from the episode seed (:class:`RandomContactModel`).

    Attributes:
        family: draw the contact model per episode (:class:`RandomContactModel`, the outermost wrapper).
    """

    family: bool = False
    SIMULATOR: ClassVar[str | None] = "mujoco"

    def _wrap(self, env: gym.Env) -> gym.Env:
        return RandomContactModel(env) if self.family else env

    @property
    def acts_through_env_arguments(self) -> bool:
        """False: the compiled vector env (exact LCP) has no MuJoCo contact model."""
        return False


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
)
"""Every named condition: the robustness benchmark's (:data:`SUITE`), ``push_x3`` (three pushes an episode: a
harder test, and a training condition that gives a learner's rollouts three push recoveries each) and the contact
conditions (:data:`CONTACT_CONDITIONS`, in the MuJoCo twin)."""
CONTACT_CONDITIONS: tuple[str, ...] = tuple(n for n, c in CONDITIONS.items() if isinstance(c, ContactCondition))
"""The contact-model conditions: ``contact_family`` and one ``contact_<corner>`` per corner of
:data:`hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`; not in :data:`SUITE`."""
SUITE: tuple[str, ...] = tuple(name for name in CONDITIONS if name != "push_x3" and name not in CONTACT_CONDITIONS)
"""The robustness benchmark's conditions (every condition of :data:`CONDITIONS` but ``push_x3`` and the contact
conditions, target speeds 0.5 and 1.5 m/s included): the default of ``experiments/robustness.py`` and
``experiments/imitation_robustness.py``."""


def get_condition(name: str) -> Condition:
    """The :class:`Condition` called ``name`` (ValueError naming the known ones otherwise)."""
    if not isinstance(name, str) or name not in CONDITIONS:
        raise ValueError(f"condition must be one of {list(CONDITIONS)}, got {name!r}")
    return CONDITIONS[name]


def check_conditions(names, argument: str = "conditions") -> tuple[str, ...]:
    """``names`` (a non-empty sequence of :data:`CONDITIONS` names, repeats allowed) as a tuple; ``ValueError``
    naming ``argument`` and the allowed names otherwise."""
    if isinstance(names, str) or not isinstance(names, (list, tuple)) or not names:
        raise ValueError(f"{argument} must be a non-empty list of condition names, got {names!r}")
    bad = [n for n in names if not isinstance(n, str) or n not in CONDITIONS]
    if bad:
        raise ValueError(f"{argument}: unknown condition(s) {bad}; allowed: {list(CONDITIONS)}")
    return tuple(names)


def wrapper_info_keys(env: gym.Env) -> frozenset:
    """The ``info`` keys the wrappers of ``env`` add to the unwrapped env's (their ``INFO_KEYS``): the keys a
    recorder drops to keep the env's own per-step schema (``push`` appears at reset only)."""
    keys: set = set()
    e = env
    while isinstance(e, gym.Wrapper):
        keys.update(getattr(e, "INFO_KEYS", ()))
        e = e.env
    return frozenset(keys)


def true_observation(env: gym.Env) -> np.ndarray:
    """The observation ``(layout.size,)`` float32 of the env's *true* current state (what the unwrapped env
    returned at the last reset/step, before any :class:`ObservationNoise`), built from the public state,
    contact flags and clock of ``env.unwrapped``; for an env without observation noise it equals the
    observation the env returned."""
    from hsddp_gym.core.observation import build_observation

    u = env.unwrapped
    return build_observation(u.state, u.contact, u.time, u.gait_period, u.observation_layout)


def make_env(condition: str | Condition, **make_kwargs) -> gym.Env:
    """The env of a condition (a name of :data:`CONDITIONS` or a :class:`Condition`), see :meth:`Condition.make`."""
    if isinstance(condition, Condition):
        return condition.make(**make_kwargs)
    return get_condition(condition).make(**make_kwargs)
