"""Compiled (numba) elementwise kernels of the solver, fused over the horizon so that one call replaces a few dozen
small NumPy temporaries: the quadratic cost terms and the relaxed barriers (paper eq. 27,
[`relaxed_barrier`][hsddp_gym.planners.optimizer.barrier.relaxed_barrier]) of
[`Objective`][hsddp_gym.planners.optimizer.objective.Objective], and the assembly of the discrete Jacobians.

Every kernel does, element by element, the same IEEE operations in the same order as the NumPy expressions it
replaces (no fast-math, so no fused multiply-adds; NumPy's error model, so a division by zero gives inf or nan as in
NumPy), and the results are bit-identical to them. What is not elementwise stays in NumPy: the matrix products
(BLAS), the ``einsum`` contractions, the sums and the logarithm (NumPy's SIMD ``log`` rounds differently from the C
library's in about 1e-4 of the cases), so a barrier value is computed in two passes around one ``np.log``:
[`barrier_safe`][barrier_safe] then [`barrier_values`][barrier_values].

Constraint layout (N knots): torque rows ``umax - U`` (N, 4) and ``umax + U`` (N, 4); ground-force rows
``c = GRF @ A_grf.T`` (N, 6), weighted by the stance mask ``mask`` (N, 6). Compiled once per machine with the
backward pass, in [`hsddp_gym.planners.optimizer.riccati.warm_up`][hsddp_gym.planners.optimizer.riccati.warm_up] (cached
on disk). The rollout's dynamics and integrator step are compiled in
[`hsddp_gym.core.planar_dynamics`][hsddp_gym.core.planar_dynamics]. """

from __future__ import annotations

import numba
import numpy as np

from hsddp_gym.core.conventions import NGRF, NQ, NU, NX
from hsddp_gym.core.dynamics import assemble_linearization


@numba.njit(cache=True, error_model="numpy")
def _slope_curvature(c, delta):
    """``(dB/dc, d2B/dc2)`` of the relaxed barrier at ``c`` (the log branch for ``c > delta``)."""
    if c > delta:
        return -1.0 / c, 1.0 / (c * c)  # c * c overflows to inf for c > 1e154: curvature 0, its limit
    t = (c - 2.0 * delta) / delta
    return t / delta, 1.0 / (delta * delta)


@numba.njit(cache=True, error_model="numpy")
def quadratic_derivatives(X, U, GRF, XR, YR, h, Qd, Rd, Sd, X_pre, XF, QF, l_x, l_u, l_xx, l_uu, gy, W, Phi_x,
                          Phi_xx):
    """The quadratic cost terms' derivatives, written whole (off-diagonals zeroed).

    Args:
        X (>= N, 14), U (N, 4), GRF (N, 4): the trajectory; XR (N, 14), YR (N, 4), h (N,), Qd (N, 14),
            Rd (N, 4), Sd (N, 4): per-knot references, steps and diagonal weights; X_pre, XF, QF (n, 14): the
            pre-switch states, terminal references and weights.
        l_x (N, 14), l_u (N, 4), l_xx (N, 14, 14), l_uu (N, 4, 4): running cost ``h (dx' Q dx + u' R u)``;
        gy (N, 4), W (N, 4, 4): gradient and Hessian of the force-tracking term in force space;
        Phi_x (n, 14), Phi_xx (n, 14, 14): terminal cost ``1/2 dx' Qf dx`` (outputs).
    """
    for k in range(U.shape[0]):
        two_h = 2.0 * h[k]
        for i in range(NX):
            w = two_h * Qd[k, i]
            l_x[k, i] = (X[k, i] - XR[k, i]) * w
            for j in range(NX):
                l_xx[k, i, j] = 0.0
            l_xx[k, i, i] = w
        for i in range(NU):
            w = two_h * Rd[k, i]
            l_u[k, i] = U[k, i] * w
            for j in range(NU):
                l_uu[k, i, j] = 0.0
            l_uu[k, i, i] = w
        for i in range(NGRF):
            w = two_h * Sd[k, i]
            gy[k, i] = (GRF[k, i] - YR[k, i]) * w
            for j in range(NGRF):
                W[k, i, j] = 0.0
            W[k, i, i] = w
    for p in range(X_pre.shape[0]):
        for i in range(NX):
            Phi_x[p, i] = (X_pre[p, i] - XF[p, i]) * QF[p, i]
            for j in range(NX):
                Phi_xx[p, i, j] = 0.0
            Phi_xx[p, i, i] = QF[p, i]


@numba.njit(cache=True, error_model="numpy")
def torque_barrier_derivatives(U, umax, delta, eps, l_u, l_uu):
    """Add the torque barriers ``eps (B(umax - u) + B(umax + u))`` to ``l_u`` (N, 4) and the diagonal of ``l_uu``
    (N, 4, 4) (in place; ``U`` (N, 4), ``umax``, ``delta``, ``eps`` scalars)."""
    for k in range(U.shape[0]):
        for i in range(NU):
            d_up, dd_up = _slope_curvature(umax - U[k, i], delta)
            d_lo, dd_lo = _slope_curvature(umax + U[k, i], delta)
            l_u[k, i] = l_u[k, i] + eps * (d_lo - d_up)
            l_uu[k, i, i] = l_uu[k, i, i] + eps * (dd_up + dd_lo)


@numba.njit(cache=True, error_model="numpy")
def force_barrier_derivatives(c, delta, eps, mask, dc, ddc):
    """Slope ``dc`` (N, 6) and curvature ``ddc`` (N, 6) of the ground-force barriers ``eps mask B(c)`` at the
    force rows ``c`` (N, 6) (outputs)."""
    for k in range(c.shape[0]):
        for j in range(c.shape[1]):
            s, cv = _slope_curvature(c[k, j], delta)
            w = eps * mask[k, j]
            dc[k, j] = s * w
            ddc[k, j] = cv * w


@numba.njit(cache=True, error_model="numpy")
def barrier_safe(U, c, umax, delta_torque, delta_grf, safe):
    """First pass of the barrier value: ``safe`` (N, 14) = the constraint where it is in the log branch
    (``> delta``), else 1 (columns: ``umax - U`` (4), ``umax + U`` (4), ``c`` (6)); its ``np.log`` feeds
    [`barrier_values`][barrier_values]."""
    for k in range(U.shape[0]):
        for i in range(NU):
            up = umax - U[k, i]
            lo = umax + U[k, i]
            safe[k, i] = up if up > delta_torque else 1.0
            safe[k, NU + i] = lo if lo > delta_torque else 1.0
        for j in range(c.shape[1]):
            v = c[k, j]
            safe[k, 2 * NU + j] = v if v > delta_grf else 1.0


@numba.njit(cache=True, error_model="numpy")
def barrier_values(U, c, umax, delta_torque, delta_grf, log_delta_torque, log_delta_grf, log_safe, mask, b_up, b_lo,
                   b_f):
    """Second pass of the barrier value: the relaxed barrier of every constraint, ``b_up``, ``b_lo`` (N, 4) and
    ``mask * B(c)`` as ``b_f`` (N, 6) (outputs), from ``log_safe = np.log(safe)`` (N, 14) of
    [`barrier_safe`][barrier_safe] and the NumPy logs of the two deltas."""
    for k in range(U.shape[0]):
        for i in range(NU):
            up = umax - U[k, i]
            lo = umax + U[k, i]
            if up > delta_torque:
                b_up[k, i] = -log_safe[k, i]
            else:
                t = (up - 2.0 * delta_torque) / delta_torque
                b_up[k, i] = 0.5 * (t * t - 1.0) - log_delta_torque
            if lo > delta_torque:
                b_lo[k, i] = -log_safe[k, NU + i]
            else:
                t = (lo - 2.0 * delta_torque) / delta_torque
                b_lo[k, i] = 0.5 * (t * t - 1.0) - log_delta_torque
        for j in range(c.shape[1]):
            v = c[k, j]
            if v > delta_grf:
                b = -log_safe[k, 2 * NU + j]
            else:
                t = (v - 2.0 * delta_grf) / delta_grf
                b = 0.5 * (t * t - 1.0) - log_delta_grf
            b_f[k, j] = b * mask[k, j]


def warm_up_kernels() -> None:
    """Call every kernel once on a 2-knot problem with the dtypes and layouts the solver passes (C-contiguous
    float64), so that numba compiles or loads them before anything is timed."""
    n, m = 2, 1
    z = np.zeros
    quadratic_derivatives(z((n + 1, NX)), z((n, NU)), z((n, NGRF)), z((n, NX)), z((n, NGRF)), np.ones(n),
                          z((n, NX)), z((n, NU)), z((n, NGRF)), z((m, NX)), z((m, NX)), z((m, NX)), z((n, NX)),
                          z((n, NU)), z((n, NX, NX)), z((n, NU, NU)), z((n, NGRF)), z((n, NGRF, NGRF)), z((m, NX)),
                          z((m, NX, NX)))
    torque_barrier_derivatives(z((n, NU)), 1.0, 0.1, 1.0, z((n, NU)), z((n, NU, NU)))
    force_barrier_derivatives(z((n, 6)), 0.1, 1.0, z((n, 6)), z((n, 6)), z((n, 6)))
    barrier_safe(z((n, NU)), z((n, 6)), 1.0, 0.1, 0.1, z((n, 2 * NU + 6)))
    barrier_values(z((n, NU)), z((n, 6)), 1.0, 0.1, 0.1, 0.0, 0.0, z((n, 2 * NU + 6)), z((n, 6)), z((n, NU)),
                   z((n, NU)), z((n, 6)))
    assemble_linearization(z((n, NQ, NQ)), z((n, NQ, NQ)), z((n, NQ, NQ)), z((n, 6)), z((n, 6, NQ)), z((n, 6, NQ)),
                           z((n, 6, NQ)), np.zeros(n, dtype=np.int64), np.ones(n), True,
                           np.zeros((4, NGRF, 2), dtype=np.int64), np.zeros(4, dtype=np.int64), z((n, NX, NX)),
                           z((n, NX, NU)), z((n, NGRF)), z((n, NGRF, NX)), z((n, NGRF, NU)))


KERNELS = (quadratic_derivatives, torque_barrier_derivatives, force_barrier_derivatives, barrier_safe, barrier_values,
           assemble_linearization)
"""The compiled entry points the solver calls besides the backward pass, with the linearization's assembly of
[`hsddp_gym.core.dynamics`][hsddp_gym.core.dynamics] ([`finish`][hsddp_gym.core.dynamics.Linearization.finish]): all
warmed up by [`warm_up_kernels`][warm_up_kernels], their numba caches checked by the warm-up."""
