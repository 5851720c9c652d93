"""The contact LCP of [`hsddp_gym.core.contact_lcp`][hsddp_gym.core.contact_lcp] written out for numba: the contact
kernel's ([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]) enumeration of foot states and its small dense
solves.

The same enumeration as [`solve_contact_lcp_lists`][hsddp_gym.core.contact_lcp.solve_contact_lcp_lists] -- the guess
first, then the fixed order [`BASE_ORDER`][hsddp_gym.core.contact_lcp.BASE_ORDER] (its product for two feet), the
least-violating combination when none is exact -- with the same linear solves (closed form for n <= 2, Gaussian
elimination with partial pivoting, a Cholesky factorization for n = 3, 4) and the same tolerances, on
preallocated arrays (the kernel's scratch, passed one by one). Rows are ``[n_0, t_0, n_1, t_1]``: ``G`` (2k, 2k) the
Delassus matrix, ``c`` (2k,) the free contact velocity plus the gap term, ``lam`` (2k,) the impulses.
"""

from __future__ import annotations

import math

import numpy as np

from hsddp_gym.core.batch_model import kernel_jit
from hsddp_gym.core.contact_lcp import (
    BASE_ORDER,
    LCP_IMPULSE_TOLERANCE,
    LCP_VELOCITY_TOLERANCE,
    SEPARATE,
    SLIDE_NEG,
    SLIDE_POS,
    STICK,
)

_TOL_V = LCP_VELOCITY_TOLERANCE
_TOL_L = LCP_IMPULSE_TOLERANCE
_BASE_ORDER = np.array(BASE_ORDER)


@kernel_jit
def _solve_linear(A, b, n, z):
    """``A z = b`` for the leading ``n x n`` block (n <= 4): contact_lcp._solve_linear (closed form for n <= 2,
    Gaussian elimination with partial pivoting otherwise); A, b are overwritten; False if singular."""
    if n == 1:
        a = A[0, 0]
        if abs(a) < 1e-300:
            return False
        z[0] = b[0] / a
        return True
    if n == 2:
        a, bb = A[0, 0], A[0, 1]
        c, d = A[1, 0], A[1, 1]
        det = a * d - bb * c
        scale = max(abs(a * d), abs(bb * c), 1e-300)
        if abs(det) <= 1e-13 * scale:
            return False
        z[0] = (b[0] * d - bb * b[1]) / det
        z[1] = (a * b[1] - c * b[0]) / det
        return True
    for col in range(n):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                best = abs(A[r, col])
                piv = r
        if abs(A[piv, col]) < 1e-300:
            return False
        if piv != col:
            for j in range(n):
                t = A[col, j]
                A[col, j] = A[piv, j]
                A[piv, j] = t
            t = b[col]
            b[col] = b[piv]
            b[piv] = t
        pv = A[col, col]
        for r in range(col + 1, n):
            f = A[r, col] / pv
            if f != 0.0:
                for j in range(col, n):
                    A[r, j] -= f * A[col, j]
                b[r] -= f * b[col]
    for r in range(n - 1, -1, -1):
        s = b[r]
        for j in range(r + 1, n):
            s -= A[r, j] * z[j]
        z[r] = s / A[r, r]
    return True


@kernel_jit
def _cholesky_small(S, r, n, z, L):
    """contact_lcp.solve_spd for n = 3, 4 (upper triangle of S read, as the unrolled version); False if not PD."""
    for i in range(n):
        for j in range(i + 1):
            if i == j:
                d = S[i, i]
                for k in range(i):
                    d -= L[i, k] * L[i, k]
                if i == 0:
                    if d <= 0.0:
                        return False
                elif d <= 1e-12 * S[i, i]:
                    return False
                L[i, i] = math.sqrt(d)
            else:
                s = S[j, i]
                for k in range(j):
                    s -= L[i, k] * L[j, k]
                L[i, j] = s / L[j, j]
    for i in range(n):
        s = r[i]
        for k in range(i):
            s -= L[i, k] * z[k]
        z[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = z[i]
        for k in range(i + 1, n):
            s -= L[k, i] * z[k]
        z[i] = s / L[i, i]
    return True


@kernel_jit
def solve_spd(S, r, n, z, L):
    """contact_lcp.solve_spd: ``S z = r`` (n <= 4) for symmetric positive-definite ``S``; S, r may be overwritten."""
    if n <= 2:
        return _solve_linear(S, r, n, z)
    return _cholesky_small(S, r, n, z, L)


@kernel_jit
def _try_states(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, cols_j, cols_c, cols_n, rows):
    """contact_lcp._try_states for ``k`` candidate feet with states ``(s0, s1)``; returns the violation
    (inf if singular) and fills ``lam`` (2k,)."""
    m = 2 * k
    ncol = 0
    nrow = 0
    for i in range(k):
        s = s0 if i == 0 else s1
        n, t = 2 * i, 2 * i + 1
        if s == STICK:
            cols_n[ncol] = 1
            cols_j[ncol, 0] = n
            cols_c[ncol, 0] = 1.0
            ncol += 1
            cols_n[ncol] = 1
            cols_j[ncol, 0] = t
            cols_c[ncol, 0] = 1.0
            ncol += 1
            rows[nrow] = n
            rows[nrow + 1] = t
            nrow += 2
        elif s == SLIDE_POS or s == SLIDE_NEG:
            cols_n[ncol] = 2
            cols_j[ncol, 0] = n
            cols_c[ncol, 0] = 1.0
            cols_j[ncol, 1] = t
            cols_c[ncol, 1] = -mu if s == SLIDE_POS else mu
            ncol += 1
            rows[nrow] = n
            nrow += 1
    for j in range(m):
        lam[j] = 0.0
    if nrow > 0:
        for a in range(nrow):
            r = rows[a]
            for b in range(ncol):
                acc = 0.0
                for e in range(cols_n[b]):
                    acc += cols_c[b, e] * G[r, cols_j[b, e]]
                A[a, b] = acc
            rhs[a] = -c[r]
        if not _solve_linear(A, rhs, nrow, zz):
            return np.inf
        for b in range(ncol):
            for e in range(cols_n[b]):
                lam[cols_j[b, e]] += cols_c[b, e] * zz[b]
    for r in range(m):
        acc = 0.0
        for j in range(m):
            acc += G[r, j] * lam[j]
        w[r] = c[r] + acc
    viol = 0.0
    for i in range(k):
        s = s0 if i == 0 else s1
        n, t = 2 * i, 2 * i + 1
        if s == SEPARATE:
            viol = max(viol, (-w[n] - _TOL_V) / _TOL_V)
        else:
            viol = max(viol, (-lam[n] - _TOL_L) / _TOL_L)
            if s == STICK:
                viol = max(viol, (abs(lam[t]) - mu * lam[n] - _TOL_L) / _TOL_L)
            elif s == SLIDE_POS:
                viol = max(viol, (-w[t] - _TOL_V) / _TOL_V)
            else:
                viol = max(viol, (w[t] - _TOL_V) / _TOL_V)
    return viol


@kernel_jit
def _try_double_stick(G, c, mu, lam, L, rhs, zz):
    """contact_lcp._try_double_stick: ``lam = -G^-1 c`` by Cholesky; returns the violation (inf if not PD)."""
    for i in range(4):
        rhs[i] = -c[i]
    if not _cholesky_small(G, rhs, 4, zz, L):
        return np.inf
    n0, t0, n1, t1 = zz[0], zz[1], zz[2], zz[3]
    lam[0] = n0
    lam[1] = t0
    lam[2] = n1
    lam[3] = t1
    return max(-n0 - _TOL_L, -n1 - _TOL_L, abs(t0) - mu * n0 - _TOL_L, abs(t1) - mu * n1 - _TOL_L) / _TOL_L


@kernel_jit
def _try(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows):
    if k == 2 and s0 == STICK and s1 == STICK:
        return _try_double_stick(G, c, mu, lam, L, rhs, zz)
    return _try_states(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, cols_j, cols_c, cols_n, rows)


@kernel_jit
def solve_lcp(G, c, mu, k, g0, g1, lam, out_states, best_lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows):
    """contact_lcp.solve_contact_lcp_lists: the guess ``(g0, g1)`` first, then the fixed order; fills ``lam``
    (2k,) and ``out_states`` (k,); returns True when exact (False: the least-violating combination). The
    other arrays are scratch (the [`Scratch`][hsddp_gym.core.batch_contact.Scratch] fields of the same names; passed
    one by one, which is cheaper than passing the whole tuple)."""
    best_v = np.inf
    have = False
    b0 = SEPARATE
    b1 = SEPARATE
    viol = _try(G, c, mu, k, g0, g1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows)
    if viol <= 0.0:
        out_states[0] = g0
        out_states[1] = g1
        return True
    if viol < np.inf:
        best_v = viol
        have = True
        b0, b1 = g0, g1
        for j in range(2 * k):
            best_lam[j] = lam[j]
    n_combos = 4 if k == 1 else 16
    for idx in range(n_combos):
        if k == 1:
            s0 = _BASE_ORDER[idx]
            s1 = SEPARATE
        else:
            s0 = _BASE_ORDER[idx // 4]
            s1 = _BASE_ORDER[idx % 4]
        if s0 == g0 and (k == 1 or s1 == g1):
            continue
        viol = _try(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows)
        if viol <= 0.0:
            out_states[0] = s0
            out_states[1] = s1
            return True
        if viol < best_v:
            best_v = viol
            have = True
            b0, b1 = s0, s1
            for j in range(2 * k):
                best_lam[j] = lam[j]
    if not have:
        for j in range(2 * k):
            lam[j] = 0.0
        out_states[0] = SEPARATE
        out_states[1] = SEPARATE
        return False
    for j in range(2 * k):
        lam[j] = best_lam[j]
    out_states[0] = b0
    out_states[1] = b1
    return False
