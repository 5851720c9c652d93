"""State estimation for a policy that knows its model: latency prediction and a contact-aware velocity filter.

* [`ContactModelPredictor`][ContactModelPredictor] integrates the nominal robot with the state-based contact model
  ([`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator]'s scheme: impacts, friction, lift-offs; stepped by the
  compiled kernel, [`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator]) over a few
  control steps under known torques.
* [`ContactModelPredictor.predict`][ContactModelPredictor.predict] over the actions already sent but not yet executed
gives the state at the moment a new action will act: the MPC's latency compensation.
* [`StateFilter`][StateFilter]: a Kalman filter: the estimate is propagated one control step with the model and the
  executed torques, then corrected toward the measurement pair by pair (each coordinate's position and velocity)
  with the Kalman gain of a stated noise model, its covariance carried from step to step (the steady-state gain of
  [`steady_state_kalman_gain`][steady_state_kalman_gain] a few steps after a start); an innovation far beyond that noise
  for ``restart_steps`` observations in a row (a push, another model) restarts it from the measurement. The contact
  flags of the observation (clean) set the prior's mode; at a measured mode change the correction is complete for
  the velocities (the impact is where the model is least sure).
* [`MeasurementBias`][MeasurementBias], [`Odometry`][Odometry] and [`MassEstimate`][MassEstimate]: what the feet on the
  ground tell of the sensors and the robot: a constant bias of the measured trunk height and pitch, of the measured
  forward speed (and the trunk x integrated from it), and the trunk's mass.
"""

from __future__ import annotations

import collections
import math

import numpy as np
import pinocchio as pin

from hsddp_gym.core.compiled_contact import CompiledContactSimulator
from hsddp_gym.core.conventions import (
    BACK,
    FOOT_JOINTS,
    FRONT,
    IPITCH,
    IZ,
    JOINT_DOFS,
    NQ,
    NU,
    NX,
    Mode,
    mode_from_contacts,
)
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector


class ContactModelPredictor:
    """Forward prediction with the model: the nominal robot in the state-based contact model of
    [`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] (rigid bodies, inelastic impacts, Coulomb friction
    with the nominal ``mu``, lift-offs decided by the contact LCP, the motors' torque-speed limit), the physics the
    policy believes in. It knows nothing of the env's actual friction, masses or pushes. Stepped by the compiled kernel
    ([`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator]: 24 us per 5 ms control step
    against 190 us for the Python reference, the same states to 1e-12; the state filter predicts every control step).

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
        self.sim = CompiledContactSimulator(robot, timestep=self.control_dt / self.n_sub, friction=friction,
                                            motor_speed_limits=motor_speed_limits, torque_limit=torque_limit)
        self.robot = self.sim.robot

    @property
    def terrain(self):
        """The ground the model's feet contact (a [`Terrain`][hsddp_gym.core.terrain.Terrain]; None: flat)."""
        return self.sim.terrain

    def set_terrain(self, terrain) -> None:
        """Predict on ``terrain`` (a [`Terrain`][hsddp_gym.core.terrain.Terrain], or None: the flat ground), the env's
        contact on its simulated surface ([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices])."""
        self.sim.set_terrain(terrain)

    def step(self, x: np.ndarray, u: np.ndarray, mode: Mode | None = None, ground: float = 0.0
             ) -> tuple[np.ndarray, Mode]:
        """One control period from ``x`` (14,) under torques ``u`` (4,) [N m]: ``(x_next (14,), contact mode at
        the end)``. The contacts follow from the state (``mode`` is accepted for symmetry and not needed).
        ``ground`` [m]: the height of the ground (of `terrain` raised by it), in the frame of ``x``."""
        sim = self.sim
        if ground:
            ground = check_ground(ground)
            x = np.array(x, dtype=np.float64)
            x[IZ] -= ground
        sim.set_state(x)
        sim.run(np.asarray(u, dtype=np.float64), self.n_sub)
        x_next = sim.x.copy()
        if ground:
            x_next[IZ] += ground
        if not np.all(np.isfinite(x_next)):
            raise ArithmeticError("the model prediction diverged")
        return x_next, mode_from_contacts(bool(sim.contact[0]), bool(sim.contact[1]))

    def predict(self, x: np.ndarray, mode: Mode | None, torques, ground: float = 0.0
                ) -> tuple[np.ndarray, Mode | None]:
        """The state after holding each row of ``torques`` (n, 4) [N m] for one control period, from ``x`` (14,):
        ``(x (14,), contact mode)`` (``(x, mode)`` itself for n = 0). ``ground``: as in [`step`][step]."""
        x = check_vector(x, NX, "x").copy()
        for u in torques:
            x, mode = self.step(x, np.asarray(u, dtype=np.float64), mode, ground)
        return x, mode


def check_ground(ground) -> float:
    """``ground`` (a height [m] of the ground in the measurement's frame) as a finite float; ``TypeError`` /
    ``ValueError`` naming ``ground`` otherwise."""
    return check_in_range(ground, -math.inf, math.inf, "ground")


CONTACT_TOLERANCE = 1e-4
"""Feet in contact within this distance [m] of the ground are left where they are (the env's own contact
resolution leaves micrometres)."""


def terrain_clearance(robot: CheetahModel, q: np.ndarray, foot: int, terrain=None) -> float:
    """Height [m] of ``foot`` of configuration ``q`` (7,) above the ground under it: the simulated surface of
    ``terrain`` ([`surface_heights`][hsddp_gym.core.terrain.Terrain.surface_heights], the env's
    ``info["foot_heights"]``), or the plane ``z = 0`` for None."""
    if terrain is None:
        return robot.foot_height(q, foot)
    p = robot.foot_positions(q)[foot]
    return float(p[1] - terrain.surface_heights(float(p[0])))


def clearance_jacobian(robot: CheetahModel, q: np.ndarray, foot: int, index, terrain=None) -> np.ndarray:
    """Derivatives of [`terrain_clearance`][terrain_clearance] with respect to the coordinates ``q[index]``: the foot's
    vertical Jacobian less the surface's slope under the foot times its horizontal one."""
    J = robot.foot_jacobian(q, foot)
    if terrain is None:
        return J[1, index]
    n = terrain.surface_normals(float(robot.foot_positions(q)[foot, 0]))
    return J[1, index] + (float(n[0]) / float(n[1])) * J[0, index]


def project_onto_contacts(robot: CheetahModel, x: np.ndarray, mode: Mode, terrain=None,
                          ground: float = 0.0) -> np.ndarray:
    """``x`` (14,) with its trunk height (and, for two feet, pitch) moved so that the feet in contact in ``mode`` are
    on the ground (one Gauss-Newton step on the feet's heights; a copy), unless they all are within
    [`CONTACT_TOLERANCE`][CONTACT_TOLERANCE] of it. ``terrain``: the ground ([`terrain_clearance`][terrain_clearance];
    None: ``z = 0``), raised by ``ground`` [m]."""
    x = np.array(x, dtype=np.float64)
    ground = check_ground(ground)
    feet = [f for f in (0, 1) if Mode(mode).in_contact(f)]
    if not feet:
        return x
    if ground:
        x[IZ] -= ground
        x = project_onto_contacts(robot, x, mode, terrain)
        x[IZ] += ground
        return x
    # the common case needs no derivatives
    heights = [terrain_clearance(robot, x[:NQ], f, terrain) for f in feet]
    if max(abs(g) for g in heights) <= CONTACT_TOLERANCE:
        return x
    if len(feet) == 1:
        x[1] -= heights[0]
        return x
    if terrain is None:
        A = np.array([[g[1], g[2]] for _, g, _ in (robot.foot_height_derivatives(x[:NQ], f) for f in feet)])
    else:
        A = np.array([clearance_jacobian(robot, x[:NQ], f, [IZ, IPITCH], terrain) for f in feet])
    h = np.array(heights)
    try:
        dz, dpitch = np.linalg.solve(A, -h)
    except np.linalg.LinAlgError:
        return x
    x[1] += dz
    x[2] += dpitch
    return x


class MeasurementBias:
    """A constant offset of the measured trunk height and pitch, estimated from the feet on the ground.

    A foot the (clean) contact flags report on the ground, after ``settle_steps`` observations in contact, is at
    the ground, whatever the sensors say. The height of such a foot computed from the measurement ``y`` is then the
    measurement's error seen at the foot: to first order ``h_f(y) = J_f b`` with ``J_f = (dh_f/dz, dh_f/dpitch)``
    and ``b = (b_z, b_pitch)`` the biases. One foot sees a combination of them; the two feet of a gait over a cycle
    see both. They are estimated by least squares over the observations, the older ones forgotten with the time
    constant ``memory`` (an exponential weight), from a prior of zero bias worth ``prior_steps`` observations of one
    foot (a pitch's observation scaled by the hip's lever arm). [`ground_offset`][ground_offset] is then the height at
    which the measurement puts a foot that stands on the ground (where a landing foot will stop, in the measurement's
    frame); [`correct`][correct] subtracts the bias from a measurement.

    Whatever else holds a stance foot off the flat ground is read as a bias too: a foot that sinks into a soft
    contact or stands on a step. For [`ground_offset`][ground_offset] that is right (a landing foot will sink as deep);
    for [`correct`][correct] it is not (in a flight the trunk is where the sensors say, not where the sunk feet put it),
    so the MPC uses the estimate as the ground (of its plans, of its late-landing rule and of the model its state
    filter and latency compensation step) and never corrects the state with it. A sample whose residual from the
    estimate exceeds ``gate`` [m] (a foot flagged on the ground far from where the estimate puts it) is not used;
    before [`calibrated`][calibrated] the estimate is not yet known, and the gate is measured from the bound instead (a
    residual up to ``gate`` plus the height bound is used, so that a bias beyond ``gate`` is found at all). The
    estimates are bounded by ``limit`` (``(height [m], pitch [rad])``). Velocities are not estimated: on a compliant
    contact a stance foot is not at rest (it sinks and rebounds), and a velocity bias of the size of the measurement
    noise is the feedback's business (the MPC's speed integral).

    Args:
        robot: the model (its kinematics).
        control_dt: period of the observations [s].
        memory: time constant of the forgetting [s] (> 0).
        settle_steps: observations a foot must have been in contact before it is used (>= 1).
        prior_steps: weight of the zero-bias prior, in observations of one foot (> 0).
        gate: residual [m] beyond which a sample is not used (> 0; before the calibration, beyond ``gate`` plus the
            height bound).
        limit: ``(height [m], pitch [rad])`` bounds of the estimates (> 0).

    Attributes:
        bias: the estimate (14,) in state order (zeros but the trunk height and pitch).
        samples: foot observations used since [`reset`][reset].
        terrain: the ground the feet stand on when it is known (a [`Terrain`][hsddp_gym.core.terrain.Terrain]; None,
            the default: the plane ``z = 0``). A foot's residual is then its height above the terrain's surface under
            it ([`terrain_clearance`][terrain_clearance]), so only the sensors' bias is estimated and the measurement
            stays in the world frame instead of the frame of the ground under the stance feet.
    """

    CALIBRATION_STEPS = 5.0
    """The weight of observations of the height (in one foot's observations) after which [`calibrated`][calibrated]."""
    INDEX = np.array([IZ, IPITCH])

    def __init__(self, robot: CheetahModel, control_dt: float, memory: float = 1.0, settle_steps: int = 2,
                 prior_steps: float = 1.0, gate: float = 0.05, limit: tuple = (0.1, 0.1)) -> None:
        if not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
        self.robot = robot
        self.forget = math.exp(-check_positive(control_dt, "control_dt") / check_positive(memory, "memory"))
        self.settle_steps = check_int(settle_steps, "settle_steps", minimum=1)
        prior = check_positive(prior_steps, "prior_steps")
        self.gate = check_positive(gate, "gate")
        self.limit = check_vector(limit, 2, "limit")
        if np.any(self.limit <= 0):
            raise ValueError(f"limit must be positive, got {limit!r}")
        self._prior = prior * np.diag([1.0, float(robot.params.hip_offset) ** 2])
        self.terrain = None
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (zero bias)."""
        self.bias = np.zeros(NX)
        self.samples = 0
        self._in_contact = [0, 0]
        self._info, self._vec = np.zeros((2, 2)), np.zeros(2)

    @property
    def calibrated(self) -> bool:
        """True once the feet on the ground have given the height the weight of [`CALIBRATION_STEPS`][CALIBRATION_STEPS]
        observations: before, where the measurement puts the ground is not known."""
        return bool(self._info[0, 0] >= self.CALIBRATION_STEPS)

    def update(self, y: np.ndarray, mode: Mode) -> np.ndarray:
        """Fold in the measurement ``y`` (14,) with the contact ``mode``; return
        [`bias`][hsddp_gym.core.batch_model.bias] (14,)."""
        mode = Mode(mode)
        self._info *= self.forget
        self._vec *= self.forget
        used = False
        gate = self.gate if self.calibrated else self.gate + float(self.limit[0])
        for f in (FRONT, BACK):
            self._in_contact[f] = self._in_contact[f] + 1 if mode.in_contact(f) else 0
            if self._in_contact[f] <= self.settle_steps:
                continue
            if self.terrain is None:
                j = self.robot.foot_jacobian(y[:NQ], f)[1, self.INDEX]
                h = self.robot.foot_height(y[:NQ], f)
            else:
                j = clearance_jacobian(self.robot, y[:NQ], f, self.INDEX, self.terrain)
                h = terrain_clearance(self.robot, y[:NQ], f, self.terrain)
            if abs(h - j @ self.bias[self.INDEX]) > gate:
                continue
            self._info += np.outer(j, j)
            self._vec += j * h
            self.samples += 1
            used = True
        if used:
            b = np.linalg.solve(self._info + self._prior, self._vec)
            self.bias[self.INDEX] = np.clip(b, -self.limit, self.limit)
        return self.bias

    def ground_offset(self, q: np.ndarray, foot: int) -> float:
        """The height [m] above the ground (or `terrain`) at which a configuration ``q`` (7,) measured now
        puts ``foot`` when it stands on the ground: ``J_f(q) b`` (0 before any foot on the ground)."""
        if self.terrain is None:
            j = self.robot.foot_jacobian(q, foot)[1, self.INDEX]
        else:
            j = clearance_jacobian(self.robot, q, foot, self.INDEX, self.terrain)
        return float(j @ self.bias[self.INDEX])

    def correct(self, y: np.ndarray, mode: Mode) -> np.ndarray:
        """The measurement ``y`` (14,) less the bias estimated with it ([`update`][update]): a new array."""
        y = check_vector(y, NX, "y")
        return y - self.update(y, mode)


class Odometry:
    """The trunk x where the observation lacks it: the measured forward speed integrated, less its constant bias
    estimated from the feet on the ground.

    A foot the (clean) contact flags report on the ground, after ``settle_steps`` observations in contact, touches it
    at a point at rest unless it slips. The foot frame's forward velocity computed from the measurement ``y``
    (``J_x(q) v``) is then the measurement's forward-speed bias ``b`` plus, for a round foot larger than the model's
    point, its rolling: the frame (the foot's centre) moves at ``rho w`` with ``w`` the shank's angular rate
    (pitch + hip + knee rates) and ``rho`` how much larger its radius is. ``b`` and ``rho`` are fitted by least squares
    to the last ``memory / control_dt`` samples (at least ``min_samples``; 0 before; ridge priors of zero, worth one
    sample for ``b`` and [`ROLLING_PRIOR`][ROLLING_PRIOR] for ``rho``) within ``gate`` of the fit: a foot that slips
    (friction 0.4 slides a whole first stance back at 0.2-1 m/s) or lifts while still flagged on the ground is not at
    rest and is left out, where a mean would take it for a bias, and a rolling foot (0.085 m/s on the large-feet
    MuJoCo contact) is not a bias either. ``b`` is bounded by ``limit``. The bias being constant, the correction
    applies to the whole integral: ``x = int v dt - b t`` (trapezoidal, from 0 at the first observation), so what the
    integral gathered before the estimate settled is taken back too. Without ``memory`` (None) the bias is not
    estimated.

    Args:
        robot: the model (its kinematics).
        control_dt: period of the observations [s].
        memory: the samples of how many seconds of observations the fit is over [s] (> 0), or None.
        settle_steps: observations a foot must have been in contact before it is used (>= 1).
        min_samples: the fewest samples a fit is made of (>= 2).
        gate: a sample further than this [m/s] from the fit is not used (> 0).
        limit: bound [m/s] of the estimate (> 0).

    Attributes:
        speed_bias: the estimate ``b`` [m/s].
        rolling: the estimate ``rho`` [m] (how much a stance foot's centre moves per rad of its shank's rotation).
        samples: foot samples used since [`reset`][reset].
    """

    ROLLING_PRIOR = 50.0
    """Weight [(rad/s)^2] of the prior ``rho = 0``: the samples of one stance turn their shank at nearly one rate, and
    a rolling the data do not separate from the bias is none."""

    def __init__(self, robot: CheetahModel, control_dt: float, memory: float | None = 1.0, settle_steps: int = 2,
                 min_samples: int = 10, gate: float = 0.2, limit: float = 0.3) -> None:
        if not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
        self.robot = robot
        self.dt = check_positive(control_dt, "control_dt")
        self.window = None if memory is None else max(2, round(check_positive(memory, "memory") / self.dt))
        self.settle_steps = check_int(settle_steps, "settle_steps", minimum=1)
        self.min_samples = check_int(min_samples, "min_samples", minimum=2)
        self.gate = check_positive(gate, "gate")
        self.limit = check_positive(limit, "limit")
        self.reset()

    def reset(self) -> None:
        """Start at x = 0 with no bias."""
        self.speed_bias = 0.0
        self.rolling = 0.0
        self.samples = 0
        self._integral: float | None = None
        self._speed = 0.0
        self._time = 0.0
        self._in_contact = [0, 0]
        self._recent: collections.deque = collections.deque(maxlen=self.window or 2)  # (w, v) pairs

    def update(self, y: np.ndarray, mode: Mode) -> float:
        """Fold in the measurement ``y`` (14,) with the contact ``mode``; return the trunk x [m] ([`x`][x])."""
        y = check_vector(y, NX, "y")
        vx = float(y[NQ])
        if self._integral is None:
            self._integral = 0.0
        else:
            self._integral += 0.5 * (self._speed + vx) * self.dt
            self._time += self.dt
        self._speed = vx
        if self.window is not None:
            self._fold(y, Mode(mode))
        return self.x

    @property
    def integral(self) -> float:
        """The measured forward speed's integral [m] (trapezoidal, 0 before the first observation)."""
        return 0.0 if self._integral is None else self._integral

    @property
    def x(self) -> float:
        """The trunk x [m]: [`integral`][integral] less the speed bias over the time since the first observation."""
        return self.integral - self.speed_bias * self._time

    def _fold(self, y: np.ndarray, mode: Mode) -> None:
        used = False
        for f in (FRONT, BACK):
            self._in_contact[f] = self._in_contact[f] + 1 if mode.in_contact(f) else 0
            if self._in_contact[f] <= self.settle_steps:
                continue
            v = float(self.robot.foot_jacobian(y[:NQ], f)[0] @ y[NQ:])
            hip, knee = FOOT_JOINTS[f]
            w = float(y[NQ + IPITCH] + y[NQ + hip] + y[NQ + knee])
            if abs(v - self.speed_bias - self.rolling * w) > self.gate:
                continue
            self._recent.append((w, v))
            self.samples += 1
            used = True
        if used and len(self._recent) >= self.min_samples:
            w, v = np.array(self._recent).T
            normal = np.array([[w.size + 1.0, w.sum()], [w.sum(), w @ w + self.ROLLING_PRIOR]])
            b, rho = np.linalg.solve(normal, np.array([v.sum(), w @ v]))
            self.speed_bias = float(np.clip(b, -self.limit, self.limit))
            self.rolling = float(rho)


class MassEstimate:
    """The trunk's mass relative to the model's, from the vertical impulse of the stances.

    A stance leg's joint torques ``tau`` hold the ground's force on its foot, ``tau = -J^T F`` (``J`` the foot's
    (2, 2) Jacobian in the leg's joints; the legs' own inertia neglected), so the executed torques give the vertical
    impulse of a stance up to each observation, ``I_k = sum F_z dt`` (over the observations of a contact mode held,
    counted from ``settle_steps`` after it began: the impact is not). For a robot of total mass ``M'`` the centre of
    mass's vertical velocity is then ``vz_k = v_0 - g t_k + I_k / M'``; the model's mass is ``M``. With
    ``P_k = I_k / M`` (the change the model expects) and ``Y_k = vz_k + g t_k`` (measured), ``r = M / M'`` is the slope
    of ``Y`` on ``P`` within each stance (least squares, each stance its own ``v_0``; every observation counts, not only
    the ends), pooled over the stances (``sum S_PY / sum S_PP``), the older stances forgotten with the time constant
    ``memory``, from a prior of ``r = 1`` worth ``prior`` [(m/s)^2] of ``S_PP``; a stance shorter than ``min_steps``
    is not used. It is read as the trunk's mass (and pitch inertia) scale, the legs as the model has them:
    ``scale = 1 + (M / m_trunk)(1 / r - 1)``, bounded by ``limits``.

    Args:
        robot: the model (its kinematics, masses and gravity).
        control_dt: period of the observations [s].
        memory: time constant of the forgetting [s] (> 0).
        settle_steps: observations in a contact mode before its stance is counted (>= 1).
        min_steps: the fewest counted observations of a stance that is used (>= 1).
        prior: weight of the prior ``r = 1`` [(m/s)^2] (> 0).
        limits: ``(lowest, highest)`` trunk mass scale (0 < lowest < 1 < highest).

    Attributes:
        scale: the estimate of the trunk's mass scale (1 before any stance).
        stances: stances used since [`reset`][reset].
    """

    def __init__(self, robot: CheetahModel, control_dt: float, memory: float = 5.0, settle_steps: int = 3,
                 min_steps: int = 5, prior: float = 0.2, limits: tuple = (0.7, 1.4)) -> None:
        if not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
        self.robot = robot
        self.dt = check_positive(control_dt, "control_dt")
        self.forget = math.exp(-self.dt / check_positive(memory, "memory"))
        self.settle_steps = check_int(settle_steps, "settle_steps", minimum=1)
        self.min_steps = check_int(min_steps, "min_steps", minimum=1)
        self.prior = check_positive(prior, "prior")
        lo, hi = check_vector(limits, 2, "limits")
        if not 0.0 < lo < 1.0 < hi:
            raise ValueError(f"limits must satisfy 0 < lowest < 1 < highest, got {limits!r}")
        self.limits = (float(lo), float(hi))
        params = robot.params
        self.gravity = float(params.gravity)
        self.total_mass = float(params.total_mass)
        self.mass_ratio = self.total_mass / float(params.trunk.mass)
        self._data = robot.new_data()
        self.reset()

    def reset(self) -> None:
        """Forget the stances (scale 1)."""
        self.scale = 1.0
        self.stances = 0
        self._mode: Mode | None = None
        self._run = 0
        self._stance = np.zeros(6)  # this stance's n, sum P, sum Y, sum PY, sum PP, and P (the impulse / M so far)
        self._t = 0.0
        self._spy = 0.0
        self._spp = 0.0

    def vertical_force(self, q: np.ndarray, torque: np.ndarray, mode: Mode) -> float:
        """The ground's vertical force [N] on the feet ``mode`` has on the ground, held by the joint ``torque`` (4,)
        [N m] at the configuration ``q`` (7,) (``-J^{-T} tau`` per stance leg).

        Raises:
            numpy.linalg.LinAlgError: a stance leg stretched straight (its Jacobian singular).
        """
        total = 0.0
        for f in (FRONT, BACK):
            if mode.in_contact(f):
                joints = list(FOOT_JOINTS[f])
                jac = self.robot.foot_jacobian(q, f)[:, joints]
                total -= float(np.linalg.solve(jac.T, torque[[j - JOINT_DOFS.start for j in joints]])[1])
        return total

    def update(self, y: np.ndarray, torque: np.ndarray | None, mode: Mode) -> float:
        """Fold in one observation: the measured state ``y`` (14,), the joint torque (4,) [N m] executed over the last
        control period (None: not known), the measured contact ``mode``; return ``scale``.

        Raises:
            ValueError: ``y`` or ``torque`` not finite vectors of their shapes.
        """
        y = check_vector(y, NX, "y")
        torque = None if torque is None else check_vector(torque, NU, "torque")
        mode = Mode(mode)
        self._spy *= self.forget
        self._spp *= self.forget
        if mode != self._mode:
            self._close()
            self._mode, self._run = mode, 0
        if mode == Mode.FLIGHT:
            return self.scale
        self._run += 1
        if self._run < self.settle_steps:
            return self.scale
        st = self._stance
        if self._run > self.settle_steps:
            force = None if torque is None else self._stance_force(y[:NQ], torque, mode)
            if force is None:  # no torque known, or a leg stretched straight: a new stance from here
                self._close()
            else:
                st[5] += force / self.total_mass * self.dt
                self._t += self.dt
        pin.centerOfMass(self.robot.model, self._data, y[:NQ], y[NQ:])
        p, v = st[5], float(self._data.vcom[0][2]) + self.gravity * self._t
        st[:5] += (1.0, p, v, p * v, p * p)
        return self.scale

    def _stance_force(self, q: np.ndarray, torque: np.ndarray, mode: Mode) -> float | None:
        """[`vertical_force`][vertical_force], None where a stance leg's Jacobian is singular (stretched straight)."""
        try:
            return self.vertical_force(q, torque, mode)
        except np.linalg.LinAlgError:
            return None

    def _close(self) -> None:
        """End the stance being counted: fold it in when long enough."""
        n, sp, sy, spy, spp, _ = self._stance
        if n >= self.min_steps:
            self._spy += spy - sp * sy / n
            self._spp += spp - sp * sp / n
            self.stances += 1
            r = (self._spy + self.prior) / (self._spp + self.prior)
            scale = 1.0 + self.mass_ratio * (1.0 / max(r, 1e-3) - 1.0)
            self.scale = float(np.clip(scale, *self.limits))
        self._stance[:] = 0.0
        self._t = 0.0


def _noise_model(dt: float, position_noise: float, velocity_noise: float, acceleration_noise: float):
    """``(A, Q, R)`` (2, 2) each of one coordinate ``(q, v)``: transition, process and measurement covariances."""
    dt = check_positive(dt, "dt")
    sp = check_positive(position_noise, "position_noise")
    sv = check_positive(velocity_noise, "velocity_noise")
    sa = check_positive(acceleration_noise, "acceleration_noise")
    A = np.array([[1.0, dt], [0.0, 1.0]])
    G = np.array([0.5 * dt * dt, dt])
    return A, np.outer(G, G) * sa * sa, np.diag([sp * sp, sv * sv])


def steady_state_kalman_gain(dt: float, position_noise: float, velocity_noise: float,
                             acceleration_noise: float) -> tuple[np.ndarray, np.ndarray]:
    """The steady-state Kalman filter of one coordinate measured in position and velocity.

    The coordinate ``(q, v)`` follows the model exactly up to an unmodelled acceleration, white with standard
    deviation ``acceleration_noise`` and held over each period ``dt`` (``q += v dt + a dt^2 / 2``, ``v += a dt``);
    ``q`` and ``v`` are measured with independent noise of standard deviations ``position_noise`` and
    ``velocity_noise``. Returns ``(L, S)``: the gain ``L (2, 2)`` (the correction of ``(q, v)`` is
    ``L @ innovation``) and the covariance ``S (2, 2)`` of the innovation, both at the fixed point of the Riccati
    recursion (which [`StateFilter`][StateFilter] runs step by step).
    """
    A, Q, R = _noise_model(dt, position_noise, velocity_noise, acceleration_noise)
    P = R.copy()
    for _ in range(100_000):
        prior = A @ P @ A.T + Q
        S = prior + R
        L = prior @ np.linalg.inv(S)
        P_next = (np.eye(2) - L) @ prior
        if np.abs(P_next - P).max() <= 1e-15 * np.abs(P).max():
            break
        P = P_next
    return L, S


class StateFilter:
    """Contact-aware Kalman filter of the state from noisy observations (see the module docstring).

    Each observation ``y`` (14,) is compared with the prior ``x_prior`` (the previous estimate propagated one
    control period with the model and the torque the env executed). Every coordinate's (position, velocity) pair
    is corrected by the Kalman gain of the noise model of [`steady_state_kalman_gain`][steady_state_kalman_gain], ``x =
    x_prior + L (y - x_prior)`` pair by pair, with the covariance ``P (2, 2)`` of the estimate carried from step to step
    (the same for every coordinate: they share the noise model): right after a start or a restart the estimate is one
    observation and the gain is high; it settles to the steady-state gain within a few steps. (A coordinate whose
    position the model integrates from its velocity: the velocity measurement, integrated, says more about the position
    than the position measurement does, so the steady-state position gain is small.) Two cases take the measurement
    instead of the model:

    * the **innovation test**: the normalized innovation squared ``sum_i e_i^T S^-1 e_i`` over the observed
      coordinates (13: the trunk ``x`` is not observed; ``S = P_prior + R``) exceeds ``innovation_gate`` -- far
      more than the assumed noise explains (the default 35 is exceeded by chance once in ~1000 observations) --
      on ``restart_steps`` observations in a row: the model is wrong (a push, a slip, another friction, mass or
      contact model), and the estimate restarts from the measurement (``P = R``). A shorter run of exceedances
      (`outliers`) is corrected as any observation: one step the model could not predict (an impact on a
      soft or stiff contact, which the rigid model has no state for) leaves the estimate to the prior and the
      gain, while a push keeps the innovation beyond the gate at the next observation too (the blended estimate
      is still far from it) and restarts then;
    * an observed contact **mode change the model did not predict**: the velocities are taken whole (the impact is
      where the model is least sure).

    The feet the (clean) contact flags report on the ground are put on it
    ([`project_onto_contacts`][project_onto_contacts]: trunk height, and pitch for two feet; on the predictor's terrain,
    [`ContactModelPredictor.set_terrain`][ContactModelPredictor.set_terrain]), so that the prior's contact model neither
    lifts nor sinks them through noise in the measured heights and angles. The ground is where the measurement puts it:
    ``update(..., ground=)`` raises it (the terrain, or ``z = 0``) by the height at which a biased measurement puts a
    foot that stands on it (the height bias of [`MeasurementBias`][MeasurementBias]), and when that height moves the
    estimate moves with it. With exact observations and the exact model the estimate is the observation (to round-off).

    Args:
        predictor: the model used for the prior (its ``control_dt`` is the filter's period).
        position_noise: assumed standard deviation of a measured position [m or rad] (> 0).
        velocity_noise: assumed standard deviation of a measured velocity [m/s or rad/s] (> 0).
        acceleration_noise: standard deviation of the accelerations the model misses [m/s^2 or rad/s^2] (> 0):
            larger trusts the model less (gains toward 1).
        innovation_gate: threshold of the innovation test (> 0).
        restart_steps: consecutive observations beyond ``innovation_gate`` that restart the estimate (>= 1; 1: the
            first restarts it).

    Attributes:
        gain: the steady-state Kalman gain ``L (2, 2)``.
        innovation_covariance: the steady-state innovation covariance ``S (2, 2)``.
        covariance: the current ``P (2, 2)`` (None before the first observation).
        restarts: the observations taken whole by the innovation test since [`reset`][reset].
        outliers: the observations beyond the gate that did not restart the estimate (a run shorter than
            ``restart_steps``) since [`reset`][reset].
        last_nis: the normalized innovation squared of the last corrected observation (None before one).
    """

    def __init__(self, predictor: ContactModelPredictor, position_noise: float = 0.01, velocity_noise: float = 0.1,
                 acceleration_noise: float = 3.0, innovation_gate: float = 35.0, restart_steps: int = 1) -> None:
        if not isinstance(predictor, ContactModelPredictor):
            raise TypeError(f"predictor must be a ContactModelPredictor, got {type(predictor).__name__}")
        self.predictor = predictor
        self.innovation_gate = check_positive(innovation_gate, "innovation_gate")
        self.restart_steps = check_int(restart_steps, "restart_steps", minimum=1)
        self._A, self._Q, self._R = _noise_model(predictor.control_dt, position_noise, velocity_noise,
                                                 acceleration_noise)
        self.gain, self.innovation_covariance = steady_state_kalman_gain(
            predictor.control_dt, position_noise, velocity_noise, acceleration_noise)
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (the next observation is taken as it is)."""
        self.x: np.ndarray | None = None
        self.covariance: np.ndarray | None = None
        self.restarts = 0
        self.outliers = 0
        self.last_nis: float | None = None
        self._beyond = 0  # consecutive observations beyond the gate
        self._ground = 0.0  # the ground [m] of the last update (the estimate moves with it)

    def _take(self, y: np.ndarray, mode: Mode, ground: float = 0.0) -> np.ndarray:
        self._ground = ground
        self.x = project_onto_contacts(self.predictor.robot, y, mode, self.predictor.terrain, ground)
        self.covariance = self._R.copy()
        self._beyond = 0
        return self.x.copy()

    def update(self, y: np.ndarray, mode: Mode, u_executed: np.ndarray | None, ground: float = 0.0) -> np.ndarray:
        """The estimate (14,) after measuring ``y`` (14,) in the (clean) contact ``mode``; ``u_executed`` (4,)
        [N m] is the torque the env executed over the last control period (None: take ``y`` as it is); ``ground``
        [m]: the height of the ground in the measurement's frame (the predictor's terrain, or ``z = 0``, raised by
        it). A ground other than the last update's moves the estimate's trunk height by the difference."""
        y = check_vector(y, NX, "y")
        mode = Mode(mode)
        ground = check_ground(ground)
        if self.x is None or u_executed is None:
            return self._take(y, mode, ground)
        if ground != self._ground:  # the ground moved in the measurement's frame: the estimate moves with it
            self.x[IZ] += ground - self._ground
            self._ground = ground
        try:
            prior, prior_mode = self.predictor.step(self.x, np.asarray(u_executed, dtype=np.float64), ground=ground)
        except (ArithmeticError, ValueError, RuntimeError):
            return self._take(y, mode, ground)
        A = self._A
        P_prior = A @ self.covariance @ A.T + self._Q
        S = P_prior + self._R
        si = np.linalg.inv(S)
        eq = y[:NQ] - prior[:NQ]
        eq[0] = 0.0  # the trunk x is not observed
        ev = y[NQ:] - prior[NQ:]
        nis = float(np.sum(si[0, 0] * eq * eq + 2.0 * si[0, 1] * eq * ev + si[1, 1] * ev * ev))
        # the trunk x: only its velocity is measured (its pair's position term is zero above, the cross term too,
        # and its velocity term uses S_vv alone)
        nis += float(ev[0] * ev[0] * (1.0 / S[1, 1] - si[1, 1]))
        self.last_nis = nis
        self._beyond = self._beyond + 1 if nis > self.innovation_gate else 0
        if self._beyond >= self.restart_steps:
            self.restarts += 1
            x = self._take(y, mode, ground)
        else:
            self.outliers += int(self._beyond > 0)
            L = P_prior @ si
            x = prior.copy()
            x[:NQ] += L[0, 0] * eq + L[0, 1] * ev
            P = (np.eye(2) - L) @ P_prior
            if prior_mode != mode:
                x[NQ:] = y[NQ:]
                P[0, 1] = P[1, 0] = 0.0
                P[1, 1] = self._R[1, 1]
            else:
                x[NQ:] += L[1, 0] * eq + L[1, 1] * ev
            self.covariance = P
            x = project_onto_contacts(self.predictor.robot, x, mode, self.predictor.terrain, ground)
        x[0] = y[0]
        self.x = x
        return x.copy()


def queue_torques(actions, torque_limit: float) -> np.ndarray:
    """Normalized actions (n, 4) as the torques [N m] the env will execute (clipped to the box)."""
    a = np.asarray(actions, dtype=np.float64).reshape(-1, NU)
    return np.clip(a, -1.0, 1.0) * float(torque_limit)

