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
:mod:`hsddp_gym.references`) with the hip shifted by a Raibert-style speed correction.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hsddp_gym.conventions import BACK, FOOT_JOINTS, FOOT_U, FRONT, IPITCH, IVX, IVZ, IZ, JOINT_DOFS, NQ, NU, NX, Mode
from hsddp_gym.model import CheetahModel
from hsddp_gym.references import end_of_mode_reference
from hsddp_gym.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.validation import check_vector


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
        robot: the model. gains: :class:`HeuristicGains`.
    """

    def __init__(self, robot: CheetahModel | None = None, gains: HeuristicGains = HeuristicGains()) -> None:
        self.robot = robot if robot is not None else CheetahModel()
        if not isinstance(gains, HeuristicGains):
            raise TypeError(f"gains must be a HeuristicGains, got {type(gains).__name__}")
        self.gains = gains
        self._kp = np.asarray(gains.kp, dtype=float)
        self._kd = np.asarray(gains.kd, dtype=float)
        # touchdown postures: the front foot lands after back stance, the back foot after front stance
        self._land = {FRONT: end_of_mode_reference(Mode.FLIGHT, FRONT, gains.speed, params=self.robot.params),
                      BACK: end_of_mode_reference(Mode.FLIGHT, BACK, gains.speed, params=self.robot.params)}
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
                fx = (self._inertia * ddpitch / len(feet) + r[0] * fz) / r[1] + g.kv * (g.speed - x[IVX])
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
        """A ``controller(x, mode, phase, k)`` for :func:`hsddp_gym.rollout.rollout`; with a schedule, the
        touchdown foot of each flight phase comes from it."""

        def controller(x, mode, phase, k):
            td = schedule.bounding_touchdown_foot(phase) if schedule is not None and mode == Mode.FLIGHT else None
            return self.torque(x, mode, td)

        return controller
