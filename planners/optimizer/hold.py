"""The feedback law of a plan whose control is held over several knots (a zero-order hold at the control rate).

The solver plans on a grid of step ``h`` (2.5 ms for the MPC) and its backward pass gives one gain per knot,
``u_k = U_k + K_k dx_k``, for a control that changes at every knot. A controller that runs at a slower rate holds
each control for ``m`` knots (the env's 5 ms control period: ``m = 2``). Applied that way, the per-knot gain acts
for ``m`` steps on the state it saw at the first: for the stiff gains near a planned touchdown (the switching
constraint's penalty) the loop gain is roughly ``m`` times the designed one, and a light joint (a leg in flight)
oscillates from one control step to the next, its velocity flipping sign at every step.

[`held_input_gains`][held_input_gains] gives, from the same backward pass, the gain of a control held over knots
``k .. k + m - 1``: the minimizer over ``du`` (the same ``du`` at every one of the ``m`` knots) of the quadratic
model of the cost of those knots plus the value at knot ``k + m``::

    dx_{j+1} = A_j dx_j + B_j du,      Q(dx, du) = sum_j l_j(dx_j, du) + 1/2 dx_{k+m}^T V_xx[k+m] dx_{k+m}

    K_hold[k] = -Q_uu^-1 Q_ux

It is Riccati's gain for the held input (move blocking, e.g. Cagienard et al. 2007), with the value Hessians of
the per-knot backward pass beyond the held knots. With ``m = 1`` it is the backward pass's own gain. A hold that
would cross the end of a phase (a switch inside the held knots) keeps the per-knot gain, as does a knot whose
``Q_uu`` or ``Q_ux`` is not finite or whose ``Q_uu`` is not positive definite.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.util.validation import check_int


def held_input_gains(solver, problem, hold: int) -> np.ndarray:
    """Gains ``(N, 4, 14)`` of the plan of ``solver``'s last solve of ``problem`` for a control held over ``hold``
    knots (see the module docstring); the solve's own gains where a hold would cross a phase's end.

    Args:
        solver: the [`HSDDP`][hsddp_gym.planners.optimizer.hsddp.HSDDP] that has just solved ``problem`` (its
            workspace holds the last backward pass: dynamics Jacobians, cost derivatives, value Hessians).
        problem: that [`HybridProblem`][hsddp_gym.planners.optimizer.problem.HybridProblem].
        hold: knots per held control (>= 1).
    """
    m = check_int(hold, "hold", minimum=1)
    ws = solver._ws
    if ws is None or solver.last_problem is not problem:
        raise ValueError("solver has not just solved problem: solve it first")
    N = problem.n_knots
    K = ws.K[:N].copy()
    if m == 1:
        return K
    f_x, f_u = ws.lin.f_x[:N], ws.lin.f_u[:N]
    l_xx, l_uu, l_ux = ws.l_xx[:N], ws.l_uu[:N], ws.l_ux[:N]
    starts = problem.phase_start
    last = problem.n_phases - 1
    with np.errstate(over="ignore", invalid="ignore"):  # non-finite models are found and skipped below
        for i in range(problem.n_phases):
            _held_phase(ws, K, f_x, f_u, l_xx, l_uu, l_ux, int(starts[i]), int(starts[i + 1]), i == last, i, m)
    return K


def _held_phase(ws, K, f_x, f_u, l_xx, l_uu, l_ux, a: int, b: int, is_last: bool, i: int, m: int) -> None:
    """The held-input gains of phase ``i`` (knots ``a .. b - 1``) into ``K`` (see
    [`held_input_gains`][held_input_gains])."""
    ks = np.arange(a, b - m + 1)  # holds that end inside the phase or at its end
    if ks.size == 0:
        return
    # the value Hessian after the held knots: inside the phase V_xx[k + m]; at the phase's end the value before
    # the switch (eq. 22: Phi_xx + P_x^T V_xx^+ P_x; the last phase: the terminal Phi_xx)
    V = ws.V_xx[ks + m].copy()
    at_end = ks + m == b
    if np.any(at_end):
        if is_last:
            V[at_end] = ws.Phi_xx[i]
        else:
            P = ws.P_x[i]
            V[at_end] = ws.Phi_xx[i] + P.T @ ws.V_xx[b] @ P
    n = ks.size
    Ax = np.broadcast_to(np.eye(f_x.shape[1]), (n,) + f_x.shape[1:]).copy()  # d x_j / d x_k
    Bx = np.zeros((n,) + f_u.shape[1:])                                          # d x_j / d u
    Quu = np.zeros((n,) + l_uu.shape[1:])
    Qux = np.zeros((n,) + l_ux.shape[1:])
    for j in range(m):
        kj = ks + j
        lxx, luu, lux = l_xx[kj], l_uu[kj], l_ux[kj]
        BtL = np.swapaxes(Bx, 1, 2) @ lxx                       # (n, 4, 14)
        LuxB = lux @ Bx                                          # (n, 4, 4)
        Quu += luu + BtL @ Bx + LuxB + np.swapaxes(LuxB, 1, 2)
        Qux += lux @ Ax + BtL @ Ax
        Ax, Bx = f_x[kj] @ Ax, f_x[kj] @ Bx + f_u[kj]
    BtV = np.swapaxes(Bx, 1, 2) @ V
    Quu += BtV @ Bx
    Qux += BtV @ Ax
    Quu = 0.5 * (Quu + np.swapaxes(Quu, 1, 2))
    # only finite, positive definite Q_uu (a warm start far off can overflow the barrier terms, as in the
    # backward pass); elsewhere the per-knot gain stays
    ok = np.isfinite(Quu).all(axis=(1, 2)) & np.isfinite(Qux).all(axis=(1, 2))
    if ok.any():
        w = np.linalg.eigvalsh(Quu[ok])
        good = np.flatnonzero(ok)[w[:, 0] > 1e-12 * np.maximum(1.0, np.abs(w).max(axis=1))]
        K[ks[good]] = -np.linalg.solve(Quu[good], Qux[good])


def held_feedforward(U: np.ndarray, phase_start: np.ndarray, hold: int) -> np.ndarray:
    """Feed-forward controls ``(N, 4)`` for a control held over ``hold`` knots: the mean of the plan's controls
    ``U (N, 4)`` over knots ``k .. k + hold - 1`` (the plan's impulse over the held knots, the same to first order in
    the step), the plan's own control where the hold would cross the end of a phase (``phase_start (n+1,)``)."""
    m = check_int(hold, "hold", minimum=1)
    U = np.asarray(U, dtype=np.float64)
    if U.ndim != 2:
        raise ValueError(f"U must be a (N, nu) array, got shape {U.shape}")
    starts = np.asarray(phase_start, dtype=np.int64)
    if starts.ndim != 1 or starts.size < 2 or starts[0] != 0 or starts[-1] != len(U) or np.any(np.diff(starts) < 1):
        raise ValueError(f"phase_start must rise from 0 to N = {len(U)} (the phases' first knots, then N), "
                         f"got {np.asarray(phase_start).tolist()}")
    out = U.copy()
    for a, b in zip(starts[:-1], starts[1:]):
        n = int(b - a) - m + 1
        if m > 1 and n > 0:
            out[a:a + n] = sum(U[a + j:a + j + n] for j in range(m)) / m
    return out
