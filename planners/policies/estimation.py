"""State estimation for a policy that knows its model: latency prediction and a contact-aware velocity filter.

* :class:`ContactModelPredictor` integrates the nominal robot with the state-based contact model
  (:class:`~hsddp_gym.core.contact.ContactSimulator`: impacts, friction, lift-offs) over a few control steps
  under known torques.
* :meth:`ContactModelPredictor.predict` over the actions already sent but not yet executed gives the state at
  the moment a new action will act: the MPC's latency compensation.
* :class:`VelocityFilter`: a fixed-gain (steady-state Kalman-like) observer: the estimate is propagated one
  control step with the model and the executed torques, then corrected toward the measurement,
  ``x = x_prior + L (y - x_prior)`` with separate gains for positions and velocities. The contact flags of the
  observation (clean) set the prior's mode; at a measured mode change the correction is complete for the
  velocities (the impact is where the model is least sure).
"""

from __future__ import annotations

import math

import numpy as np

from hsddp_gym.core.contact import ContactSimulator
from hsddp_gym.core.conventions import NQ, NU, NX, Mode, mode_from_contacts
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.util.validation import check_in_range, check_positive, check_vector


class ContactModelPredictor:
    """Forward prediction with the model: the nominal robot in the state-based contact model of
    :class:`~hsddp_gym.core.contact.ContactSimulator` (rigid bodies, inelastic impacts, Coulomb friction with the
    nominal ``mu``, lift-offs decided by the contact LCP, the motors' torque-speed limit), the physics the policy
    believes in. It knows nothing of the env's actual friction, masses or pushes.

    Args:
        control_dt: control period [s] (one torque vector is held for it).
        substep: integration step [s] (default 1 ms, the env's simulation step); the control period is split
            into ``ceil(control_dt / substep)`` equal steps.
        robot: the model (default: the nominal robot). friction: the model's Coulomb coefficient (default: the
            robot's, 0.6).
        motor_speed_limits: ``(w_full, w_zero)`` [rad/s], the torque-speed limit (a torque driving its joint
            faster than ``w_full`` is cut linearly to 0 at ``w_zero``), or None (ideal torque sources).
        torque_limit: the torque the speed limit scales [N m].
    """

    def __init__(self, control_dt: float, substep: float = 1e-3, robot: CheetahModel | None = None,
                 friction: float | None = None, motor_speed_limits=(36.0, 50.0), torque_limit: float = 33.0) -> None:
        self.control_dt = check_positive(control_dt, "control_dt")
        substep = check_positive(substep, "substep")
        self.n_sub = max(1, math.ceil(self.control_dt / substep - 1e-9))
        self.sim = ContactSimulator(robot, timestep=self.control_dt / self.n_sub, friction=friction,
                                    motor_speed_limits=motor_speed_limits, torque_limit=torque_limit)
        self.robot = self.sim.robot

    def step(self, x: np.ndarray, u: np.ndarray, mode: Mode | None = None) -> tuple[np.ndarray, Mode]:
        """One control period from ``x`` (14,) under torques ``u`` (4,) [N m]: ``(x_next (14,), contact mode at
        the end)``. The contacts follow from the state (``mode`` is accepted for symmetry and not needed)."""
        sim = self.sim
        sim.set_state(x)
        sim.run(np.asarray(u, dtype=np.float64), self.n_sub)
        x_next = sim.x.copy()
        if not np.all(np.isfinite(x_next)):
            raise ArithmeticError("the model prediction diverged")
        return x_next, mode_from_contacts(bool(sim.contact[0]), bool(sim.contact[1]))

    def predict(self, x: np.ndarray, mode: Mode | None, torques) -> tuple[np.ndarray, Mode | None]:
        """The state after holding each row of ``torques`` (n, 4) [N m] for one control period, from ``x`` (14,):
        ``(x (14,), contact mode)`` (``(x, mode)`` itself for n = 0)."""
        x = check_vector(x, NX, "x").copy()
        for u in torques:
            x, mode = self.step(x, np.asarray(u, dtype=np.float64), mode)
        return x, mode


CONTACT_TOLERANCE = 1e-4
"""Feet in contact within this distance [m] of the ground are left where they are (the env's own contact
resolution leaves micrometres)."""


def project_onto_contacts(robot: CheetahModel, x: np.ndarray, mode: Mode) -> np.ndarray:
    """``x`` (14,) with its trunk height (and, for two feet, pitch) moved so that the feet in contact in ``mode`` are
    on the ground (one Gauss-Newton step on the feet's heights; a copy), unless they all are within
    :data:`CONTACT_TOLERANCE` of it."""
    x = np.array(x, dtype=np.float64)
    feet = [f for f in (0, 1) if Mode(mode).in_contact(f)]
    if not feet:
        return x
    heights = [robot.foot_height(x[:NQ], f) for f in feet]  # the common case needs no derivatives
    if max(abs(g) for g in heights) <= CONTACT_TOLERANCE:
        return x
    if len(feet) == 1:
        x[1] -= heights[0]
        return x
    A = np.array([[g[1], g[2]] for _, g, _ in (robot.foot_height_derivatives(x[:NQ], f) for f in feet)])
    h = np.array(heights)
    try:
        dz, dpitch = np.linalg.solve(A, -h)
    except np.linalg.LinAlgError:
        return x
    x[1] += dz
    x[2] += dpitch
    return x


class VelocityFilter:
    """Fixed-gain observer of the state from noisy observations (see the module docstring).

    Each observation ``y`` (14,) is compared with the prior ``x_prior`` (the previous estimate propagated one
    control period with the model and the torque the env executed); the estimate is
    ``x = x_prior + L (y - x_prior)`` per component, with ``L = position_gain`` for positions and
    ``velocity_gain`` for velocities, except that an innovation ``|y - x_prior|`` beyond ``position_gate`` /
    ``velocity_gate`` (far more than sensor noise: the model is wrong, e.g. a slip, a push, another friction or
    mass) is taken whole (``L = 1``), as is every velocity when the observed contact mode differs from the
    predicted one (an impact the model placed elsewhere). The feet the (clean) contact flags report on the
    ground are put on it (:func:`project_onto_contacts`: trunk height, and pitch for two feet), so that the
    prior's contact model neither lifts nor sinks them through noise in the measured heights and angles. With
    exact observations and the exact model the estimate is the observation (to round-off).

    Args:
        predictor: the model used for the prior.
        position_gain, velocity_gain: the correction gains in (0, 1] (1: no filtering).
        position_gate, velocity_gate: innovations beyond these [m or rad, m/s or rad/s] are not filtered.
    """

    def __init__(self, predictor: ContactModelPredictor, position_gain: float = 0.5, velocity_gain: float = 0.3,
                 position_gate: float = 0.05, velocity_gate: float = 0.5) -> None:
        if not isinstance(predictor, ContactModelPredictor):
            raise TypeError(f"predictor must be a ContactModelPredictor, got {type(predictor).__name__}")
        self.predictor = predictor
        self.position_gain = check_in_range(position_gain, 1e-6, 1.0, "position_gain")
        self.velocity_gain = check_in_range(velocity_gain, 1e-6, 1.0, "velocity_gain")
        self.position_gate = check_positive(position_gate, "position_gate")
        self.velocity_gate = check_positive(velocity_gate, "velocity_gate")
        self._gain = np.concatenate([np.full(NQ, self.position_gain), np.full(NX - NQ, self.velocity_gain)])
        self._gate = np.concatenate([np.full(NQ, self.position_gate), np.full(NX - NQ, self.velocity_gate)])
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (the next observation is taken as it is)."""
        self.x: np.ndarray | None = None

    def update(self, y: np.ndarray, mode: Mode, u_executed: np.ndarray | None) -> np.ndarray:
        """The estimate (14,) after measuring ``y`` (14,) in the (clean) contact ``mode``; ``u_executed`` (4,)
        [N m] is the torque the env executed over the last control period (None: take ``y`` as it is)."""
        y = check_vector(y, NX, "y")
        mode = Mode(mode)
        robot = self.predictor.robot
        if self.x is None or u_executed is None:
            self.x = project_onto_contacts(robot, y, mode)
            return self.x.copy()
        try:
            prior, prior_mode = self.predictor.step(self.x, np.asarray(u_executed, dtype=np.float64))
        except (ArithmeticError, ValueError, RuntimeError):
            self.x = project_onto_contacts(robot, y, mode)
            return self.x.copy()
        innovation = y - prior
        innovation[0] = 0.0  # the trunk x is not observed
        gain = np.where(np.abs(innovation) > self._gate, 1.0, self._gain)
        if prior_mode != mode:
            gain[NQ:] = 1.0
        x = project_onto_contacts(robot, prior + gain * innovation, mode)
        x[0] = y[0]
        self.x = x
        return x.copy()


def queue_torques(actions, torque_limit: float) -> np.ndarray:
    """Normalized actions (n, 4) as the torques [N m] the env will execute (clipped to the box)."""
    a = np.asarray(actions, dtype=np.float64).reshape(-1, NU)
    return np.clip(a, -1.0, 1.0) * float(torque_limit)

