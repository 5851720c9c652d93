"""The planar Mini Cheetah as a Pinocchio model, and its foot kinematics.

The kinematic tree is ``x (PX) -> z (PZ) -> pitch (RY, trunk) -> {front, back} hip (RY, thigh) -> knee
(RY, shank) -> foot`` (a point at the end of the shank). The two prismatic joints carry massless bodies,
so ``nq = nv = 7`` and the neutral configuration is all zeros (legs straight down, body level, trunk
origin at z = 0 -- add ``leg_length`` to stand on the ground). See
[`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]. """

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hsddp_gym.core.conventions import FEET, FOOT_JOINTS, FOOT_NAMES, FOOT_SIGN, IPITCH, IX, IZ, NQ, NV, NX
from hsddp_gym.core.params import DEFAULT_PARAMS, LinkParams, RobotParams
from hsddp_gym.util.validation import check_vector

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _planar_inertia(link: LinkParams) -> pin.Inertia:
    """A spatial inertia whose I_yy about the CoM is ``link.inertia_yy`` (the other axes cannot act)."""
    com = np.array([0.0, 0.0, link.com_z])
    return pin.Inertia(link.mass, com, np.eye(3) * link.inertia_yy)


def build_pinocchio_model(params: RobotParams = DEFAULT_PARAMS) -> tuple[pin.Model, tuple[int, int]]:
    """Build the planar model.

    Returns:
        ``(model, foot_frame_ids)`` with the Pinocchio model (nq = nv = 7) and the frame ids of the
        front and back feet.
    """
    model = pin.Model()
    model.name = "planar_mini_cheetah"
    eye = pin.SE3.Identity()
    jx = model.addJoint(0, pin.JointModelPX(), eye, "x")
    model.appendBodyToJoint(jx, pin.Inertia.Zero(), eye)
    jz = model.addJoint(jx, pin.JointModelPZ(), eye, "z")
    model.appendBodyToJoint(jz, pin.Inertia.Zero(), eye)
    jb = model.addJoint(jz, pin.JointModelRY(), eye, "pitch")
    model.appendBodyToJoint(jb, _planar_inertia(params.trunk), eye)
    model.addFrame(pin.Frame("trunk", jb, eye, pin.FrameType.OP_FRAME))
    foot_ids = []
    for foot in FEET:
        name = FOOT_NAMES[foot]
        hip_at = pin.SE3(np.eye(3), np.array([FOOT_SIGN[foot] * params.hip_offset, 0.0, 0.0]))
        jh = model.addJoint(jb, pin.JointModelRY(), hip_at, f"hip_{name}")
        model.appendBodyToJoint(jh, _planar_inertia(params.thigh), eye)
        knee_at = pin.SE3(np.eye(3), np.array([0.0, 0.0, -params.thigh.length]))
        jk = model.addJoint(jh, pin.JointModelRY(), knee_at, f"knee_{name}")
        model.appendBodyToJoint(jk, _planar_inertia(params.shank), eye)
        foot_at = pin.SE3(np.eye(3), np.array([0.0, 0.0, -params.shank.length]))
        foot_ids.append(model.addFrame(pin.Frame(f"foot_{name}", jk, foot_at, pin.FrameType.OP_FRAME)))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -params.gravity]), np.zeros(3))
    model.effortLimit[:] = 0.0
    model.effortLimit[3:] = params.torque_limit
    if model.nq != NQ or model.nv != NV:  # pragma: no cover - guards the convention module
        raise RuntimeError(f"model has nq={model.nq}, nv={model.nv}; conventions say {NQ}, {NV}")
    return model, (foot_ids[0], foot_ids[1])


class CheetahModel:
    """The robot: parameters, the Pinocchio model and foot kinematics.

    A ``CheetahModel`` only describes; algorithms that need scratch space create their own
    ``pin.Data`` with [`new_data`][new_data] (Pinocchio derivative routines leave state in a Data that
    corrupts other algorithms run on it later).

    Args:
        params: physical parameters (default: the paper's robot).
    """

    def __init__(self, params: RobotParams = DEFAULT_PARAMS) -> None:
        if not isinstance(params, RobotParams):
            raise TypeError(f"params must be a RobotParams, got {type(params).__name__}")
        self.params = params
        self.model, self.foot_frame_ids = build_pinocchio_model(params)
        self.foot_joint_ids = tuple(self.model.frames[f].parentJoint for f in self.foot_frame_ids)
        self._data = self.model.createData()
        self._jac = np.zeros((6, NV))

    def new_data(self) -> pin.Data:
        """A fresh ``pin.Data`` for this model."""
        return self.model.createData()

    @property
    def total_mass(self) -> float:
        """Total mass from the Pinocchio model [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    # ----------------------------------------------------------------------------- kinematics
    def foot_positions(self, q: np.ndarray) -> np.ndarray:
        """World ``(x, z)`` of both feet.

        Args:
            q: configuration (7,).
        Returns:
            ``(2, 2)`` array, row ``foot`` = ``[x, z]``.
        """
        q = check_vector(q, NQ, "q")
        pin.framesForwardKinematics(self.model, self._data, q)
        out = np.empty((2, 2))
        for foot, fid in enumerate(self.foot_frame_ids):
            t = self._data.oMf[fid].translation
            out[foot, 0] = t[0]
            out[foot, 1] = t[2]
        return out

    def foot_heights(self, q: np.ndarray) -> np.ndarray:
        """Height above the ground of both feet, ``g_c(x)`` of the paper: (2,)."""
        return self.foot_positions(q)[:, 1]

    def foot_height(self, q: np.ndarray, foot: int) -> float:
        """Height above the ground of one foot for a configuration ``q`` (7,): ``foot_heights(q)[foot]`` (bit for
        bit), from the placement of that foot's frame alone (the solver's switching constraints)."""
        q = check_vector(q, NQ, "q")
        _check_foot(foot)
        pin.forwardKinematics(self.model, self._data, q)
        return float(pin.updateFramePlacement(self.model, self._data, self.foot_frame_ids[foot]).translation[2])

    def foot_velocities(self, x: np.ndarray) -> np.ndarray:
        """World ``(vx, vz)`` of both feet for a state ``x`` (14,): ``(2, 2)``."""
        x = check_vector(x, NX, "x")
        pin.forwardKinematics(self.model, self._data, x[:NQ], x[NQ:])
        out = np.empty((2, 2))
        for foot, fid in enumerate(self.foot_frame_ids):
            lin = pin.getFrameVelocity(self.model, self._data, fid, LWA).linear
            out[foot, 0] = lin[0]
            out[foot, 1] = lin[2]
        return out

    def foot_jacobian(self, q: np.ndarray, foot: int) -> np.ndarray:
        """``(2, 7)`` Jacobian of the foot's world ``(x, z)`` with respect to ``q``."""
        q = check_vector(q, NQ, "q")
        _check_foot(foot)
        J = pin.computeFrameJacobian(self.model, self._data, q, self.foot_frame_ids[foot], LWA)
        return J[[0, 2], :].copy()

    def place_feet(self, q: np.ndarray, feet: np.ndarray, iterations: int = 50, tolerance: float = 1e-12
                   ) -> np.ndarray:
        """The configuration ``q (7,)`` with the four joint angles moved so that the feet are at the world ``(x, z)``
        of ``feet (2, 2)`` [m], the trunk (``x``, ``z``, pitch) where ``q`` has it: Newton's method on each foot's
        position over its own (hip, knee), from ``q``'s joint angles (which pick the knee's bend). A copy.

        Raises:
            ValueError: no convergence to ``tolerance`` [m] within ``iterations`` (a foot out of its leg's reach).
        """
        q = np.array(check_vector(q, NQ, "q"), dtype=float)
        feet = np.asarray(feet, dtype=float)
        if feet.shape != (2, 2) or not np.all(np.isfinite(feet)):
            raise ValueError(f"feet must be a finite (2, 2) array of (x, z) per foot, got {feet!r}")
        for _ in range(iterations):
            err = feet - self.foot_positions(q)
            if np.max(np.abs(err)) < tolerance:
                return q
            for foot, joints in enumerate(FOOT_JOINTS):
                J = self.foot_jacobian(q, foot)[:, list(joints)]
                q[list(joints)] += np.linalg.solve(J, err[foot])
        raise ValueError(f"feet {feet.tolist()} m are out of the legs' reach from the trunk at x = {q[IX]:.4g} m, "
                         f"z = {q[IZ]:.4g} m, pitch = {q[IPITCH]:.4g} rad")

    def hip_positions(self, q: np.ndarray) -> np.ndarray:
        """World ``(x, z)`` of both hips: ``(2, 2)``."""
        q = check_vector(q, NQ, "q")
        pin.forwardKinematics(self.model, self._data, q)
        return np.array([[self._data.oMi[j].translation[0], self._data.oMi[j].translation[2]]
                         for j in self._hip_joint_ids()])

    def _hip_joint_ids(self) -> tuple[int, int]:
        return tuple(self.model.parents[j] for j in self.foot_joint_ids)  # knee's parent is the hip

    def link_points(self, q: np.ndarray) -> np.ndarray:
        """Points to draw the robot: ``(2, 4, 2)`` = per foot ``[hip, knee, foot]`` world ``(x, z)`` plus
        the trunk origin in slot 3 (drawing helper)."""
        q = check_vector(q, NQ, "q")
        pin.framesForwardKinematics(self.model, self._data, q)
        out = np.empty((2, 4, 2))
        for foot, fid in enumerate(self.foot_frame_ids):
            knee = self.foot_joint_ids[foot]
            hip = self.model.parents[knee]
            for slot, pos in enumerate((self._data.oMi[hip].translation, self._data.oMi[knee].translation,
                                        self._data.oMf[fid].translation, self._data.oMi[3].translation)):
                out[foot, slot] = (pos[0], pos[2])
        return out

    def foot_height_derivatives(self, q: np.ndarray, foot: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Height of ``foot`` with its gradient and Hessian with respect to the state.

        The Hessian is exact for the planar chain: for revolute joints i, j of the foot's chain,
        ``d2 p_z / dq_i dq_j = -(p_z - o_z)`` where ``o`` is the pivot of the later of the two joints
        (a rotation about +y of a point about its pivot); prismatic joints add no curvature.

        Args:
            q: configuration (7,) (or the first 7 entries of a state).
            foot: ``FRONT`` or ``BACK``.
        Returns:
            ``(g, g_x (14,), g_xx (14, 14))``; the height does not depend on velocities.
        """
        q = check_vector(np.asarray(q)[:NQ] if np.ndim(q) == 1 and np.size(q) == NX else q, NQ, "q")
        _check_foot(foot)
        data = self._data
        pin.forwardKinematics(self.model, data, q)
        p = pin.updateFramePlacement(self.model, data, self.foot_frame_ids[foot]).translation.tolist()
        knee = self.foot_joint_ids[foot]
        hip = self._hip_joint_ids()[foot]
        hip_q, knee_q = FOOT_JOINTS[foot]
        oMi = data.oMi
        pivots = ((IPITCH, oMi[3].translation.tolist()), (hip_q, oMi[hip].translation.tolist()),
                  (knee_q, oMi[knee].translation.tolist()))
        g_x = np.zeros(NX)
        g_xx = np.zeros((NX, NX))
        g_x[IZ] = 1.0
        g_x[IX] = 0.0
        for a, (ia, oa) in enumerate(pivots):
            g_x[ia] = -(p[0] - oa[0])
            for ib, ob in pivots[a:]:
                # the later pivot of (a, b) is b since pivots are in chain order
                val = -(p[2] - ob[2])
                g_xx[ia, ib] = val
                g_xx[ib, ia] = val
        return float(p[2]), g_x, g_xx


def _check_foot(foot: int) -> None:
    if foot not in FEET:
        raise ValueError(f"foot must be one of {FEET} (FRONT, BACK), got {foot!r}")
