"""The policy protocol: [`EnvInterface`][EnvInterface] (the env settings a policy may read) and the [`Policy`][Policy]
base class."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from hsddp_gym.core.conventions import NU, Mode
from hsddp_gym.core.observation import DEFAULT_LAYOUT, ObservationLayout, state_from_observation
from hsddp_gym.util.validation import check_int, check_positive


@dataclasses.dataclass(frozen=True)
class EnvInterface:
    """The public settings of the environment a policy acts in.

    Attributes:
        control_dt: control period of one env step [s] (``frame_skip * sim_timestep``).
        torque_limit: torque of a normalized action of 1 [N m].
        layout: the observation layout.
        gait_period: period of the observation's phase clock [s].
        target_speed: the env's desired forward speed [m/s].
        action_delay_steps: control steps between an action's return and its execution (the env's known
            actuation latency, e.g.
            [`hsddp_gym.envs.perturbations.ActionDelay`][hsddp_gym.envs.perturbations.wrappers.ActionDelay]; 0: none).
        motor_speed_limits: the env's motor torque-speed limit ``(w_full, w_zero)`` [rad/s], or None.
    """

    control_dt: float = 0.005
    torque_limit: float = 33.0
    layout: ObservationLayout = DEFAULT_LAYOUT
    gait_period: float = 0.296
    target_speed: float = 1.0
    action_delay_steps: int = 0
    motor_speed_limits: tuple | None = (36.0, 50.0)

    def __post_init__(self) -> None:
        check_positive(self.control_dt, "control_dt")
        check_positive(self.torque_limit, "torque_limit")
        check_positive(self.gait_period, "gait_period")
        check_int(self.action_delay_steps, "action_delay_steps", minimum=0)
        m = self.motor_speed_limits
        if m is not None and (not isinstance(m, tuple) or len(m) != 2 or not 0 < m[0] < m[1]):
            raise ValueError(f"motor_speed_limits must be None or a tuple (w_full, w_zero) with 0 < w_full < w_zero "
                             f"[rad/s], got {m!r}")
        if not isinstance(self.layout, ObservationLayout):
            raise TypeError(f"layout must be an ObservationLayout, got {type(self.layout).__name__}")

    @classmethod
    def from_env(cls, env) -> EnvInterface:
        """Read the settings of a (possibly wrapped) ``Bounding-v0`` env (the action delay from a wrapper's
        ``action_delay_steps`` attribute, 0 without one)."""
        u = env.unwrapped
        try:
            delay = int(env.get_wrapper_attr("action_delay_steps"))
        except AttributeError:
            delay = 0
        return cls(control_dt=float(u.dt), torque_limit=float(u.torque_limit), layout=u.observation_layout,
                   gait_period=float(u.gait_period), target_speed=float(u.target_speed), action_delay_steps=delay,
                   motor_speed_limits=getattr(u.sim, "motor_speed_limits", None))

    def action_from_torque(self, u: np.ndarray) -> np.ndarray:
        """Normalized action (4,) float32 from torques [N m] (clipped to the box)."""
        return np.clip(np.asarray(u, dtype=np.float64) / self.torque_limit, -1.0, 1.0).astype(np.float32)


class Policy:
    """Base class: subclasses implement [`act`][act] (one env) and [`reset`][reset]."""

    def __init__(self, interface: EnvInterface = EnvInterface()) -> None:
        if not isinstance(interface, EnvInterface):
            raise TypeError(f"interface must be an EnvInterface, got {type(interface).__name__}")
        self.interface = interface
        self._copies: list[Policy] = []

    @classmethod
    def from_env(cls, env, **kwargs):
        """Build the policy for ``env`` (reads its [`EnvInterface`][EnvInterface])."""
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
        """The ``n`` per-env copies used by [`predict`][predict] (override to make copy 0 act like ``self``)."""
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
