"""The exact planar Coulomb contact LCP of one or two point feet, solved by enumerating foot states.

With ``G = J_c M^-1 J_c^T`` the Delassus matrix of the candidate feet (rows ``[n_0, t_0, n_1, t_1]``: normal,
tangent) and ``c`` their free velocity plus the gap term, the post-step contact velocity is ``w = G lam + c``. Every
solution puts each foot in one of four *states* -- ``SEPARATE`` (``lam = 0``, ``w_n >= 0``), ``STICK`` (``w = 0``,
``|lam_t| <= mu lam_n``), ``SLIDE_POS`` / ``SLIDE_NEG`` (``w_n = 0``, ``lam_t = -/+ mu lam_n``, sliding toward +x /
-x) -- so with at most two feet the LCP is solved *exactly* by enumerating the at most ``4^2 = 16`` state
combinations, each a linear system of size <= 4 followed by sign checks: the guess (the previous step's states)
first, then the fixed order [`BASE_ORDER`][BASE_ORDER] (and its product for two feet), so the result is deterministic.
If round-off makes every combination fail the checks, the least-violating one is returned (``exact = False``).

[`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] solves it on Python lists
([`solve_contact_lcp_lists`][solve_contact_lcp_lists]); the compiled kernel
([`hsddp_gym.core.batch_lcp`][hsddp_gym.core.batch_lcp]) is the same enumeration written out for numba. """

from __future__ import annotations

import itertools

import numpy as np

from hsddp_gym.util.validation import check_positive

SEPARATE = 0
"""Foot state: no impulse; the foot leaves or stays above the ground."""
STICK = 1
"""Foot state: no slip; the impulse is inside the friction cone."""
SLIDE_POS = 2
"""Foot state: slipping toward +x; friction ``lam_t = -mu lam_n``."""
SLIDE_NEG = 3
"""Foot state: slipping toward -x; friction ``lam_t = +mu lam_n``."""
STATE_NAMES = ("separate", "stick", "slide_pos", "slide_neg")

BASE_ORDER = (STICK, SLIDE_POS, SLIDE_NEG, SEPARATE)
"""The fixed order in which the LCP tries a foot's states (after the guess); two feet: its product."""
LCP_VELOCITY_TOLERANCE = 1e-9
"""Feasibility tolerance of a combination's contact velocities [m/s] (``tol_v``)."""
LCP_IMPULSE_TOLERANCE = 1e-12
"""Feasibility tolerance of a combination's impulses [N s] (``tol_l``)."""
_ORDERS = {1: [(s,) for s in BASE_ORDER], 2: list(itertools.product(BASE_ORDER, repeat=2))}
_DOUBLE_STICK = (STICK, STICK)


def _solve_linear(A: list, b: list) -> list | None:
    """Solve ``A z = b`` (n <= 4, lists) by Gaussian elimination with partial pivoting; None if singular."""
    n = len(b)
    if n == 1:
        a = A[0][0]
        return None if abs(a) < 1e-300 else [b[0] / a]
    if n == 2:
        a, bb = A[0]
        c, d = A[1]
        det = a * d - bb * c
        scale = max(abs(a * d), abs(bb * c), 1e-300)
        if abs(det) <= 1e-13 * scale:
            return None
        return [(b[0] * d - bb * b[1]) / det, (a * b[1] - c * b[0]) / det]
    A = [row[:] for row in A]
    b = b[:]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(A[r][col]))
        if abs(A[piv][col]) < 1e-300:
            return None
        if piv != col:
            A[col], A[piv] = A[piv], A[col]
            b[col], b[piv] = b[piv], b[col]
        p = A[col][col]
        for r in range(col + 1, n):
            f = A[r][col] / p
            if f != 0.0:
                row_r, row_c = A[r], A[col]
                for j in range(col, n):
                    row_r[j] -= f * row_c[j]
                b[r] -= f * b[col]
    z = [0.0] * n
    for r in range(n - 1, -1, -1):
        s = b[r]
        row = A[r]
        for j in range(r + 1, n):
            s -= row[j] * z[j]
        z[r] = s / row[r]
    return z


def solve_spd(S: list, r: list) -> list | None:
    """Solve ``S z = r`` for a symmetric positive-definite ``S`` (lists, n <= 4): closed form for n <= 2, an
    unrolled Cholesky factorization for n = 3, 4 (~10x faster than `_solve_linear` there); None when
    ``S`` is not numerically positive definite."""
    n = len(r)
    if n <= 2:
        return _solve_linear(S, r)
    if n == 3:
        (a00, a01, a02), (_, a11, a12), (_, _, a22) = S
        if a00 <= 0.0:
            return None
        l00 = a00 ** 0.5
        l10, l20 = a01 / l00, a02 / l00
        d1 = a11 - l10 * l10
        if d1 <= 1e-12 * a11:
            return None
        l11 = d1 ** 0.5
        l21 = (a12 - l20 * l10) / l11
        d2 = a22 - l20 * l20 - l21 * l21
        if d2 <= 1e-12 * a22:
            return None
        l22 = d2 ** 0.5
        y0 = r[0] / l00
        y1 = (r[1] - l10 * y0) / l11
        y2 = (r[2] - l20 * y0 - l21 * y1) / l22
        z2 = y2 / l22
        z1 = (y1 - l21 * z2) / l11
        return [(y0 - l10 * z1 - l20 * z2) / l00, z1, z2]
    (a00, a01, a02, a03), (_, a11, a12, a13), (_, _, a22, a23), (_, _, _, a33) = S
    if a00 <= 0.0:
        return None
    l00 = a00 ** 0.5
    l10, l20, l30 = a01 / l00, a02 / l00, a03 / l00
    d1 = a11 - l10 * l10
    if d1 <= 1e-12 * a11:
        return None
    l11 = d1 ** 0.5
    l21, l31 = (a12 - l20 * l10) / l11, (a13 - l30 * l10) / l11
    d2 = a22 - l20 * l20 - l21 * l21
    if d2 <= 1e-12 * a22:
        return None
    l22 = d2 ** 0.5
    l32 = (a23 - l30 * l20 - l31 * l21) / l22
    d3 = a33 - l30 * l30 - l31 * l31 - l32 * l32
    if d3 <= 1e-12 * a33:
        return None
    l33 = d3 ** 0.5
    y0 = r[0] / l00
    y1 = (r[1] - l10 * y0) / l11
    y2 = (r[2] - l20 * y0 - l21 * y1) / l22
    y3 = (r[3] - l30 * y0 - l31 * y1 - l32 * y2) / l33
    z3 = y3 / l33
    z2 = (y2 - l32 * z3) / l22
    z1 = (y1 - l21 * z2 - l31 * z3) / l11
    return [(y0 - l10 * z1 - l20 * z2 - l30 * z3) / l00, z1, z2, z3]


def _try_states(G: list, c: list, mu: float, states: tuple, tol_v: float, tol_l: float):
    """Solve the linear system of one state combination; return ``(violation, lam, w)``."""
    m = 2 * len(states)
    cols = []  # each unknown is an impulse direction: list of (row index, coefficient)
    rows = []  # each equation sets one row of w to zero
    for i, s in enumerate(states):
        n, t = 2 * i, 2 * i + 1
        if s == STICK:
            cols.append(((n, 1.0),))
            cols.append(((t, 1.0),))
            rows.append(n)
            rows.append(t)
        elif s == SLIDE_POS:
            cols.append(((n, 1.0), (t, -mu)))
            rows.append(n)
        elif s == SLIDE_NEG:
            cols.append(((n, 1.0), (t, mu)))
            rows.append(n)
    lam = [0.0] * m
    if rows:
        A = [[sum(coef * G[r][j] for j, coef in col) for col in cols] for r in rows]
        z = _solve_linear(A, [-c[r] for r in rows])
        if z is None:
            return float("inf"), None, None
        for col, zi in zip(cols, z):
            for j, coef in col:
                lam[j] += coef * zi
    w = [c[r] + sum(G[r][j] * lam[j] for j in range(m)) for r in range(m)]
    viol = 0.0
    for i, s in enumerate(states):
        n, t = 2 * i, 2 * i + 1
        if s == SEPARATE:
            viol = max(viol, (-w[n] - tol_v) / tol_v)
        else:
            viol = max(viol, (-lam[n] - tol_l) / tol_l)
            if s == STICK:
                viol = max(viol, (abs(lam[t]) - mu * lam[n] - tol_l) / tol_l)
            elif s == SLIDE_POS:
                viol = max(viol, (-w[t] - tol_v) / tol_v)
            else:
                viol = max(viol, (w[t] - tol_v) / tol_v)
    return viol, lam, w


def _try_double_stick(G: list, c: list, mu: float, tol_l: float):
    """Both feet sticking, the common double-stance case: ``lam = -G^-1 c`` by an unrolled Cholesky
    factorization of the 4x4 Delassus matrix (~1 us in Python, 6x faster than ``np.linalg.solve``);
    ``w = 0`` exactly, so only the impulse conditions are checked."""
    (a00, a01, a02, a03), (_, a11, a12, a13), (_, _, a22, a23), (_, _, _, a33) = G
    if a00 <= 0.0:
        return float("inf"), None, None
    l00 = a00 ** 0.5
    l10, l20, l30 = a01 / l00, a02 / l00, a03 / l00
    d1 = a11 - l10 * l10
    if d1 <= 1e-12 * a11:
        return float("inf"), None, None
    l11 = d1 ** 0.5
    l21, l31 = (a12 - l20 * l10) / l11, (a13 - l30 * l10) / l11
    d2 = a22 - l20 * l20 - l21 * l21
    if d2 <= 1e-12 * a22:
        return float("inf"), None, None
    l22 = d2 ** 0.5
    l32 = (a23 - l30 * l20 - l31 * l21) / l22
    d3 = a33 - l30 * l30 - l31 * l31 - l32 * l32
    if d3 <= 1e-12 * a33:
        return float("inf"), None, None
    l33 = d3 ** 0.5
    b0, b1, b2, b3 = -c[0], -c[1], -c[2], -c[3]
    y0 = b0 / l00
    y1 = (b1 - l10 * y0) / l11
    y2 = (b2 - l20 * y0 - l21 * y1) / l22
    y3 = (b3 - l30 * y0 - l31 * y1 - l32 * y2) / l33
    t1 = y3 / l33
    n1 = (y2 - l32 * t1) / l22
    t0 = (y1 - l21 * n1 - l31 * t1) / l11
    n0 = (y0 - l10 * t0 - l20 * n1 - l30 * t1) / l00
    viol = max(-n0 - tol_l, -n1 - tol_l, abs(t0) - mu * n0 - tol_l, abs(t1) - mu * n1 - tol_l) / tol_l
    return viol, [n0, t0, n1, t1], None


def solve_contact_lcp_lists(G: list, c: list, mu: float, guess: tuple | None = None,
                            tol_v: float = LCP_VELOCITY_TOLERANCE,
                            tol_l: float = LCP_IMPULSE_TOLERANCE):
    """The hot-path LCP solver on Python lists (no input checks); see [`solve_contact_lcp`][solve_contact_lcp].

    Returns:
        ``(lam (list of 2k floats), states (tuple of k ints), exact (bool))``.
    """
    k = len(c) // 2
    best = (float("inf"), None, None, None)
    if guess is not None:
        if guess == _DOUBLE_STICK:
            viol, lam, _ = _try_double_stick(G, c, mu, tol_l)
        else:
            viol, lam, _ = _try_states(G, c, mu, guess, tol_v, tol_l)
        if viol <= 0.0:
            return lam, guess, True
        best = (viol, lam, guess)
    for states in _ORDERS[k]:
        if states == guess:
            continue
        if states == _DOUBLE_STICK:
            viol, lam, _ = _try_double_stick(G, c, mu, tol_l)
        else:
            viol, lam, _ = _try_states(G, c, mu, states, tol_v, tol_l)
        if viol <= 0.0:
            return lam, states, True
        if viol < best[0]:
            best = (viol, lam, states)
    if best[1] is None:  # pragma: no cover - every combination singular: no impulse at all
        return [0.0] * (2 * k), (SEPARATE,) * k, False
    return best[1], best[2], False


def solve_contact_lcp(G, c, mu: float, guess=None, tol_v: float = LCP_VELOCITY_TOLERANCE,
                      tol_l: float = LCP_IMPULSE_TOLERANCE):
    """Solve the planar contact LCP exactly for ``k`` = 1 or 2 point contacts.

    Rows are ordered ``[n_0, t_0, n_1, t_1]`` (normal = +z, tangent = +x per contact). The post-step
    contact velocity is ``w = G lam + c``; the solution satisfies, per contact,
    ``lam_n >= 0``, ``w_n >= 0``, ``lam_n w_n = 0``, ``|lam_t| <= mu lam_n`` and Coulomb's maximum
    dissipation (``w_t != 0`` only if ``lam_t = -mu lam_n sign(w_t)``).

    Args:
        G: Delassus matrix ``J M^-1 J^T`` (2k, 2k), symmetric positive semi-definite.
        c: free velocity plus the gap term, ``J v_free + [phi_eff/h, 0, ...]`` (2k,).
        mu: friction coefficient >= 0.
        guess: states (k,) to try first (e.g. the previous step's); any of
            ``SEPARATE, STICK, SLIDE_POS, SLIDE_NEG``.
        tol_v: feasibility tolerance on velocities [m/s].
        tol_l: feasibility tolerance on impulses [N s].
    Returns:
        ``(lam (2k,), states (k,) ints, exact)``; ``exact`` is False only if round-off made every
        combination infeasible and the least-violating one was returned.
    """
    G = np.asarray(G, dtype=np.float64)
    c = np.asarray(c, dtype=np.float64)
    if c.ndim != 1 or c.shape[0] not in (2, 4):
        raise ValueError(f"c must have shape (2,) or (4,) (one or two contacts), got {c.shape}")
    if G.shape != (c.shape[0], c.shape[0]):
        raise ValueError(f"G must have shape {(c.shape[0], c.shape[0])} to match c, got {G.shape}")
    if not (np.all(np.isfinite(G)) and np.all(np.isfinite(c))):
        raise ValueError("G and c must be finite")
    mu = check_positive(mu, "mu", allow_zero=True)
    k = c.shape[0] // 2
    if guess is not None:
        guess = tuple(int(s) for s in guess)
        if len(guess) != k or any(s not in (SEPARATE, STICK, SLIDE_POS, SLIDE_NEG) for s in guess):
            raise ValueError(f"guess must hold {k} contact states in 0..3, got {guess!r}")
    lam, states, exact = solve_contact_lcp_lists(G.tolist(), c.tolist(), mu, guess, tol_v, tol_l)
    return np.array(lam), np.array(states, dtype=np.int64), exact
