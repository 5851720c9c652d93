"""The MPC's perception for any policy: act on the filtered state, predicted over the actuation delay.

[`EstimatedStatePolicy`][EstimatedStatePolicy] wraps a policy (a learner, the heuristic, an SB3 model) in the two
estimation steps the MPC runs before it plans
([`hsddp_gym.planners.policies.estimation`][hsddp_gym.planners.policies.estimation]):

1. **state filter** ([`StateFilter`][hsddp_gym.planners.policies.estimation.StateFilter]): the observed positions and
   velocities are replaced by the Kalman estimate, propagated with the model and the torques the env executed;
2. **latency compensation**: with an action delay of ``d`` control steps (``EnvInterface.action_delay_steps``), the
   estimate is predicted ``d`` steps ahead under the actions already sent
   ([`ContactModelPredictor`][hsddp_gym.planners.policies.estimation.ContactModelPredictor]), with the contact flags the
   model predicts and the observation's gait clock advanced by ``d`` control periods.

The wrapped policy receives that as an ordinary observation (the env's layout) and acts as it would without noise
or delay: it is built for an undelayed env (its interface's ``action_delay_steps`` must be 0). With exact
observations and no delay the wrapper passes the state through unchanged (the filter's estimate is the observation
to round-off). The estimates use the nominal model: they know nothing of a push, another friction or another mass
(the filter's innovation test restarts from the measurement when the model misses by far more than the noise).
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, NU, Mode
from hsddp_gym.core.observation import fill_observation
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.estimation import ContactModelPredictor, StateFilter, queue_torques


def _checked_action(action) -> np.ndarray:
    a = np.array(action, dtype=np.float32)
    if a.shape != (NU,) or not np.all(np.isfinite(a)):
        raise ValueError(f"action must be a finite vector of shape ({NU},), got {a!r}")
    return a


@dataclasses.dataclass(frozen=True)
class EstimationOptions:
    """What [`EstimatedStatePolicy`][EstimatedStatePolicy] does before the wrapped policy acts.

    Attributes:
        state_filter: filter the observed state ([`StateFilter`][StateFilter]).
        latency_compensation: predict over the env's action delay.
        position_noise, velocity_noise, acceleration_noise, innovation_gate: the filter's noise model (None: the
            MPC's, ``MPCOptions().estimator``, so that one place sets them).
    """

    state_filter: bool = True
    latency_compensation: bool = True
    position_noise: float | None = None
    velocity_noise: float | None = None
    acceleration_noise: float | None = None
    innovation_gate: float | None = None

    def __post_init__(self) -> None:
        for name in ("state_filter", "latency_compensation"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be a bool, got {getattr(self, name)!r}")
        for name in ("position_noise", "velocity_noise", "acceleration_noise", "innovation_gate"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float, np.floating))
                                  or not math.isfinite(v) or v <= 0):
                raise ValueError(f"{name} must be a finite number > 0 or None, got {v!r}")

    def filter_noise(self) -> tuple[float, float, float, float]:
        """``(position, velocity, acceleration, innovation gate)`` in effect (the MPC's defaults for None)."""
        from hsddp_gym.planners.policies.mpc import MPCOptions

        d = MPCOptions().estimator
        pairs = ((self.position_noise, d.position_noise), (self.velocity_noise, d.velocity_noise),
                 (self.acceleration_noise, d.acceleration_noise), (self.innovation_gate, d.innovation_gate))
        return tuple(float(default if v is None else v) for v, default in pairs)


class EstimatedStatePolicy(Policy):
    """``inner`` acting on the filtered state predicted over the action delay (see the module docstring).

    Args:
        inner: the wrapped policy, built for the same env without its delay (``inner.interface`` equal to
            ``interface`` with ``action_delay_steps=0``: [`undelayed`][undelayed]; [`around`][around] builds and wraps
            it).
        interface: the env's interface (its ``action_delay_steps`` is the delay predicted over).
        options: [`EstimationOptions`][EstimationOptions].

    Attributes:
        last_estimate: the filtered state (14,) of the last observation; last_prediction: the state (14,) the inner
            policy was given (the estimate predicted over the delay; the estimate itself when the model's prediction
            diverges, counted in [`stats`][stats] as ``prediction_failures``).
    """

    def __init__(self, inner: Policy, interface: EnvInterface = EnvInterface(),
                 options: EstimationOptions = EstimationOptions()) -> None:
        super().__init__(interface)
        if not isinstance(inner, Policy):
            raise TypeError(f"inner must be a Policy, got {type(inner).__name__}")
        if not isinstance(options, EstimationOptions):
            raise TypeError(f"options must be an EstimationOptions, got {type(options).__name__}")
        if inner.interface.layout != interface.layout:
            raise ValueError("inner must act on the env's observation layout (inner.interface.layout differs)")
        if options.latency_compensation and inner.interface.action_delay_steps:
            raise ValueError(f"inner must be built for an undelayed env (inner.interface.action_delay_steps="
                             f"{inner.interface.action_delay_steps}): it acts on the state predicted over the delay")
        self.inner = inner
        self.options = options
        self.delay = int(interface.action_delay_steps) if options.latency_compensation else 0
        self._make_models()
        self.reset()

    @staticmethod
    def undelayed(interface: EnvInterface) -> EnvInterface:
        """The interface to build the inner policy with: ``interface`` without its action delay."""
        return dataclasses.replace(interface, action_delay_steps=0)

    @classmethod
    def around(cls, build_inner, interface: EnvInterface, options: EstimationOptions = EstimationOptions()):
        """``build_inner(interface) -> Policy`` called with [`undelayed`][undelayed] ``interface``, wrapped for
        ``interface`` (e.g. ``EstimatedStatePolicy.around(HeuristicPolicy, EnvInterface.from_env(env))``)."""
        return cls(build_inner(cls.undelayed(interface)), interface, options)

    def _make_models(self) -> None:
        i = self.interface
        # one model for both: every step of it starts from the state it is given
        self._predictor = ContactModelPredictor(i.control_dt, motor_speed_limits=i.motor_speed_limits,
                                                torque_limit=i.torque_limit)
        pos, vel, acc, gate = self.options.filter_noise()
        self._filter = StateFilter(self._predictor, pos, vel, acc, gate)
        self._obs = np.empty(i.layout.size, dtype=np.float32)

    def _reset_copy_state(self) -> None:
        self.inner = self.inner.spawn()
        self._make_models()

    def reset(self) -> None:
        self.inner.reset()
        self._filter.reset()
        # the env's action delay executes zeros first; the oldest entry was executed over the last control period
        self._sent = collections.deque((np.zeros(NU, dtype=np.float32) for _ in range(self.delay + 1)),
                                       maxlen=self.delay + 1)
        self._first = True
        self._prediction_failures = 0
        self.last_estimate: np.ndarray | None = None
        self.last_prediction: np.ndarray | None = None

    def observation_for_inner(self, obs: np.ndarray) -> np.ndarray:
        """The observation (layout size,) float32 the inner policy acts on for the env's ``obs``; advances the
        filter (call once per step, as `act` does)."""
        i = self.interface
        x, mode, phase = self._parse(obs)
        if self.options.state_filter:
            executed = None if self._first else queue_torques(self._sent[0], i.torque_limit)[0]
            x = self._filter.update(x, mode, executed)
        self._first = False
        self.last_estimate = x.copy()
        if self.delay:
            try:
                x, predicted = self._predictor.predict(x, mode, queue_torques(list(self._sent)[1:], i.torque_limit))
                mode = Mode(predicted)
            except (ArithmeticError, ValueError, RuntimeError):
                self._prediction_failures += 1  # a diverging prediction: act on the estimate itself
        self.last_prediction = x.copy()
        if not self.options.state_filter and not self.delay:
            return np.asarray(obs, dtype=np.float32)
        cycles = phase + self.delay * i.control_dt / i.gait_period
        fill_observation(self._obs, x, mode.in_contact(FRONT), mode.in_contact(BACK), cycles,
                         i.layout.exclude_current_positions)
        return self._obs.copy()

    def act(self, obs: np.ndarray) -> np.ndarray:
        action = np.asarray(self.inner.act(self.observation_for_inner(obs)), dtype=np.float32)
        self.record_sent(action)
        return action

    def record_sent(self, action) -> None:
        """The action (4,) sent to the env this step, for a caller that calls
        [`observation_for_inner`][observation_for_inner] and acts itself (a DAgger rollout storing what the learner
        sees); `act` records its own."""
        self._sent.append(_checked_action(action))

    def note_sent_action(self, action) -> None:
        """The action (4,) actually sent in place of the last one returned (DART noise, a DAgger mixture): the filter
        and the prediction use it; the inner policy is told too when it listens."""
        a = _checked_action(action)
        self._sent[-1] = a
        note = getattr(self.inner, "note_sent_action", None)
        if note is not None:
            note(a.copy())

    @property
    def stats(self) -> dict:
        """Since the last reset: the filter's restarts (the innovation test) and the predictions over the delay that
        diverged (the inner policy then got the estimate itself)."""
        return {"filter_restarts": int(self._filter.restarts), "prediction_failures": self._prediction_failures}
