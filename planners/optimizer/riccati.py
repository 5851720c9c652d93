"""The backward pass of impact-aware iLQR (paper eqs. 5, 7 and 22), compiled with numba.

Notation (trajax / Tassa et al. 2012): knots ``k = 0..N-1`` with dynamics Jacobians ``f_x (N, 14, 14)``,
``f_u (N, 14, 4)``, running-cost derivatives ``l_x (N, 14)``, ``l_u (N, 4)``, ``l_xx (N, 14, 14)``,
``l_uu (N, 4, 4)``, ``l_ux (N, 4, 14)``; per phase ``i`` the terminal-cost derivatives ``Phi_x (n, 14)``,
``Phi_xx (n, 14, 14)`` at the pre-switch state ``x_i^-`` and the reset Jacobian ``P_x (n, 14, 14)``
into phase ``i + 1``. Phase ``i`` owns knots ``phase_start[i] .. phase_start[i+1] - 1``.

At the end of phase ``i`` (paper eq. 22)::

    V_x^-  = Phi_x + P_x^T V_x^+,    V_xx^- = Phi_xx + P_x^T V_xx^+ P_x,    dV^- = dV^+

(the last phase: ``V^- = Phi``). Inside a phase, iLQR (eqs. 5 and 7, without second-order dynamics):
``Q_x = l_x + f_x^T V_x'`` ... and the gains ``k = -Q_uu^-1 Q_u``, ``K = -Q_uu^-1 Q_ux`` with ``Q_uu``
regularized by ``mu I``. The value update uses the regularized gains with the exact ``Q`` blocks
(Tassa et al. 2012, eq. 11), which keeps ``V_xx`` consistent when ``mu > 0``.
"""

from __future__ import annotations

import numba
import numpy as np

from hsddp_gym.core.conventions import NU, NX
from hsddp_gym.core.planar_dynamics import KERNELS as DYNAMICS
from hsddp_gym.core.planar_dynamics import warm_up as warm_up_dynamics
from hsddp_gym.core.small_linalg import cholesky_solve
from hsddp_gym.planners.optimizer.kernels import KERNELS, warm_up_kernels


@numba.njit(cache=True, inline="always")
def _accumulate(M, a, R, b, n, s0, s1, s2, s3):
    """``s_j + sum_c M[a, c] R[c, b + j]`` for j = 0..3 over ``c < n`` ascending, skipping ``M[a, c] == 0``."""
    for c in range(n):
        v = M[a, c]
        if v != 0.0:
            s0 += v * R[c, b]
            s1 += v * R[c, b + 1]
            s2 += v * R[c, b + 2]
            s3 += v * R[c, b + 3]
    return s0, s1, s2, s3


@numba.njit(cache=True, inline="always")
def _accumulate1(M, a, R, b, n, s):
    """``s + sum_c M[a, c] R[c, b]`` over ``c < n`` ascending, skipping ``M[a, c] == 0``."""
    for c in range(n):
        v = M[a, c]
        if v != 0.0:
            s += v * R[c, b]
    return s


@numba.njit(cache=True, inline="always")
def _product(M, R, init, out, m, n, p):
    """``out[a, b] = init[a, b] + sum_c M[a, c] R[c, b]`` (``init`` None: 0) for ``a < m``, ``b < p``, the sum over
    ``c < n`` ascending, skipping ``M[a, c] == 0``: four columns at a time in registers."""
    p4 = p - p % 4
    for a in range(m):
        for b in range(0, p4, 4):
            if init is None:
                s0 = s1 = s2 = s3 = 0.0
            else:
                s0, s1, s2, s3 = init[a, b], init[a, b + 1], init[a, b + 2], init[a, b + 3]
            s0, s1, s2, s3 = _accumulate(M, a, R, b, n, s0, s1, s2, s3)
            out[a, b] = s0
            out[a, b + 1] = s1
            out[a, b + 2] = s2
            out[a, b + 3] = s3
        for b in range(p4, p):
            out[a, b] = _accumulate1(M, a, R, b, n, 0.0 if init is None else init[a, b])


@numba.njit(cache=True)
def backward_pass(f_x, f_u, l_x, l_u, l_xx, l_uu, l_ux, Phi_x, Phi_xx, P_x, phase_start, mu,
                  k_ff, K, V_x_out, V_xx_out):
    """Impact-aware iLQR backward pass.

    Writes the feed-forward terms ``k_ff (N, 4)``, gains ``K (N, 4, 14)``, and the value gradient /
    Hessian at every knot ``V_x_out (N+1, 14)``, ``V_xx_out (N+1, 14, 14)`` (knot N: the final state).
    Any state and control sizes are accepted; the robot's (14, 4) run a copy compiled with those sizes as
    constants (fixed trip counts: about 15 % faster, the same operations in the same order).

    Returns:
        ``(ok, failed_knot, dV1, dV2)``: the expected cost change of a step ``eps`` is
        ``eps * dV1 + eps^2 / 2 * dV2``. ``ok`` is False (with the knot) when ``Q_uu + mu I`` is not
        positive definite.
    """
    nx = f_x.shape[1]
    nu = f_u.shape[2]
    if nx == NX and nu == NU:
        return _backward_pass(NX, NU, f_x, f_u, l_x, l_u, l_xx, l_uu, l_ux, Phi_x, Phi_xx, P_x, phase_start, mu,
                              k_ff, K, V_x_out, V_xx_out)
    return _backward_pass(nx, nu, f_x, f_u, l_x, l_u, l_xx, l_uu, l_ux, Phi_x, Phi_xx, P_x, phase_start, mu, k_ff,
                          K, V_x_out, V_xx_out)


@numba.njit(cache=True, inline="always")
def _backward_pass(nx, nu, f_x, f_u, l_x, l_u, l_xx, l_uu, l_ux, Phi_x, Phi_xx, P_x, phase_start, mu, k_ff, K,
                   V_x_out, V_xx_out):
    """[`backward_pass`][backward_pass] for ``nx`` states and ``nu`` controls (inlined into it, where constant sizes
    specialize it)."""
    n_phase = phase_start.shape[0] - 1
    Vx = np.empty(nx)
    Vxx = np.empty((nx, nx))
    tmp_xx = np.empty((nx, nx))
    Qx = np.empty(nx)
    Qu = np.empty(nu)
    Qxx = np.empty((nx, nx))
    Quu = np.empty((nu, nu))
    Quu_reg = np.empty((nu, nu))
    Qux = np.empty((nu, nx))
    VxxFx = np.empty((nx, nx))
    VxxFu = np.empty((nx, nu))
    rhs = np.empty((nu, nx + 1))
    sol = np.empty((nu, nx + 1))
    L = np.zeros((nu, nu))
    dV1 = 0.0
    dV2 = 0.0
    last = n_phase - 1
    for a in range(nx):
        Vx[a] = Phi_x[last, a]
        for b in range(nx):
            Vxx[a, b] = Phi_xx[last, a, b]
    N = f_x.shape[0]
    V_x_out[N, :] = Vx
    V_xx_out[N, :, :] = Vxx
    for i in range(n_phase - 1, -1, -1):
        if i < n_phase - 1:
            # impact-aware value update at the end of phase i (eq. 22)
            P = P_x[i]
            for a in range(nx):
                s = Phi_x[i, a]
                for c in range(nx):
                    s += P[c, a] * Vx[c]
                Qx[a] = s
            for a in range(nx):
                Vx[a] = Qx[a]
            for a in range(nx):
                for b in range(nx):
                    s = 0.0
                    for c in range(nx):
                        s += Vxx[a, c] * P[c, b]
                    tmp_xx[a, b] = s
            for a in range(nx):
                for b in range(nx):
                    s = Phi_xx[i, a, b]
                    for c in range(nx):
                        s += P[c, a] * tmp_xx[c, b]
                    Qxx[a, b] = s
            for a in range(nx):
                for b in range(nx):
                    Vxx[a, b] = 0.5 * (Qxx[a, b] + Qxx[b, a])
        for k in range(phase_start[i + 1] - 1, phase_start[i] - 1, -1):
            A = f_x[k]
            B = f_u[k]
            # VxxFx = Vxx A, VxxFu = Vxx B (each element summed over c ascending, four columns at a time)
            _product(Vxx, A, None, VxxFx, nx, nx, nx)
            _product(Vxx, B, None, VxxFu, nx, nx, nu)
            for a in range(nx):
                s = l_x[k, a]
                for c in range(nx):
                    s += A[c, a] * Vx[c]
                Qx[a] = s
            for a in range(nu):
                s = l_u[k, a]
                for c in range(nx):
                    s += B[c, a] * Vx[c]
                Qu[a] = s
            _product(A.T, VxxFx, l_xx[k], Qxx, nx, nx, nx)
            for a in range(nu):
                for b in range(a, nu):
                    s = l_uu[k, a, b]
                    for c in range(nx):
                        s += B[c, a] * VxxFu[c, b]
                    Quu[a, b] = s
                    Quu[b, a] = s
            _product(B.T, VxxFx, l_ux[k], Qux, nu, nx, nx)
            for a in range(nu):
                for b in range(nu):
                    Quu_reg[a, b] = Quu[a, b]
                Quu_reg[a, a] += mu
                rhs[a, 0] = -Qu[a]
                for b in range(nx):
                    rhs[a, b + 1] = -Qux[a, b]
            if not cholesky_solve(Quu_reg, rhs, L, sol):
                return False, k, dV1, dV2
            for a in range(nu):
                k_ff[k, a] = sol[a, 0]
                for b in range(nx):
                    K[k, a, b] = sol[a, b + 1]
            kf = k_ff[k]
            Kk = K[k]
            # expected change
            for a in range(nu):
                dV1 += kf[a] * Qu[a]
                s = 0.0
                for b in range(nu):
                    s += Quu[a, b] * kf[b]
                dV2 += kf[a] * s
            # V_x = Q_x + K^T Quu k + K^T Q_u + Q_ux^T k
            for a in range(nx):
                s = Qx[a]
                for b in range(nu):
                    t = Qu[b]
                    for c in range(nu):
                        t += Quu[b, c] * kf[c]
                    s += Kk[b, a] * t + Qux[b, a] * kf[b]
                Vx[a] = s
            # V_xx = Q_xx + K^T Quu K + K^T Q_ux + Q_ux^T K
            for b in range(nu):
                for a in range(nx):
                    s = 0.0
                    for c in range(nu):
                        s += Quu[b, c] * Kk[c, a]
                    rhs[b, a] = s  # rhs reused as (Quu K)  [nu x nx]
            for a in range(nx):
                for b in range(a, nx):
                    s = Qxx[a, b]
                    for c in range(nu):
                        s += Kk[c, a] * (rhs[c, b] + Qux[c, b]) + Qux[c, a] * Kk[c, b]
                    Vxx[a, b] = s
                    Vxx[b, a] = s
            for a in range(nx):
                V_x_out[k, a] = Vx[a]
                for b in range(nx):
                    V_xx_out[k, a, b] = Vxx[a, b]
    return True, -1, dV1, dV2


# ================================================================================================ warm-up
_READY = False
ANNOUNCE_AFTER_S = 5.0
"""With a cache index on disk, the warm-up still says that numba compiles when it takes longer than this (a
stale cache; loading a valid one takes well under a second, a few on a loaded machine)."""


def _cache_index_exists() -> bool:
    """Whether numba's cache indexes of the backward pass and of the cost kernels
    ([`kernels`][hsddp_gym.planners.optimizer.kernels]) are all on disk (numba internals: False if they moved)."""
    import os

    try:
        return all(os.path.exists(k._cache._cache_file._index_path) for k in (backward_pass, *KERNELS, *DYNAMICS))
    except AttributeError:  # pragma: no cover (another numba version)
        return False


def warm_up(announce: bool = True) -> float:
    """Make the compiled kernels ready before anything is timed: compile them (the first run on a machine,
    10-20 s) or load numba's on-disk cache (``cache=True``; later runs, well under a second), once per
    process, on a 2-knot problem with the dtypes and layouts the solver passes (so its calls reuse this
    specialization): the backward pass, the objective's kernels
    ([`hsddp_gym.planners.optimizer.kernels.warm_up_kernels`][hsddp_gym.planners.optimizer.kernels.warm_up_kernels]) and
    the compiled dynamics of the rollouts
    ([`hsddp_gym.core.planar_dynamics.warm_up`][hsddp_gym.core.planar_dynamics.warm_up]). With ``announce``, a line on
    stderr says when a compile is under way and how long it took. Returns the seconds spent (0 when already done).
    [`HSDDP`][hsddp_gym.planners.optimizer.hsddp.HSDDP] calls it before its clock starts, so compile time never lands in
    ``solve_time_s``."""
    global _READY
    if _READY:
        return 0.0
    import sys
    import threading
    import time

    def say():
        print(f"numba: compiling the HS-DDP dynamics, backward pass and cost kernels, once (the first run on this "
              f"machine takes 20-40 s; later runs load them from the cache in {backward_pass.stats.cache_path}) ...",
              file=sys.stderr, flush=True)

    if announce and not _cache_index_exists():
        say()  # nothing cached: this compiles
        announce_later = False
    else:
        announce_later = announce  # a cache index exists; a stale one (other source, other numba) recompiles
    timer = threading.Timer(ANNOUNCE_AFTER_S, say) if announce_later else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    t0 = time.perf_counter()
    try:
        n, nx, nu = 2, 14, 4
        eye = np.broadcast_to(np.eye(nx), (n, nx, nx)).copy()
        backward_pass(eye.copy(), np.zeros((n, nx, nu)), np.zeros((n, nx)), np.zeros((n, nu)), eye.copy(),
                      np.broadcast_to(np.eye(nu), (n, nu, nu)).copy(), np.zeros((n, nu, nx)), np.zeros((1, nx)),
                      np.eye(nx)[None].copy(), np.eye(nx)[None].copy(), np.array([0, n], dtype=np.int64), 0.0,
                      np.zeros((n, nu)), np.zeros((n, nu, nx)), np.zeros((n + 1, nx)), np.zeros((n + 1, nx, nx)))
        warm_up_kernels()
        warm_up_dynamics()
    finally:
        if timer is not None:
            timer.cancel()
    elapsed = time.perf_counter() - t0
    if announce and any(sum(k.stats.cache_misses.values()) for k in (backward_pass, *KERNELS, *DYNAMICS)):
        print(f"numba: compiled in {elapsed:.1f} s (not counted in solver timings); cached for later runs",
              file=sys.stderr, flush=True)
    _READY = True
    return elapsed
