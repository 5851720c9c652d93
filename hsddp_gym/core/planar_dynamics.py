"""The planar Mini Cheetah's contact dynamics and their derivatives, compiled (numba): the planner's hot path.

The same equations as [`hsddp_gym.core.dynamics.HybridDynamics`][hsddp_gym.core.dynamics.HybridDynamics] solves with
Pinocchio (paper eq. 11), for the feet ``c`` in contact in a mode::

    M(q) a + b(q, v) = tau + J_c(q)^T f,      J_c a + dJ_c v = 0

with ``J_c`` the world ``(x, z)`` rows of the feet in contact (Pinocchio's 3D contacts carry a third, identically
zero ``y`` row, which its proximal solver handles; here it is left out, and its force and derivative rows are
zero). The rigid-body terms and their partial derivatives come from `hsddp_gym.core._planar_terms`
(generated symbolically by [`hsddp_gym.core.planar_codegen`][hsddp_gym.core.planar_codegen]); the KKT system is solved
through the Schur complement ``G = J_c M^-1 J_c^T``, and its derivatives follow from differentiating it (``r = M a + b -
J_c^T f``, ``c = J_c a + dJ_c v``)::

    df/dz = G^-1 (-c_z - J_c M^-1 (dtau/dz - r_z)),     da/dz = M^-1 (dtau/dz - r_z + J_c^T df/dz)

for ``z`` in ``(q, v, tau)``: the numbers of Pinocchio's ``computeConstraintDynamicsDerivatives`` (and
``computeABADerivatives`` in flight) to rounding, in the layout of
[`hsddp_gym.core.dynamics.Linearization`][hsddp_gym.core.dynamics.Linearization] (``tests/test_planar_dynamics.py``).
One call rolls a whole phase out ([`rollout_phase`][rollout_phase]), with no Python in the per-knot loop: a pass over a
re-plan's horizon with derivatives costs about a fifth of the same Pinocchio calls (``python experiments/bench_mpc.py``
prints both). """

from __future__ import annotations

import numba
import numpy as np
import pinocchio as pin

from hsddp_gym.core import _planar_terms
from hsddp_gym.core.conventions import NQ, NU, NV
from hsddp_gym.core.model import LWA, CheetahModel
from hsddp_gym.core.small_linalg import cholesky_solve


def kernel_params(robot: CheetahModel) -> np.ndarray:
    """The parameter vector ``p (13,)`` of the compiled terms (`hsddp_gym.core.planar_codegen.PARAM_NAMES`),
    read from ``robot``'s Pinocchio model (so a model changed after it was built, e.g. another gravity, is the one
    compiled) and checked against it: Pinocchio's mass matrix, bias and feet Jacobians at a few states must equal
    the compiled terms', else ``ValueError`` (a model of another structure than the generated one)."""
    if not isinstance(robot, CheetahModel):
        raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
    model = robot.model
    jb, jh, jk = 3, 4, 5  # pitch, front hip, front knee (hsddp_gym.core.model.build_pinocchio_model)
    foot = model.frames[robot.foot_frame_ids[0]].placement.translation
    links = [model.inertias[j] for j in (jb, jh, jk)]
    p = np.array([links[0].mass, links[0].inertia[1, 1], links[0].lever[2], links[1].mass, links[1].inertia[1, 1],
                  links[1].lever[2], -model.jointPlacements[jk].translation[2], links[2].mass,
                  links[2].inertia[1, 1], links[2].lever[2], -foot[2], model.jointPlacements[jh].translation[0],
                  -model.gravity.linear[2]], dtype=np.float64)
    _check_against_pinocchio(robot, p)
    return p


def _check_against_pinocchio(robot: CheetahModel, p: np.ndarray) -> None:
    """``ValueError`` unless the compiled terms with ``p`` reproduce Pinocchio's at three seeded states."""
    model, data = robot.model, robot.model.createData()
    M, b, J, drift = np.zeros((NV, NV)), np.zeros(NV), np.zeros((4, NV)), np.zeros(4)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q, v = rng.uniform(-1.0, 1.0, NQ), rng.uniform(-3.0, 3.0, NV)
        _planar_terms.terms(q, v, p, M, b, J, drift)
        M_ref = pin.crba(model, data, q)
        M_ref = np.triu(M_ref) + np.triu(M_ref, 1).T
        b_ref = pin.rnea(model, data, q, v, np.zeros(NV))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J_ref = np.vstack([pin.getFrameJacobian(model, data, fid, LWA)[[0, 2]] for fid in robot.foot_frame_ids])
        for name, got, ref in (("mass matrix", M, M_ref), ("bias", b, b_ref), ("feet Jacobians", J, J_ref)):
            if not np.allclose(got, ref, rtol=1e-9, atol=1e-9):
                raise ValueError(f"robot: its Pinocchio model is not the planar Mini Cheetah the compiled dynamics "
                                 f"were generated for ({name} differs by {np.max(np.abs(got - ref)):.3g}); "
                                 "see hsddp_gym.core.planar_codegen")


@numba.njit(cache=True)
def knot_dynamics(q, v, tau, mode, p, derivs, ws, a, lam, a_q, a_v, a_tau, l_q, l_v, l_tau):
    """Accelerations and contact forces of one knot, and optionally their derivatives.

    Args:
        q: ``(7,)``.
        v: ``(7,)``.
        tau: ``(7,)`` generalized forces (the base rows are 0 for the robot).
        mode: contact mode bits (``FRONT_STANCE = 1``, ``BACK_STANCE = 2``).
        p: ``(13,)``, [`kernel_params`][kernel_params].
        derivs: also the derivatives.
        ws: a [`Scratch`][Scratch]'s arrays (``ws.arrays``).
    Writes:
        ``a (7,)``; ``lam (>= 3 nc,)``: Pinocchio's ``lambda_c`` layout, ``[fx, fy, fz]`` per foot in contact in
        foot order (``fy = 0``); with ``derivs``: ``a_q, a_v, a_tau (7, 7)`` and, in stance, ``l_q, l_v, l_tau``
        (``>= 3 nc``, 7) in the same row layout (the rows past ``3 nc`` are not touched).
    Returns:
        False when ``M`` or ``G`` is not positive definite (a non-finite configuration): the outputs are then
        undefined. Non-finite velocities or torques give non-finite outputs (the caller checks the states).
    """
    M, b, J, drift, Lm, Minv, Jc, MJ, G, Lg, Ginv, rhs, f_all, r_q, r_v, c_q, c_v, R, D, eye = ws
    _planar_terms.terms(q, v, p, M, b, J, drift)
    if not cholesky_solve(M, eye, Lm, Minv):
        return False
    # rows of the feet in contact (x, z per foot, in foot order)
    nc = 0
    for foot in range(2):
        if mode & (1 << foot):
            for r in range(2):
                for j in range(NV):
                    Jc[nc, j] = J[2 * foot + r, j]
                rhs[nc] = drift[2 * foot + r]
                nc += 1
    # a0 = M^-1 (tau - b)
    for i in range(NV):
        s = 0.0
        for j in range(NV):
            s += Minv[i, j] * (tau[j] - b[j])
        a[i] = s
    for i in range(4):
        f_all[i] = 0.0
    if nc > 0:
        # MJ = M^-1 Jc^T (7, nc), G = Jc M^-1 Jc^T (nc, nc)
        for i in range(NV):
            for r in range(nc):
                s = 0.0
                for j in range(NV):
                    s += Minv[i, j] * Jc[r, j]
                MJ[i, r] = s
        for r in range(nc):
            for c in range(nc):
                s = 0.0
                for j in range(NV):
                    s += Jc[r, j] * MJ[j, c]
                G[r, c] = s
        if not cholesky_solve(G[:nc, :nc], eye[:nc, :nc], Lg, Ginv):
            return False
        # f = -G^-1 (Jc a0 + drift), a = a0 + MJ f
        for r in range(nc):
            s = rhs[r]
            for j in range(NV):
                s += Jc[r, j] * a[j]
            rhs[r] = -s
        ci = 0
        for foot in range(2):
            if mode & (1 << foot):
                for rr in range(2):
                    r = 2 * ci + rr
                    s = 0.0
                    for c in range(nc):
                        s += Ginv[r, c] * rhs[c]
                    f_all[2 * foot + rr] = s
                ci += 1
        ci = 0
        for foot in range(2):
            if mode & (1 << foot):
                lam[3 * ci] = f_all[2 * foot]
                lam[3 * ci + 1] = 0.0
                lam[3 * ci + 2] = f_all[2 * foot + 1]
                ci += 1
        for i in range(NV):
            s = a[i]
            ci = 0
            for foot in range(2):
                if mode & (1 << foot):
                    s += MJ[i, 2 * ci] * f_all[2 * foot] + MJ[i, 2 * ci + 1] * f_all[2 * foot + 1]
                    ci += 1
            a[i] = s
    if not derivs:
        return True
    _planar_terms.partials(q, v, a, f_all, p, r_q, r_v, c_q, c_v)
    for which in range(3):  # z = q, v, tau: R = dtau/dz - r_z (7, 7); C = -c_z (nc, 7)
        out_a = a_q if which == 0 else (a_v if which == 1 else a_tau)
        out_l = l_q if which == 0 else (l_v if which == 1 else l_tau)
        for i in range(NV):
            for j in range(NV):
                if which == 0:
                    R[i, j] = -r_q[i, j]
                elif which == 1:
                    R[i, j] = -r_v[i, j]
                else:
                    R[i, j] = 1.0 if i == j else 0.0
        # W = M^-1 R into out_a
        for i in range(NV):
            for j in range(NV):
                s = 0.0
                for k in range(NV):
                    s += Minv[i, k] * R[k, j]
                out_a[i, j] = s
        if nc == 0:
            continue
        # D = C - Jc W (nc, 7), df = G^-1 D, da = W + MJ df
        r = 0
        for foot in range(2):
            if mode & (1 << foot):
                for rr in range(2):
                    for j in range(NV):
                        s = 0.0
                        if which == 0:
                            s = -c_q[2 * foot + rr, j]
                        elif which == 1:
                            s = -c_v[2 * foot + rr, j]
                        for k in range(NV):
                            s -= Jc[r, k] * out_a[k, j]
                        D[r, j] = s
                    r += 1
        for r in range(nc):
            ci, rr = r // 2, r % 2
            row = 3 * ci + (2 if rr else 0)
            for j in range(NV):
                s = 0.0
                for c in range(nc):
                    s += Ginv[r, c] * D[c, j]
                out_l[row, j] = s
        for ci in range(nc // 2):
            for j in range(NV):
                out_l[3 * ci + 1, j] = 0.0
        for i in range(NV):
            for j in range(NV):
                s = out_a[i, j]
                for r in range(nc):
                    s += MJ[i, r] * out_l[3 * (r // 2) + (2 if r % 2 else 0), j]
                out_a[i, j] = s
    return True


class Scratch:
    """Work arrays of [`knot_dynamics`][knot_dynamics] (``arrays``: a tuple to pass as its ``ws``)."""

    def __init__(self) -> None:
        n = NV
        self.arrays = (np.zeros((n, n)), np.zeros(n), np.zeros((4, n)), np.zeros(4), np.zeros((n, n)),
                       np.zeros((n, n)), np.zeros((4, n)), np.zeros((n, 4)), np.zeros((4, 4)), np.zeros((4, 4)),
                       np.zeros((4, 4)), np.zeros(4), np.zeros(4), np.zeros((n, n)), np.zeros((n, n)),
                       np.zeros((4, n)), np.zeros((4, n)), np.zeros((n, n)), np.zeros((4, n)), np.eye(n))


@numba.njit(cache=True)
def rollout_phase(X, U, K, c, feedback, k0, k1, mode, h, semi_implicit, p, derivs, ws, tau, lam6, acc, a_q, a_v,
                  a_tau, l_q, l_v, l_tau):
    """Roll knots ``k0 .. k1 - 1`` of one phase out: ``U[k] = K[k] X[k] + c[k]`` (``feedback``; else ``U[k] =
    c[k]``), the dynamics of ``mode`` ([`knot_dynamics`][knot_dynamics], with ``derivs`` their derivatives into row
    ``k`` of ``a_q, a_v, a_tau (N, 7, 7)``, ``l_q, l_v, l_tau (N, 6, 7)``), ``lam6[k]``, ``acc[k]``, and the step ``h``
    into ``X[k + 1]`` (semi-implicit Euler: ``v+ = v + h a``, ``q+ = q + h v+``; else explicit Euler).

    Shapes: ``X (>= k1 + 1, 14)``, ``U (>= k1, 4)``, ``K (>= k1, 4, 14)`` (any ``(1, 4, 14)`` without ``feedback``),
    ``c (>= k1, 4)``, ``lam6 (>= k1, 6)``, ``tau (7,)`` scratch; without ``derivs``, ``acc (1, 7)`` and the derivative
    arrays ``(1, ., 7)`` suffice (scratch).
    Returns the first knot whose dynamics failed (a non-finite state), or -1.
    """
    for k in range(k0, k1):
        x = X[k]
        u = U[k]
        if feedback:
            Kk = K[k]
            for i in range(NU):
                s = 0.0
                for j in range(2 * NQ):
                    s += Kk[i, j] * x[j]
                u[i] = s + c[k, i]
        else:
            for i in range(NU):
                u[i] = c[k, i]
        for i in range(3):
            tau[i] = 0.0
        for i in range(NU):
            tau[3 + i] = u[i]
        kd = k if derivs else 0  # without derivatives, acc and the derivative arrays may be single-row scratch
        ak = acc[kd]
        if not knot_dynamics(x[:NQ], x[NQ:], tau, mode, p, derivs, ws, ak, lam6[k], a_q[kd], a_v[kd], a_tau[kd],
                             l_q[kd], l_v[kd], l_tau[kd]):
            return k
        xn = X[k + 1]
        for i in range(NV):
            xn[NQ + i] = x[NQ + i] + ak[i] * h
        for i in range(NQ):
            xn[i] = x[i] + (xn[NQ + i] if semi_implicit else x[NQ + i]) * h
    return -1


@numba.njit(cache=True)
def linearize_knots(X, U, modes, p, ws, tau, lam6, acc, a_q, a_v, a_tau, l_q, l_v, l_tau):
    """[`knot_dynamics`][knot_dynamics] with derivatives at the knots ``k < N`` of a given trajectory ``X (>= N, 14)``,
    ``U (N, 4)`` in ``modes (N,)`` (int64), into row ``k`` of ``lam6 (N, 6)``, ``acc (N, 7)``, ``a_q, a_v, a_tau
    (N, 7, 7)``, ``l_q, l_v, l_tau (N, 6, 7)``; ``tau (7,)`` scratch. Returns the first knot that failed, or -1."""
    for k in range(U.shape[0]):
        x = X[k]
        for i in range(3):
            tau[i] = 0.0
        for i in range(NU):
            tau[3 + i] = U[k, i]
        if not knot_dynamics(x[:NQ], x[NQ:], tau, modes[k], p, True, ws, acc[k], lam6[k], a_q[k], a_v[k], a_tau[k],
                             l_q[k], l_v[k], l_tau[k]):
            return k
    return -1


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels with the types the solver passes, before anything is
    timed."""
    dyn_p = np.zeros(13)
    dyn_p[[0, 1, 3, 4, 7, 8]] = 1.0
    ws = Scratch().arrays
    n = 2
    X, U, K, c = np.zeros((n + 1, 2 * NQ)), np.zeros((n, NU)), np.zeros((n, NU, 2 * NQ)), np.zeros((n, NU))
    z7, z6 = np.zeros((n, NV, NV)), np.zeros((n, 6, NV))
    lam6, acc, tau = np.zeros((n, 6)), np.zeros((n, NV)), np.zeros(NV)
    for feedback in (True, False):
        for derivs in (True, False):
            rollout_phase(X, U, K, c, feedback, 0, n, 1, 0.001, True, dyn_p, derivs, ws, tau, lam6, acc, z7, z7.copy(),
                          z7.copy(), z6, z6.copy(), z6.copy())
    linearize_knots(X, U, np.zeros(n, dtype=np.int64), dyn_p, ws, tau, lam6, acc, z7, z7.copy(), z7.copy(), z6,
                    z6.copy(), z6.copy())


KERNELS = (rollout_phase, linearize_knots)
"""The compiled entry points the solver calls (numba dispatchers; the functions they call are compiled into them), for
the warm-up's cache checks."""
