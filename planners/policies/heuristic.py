"""The heuristic bounding controller used to warm-start the optimizer (paper Sec. V-B).

Structure as in the paper and the authors' code (original_code_facts §4): joint PD control in flight;
in stance a ground reaction force built from a spring model, converted to joint torques through the
stance-foot Jacobian. The authors' exact gains (a hip-foot spring k = 2200 N/m, l0 = 0.2462 m, torque
scale 1.4-3.0) pull on the ground from the paper's initial state (the back leg is longer than l0 there)
and tumble within two cycles on our 80/72/72/72 ms schedule, so the stance force here is a virtual
model that a demanding user can read and tune:

* vertical: ``F_z = m g T_cycle / T_stance + k_z (z_ref - z) - d_z dz`` (the stance phases carry the
  weight of the whole cycle, a spring-damper on the trunk height);
* horizontal: the force whose moment about the trunk origin gives the pitch a PD-controlled angular
  acceleration, ``F_x = (I_pitch * ddpitch_des + r_x F_z) / r_z``, plus a speed term ``k_v (v_d - dx)``;
* clipped to the friction cone ``|F_x| <= mu F_z`` and ``F_z >= 0``, then ``u_leg = -J_leg^T F``
  (F is the force of the ground on the robot); the swing leg holds its touchdown posture with PD.

In flight every joint tracks the posture of the next touchdown (the per-mode references of
[`hsddp_gym.core.references`][hsddp_gym.core.references]) with the hip shifted by a Raibert-style speed correction.

[`ContactEventBoundingController`][ContactEventBoundingController] is the same idea for a simulator whose contacts
follow the state (``hsddp_gym/Bounding-v0``), where no schedule says when a stance ends: there a stance lasts until the
leg force vanishes (~140 ms with the gains above) and the trunk pitches over. It is a per-leg state machine
driven by touchdown events (contact flags) and its own timers:

* **stance** starts when a swinging leg touches the ground and lasts a fixed ``stance_duration``; the
  stance legs produce a ground force ``F`` (``u = -J^T F``) that best realizes, by weighted least squares
  inside the friction cone, a desired force and pitch moment: vertical ``m (g + (vz_lo - vz) / T_rem)``
  reaching at lift-off the vertical speed of a ``flight_duration`` hop (plus a height correction),
  horizontal ``m k_v (v_d - vx)``, and a pitch moment ``I (w_lo - w) / T_rem`` reaching at lift-off the
  bounding pitch rate (``+pitch_rate`` nose-down after a back stance, ``-pitch_rate`` after a front
  stance), corrected by the pitch error; ``T_rem`` is the stance time left (at least ``horizon_floor``);
* **swing**: when the stance time is up the leg is actively folded (foot ``retract_leg`` below the hip)
  for ``retract_duration``, so it lifts off, then it reaches for the ground: its foot goes to
  ``touchdown_leg`` below the hip (world vertical), ahead of it by ``neutral * vx * T_stance / 2 +
  raibert * (vx - v_d)`` (Raibert foot placement), through joint PD on the inverse kinematics. Only a
  leg in this reaching phase can start a new stance.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np

from hsddp_gym.core.conventions import (
    BACK,
    FOOT_JOINTS,
    FOOT_U,
    FRONT,
    IPITCH,
    IVX,
    IVZ,
    IZ,
    JOINT_DOFS,
    NQ,
    NU,
    NX,
    Mode,
)
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.references import end_of_mode_reference
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.validation import check_vector

_MIN_FOOT_DEPTH = 0.01
"""Smallest foot depth below the trunk [m] used in the pitch-moment balance (a foot level with the trunk,
only possible mid-tumble, would otherwise divide by zero)."""


@dataclasses.dataclass(frozen=True)
class HeuristicGains:
    """Gains of the heuristic controller.

    Attributes:
        kp, kd: flight / swing joint PD gains (4,) [N m/rad], [N m s/rad] (the authors' kp = 5 diag(8, 1, 12,
            10) with a stiffer front knee, their kd = 1).
        speed: desired forward speed [m/s]. height: desired trunk height [m].
        kz, dz: trunk height spring [N/m] and damper [N s/m].
        kpitch, dpitch: pitch PD on the desired pitch acceleration [1/s^2], [1/s].
        kv: speed feedback on the horizontal force [N s/m].
        raibert: hip-angle shift per m/s of speed error in flight [rad s/m].
        durations: (back stance, flight, front stance, flight) [s] for the weight-support feed-forward.
        torque_limit: saturate the output [N m] (None: no saturation).
    """

    kp: tuple = (40.0, 20.0, 60.0, 50.0)
    kd: tuple = (1.0, 1.0, 1.0, 1.0)
    speed: float = 1.0
    height: float = 0.27
    kz: float = 3000.0
    dz: float = 60.0
    kpitch: float = 400.0
    dpitch: float = 40.0
    kv: float = 20.0
    raibert: float = 0.2
    durations: tuple = PAPER_BOUNDING_DURATIONS
    torque_limit: float | None = None


class HeuristicBoundingController:
    """The warm-start controller; it acts from the state and the contact mode only.

    Args:
        robot: the model. gains: [`HeuristicGains`][HeuristicGains]. height_offset: the touchdown postures' trunk this
            much
            higher [m] ([`end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference]; the MPC's start-up
            and warm-start controllers take ``PlanOptions.height_offset``).
    """

    def __init__(self, robot: CheetahModel | None = None, gains: HeuristicGains = HeuristicGains(),
                 height_offset: float = 0.0) -> None:
        self.robot = robot if robot is not None else CheetahModel()
        if not isinstance(gains, HeuristicGains):
            raise TypeError(f"gains must be a HeuristicGains, got {type(gains).__name__}")
        self.gains = gains
        self._kp = np.asarray(gains.kp, dtype=float)
        self._kd = np.asarray(gains.kd, dtype=float)
        # touchdown postures: the front foot lands after back stance, the back foot after front stance
        self._land = {foot: end_of_mode_reference(Mode.FLIGHT, foot, gains.speed, params=self.robot.params,
                                                  height_offset=height_offset) for foot in (FRONT, BACK)}
        p = self.robot.params
        self._mass = p.total_mass
        # pitch inertia of the whole robot about the trunk origin (legs as point masses at the hips)
        legs = 2 * (p.thigh.mass + p.shank.mass)
        self._inertia = p.trunk.inertia_yy + legs * p.hip_offset ** 2
        d = gains.durations
        self._support = p.gravity * (d[0] + d[1] + d[2] + d[3]) / (d[0] + d[2])

    def torque(self, x: np.ndarray, mode: Mode, next_touchdown: int | None = None) -> np.ndarray:
        """Joint torques (4,) for state ``x`` (14,) in ``mode``.

        Args:
            next_touchdown: in flight, the foot expected to land next (default: guessed from the pitch
                rate -- the front foot lands after a back stance, when the nose moves down).
        """
        x = check_vector(x, NX, "x")
        mode = Mode(mode)
        g = self.gains
        q = x[:NQ]
        u = np.zeros(NU)
        if mode == Mode.FLIGHT:
            foot = next_touchdown if next_touchdown is not None else (FRONT if x[NQ + IPITCH] > 0 else BACK)
            target = self._land[foot][JOINT_DOFS].copy()
            shift = g.raibert * (x[IVX] - g.speed)
            target[0] -= shift
            target[2] -= shift
            u[:] = self._kp * (target - x[JOINT_DOFS]) - self._kd * x[NQ + 3:]
        else:
            feet = mode.feet
            fz = self._mass * self._support / len(feet) + (g.kz * (g.height - q[IZ]) - g.dz * x[IVZ]) / len(feet)
            fz = max(fz, 0.0)
            ddpitch = -g.kpitch * q[IPITCH] - g.dpitch * x[NQ + IPITCH]
            positions = self.robot.foot_positions(q)
            for foot in feet:
                r = positions[foot] - q[[0, IZ]]
                depth = min(r[1], -_MIN_FOOT_DEPTH)  # the foot is below the trunk; never divide by ~0
                fx = (self._inertia * ddpitch / len(feet) + r[0] * fz) / depth + g.kv * (g.speed - x[IVX])
                fx = float(np.clip(fx, -self.robot.params.friction * fz, self.robot.params.friction * fz))
                J = self.robot.foot_jacobian(q, foot)[:, list(FOOT_JOINTS[foot])]
                u[list(FOOT_U[foot])] = -(J.T @ np.array([fx, fz]))
            for swing in (f for f in (FRONT, BACK) if f not in feet):
                target = self._land[swing][list(FOOT_JOINTS[swing])]
                idx = list(FOOT_U[swing])
                u[idx] = self._kp[idx] * (target - q[list(FOOT_JOINTS[swing])]) - self._kd[idx] * x[NQ + 3:][idx]
        if g.torque_limit is not None:
            np.clip(u, -g.torque_limit, g.torque_limit, out=u)
        return u

    def as_schedule_controller(self, schedule=None):
        """A ``controller(x, mode, phase, k)`` for [`hsddp_gym.core.rollout.rollout`][hsddp_gym.core.rollout.rollout];
        with a schedule, the touchdown foot of each flight phase comes from it."""

        def controller(x, mode, phase, k):
            td = schedule.bounding_touchdown_foot(phase) if schedule is not None and mode == Mode.FLIGHT else None
            return self.torque(x, mode, td)

        return controller


@dataclasses.dataclass(frozen=True)
class ContactEventGains:
    """Gains of [`ContactEventBoundingController`][ContactEventBoundingController] (defaults: tuned in
    ``hsddp_gym/Bounding-v0`` at its default settings, 5 ms control period; they give a ~165 ms cycle of 60 ms stances
    and 15-25 ms flights at ~1 m/s).

    Attributes:
        speed: desired forward speed [m/s].
        stance_duration: time a leg pushes after its touchdown [s].
        flight_duration: flight time the vertical lift-off speed is aimed at [s].
        retract_duration: time a leg folds after its stance before it reaches for the ground [s].
        initial_stance_elapsed: stance time already elapsed for a leg in contact at the first observation [s].
        pitch_rate: magnitude of the lift-off pitch rate aimed at [rad/s].
        pitch_gain: lift-off pitch-rate change per rad of pitch error [1/s].
        horizon_floor: smallest time-to-lift-off used by the force targets [s].
        height: desired trunk height [m]; height_gain: lift-off vertical speed per m of height error [1/s].
        speed_gain: horizontal acceleration per m/s of speed error [1/s].
        weight_fx, weight_fz, weight_pitch: least-squares weights of the force / moment targets.
        touchdown_leg, retract_leg: hip-to-foot height when reaching for the ground / folded [m].
        raibert: foot placement ahead of the hip per m/s of speed error [s].
        neutral: fraction of ``vx * stance_duration / 2`` the foot is placed ahead of the hip.
        kp, kd: swing-leg joint PD gains (4,) (``kd * dt / I`` must stay below 2 for the light legs at the
            control period ``dt``, hence the small knee damping).
        torque_limit: saturate the output [N m].
    """

    speed: float = 1.0
    stance_duration: float = 0.05
    flight_duration: float = 0.044
    retract_duration: float = 0.049
    initial_stance_elapsed: float = 0.003
    pitch_rate: float = 5.84
    pitch_gain: float = 6.2
    horizon_floor: float = 0.033
    height: float = 0.297
    height_gain: float = 5.6
    speed_gain: float = 5.0
    weight_fx: float = 0.16
    weight_fz: float = 1.0
    weight_pitch: float = 187.0
    touchdown_leg: float = 0.3
    retract_leg: float = 0.174
    raibert: float = 0.039
    neutral: float = 0.088
    kp: tuple = (40.0, 30.0, 40.0, 30.0)
    kd: tuple = (0.8, 0.15, 0.8, 0.15)
    torque_limit: float = 33.0

    def __post_init__(self) -> None:
        for name in ("stance_duration", "flight_duration", "horizon_floor", "height", "weight_fz",
                     "touchdown_leg", "retract_leg", "torque_limit"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ContactEventGains.{name} must be a positive finite number, got {value!r}")
        for name in ("retract_duration", "initial_stance_elapsed", "pitch_rate", "pitch_gain", "height_gain",
                     "speed_gain", "weight_fx", "weight_pitch", "raibert", "neutral"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"ContactEventGains.{name} must be a finite number >= 0, got {value!r}")
        for name in ("kp", "kd"):
            if len(getattr(self, name)) != NU:
                raise ValueError(f"ContactEventGains.{name} must have {NU} entries, got {getattr(self, name)!r}")


_STANCE, _SWING = "stance", "swing"


class ContactEventBoundingController:
    """The bounding controller for state-based contacts: stance and swing of each leg follow the observed
    touchdowns and the controller's own timers (see the module docstring). It keeps memory: call
    [`reset`][reset] at the start of an episode and [`torque`][torque] once per control period ``dt``.

    Args:
        dt: control period [s]. robot: the model. gains: [`ContactEventGains`][ContactEventGains].
    """

    def __init__(self, dt: float, robot: CheetahModel | None = None,
                 gains: ContactEventGains = ContactEventGains()) -> None:
        if not isinstance(gains, ContactEventGains):
            raise TypeError(f"gains must be a ContactEventGains, got {type(gains).__name__}")
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a positive finite number [s], got {dt!r}")
        self.dt = float(dt)
        self.robot = robot if robot is not None else CheetahModel()
        self.gains = gains
        self._kp = np.asarray(gains.kp, dtype=float)
        self._kd = np.asarray(gains.kd, dtype=float)
        p = self.robot.params
        self._mass = p.total_mass
        self._gravity = p.gravity
        self._mu = p.friction
        self._l1, self._l2 = p.thigh.length, p.shank.length
        legs = 2 * (p.thigh.mass + p.shank.mass)
        self._inertia = p.trunk.inertia_yy + legs * p.hip_offset ** 2
        self.reset()

    def reset(self) -> None:
        """Forget the episode (new lists, so shallow copies reset independently)."""
        self.leg_state: list[str] | None = None
        self.leg_time = [0.0, 0.0]

    def torque(self, x: np.ndarray, contact) -> np.ndarray:
        """Joint torques (4,) for state ``x`` (14,) and contact flags ``[front, back]``; advances the timers
        by ``dt``."""
        x = check_vector(x, NX, "x")
        g = self.gains
        contact = (bool(contact[FRONT]), bool(contact[BACK]))
        if self.leg_state is None:  # first observation: legs on the ground are mid-stance
            self.leg_state = [_STANCE if c else _SWING for c in contact]
            self.leg_time = [g.initial_stance_elapsed if c else g.retract_duration for c in contact]
        for f in (FRONT, BACK):
            if self.leg_state[f] == _STANCE:
                if self.leg_time[f] >= g.stance_duration:
                    self.leg_state[f], self.leg_time[f] = _SWING, 0.0
            elif contact[f] and self.leg_time[f] >= g.retract_duration:
                self.leg_state[f], self.leg_time[f] = _STANCE, 0.0
        u = np.zeros(NU)
        stance = [f for f in (FRONT, BACK) if self.leg_state[f] == _STANCE]
        if stance:
            self._stance_torque(x, stance, u)
        for f in (FRONT, BACK):
            if self.leg_state[f] == _SWING:
                self._swing_torque(x, f, u)
            self.leg_time[f] += self.dt
        return np.clip(u, -g.torque_limit, g.torque_limit, out=u)

    # ------------------------------------------------------------------ swing
    def _leg_ik(self, a: float, b: float) -> tuple[float, float]:
        """(hip, knee) putting the foot at ``(a, b)`` from the hip in the trunk frame, knee bent backward."""
        l1, l2 = self._l1, self._l2
        c = (a * a + b * b - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
        knee = -math.acos(min(max(c, -1.0), 1.0))
        hip = math.atan2(-a, -b) - math.atan2(l2 * math.sin(knee), l1 + l2 * math.cos(knee))
        return hip, knee

    def _swing_torque(self, x: np.ndarray, foot: int, u: np.ndarray) -> None:
        g = self.gains
        if self.leg_time[foot] < g.retract_duration:
            ahead, below = 0.0, g.retract_leg
        else:
            vx = x[IVX]
            ahead = g.neutral * vx * g.stance_duration / 2.0 + g.raibert * (vx - g.speed)
            below = g.touchdown_leg
        # world offset (ahead, -below) in the trunk frame (positive pitch is nose-down)
        c, s = math.cos(x[IPITCH]), math.sin(x[IPITCH])
        target = np.array(self._leg_ik(ahead * c + below * s, ahead * s - below * c))
        j, iu = list(FOOT_JOINTS[foot]), list(FOOT_U[foot])
        u[iu] = self._kp[iu] * (target - x[j]) - self._kd[iu] * x[NQ + np.asarray(j)]

    # ------------------------------------------------------------------ stance
    def _stance_torque(self, x: np.ndarray, feet: list[int], u: np.ndarray) -> None:
        g = self.gains
        q = x[:NQ]
        single = feet[0] if len(feet) == 1 else None
        elapsed = self.leg_time[single] if single is not None else 0.0
        t_rem = max(g.stance_duration - elapsed, g.horizon_floor)
        vz_lift_off = self._gravity * g.flight_duration / 2.0 + g.height_gain * (g.height - q[IZ])
        fz = self._mass * (self._gravity + (vz_lift_off - x[IVZ]) / t_rem)
        fx = self._mass * g.speed_gain * (g.speed - x[IVX])
        positions = self.robot.foot_positions(q)
        if single is not None:
            sign = 1.0 if single == BACK else -1.0  # a back stance ends pitching nose-down
            pitch = q[IPITCH]
            rate_target = sign * g.pitch_rate - g.pitch_gain * (pitch + sign * g.pitch_rate * g.flight_duration / 2.0)
            moment = self._inertia * (rate_target - x[NQ + IPITCH]) / t_rem
            forces = {single: self._allocate(positions[single] - q[[0, IZ]], np.array([fx, fz, moment]))}
        else:  # double stance: share the force, no pitch control
            half = max(fz / 2.0, 0.0)
            forces = {f: np.array([float(np.clip(fx / 2.0, -self._mu * half, self._mu * half)), half]) for f in feet}
        for f, force in forces.items():
            J = self.robot.foot_jacobian(q, f)[:, list(FOOT_JOINTS[f])]
            u[list(FOOT_U[f])] = -(J.T @ force)

    def _allocate(self, r: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Foot force ``[fx, fz]`` inside the friction cone closest (weighted least squares) to the desired
        ``[Fx, Fz, pitch moment]``; the moment of ``F`` at ``r`` from the trunk origin is ``r_z F_x - r_x F_z``."""
        g = self.gains
        A = np.array([[1.0, 0.0], [0.0, 1.0], [r[1], -r[0]]])
        w = np.array([g.weight_fx, g.weight_fz, g.weight_pitch])
        f = np.linalg.solve(A.T @ (w[:, None] * A), A.T @ (w * wrench))
        if f[1] >= 0.0 and abs(f[0]) <= self._mu * f[1]:
            return f
        best, cost = np.zeros(2), float(wrench @ (w * wrench))
        for edge in (np.array([self._mu, 1.0]), np.array([-self._mu, 1.0])):
            a = A @ edge
            lam = max(float(a @ (w * wrench)) / float(a @ (w * a)), 0.0)
            e = lam * a - wrench
            c = float(e @ (w * e))
            if c < cost:
                best, cost = lam * edge, c
        return best


class HeuristicPolicy(Policy):
    """The heuristic bounding controller driven by the env's contact flags.

    It acts with
    [`ContactEventBoundingController`][hsddp_gym.planners.policies.heuristic.ContactEventBoundingController]
    (``self.gait``): a per-leg stance/swing state machine started by the observed touchdowns, with a fixed stance time
    after which the leg is actively folded, a wrench-based stance force (height, speed, bounding pitch rate) and Raibert
    foot placement. The observation's contact flags and the policy's own timers are its only gait inputs (the gait clock
    is not used).

    ``self.controller`` is the schedule-driven
    [`HeuristicBoundingController`][hsddp_gym.planners.policies.heuristic.HeuristicBoundingController]
    (the planner's warm start, ``torque(x, mode)``), kept for callers that supply the contact mode from a
    schedule (e.g. the MPC's fallback); it is not used by `act`.

    Args:
        gains: [`HeuristicGains`][HeuristicGains] of ``self.controller`` (the desired speed defaults to the env's
            target speed).
        gait_gains: [`ContactEventGains`][ContactEventGains] of ``self.gait`` (default: tuned for the env's defaults,
            with the env's target speed and torque limit).
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
