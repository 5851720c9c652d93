"""Policies that act on ``hsddp_gym/Bounding-v0`` from observations only.

Every policy here is

* a plain callable ``policy(obs) -> action`` for one environment (``obs`` ``(obs_dim,)``, ``action`` ``(4,)``
  float32 normalized torques in ``[-1, 1]``), with its own memory (``reset()`` starts a new episode);
* a Stable-Baselines3 ``predict(observation, state=None, episode_start=None, deterministic=True) ->
  (actions, state)`` predictor (batched ``(n_envs, obs_dim)`` in, ``(n_envs, 4)`` out; one independent copy
  of the policy per environment, reset where ``episode_start`` is true), so ``evaluate_policy`` runs it;
* convertible into an SB3 ``BasePolicy`` with :func:`planners.sb3.as_sb3_policy` for imitation tooling.

Policies never look inside the simulator: they map the observation back to a state, contact mode and gait
phase with :func:`hsddp_gym.observation.state_from_observation` and use the env's public settings (control
period, torque limit, observation layout) given at construction (``Policy.from_env(env)`` reads them).
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from hsddp_gym.conventions import BACK, FRONT, NU, Mode
from hsddp_gym.observation import DEFAULT_LAYOUT, ObservationLayout, state_from_observation
from hsddp_gym.validation import check_positive
from planners.heuristic import (
    ContactEventBoundingController,
    ContactEventGains,
    HeuristicBoundingController,
    HeuristicGains,
)


@dataclasses.dataclass(frozen=True)
class EnvInterface:
    """The public settings of the environment a policy acts in.

    Attributes:
        control_dt: control period of one env step [s] (``frame_skip * sim_timestep``).
        torque_limit: torque of a normalized action of 1 [N m].
        layout: the observation layout.
        gait_period: period of the observation's phase clock [s].
        target_speed: the env's desired forward speed [m/s].
    """

    control_dt: float = 0.005
    torque_limit: float = 33.0
    layout: ObservationLayout = DEFAULT_LAYOUT
    gait_period: float = 0.296
    target_speed: float = 1.0

    def __post_init__(self) -> None:
        check_positive(self.control_dt, "control_dt")
        check_positive(self.torque_limit, "torque_limit")
        check_positive(self.gait_period, "gait_period")
        if not isinstance(self.layout, ObservationLayout):
            raise TypeError(f"layout must be an ObservationLayout, got {type(self.layout).__name__}")

    @classmethod
    def from_env(cls, env) -> EnvInterface:
        """Read the settings of a (possibly wrapped) ``Bounding-v0`` env."""
        u = env.unwrapped
        return cls(control_dt=float(u.dt), torque_limit=float(u.torque_limit), layout=u.observation_layout,
                   gait_period=float(u.gait_period), target_speed=float(u.target_speed))

    def action_from_torque(self, u: np.ndarray) -> np.ndarray:
        """Normalized action (4,) float32 from torques [N m] (clipped to the box)."""
        return np.clip(np.asarray(u, dtype=np.float64) / self.torque_limit, -1.0, 1.0).astype(np.float32)


class Policy:
    """Base class: subclasses implement :meth:`act` (one env) and :meth:`reset`."""

    def __init__(self, interface: EnvInterface = EnvInterface()) -> None:
        if not isinstance(interface, EnvInterface):
            raise TypeError(f"interface must be an EnvInterface, got {type(interface).__name__}")
        self.interface = interface
        self._copies: list[Policy] = []

    @classmethod
    def from_env(cls, env, **kwargs):
        """Build the policy for ``env`` (reads its :class:`EnvInterface`)."""
        return cls(interface=EnvInterface.from_env(env), **kwargs)

    # -------------------------------------------------------------- single env
    def reset(self) -> None:
        """Forget the episode (called at the start of each episode)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Action (4,) float32 for one observation."""
        raise NotImplementedError

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs)

    def _parse(self, obs) -> tuple[np.ndarray, Mode, float]:
        return state_from_observation(obs, self.interface.layout)

    # -------------------------------------------------------------- SB3 protocol
    def spawn(self) -> Policy:
        """An independent copy with fresh memory (one per vectorized environment)."""
        twin = copy.copy(self)
        twin._copies = []
        twin._reset_copy_state()
        twin.reset()
        return twin

    def _reset_copy_state(self) -> None:
        """Give a shallow copy its own mutable memory (override when the memory holds arrays/objects)."""

    def _spawn_copies(self, n: int) -> list[Policy]:
        """The ``n`` per-env copies used by :meth:`predict` (override to make copy 0 act like ``self``)."""
        return [self.spawn() for _ in range(n)]

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3 ``PolicyPredictor`` protocol: batched or single observations, one policy copy per env."""
        obs = np.asarray(observation)
        single = obs.ndim == 1
        batch = obs[None] if single else obs
        if batch.ndim != 2 or batch.shape[1] != self.interface.layout.size:
            raise ValueError(f"observation must have shape ({self.interface.layout.size},) or "
                             f"(n_envs, {self.interface.layout.size}), got {obs.shape}")
        n = batch.shape[0]
        fresh = len(self._copies) != n
        if fresh:
            self._copies = self._spawn_copies(n)
        starts = np.ones(n, dtype=bool) if episode_start is None and fresh else (
            np.zeros(n, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(n))
        actions = np.empty((n, NU), dtype=np.float32)
        for i in range(n):
            if starts[i] and not fresh:
                self._copies[i].reset()
            actions[i] = self._copies[i].act(batch[i])
        return (actions[0] if single else actions), state


class RandomPolicy(Policy):
    """Uniform random actions from a seeded generator (``seed``); ``reset`` keeps the stream going.

    Through :meth:`predict` (and the SB3 adapter) env 0 continues this policy's stream from its current
    state -- the same actions as calling the policy -- without advancing it, and env ``k >= 1`` draws from
    the independent stream ``SeedSequence(entropy of seed, spawn_key=(k,))``.
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), seed: int | None = 0) -> None:
        super().__init__(interface)
        self.seed = seed
        self._seed_seq = np.random.SeedSequence(seed)
        self._rng = np.random.default_rng(self._seed_seq)

    def _reset_copy_state(self) -> None:
        self._rng = copy.deepcopy(self._rng)  # its own generator (the parent's stream is not advanced)

    def _spawn_copies(self, n: int) -> list[Policy]:
        copies = []
        for k in range(n):
            twin = self.spawn()
            twin._rng = copy.deepcopy(self._rng) if k == 0 else np.random.default_rng(
                np.random.SeedSequence(self._seed_seq.entropy, spawn_key=(k,)))
            copies.append(twin)
        return copies

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self._rng.uniform(-1.0, 1.0, NU).astype(np.float32)


class HeuristicPolicy(Policy):
    """The heuristic bounding controller driven by the env's contact flags.

    It acts with :class:`planners.heuristic.ContactEventBoundingController` (``self.gait``): a per-leg
    stance/swing state machine started by the observed touchdowns, with a fixed stance time after which the
    leg is actively folded, a wrench-based stance force (height, speed, bounding pitch rate) and Raibert
    foot placement. The observation's contact flags and the policy's own timers are its only gait inputs
    (the gait clock is not used).

    ``self.controller`` is the schedule-driven :class:`~planners.heuristic.HeuristicBoundingController`
    (the planner's warm start, ``torque(x, mode)``), kept for callers that supply the contact mode from a
    schedule (e.g. the MPC's fallback); it is not used by :meth:`act`.

    Args:
        gains: :class:`HeuristicGains` of ``self.controller`` (the desired speed defaults to the env's
            target speed).
        gait_gains: :class:`ContactEventGains` of ``self.gait`` (default: tuned for the env's defaults, with
            the env's target speed and torque limit).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), gains: HeuristicGains | None = None,
                 gait_gains: ContactEventGains | None = None) -> None:
        super().__init__(interface)
        gains = gains if gains is not None else HeuristicGains(speed=interface.target_speed)
        self.controller = HeuristicBoundingController(gains=gains)
        gait_gains = gait_gains if gait_gains is not None else ContactEventGains(
            speed=interface.target_speed, torque_limit=interface.torque_limit)
        self.gait = ContactEventBoundingController(interface.control_dt, robot=self.controller.robot,
                                                   gains=gait_gains)

    def _reset_copy_state(self) -> None:
        self.gait = copy.copy(self.gait)

    def reset(self) -> None:
        self.gait.reset()

    def act(self, obs: np.ndarray) -> np.ndarray:
        x, mode, _ = self._parse(obs)
        u = self.gait.torque(x, (mode.in_contact(FRONT), mode.in_contact(BACK)))
        return self.interface.action_from_torque(u)


class PlanTrackingExpert(Policy):
    """Tracks one HS-DDP plan with its feedback law ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0).

    The plan's cursor advances by the env's control period and is kept in step with the env's contact
    events by :class:`planners.tracking.PlanTracker` (early touchdown: jump to the next phase; late
    touchdown: wait on the flight phase's last knot; lift-off: plan time). The plan should start at the
    env's initial state (e.g. ``options={"state": plan.X[0]}`` at reset). When the plan ends (the touchdown
    after its last flight, or its last knot) the expert hands over to ``fallback``.

    Args:
        solution: a :class:`~planners.solution.Solution`.
        fallback: policy used after the plan ends (None: HS-DDP MPC with default options,
            :class:`planners.mpc.MPCPolicy`, which picks up the gait from the observed contacts).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, fallback: Policy | None = None
                 ) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError("solution must be a Solution (the plan to track)")
        self.solution = solution
        if fallback is None:
            from planners.mpc import MPCPolicy  # planners.mpc imports this module

            fallback = MPCPolicy(interface)
        self.fallback = fallback
        self.tracker = None
        self.errors: list[float] = []
        """Per control step while tracking: :func:`planners.tracking.tracking_error` to the plan."""
        self.nominal_states: list[np.ndarray] = []
        """Per control step while tracking: the plan's state (14,) at the cursor the action came from."""
        self.reset()

    def _reset_copy_state(self) -> None:
        self.fallback = self.fallback.spawn()

    def reset(self) -> None:
        from planners.tracking import PlanTracker

        self.tracker = PlanTracker.from_solution(self.solution)
        self.errors = []
        self.nominal_states = []
        self.fallback.reset()

    @property
    def stats(self) -> dict | None:
        """The fallback's planner statistics (replans, failures, solve times), if it has any."""
        return getattr(self.fallback, "stats", None)

    @property
    def last_solution(self):
        """The fallback's latest plan, if it plans."""
        return getattr(self.fallback, "last_solution", None)

    def act(self, obs: np.ndarray) -> np.ndarray:
        from planners.tracking import tracking_error

        x, mode, _ = self._parse(obs)
        if self.tracker.finished:
            return self.fallback.act(obs)
        self.tracker.sync(mode)
        x_nom, _ = self.tracker.nominal()
        self.errors.append(tracking_error(x, x_nom))
        self.nominal_states.append(x_nom)
        u = self.tracker.control(x)
        self.tracker.advance(self.interface.control_dt)
        return self.interface.action_from_torque(u)
