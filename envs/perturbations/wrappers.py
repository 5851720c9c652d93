"""The Gymnasium wrappers that perturb ``hsddp_gym/Bounding-v0`` (the named conditions that combine them:
[`hsddp_gym.envs.perturbations.conditions`][hsddp_gym.envs.perturbations.conditions]):

* [`ObservationNoise`][ObservationNoise]: zero-mean Gaussian noise on the observed positions and velocities (the contact
  flags and the gait clock stay clean);
* [`ObservationBias`][ObservationBias]: a constant offset on named observed positions and velocities (a sensor bias),
fixed or drawn per episode;
* [`ActionDelay`][ActionDelay]: every action is executed ``steps`` control steps after the policy returned it (the
  first ``steps`` executed actions are zero torques); the wrapper's ``action_delay_steps`` attribute tells a
  policy its latency ([`hsddp_gym.planners.policies.base.EnvInterface`][hsddp_gym.planners.policies.base.EnvInterface]
  reads it), which may differ from the executed one (``announced``), and the executed delay may be drawn per episode
  (``jitter``);
* [`RandomPush`][RandomPush]: one push (or ``count``) per episode at a random time, a random trunk-velocity change
  ``[dvx, dvz, dpitch_rate]`` (a [`PushDistribution`][PushDistribution]) applied through the env's documented ``push``
  reset option (the compiled vector env draws the same pushes for its robots with its ``push`` argument);
* [`PhasePush`][PhasePush]: one such push at the first control step in flight (or in stance) after a random time,
  through the env's ``apply_push``;
* [`RandomContactModel`][RandomContactModel]: a contact model of the MuJoCo twin drawn per episode;
* what the wrappers of an env add and did: [`wrapper_info_keys`][wrapper_info_keys],
[`episode_perturbation`][episode_perturbation], and the
  observation of the true state, [`true_observation`][true_observation].

**Seeding.** Each wrapper draws from its own generator, seeded at every ``reset(seed=s)`` from ``(s, salt)``
(a per-wrapper constant), so an episode's perturbation is a function of its seed alone, independent of the
policy and of the env's own reset noise; ``reset()`` without a seed continues the generator (seeded from
the env's ``np_random`` on first use).
"""

from __future__ import annotations

import collections
import copy
import dataclasses
import math
import numbers

import gymnasium as gym
import numpy as np

from hsddp_gym.core.conventions import NQ, NU, Q_NAMES, X_NAMES
from hsddp_gym.core.task_constants import BOUND_PUSH_SIZE, BOUND_PUSH_WINDOW
from hsddp_gym.util.validation import check_int, check_positive


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
    The noisy observation is clipped to the observation space. ``info`` is untouched (it holds the true state).

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


def observation_entries(layout) -> dict[str, int]:
    """The observed positions and velocities of ``layout`` (an
    [`ObservationLayout`][hsddp_gym.core.observation.ObservationLayout]) by name: ``{name: index}`` with the state names
    of `hsddp_gym.core.conventions.X_NAMES` (``"z"``, ``"pitch"``, ``"hip_front"``, ..., ``"dx"`` the forward
    velocity, ``"dz"``, ``"dpitch"`` the pitch rate, ``"dhip_front"``, ...; ``"x"`` only when the layout observes
    it). The contact flags and the gait clock have no name: they are not sensor readings to bias."""
    q_names = Q_NAMES[layout.skipped_qpos:]
    v_names = X_NAMES[NQ:]
    entries = {name: layout.qpos.start + i for i, name in enumerate(q_names)}
    entries.update({name: layout.qvel.start + i for i, name in enumerate(v_names)})
    return entries


def _check_entry_values(value, name: str, entries: dict, nonneg: bool) -> dict:
    """``value`` (a dict ``{entry name: number}`` or None) validated against ``entries``."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise TypeError(f"{name} must be a dict {{observation entry: value}} or None, got {type(value).__name__}")
    unknown = [k for k in value if k not in entries]
    if unknown:
        raise ValueError(f"{name}: unknown observation entr(y/ies) {unknown}; allowed: {list(entries)}")
    out = {}
    for key, v in value.items():
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
            raise ValueError(f"{name}[{key!r}] must be a finite number, got {v!r}")
        if nonneg and float(v) < 0.0:
            raise ValueError(f"{name}[{key!r}] must be >= 0 (a half-width), got {v!r}")
        out[key] = float(v)
    return out


class ObservationBias(gym.Wrapper):
    """A constant offset on chosen observed positions and velocities (a sensor or state-estimator bias), the same
    at every observation of an episode (reset included): ``obs[i] + offset[i]`` for the named entries, clipped to
    the observation space; every other entry (the contact flags and the gait clock always) is returned unchanged.
    ``info`` is untouched (it holds the true state).

    The offset of an entry is ``bias[name] + U(-random_bias[name], random_bias[name])``: a fixed part and a part
    drawn at every reset from the episode's generator (seeded from ``(seed, ObservationBias.SALT)``, see the
    module's seeding rule; one uniform draw per observation entry, in observation order, whatever entries are
    named). The episode's offsets are ``info["observation_bias"]`` at reset (``{name: offset}`` of the named
    entries) and `offset` (``(layout.size,)``, zeros elsewhere).

    Args:
        env: a (wrapped) ``Bounding-v0``.
        bias: ``{entry: offset}`` in the entry's unit (m, rad, m/s, rad/s), or None. Entries are named as in
            [`observation_entries`][observation_entries] (``"z"``, ``"pitch"``, ``"dx"`` the forward velocity, ...).
        random_bias: ``{entry: half-width}`` (>= 0) of a uniform per-episode offset, or None.
    """

    SALT = 0xB1A5
    INFO_KEYS = ("observation_bias",)
    """The ``info`` keys this wrapper adds (at reset; [`wrapper_info_keys`][wrapper_info_keys])."""

    def __init__(self, env: gym.Env, bias: dict | None = None, random_bias: dict | None = None) -> None:
        super().__init__(env)
        layout = env.unwrapped.observation_layout
        self.entries = observation_entries(layout)
        self.bias = _check_entry_values(bias, "bias", self.entries, nonneg=False)
        self.random_bias = _check_entry_values(random_bias, "random_bias", self.entries, nonneg=True)
        self._names = [n for n in self.entries if n in self.bias or n in self.random_bias]
        self._index = np.array([self.entries[n] for n in self._names], dtype=np.intp)
        self._fixed = np.zeros(layout.size)
        self._half = np.zeros(layout.size)
        for name, v in self.bias.items():
            self._fixed[self.entries[name]] = v
        for name, v in self.random_bias.items():
            self._half[self.entries[name]] = v
        self.offset = self._fixed.copy()
        self._rng: np.random.Generator | None = None

    def _biased(self, obs: np.ndarray) -> np.ndarray:
        out = obs.copy()
        i = self._index
        space = self.observation_space
        out[i] = np.clip(obs[i] + self.offset[i], space.low[i], space.high[i])
        return out

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        if self.random_bias:
            if seed is not None or self._rng is None:
                self._rng = _episode_rng(self, seed, self.SALT)
            self.offset = self._fixed + self._half * self._rng.uniform(-1.0, 1.0, size=self._half.shape)
        bias = {n: float(self.offset[self.entries[n]]) for n in self._names}
        return self._biased(obs), dict(info, observation_bias=bias)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._biased(obs), reward, terminated, truncated, info


class ActionDelay(gym.Wrapper):
    """Actions executed ``steps`` control steps late: ``step(a_t)`` executes ``a_{t - steps}`` (zero torques for
    the first ``steps`` steps after a reset). ``info["executed_action"]`` is the action the env executed.

    The delay a policy is told (`action_delay_steps`) is ``steps`` unless ``announced`` says otherwise: a
    latency that is not known exactly (announced 1 step, executed 2, ...). With ``jitter`` the executed delay of
    each episode is drawn at reset, uniform in ``{steps - jitter, ..., steps + jitter}``, from a generator seeded
    from ``(seed, ActionDelay.SALT)`` (see the module's seeding rule); it is constant within the episode
    (`executed_delay_steps`). Without ``announced`` and ``jitter`` nothing is drawn and the wrapper is the plain delay.

    A bad action (wrong shape, non-finite) raises ``ValueError`` when it is given, not when it is executed.

    Args:
        env: a (wrapped) ``Bounding-v0``. steps: the executed delay in control steps (>= 0; 0 is the identity).
        announced: the delay announced to policies in control steps (>= 0; None: ``steps``).
        jitter: half-width of the per-episode executed delay in control steps (0 <= jitter <= steps; 0: fixed).

    Attributes:
        action_delay_steps: the announced delay (policies that know their latency read it through
            ``env.get_wrapper_attr("action_delay_steps")``;
            [`EnvInterface`][hsddp_gym.planners.policies.base.EnvInterface] does).
        executed_delay_steps: the delay the current episode executes (``steps`` without ``jitter``).
    """

    SALT = 0xDE1A
    INFO_KEYS = ("executed_action",)
    """The ``info`` keys this wrapper adds ([`wrapper_info_keys`][wrapper_info_keys])."""

    def __init__(self, env: gym.Env, steps: int = 1, announced: int | None = None, jitter: int = 0) -> None:
        super().__init__(env)
        self.steps = check_int(steps, "steps", minimum=0)
        self.jitter = check_int(jitter, "jitter", minimum=0)
        if self.jitter > self.steps:
            raise ValueError(f"jitter must be <= steps ({self.steps}: a delay is never negative), got {jitter}")
        self.action_delay_steps = self.steps if announced is None else check_int(announced, "announced", minimum=0)
        self.executed_delay_steps = self.steps
        self._rng: np.random.Generator | None = None
        self._queue: collections.deque = collections.deque()

    def reset(self, *, seed=None, options=None):
        if self.jitter:
            if seed is not None or self._rng is None:
                self._rng = _episode_rng(self, seed, self.SALT)
            self.executed_delay_steps = self.steps + int(self._rng.integers(-self.jitter, self.jitter + 1))
        self._queue = collections.deque(np.zeros(NU, dtype=np.float32) for _ in range(self.executed_delay_steps))
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
"""The salt of the push generators ([`RandomPush`][RandomPush], the vector env's ``push``): an episode reset with seed
``s`` draws its pushes from ``SeedSequence([s, PUSH_SALT])``."""


@dataclasses.dataclass(frozen=True)
class PushDistribution:
    """The random pushes of an episode: ``count`` of them (default one) at random times, each a change of the
    trunk velocities by ``delta_v ~ U(-max_delta_v, max_delta_v)`` per component (``[dvx, dvz, dpitch_rate]``,
    m/s, m/s, rad/s, positive pitch rate nose-down). With one push its time is ``t ~ U(time_range)``; with
    ``count`` pushes ``time_range`` is cut into ``count`` equal slots and push ``j`` comes at a uniform time in
    slot ``j`` (so they come in order, one recovery apart on average). One definition for [`RandomPush`][RandomPush]
    and [`hsddp_gym.envs.vector.BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv]'s ``push`` argument, so
    both draw the same pushes.

    Args (validated, ``TypeError`` / ``ValueError`` naming the argument):
        time_range: ``(low, high)`` push times [s] (>= 0). max_delta_v: (3,) largest absolute velocity change per
        component (>= 0). count: pushes per episode (>= 1).
    """

    time_range: tuple = BOUND_PUSH_WINDOW
    max_delta_v: tuple = BOUND_PUSH_SIZE
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
        """``value`` as a distribution: a [`PushDistribution`][PushDistribution], or a dict of its fields (``{}``: the
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
    """Random pushes of a [`PushDistribution`][PushDistribution] (``count`` per episode, default one, at random times,
    each a random change of the trunk velocities) through the env's ``push`` reset option (a scheduled push, or a
    schedule of them). The pushes of the episode are ``info["push"]`` at reset and `last_push`: the reset option
    given to the env, ``{"delta_v": [3 floats], "time": t}`` for one push, a list of such dicts for several.
    Giving the ``push`` reset option yourself as well raises ``ValueError``.

    Args:
        env: a (wrapped) ``Bounding-v0``. time_range, max_delta_v, count: the [`PushDistribution`][PushDistribution].
    """

    SALT = PUSH_SALT
    INFO_KEYS = ("push",)
    """The ``info`` keys this wrapper adds (at reset; [`wrapper_info_keys`][wrapper_info_keys])."""

    def __init__(self, env: gym.Env, time_range=BOUND_PUSH_WINDOW, max_delta_v=BOUND_PUSH_SIZE, count: int = 1) -> None:
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


PUSH_PHASES = ("flight", "stance")
"""The contact phases a [`PhasePush`][PhasePush] can wait for: ``"flight"`` (no foot in contact), ``"stance"`` (one or
two feet in contact)."""


class PhasePush(gym.Wrapper):
    """One push per episode timed by the contact phase: a time ``t ~ U(time_range)`` and a change of the trunk
    velocities ``delta_v ~ U(-max_delta_v, max_delta_v)`` (``[dvx, dvz, dpitch_rate]``) are drawn at reset, and
    the push is applied at the end of the first control step that ends at or after ``t`` in the phase ``phase``:
    ``"flight"`` when the step's contact flags (``info["contact"]``, the last 1 ms simulation step) are all False,
    ``"stance"`` when at least one is True. It goes through the env's documented
    [`apply_push`][hsddp_gym.envs.bounding.BoundingEnv.apply_push]; the step returns the observation after the push (the
    policy sees the pushed velocities at once) and its ``info`` gains ``"push_applied"``: ``{"delta_v": [3
    floats], "time": t [s], "contact": [front, back]}`` (``info["qvel"]`` is updated to the pushed velocities).
    No push comes after a fall or the time limit, nor if the phase never comes. The draws are those of
    [`RandomPush`][RandomPush] with the same distribution (one push, seeded from ``(seed, PUSH_SALT)``): at a given seed
    only the moment differs. The episode's push is ``info["phase_push"]`` at reset (``{"delta_v": [...],
    "earliest_time": t, "phase": phase}``) and `last_push`; `applied` is the applied one or None.

    It must wrap the env below any observation wrapper ([`ObservationNoise`][ObservationNoise],
    [`ObservationBias`][ObservationBias], a ``gym.ObservationWrapper``): ``TypeError`` otherwise.

    Args:
        env: a (wrapped) ``Bounding-v0``. phase: one of [`PUSH_PHASES`][PUSH_PHASES].
        time_range: ``(low, high)`` [s] of the earliest push time. max_delta_v: (3,) [m/s, m/s, rad/s].
    """

    SALT = PUSH_SALT
    INFO_KEYS = ("phase_push", "push_applied")
    """The ``info`` keys this wrapper adds (``phase_push`` at reset, ``push_applied`` at the push's step;
    [`wrapper_info_keys`][wrapper_info_keys])."""

    def __init__(self, env: gym.Env, phase: str = "flight", time_range=BOUND_PUSH_WINDOW,
                 max_delta_v=(1.0, 1.0, 7.0)) -> None:
        super().__init__(env)
        if not isinstance(phase, str) or phase not in PUSH_PHASES:
            raise ValueError(f"phase must be one of {list(PUSH_PHASES)}, got {phase!r}")
        e = env
        while isinstance(e, gym.Wrapper):
            if isinstance(e, (ObservationNoise, ObservationBias, gym.ObservationWrapper)):
                raise TypeError(f"env: PhasePush must wrap the env below any observation wrapper, found "
                                f"{type(e).__name__} under it")
            e = e.env
        if not callable(getattr(env.unwrapped, "apply_push", None)):
            raise TypeError(f"env must be a Bounding-v0 env with apply_push, got {type(env.unwrapped).__name__}")
        self.phase = phase
        self.distribution = PushDistribution(time_range, max_delta_v, 1)
        self.time_range = self.distribution.time_range
        self.max_delta_v = self.distribution.max_delta_v
        self._rng: np.random.Generator | None = None
        self.last_push: dict | None = None
        self.applied: dict | None = None

    def _in_phase(self, contact) -> bool:
        touching = bool(np.any(contact))
        return touching if self.phase == "stance" else not touching

    def reset(self, *, seed=None, options=None):
        if seed is not None or self._rng is None:
            self._rng = _episode_rng(self, seed, self.SALT)
        push = self.distribution.draw(self._rng)[0]
        self.last_push = {"delta_v": push["delta_v"], "earliest_time": push["time"], "phase": self.phase}
        self.applied = None
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, dict(info, phase_push=copy.deepcopy(self.last_push))

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        u = self.env.unwrapped
        if (self.applied is None and self.last_push is not None and not (terminated or truncated)
                and u.time >= self.last_push["earliest_time"] - 1e-9 and self._in_phase(info["contact"])):
            obs = u.apply_push(self.last_push["delta_v"])
            self.applied = {"delta_v": list(self.last_push["delta_v"]), "time": float(u.time),
                            "contact": [bool(c) for c in info["contact"]]}
            info = dict(info, qvel=u.state[NQ:].copy(), push_applied=copy.deepcopy(self.applied))
        return obs, reward, terminated, truncated, info


CONTACT_SALT = 0xC0A7
"""The salt of [`RandomContactModel`][RandomContactModel]'s generator: an episode reset with seed ``s`` draws its
contact model from ``SeedSequence([s, CONTACT_SALT])``."""


class RandomContactModel(gym.Wrapper):
    """A contact model of the MuJoCo twin drawn per episode: at every reset a
    [`ContactModel`][hsddp_gym.envs.mujoco_twin.ContactModel] is drawn with
    [`ContactModel.sample`][hsddp_gym.envs.mujoco_twin.ContactModel.sample] from the episode's generator
    (seeded from ``(seed, CONTACT_SALT)``: the same seed gives the same model, whatever the policy) and set on the
    env ([`set_contact_model`][hsddp_gym.envs.mujoco_twin.MuJoCoBoundingEnv.set_contact_model]) before the env's own
    reset. The control period stays 5 ms (the env's ``frame_skip`` follows the model's time step). The episode's model
    is ``info["contact_model"]`` at reset (a dict of its fields) and `last_contact_model`.

    Args:
        env: a (wrapped) ``hsddp_gym/BoundingMuJoCo-v0`` (``TypeError`` otherwise).
    """

    SALT = CONTACT_SALT
    INFO_KEYS = ("contact_model",)
    """The ``info`` keys this wrapper adds (at reset; [`wrapper_info_keys`][wrapper_info_keys])."""

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


def wrapper_info_keys(env: gym.Env) -> frozenset:
    """The ``info`` keys the wrappers of ``env`` add to the unwrapped env's (their ``INFO_KEYS``): the keys a
    recorder drops to keep the env's own per-step schema (``push`` appears at reset only)."""
    keys: set = set()
    e = env
    while isinstance(e, gym.Wrapper):
        keys.update(getattr(e, "INFO_KEYS", ()))
        e = e.env
    return frozenset(keys)


def episode_perturbation(env: gym.Env) -> dict:
    """What the hardware wrappers of ``env`` did in the current episode, for the record of a run:
    ``{"announced_delay_steps", "executed_delay_steps"}`` of an [`ActionDelay`][ActionDelay], ``"observation_bias"``
    (``{name: offset}``) of an [`ObservationBias`][ObservationBias], ``"push_applied"`` (the applied push, or None) of a
    [`PhasePush`][PhasePush]; ``{}`` without such wrappers."""
    out: dict = {}
    e = env
    while isinstance(e, gym.Wrapper):
        if isinstance(e, ActionDelay):
            out.update(announced_delay_steps=e.action_delay_steps, executed_delay_steps=e.executed_delay_steps)
        elif isinstance(e, ObservationBias):
            out["observation_bias"] = {n: float(e.offset[e.entries[n]]) for n in e._names}
        elif isinstance(e, PhasePush):
            out["push_applied"] = copy.deepcopy(e.applied)
        e = e.env
    return out


def true_observation(env: gym.Env) -> np.ndarray:
    """The observation ``(layout.size,)`` float32 of the env's *true* current state (what the unwrapped env
    returned at the last reset/step, before any [`ObservationNoise`][ObservationNoise]), built from the public state,
    contact flags and clock of ``env.unwrapped``; for an env without observation noise it equals the
    observation the env returned."""
    from hsddp_gym.core.observation import build_observation

    u = env.unwrapped
    return build_observation(u.state, u.contact, u.time, u.gait_period, u.observation_layout)
