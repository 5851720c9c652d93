"""The MPC's state estimator: from an observation to the state its plans start from.

Every control step [`StateEstimator.update`][StateEstimator.update] takes the state the observation gives
([`state_from_observation`][hsddp_gym.core.observation.state_from_observation]) and

1. on a terrain without the trunk x in the observation, puts in the trunk x integrated from the measured forward
   speed (the motion MPC's: less the speed's bias the feet on the ground show,
   [`StateEstimator.trunk_x`][StateEstimator.trunk_x]);
2. folds it into the estimate of a constant sensor bias of the trunk height and pitch from the feet on the ground
   ([`MeasurementBias`][hsddp_gym.planners.policies.estimation.MeasurementBias]; once calibrated, its height is where
   the model puts the ground, [`StateEstimator.model_ground`][StateEstimator.model_ground]); the motion MPC then
   subtracts the forward-speed bias from the state ([`StateEstimator.corrected`][StateEstimator.corrected]);
3. re-estimates the executed action delay from the robot's response to the actions already sent
   ([`DelayEstimator`][hsddp_gym.planners.policies.latency.DelayEstimator]);
4. filters it with the contact model under the executed torque
   ([`StateFilter`][hsddp_gym.planners.policies.estimation.StateFilter]);
5. folds it and the executed torque into the estimate of the trunk's mass
   ([`MassEstimate`][hsddp_gym.planners.policies.estimation.MassEstimate]; the motion MPC plans with it).

[`StateEstimator.predict`][StateEstimator.predict] then steps the estimate over the action delay under the actions sent
and not yet
executed (latency compensation): the plan and its feedback law are for the state at which the action will act.
"""

from __future__ import annotations

import collections

import numpy as np

from hsddp_gym.core.conventions import IVX, IZ, NU, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.estimation import (
    ContactModelPredictor,
    MassEstimate,
    MeasurementBias,
    Odometry,
    StateFilter,
)
from hsddp_gym.planners.policies.latency import DelayEstimator
from hsddp_gym.planners.policies.mpc.options import EstimatorOptions

PREDICTION_ERRORS = (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError)
"""What a model step may raise on a state far from any the model can step: the prediction is then not used."""


class StateEstimator:
    """Filter, bias estimate, delay estimate and prediction over the delay (see the module docstring).

    Args:
        interface: the env's public settings (control period, torque limit, motor limits, layout, announced delay).
        options: [`EstimatorOptions`][hsddp_gym.planners.policies.mpc.options.EstimatorOptions].
        robot: the model whose kinematics the bias estimate uses.
        correct_bias: subtract the forward-speed bias the feet on the ground show from the state and from the odometry's
            trunk x ([`corrected`][corrected]; False, the bounding MPC's: the speed bias is then not estimated; the
            motion MPC's ``MotionOptions.bias_correction``).
        estimate_mass: estimate the trunk's mass from the stances (False, the bounding MPC's: ``mass`` is None; the
            motion MPC's ``MotionOptions.mass_estimate``).

    Attributes:
        announced_delay: the action delay the env announces [control steps].
        action_delay: the delay compensated for: the announced one, or its online estimate (``delay_search``).
        bias: the sensor-bias estimate (a ``MeasurementBias``; None without ``bias_memory``).
        odometry: the trunk x on a terrain and, with ``correct_bias``, the forward-speed bias (an ``Odometry``, its
            memory ``bias_memory``).
        mass: the trunk-mass estimate (a ``MassEstimate``; None without ``estimate_mass``).
        correct_bias: the argument.
        delay_changes: how often the delay estimate moved since [`reset`][reset].
    """

    def __init__(self, interface: EnvInterface, options: EstimatorOptions, robot: CheetahModel,
                 correct_bias: bool = False, estimate_mass: bool = False) -> None:
        if not isinstance(options, EstimatorOptions):
            raise TypeError(f"options must be an EstimatorOptions, got {type(options).__name__}")
        for name, value in (("correct_bias", correct_bias), ("estimate_mass", estimate_mass)):
            if not isinstance(value, bool):
                raise TypeError(f"{name} must be a bool, got {value!r}")
        self.interface = interface
        self.options = options
        self.robot = robot
        self.announced_delay = int(interface.action_delay_steps)
        o = options
        self._delay_estimator = DelayEstimator(self._predictor(), self.announced_delay, o.delay_search) \
            if o.delay_search > 0 else None
        self._prediction = self._predictor()
        self._filter = StateFilter(self._predictor(), o.position_noise, o.velocity_noise, o.acceleration_noise,
                                   o.innovation_gate, o.restart_steps)
        self.bias = None if o.bias_memory is None else \
            MeasurementBias(self.robot, self.interface.control_dt, o.bias_memory)
        self.correct_bias = correct_bias
        self.odometry = Odometry(self.robot, self.interface.control_dt, o.bias_memory if correct_bias else None)
        self.mass = MassEstimate(self.robot, self.interface.control_dt) if estimate_mass else None

    def _predictor(self) -> ContactModelPredictor:
        i = self.interface
        return ContactModelPredictor(i.control_dt, motor_speed_limits=i.motor_speed_limits,
                                     torque_limit=i.torque_limit)

    def reset(self, terrain=None) -> None:
        """Start an episode on ``terrain`` (a [`Terrain`][hsddp_gym.core.terrain.Terrain], None: flat ground)."""
        self.action_delay = self.announced_delay
        history = self._delay_estimator.history if self._delay_estimator is not None else self.announced_delay + 1
        if self._delay_estimator is not None:
            self._delay_estimator.reset()
        # the last actions returned (oldest first), as many as the largest delay considered + 1: with a delay d,
        # sent[-1 - d] was executed over the last control period and the d after it are still to be executed (zeros
        # before the first ones, as the env's delay queue)
        self.sent = collections.deque((np.zeros(NU, dtype=np.float32) for _ in range(history)), maxlen=history)
        self._last_observed: np.ndarray | None = None
        self._filter.reset()
        if self.bias is not None:
            self.bias.reset()
        self.terrain = terrain
        for predictor in (self._prediction, self._filter.predictor,
                          None if self._delay_estimator is None else self._delay_estimator.predictor):
            if predictor is not None:
                predictor.set_terrain(terrain)
        if self.bias is not None:
            self.bias.terrain = terrain
        self.odometry.reset()
        if self.mass is not None:
            self.mass.reset()
        self._first = True
        self.delay_changes = 0

    # ------------------------------------------------------------------ the estimate
    def model_ground(self) -> float:
        """The height [m] of the ground the model stands on, in the measurement's frame: the calibrated height bias
        (where the feet on the ground put it), 0 before the calibration or without a bias estimate."""
        bias = self.bias
        return float(bias.bias[IZ]) if bias is not None and bias.calibrated else 0.0

    def trunk_x(self, x_obs: np.ndarray, mode: Mode) -> np.ndarray:
        """Fold ``x_obs`` (14,) into the [`Odometry`][hsddp_gym.planners.policies.estimation.Odometry]; on a terrain,
        without the trunk x in the observation, return ``x_obs`` with its x set to the odometry's (a new array; the MPC
        needs to know where it is on the terrain): the measured forward speed integrated since the first observation
        (at x = 0, the env's start up to its reset noise), with ``correct_bias`` less the speed's bias the
        feet on the ground show."""
        self.odometry.update(x_obs, mode)
        if self.terrain is None or not self.interface.layout.exclude_current_positions:
            return x_obs
        x_obs = x_obs.copy()
        x_obs[0] = self.odometry.x  # (without correct_bias the bias is not estimated: x is the plain integral)
        return x_obs

    def corrected(self, x_obs: np.ndarray) -> np.ndarray:
        """``x_obs`` (14,) less the estimated forward-speed bias, a new array (the height bias is left to
        [`model_ground`][model_ground]; the pitch bias is not taken off: the feet that estimate it on a compliant or
        round-footed contact read their sinking or rolling as a pitch, and taking it off lost more than it gained)."""
        x_obs = x_obs.copy()
        x_obs[IVX] -= self.odometry.speed_bias
        return x_obs

    def update(self, x_obs: np.ndarray, mode: Mode) -> np.ndarray:
        """The estimate (14,) from the observed state ``x_obs`` (14,) and contact ``mode`` (steps 1-4 of the module
        docstring; with ``correct_bias``, the state [`corrected`][corrected] after step 2)."""
        x_obs = self.trunk_x(x_obs, mode)
        if self.bias is not None:
            self.bias.update(x_obs, mode)
        if self.correct_bias:
            x_obs = self.corrected(x_obs)
        ground = self.model_ground()
        torque_limit = self.interface.torque_limit
        if self._delay_estimator is not None:
            if self._last_observed is not None:
                torques = np.array(self.sent, dtype=np.float64) * torque_limit
                delay = self._delay_estimator.update(self._last_observed, x_obs, torques, ground)
                if delay != self.action_delay:
                    self.delay_changes += 1
                    self.action_delay = delay
            self._last_observed = x_obs.copy()
        executed = None if self._first else self.sent[-1 - self.action_delay].astype(np.float64) * torque_limit
        self._first = False
        x = self._filter.update(x_obs, mode, executed, ground)
        if self.mass is not None:
            self.mass.update(x_obs, executed, mode)
        return x

    def predict(self, x: np.ndarray, mode: Mode) -> list[tuple[np.ndarray, Mode]] | None:
        """The states (14,) and contact modes of the ``action_delay`` control steps after the estimate ``x`` (14,) in
        contact ``mode``, under the actions sent and not yet executed, on [`model_ground`][model_ground]:
        ``[(x_1, mode_1), ...]`` (empty without a delay); None when the model cannot step the state
        ([`PREDICTION_ERRORS`][PREDICTION_ERRORS])."""
        out = []
        if not self.action_delay:
            return out
        ground = self.model_ground()
        torque_limit = self.interface.torque_limit
        try:
            for a in list(self.sent)[len(self.sent) - self.action_delay:]:  # the actions still to be executed
                x, mode = self._prediction.step(x, a.astype(np.float64) * torque_limit, mode, ground)
                out.append((x, mode))
        except PREDICTION_ERRORS:
            return None
        return out

    # ------------------------------------------------------------------ the actions sent
    def record_sent(self, action: np.ndarray) -> None:
        """The normalized action (4,) just returned to the env."""
        self.sent.append(action)

    def replace_sent(self, action) -> None:
        """The env was sent ``action`` (4,) in place of the last one returned (a learner's action, a noisy one)."""
        a = np.asarray(action, dtype=np.float32)
        if a.shape != (NU,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be a finite vector of shape ({NU},), got {a!r}")
        self.sent[-1] = a.copy()
