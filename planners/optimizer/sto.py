"""HS-DDP Algorithm 2: switching-time optimization (paper Sec. IV-E, eqs. 28-31), and the open-loop
baseline of Xu & Antsaklis [24].

Time-scaled problem (eq. 28): phase ``i`` keeps its ``N_i`` knots and steps with ``h_i = T_i / N_i``;
the durations ``z = [T_1 .. T_n]`` join the state as constants, ``X = [x, z]``. With forward Euler,
``x+ = x + (T_i / N_i) xdot(x, u)``, so per knot of phase ``i``::

    f_z = xdot / N_i,   f_xz = d(f_x)/dT_i = [[0, I], [a_q, a_v]] / N_i,   f_uz = [[0], [a_u]] / N_i,
    L = h_i l(x, u)  =>  L_z = l / N_i,  L_xz = L_x / T_i,  L_uz = L_u / T_i,  L_zz = 0, f_zz = 0

(semi-implicit Euler adds the ``h``-terms of its position update). The cross terms ``V_x' f_xz`` and
``V_x' f_uz`` are exact first-order quantities and are included; like iLQR, the dynamics' state/control
curvature is not. The backward pass then carries ``V_z (n,)``, ``V_xz (14, n)`` and ``V_zz (n, n)``
through every knot and every reset (``V_xz^- = P_x^T V_xz^+``, ``V_z``, ``V_zz`` unchanged, since
resets and terminal costs do not depend on ``z``).

Algorithm 2: after Algorithm 1 converges, ``z <- z - eps_z V_zz^-1 V_z`` (eq. 31) with a backtracking
search on ``eps_z`` that asks for a decrease of the objective, rolling out the feedback policy
``u = u_hat + K_x dx + K_z dz`` (HS-DDP) -- or the control sequence held open loop (Xu & Antsaklis,
whose derivatives are those of the open-loop cost, i.e. the same recursion with ``K = 0``); then
Algorithm 1 again, warm-started, on the new durations. Durations stay inside ``[min, max]`` bounds
(per phase); the step is a projected Newton step (a duration held at a bound its gradient pushes against is
fixed and the Newton system is solved on the others), with the eigenvalues of ``V_zz`` replaced by their
absolute values (floored) when it is not positive definite: see [`duration_step`][duration_step].
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.core.conventions import NQ, NU, NX
from hsddp_gym.planners.optimizer.hsddp import HSDDP, _Traj, rollout_policy
from hsddp_gym.planners.optimizer.objective import Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.riccati import warm_up
from hsddp_gym.planners.optimizer.solution import Solution, SolverOptions

STO_METHODS = ("hsddp", "open-loop")


def backward_pass_time(f_x, f_u, f_z, f_xz, f_uz, l_x, l_u, l_xx, l_uu, l_ux, l_z, l_xz, l_uz, Phi_x, Phi_xx, P_x,
                       phase_start, phase_of_knot, n_z, feedback, mu, K_x, K_z, k_ff, knot_tensor=None,
                       reset_tensor=None):
    """Backward pass of the time-augmented problem (see the module docstring).

    Plain NumPy (it runs once per STO iteration; numba's linear algebra would need SciPy).

    Args:
        f_z (N, 14), f_xz (N, 14, 14), f_uz (N, 14, 4): derivatives w.r.t. the knot's own phase duration.
        l_z (N,), l_xz (N, 14), l_uz (N, 4): running-cost derivatives w.r.t. that duration.
        phase_of_knot (N,): the phase (duration index) of each knot. n_z: number of durations.
        feedback: True for HS-DDP (gains from Q_uu), False for the open-loop baseline (K = 0, k = 0).
        mu: regularization added to Q_uu.
            K_x (N, 4, 14), K_z (N, 4, n_z), k_ff (N, 4): outputs.
        knot_tensor: optional ``knot_tensor(k, V_x_next) -> (T_xx, T_ux, T_uu)``, the second-order terms
            of knot k's dynamics and force-dependent cost contracted with the value gradient (full DDP
            instead of iLQR); reset_tensor: optional ``reset_tensor(i, V_x_plus) -> T_xx`` for reset maps.
    Returns:
        ``(ok, V_x0 (14,), V_z0 (n_z,), V_xx0 (14, 14), V_xz0 (14, n_z), V_zz0 (n_z, n_z), dV1, dV2)``.
    Raises:
        numpy.linalg.LinAlgError: (``feedback``) ``Q_uu + mu I`` is not positive definite at some knot, so the
            gains would not minimize the control's quadratic model; [`time_derivatives`][time_derivatives] then retries
            with a larger ``mu``.
    """
    nx = f_x.shape[1]
    nu = f_u.shape[2]
    n_phase = phase_start.shape[0] - 1
    last = n_phase - 1
    Vx = Phi_x[last].copy()
    Vxx = Phi_xx[last].copy()
    Vz = np.zeros(n_z)
    Vxz = np.zeros((nx, n_z))
    Vzz = np.zeros((n_z, n_z))
    eye_u = np.eye(nu)
    dV1 = 0.0
    dV2 = 0.0
    for i in range(n_phase - 1, -1, -1):
        if i < n_phase - 1:
            P = P_x[i]
            T_reset = reset_tensor(i, Vx) if reset_tensor is not None else 0.0
            Vx = Phi_x[i] + P.T @ Vx
            Vxx = Phi_xx[i] + P.T @ Vxx @ P + T_reset
            Vxx = 0.5 * (Vxx + Vxx.T)
            Vxz = P.T @ Vxz
        for k in range(phase_start[i + 1] - 1, phase_start[i] - 1, -1):
            A = f_x[k]
            B = f_u[k]
            j = phase_of_knot[k]
            fz = f_z[k]
            Qx = l_x[k] + A.T @ Vx
            Qu = l_u[k] + B.T @ Vx
            Qz = Vz.copy()
            Qz[j] += l_z[k] + fz @ Vx
            VxxA = Vxx @ A
            Qxx = l_xx[k] + A.T @ VxxA
            Quu = l_uu[k] + B.T @ (Vxx @ B)
            Qux = l_ux[k] + B.T @ VxxA
            if knot_tensor is not None:
                T_xx, T_ux, T_uu = knot_tensor(k, Vx)
                Qxx = Qxx + T_xx
                Qux = Qux + T_ux
                Quu = Quu + T_uu
            # (Vxx Fz + Vxz) with Fz = fz e_j^T
            M = Vxz.copy()
            Vxx_fz = Vxx @ fz
            M[:, j] += Vxx_fz
            Qxz = A.T @ M
            Qxz[:, j] += f_xz[k].T @ Vx + l_xz[k]
            Quz = B.T @ M
            Quz[:, j] += f_uz[k].T @ Vx + l_uz[k]
            # Qzz = Vzz + Fz^T Vxx Fz + Fz^T Vxz + Vxz^T Fz
            Qzz = Vzz.copy()
            fz_Vxz = fz @ Vxz
            Qzz[j, :] += fz_Vxz
            Qzz[:, j] += fz_Vxz
            Qzz[j, j] += fz @ Vxx_fz
            if feedback:
                Quu_reg = Quu + mu * eye_u
                np.linalg.cholesky(Quu_reg)  # LinAlgError unless positive definite: the caller regularizes more
                Qi = np.linalg.inv(Quu_reg)
                Qi = 0.5 * (Qi + Qi.T)
                kk = -(Qi @ Qu)
                Kx = -(Qi @ Qux)
                Kz = -(Qi @ Quz)
            else:
                kk = np.zeros(nu)
                Kx = np.zeros((nu, nx))
                Kz = np.zeros((nu, n_z))
            k_ff[k] = kk
            K_x[k] = Kx
            K_z[k] = Kz
            dV1 += kk @ Qu
            dV2 += kk @ (Quu @ kk)
            QuuK = Quu @ kk
            Vx = Qx + Kx.T @ (QuuK + Qu) + Qux.T @ kk
            Vz = Qz + Kz.T @ (QuuK + Qu) + Quz.T @ kk
            QuuKx = Quu @ Kx
            QuuKz = Quu @ Kz
            Vxx = Qxx + Kx.T @ QuuKx + Kx.T @ Qux + Qux.T @ Kx
            Vxx = 0.5 * (Vxx + Vxx.T)
            Vxz = Qxz + Kx.T @ QuuKz + Kx.T @ Quz + Qux.T @ Kz
            Vzz = Qzz + Kz.T @ QuuKz + Kz.T @ Quz + Quz.T @ Kz
            Vzz = 0.5 * (Vzz + Vzz.T)
    return True, Vx, Vz, Vxx, Vxz, Vzz, dV1, dV2


@dataclasses.dataclass
class TimeDerivatives:
    """Derivatives of the objective w.r.t. the durations at the initial knot, and the time-augmented policy.

    ``V_z (n,)``, ``V_zz (n, n)``, ``V_xz (14, n)``, gains ``K_x (N, 4, 14)``, ``K_z (N, 4, n)``,
    feed-forward ``k_ff (N, 4)``; ``dV1``, ``dV2`` the control step's expected change coefficients.
    """

    V_z: np.ndarray
    V_zz: np.ndarray
    V_xz: np.ndarray
    K_x: np.ndarray
    K_z: np.ndarray
    k_ff: np.ndarray
    dV1: float
    dV2: float


def duration_rates(problem: HybridProblem, X: np.ndarray, lin) -> np.ndarray:
    """``f_z (N, 14)``: the derivative of each knot's discrete step w.r.t. its own phase duration (the first output of
    [`time_scaled_jacobians`][time_scaled_jacobians], alone: what [`duration_gradient`][duration_gradient] needs,
    without the ``(N, 14, 14)`` and ``(N, 14, 4)`` cross terms)."""
    N = problem.n_knots
    Ni = problem.knots[problem.phase_of_knot].astype(float)[:, None]
    h = problem.h[:, None]
    v = X[:N, NQ:]
    a = lin.acc[:N]
    f_z = np.empty((N, NX))
    f_z[:, NQ:] = a / Ni
    f_z[:, :NQ] = (v + 2.0 * h * a) / Ni if problem.dynamics.integrator == "semi_implicit" else v / Ni
    return f_z


def time_scaled_jacobians(problem: HybridProblem, X: np.ndarray, lin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Derivatives of each knot's discrete step w.r.t. its own phase duration ``T_i`` (eq. 28, ``h_i = T_i / N_i``).

    Forward Euler (``q+ = q + h v``, ``v+ = v + h a``)::

        f_z = [v, a] / N_i,   f_xz = [[0, I], [a_q, a_v]] / N_i,   f_uz = [[0], [a_u]] / N_i

    semi-implicit Euler (``v+ = v + h a``, ``q+ = q + h v + h^2 a``) adds the ``h^2`` terms' derivatives
    ``2 h a / N_i`` (and ``2 h a_q``, ``2 h a_v``, ``2 h a_u`` over ``N_i``) to the position rows.

    Args:
        problem: the (time-scaled) problem; its ``knots``, ``h`` and the dynamics' integrator are used.
        X: states ``(N+1, 14)`` the linearization ``lin`` was taken at.
        lin: a [`hsddp_gym.core.dynamics.Linearization`][hsddp_gym.core.dynamics.Linearization] of ``X`` (``acc``,
            ``a_q``, ``a_v``, ``a_tau``).
    Returns:
        ``(f_z (N, 14), f_xz (N, 14, 14), f_uz (N, 14, 4))``; ``f_xz[k] = d f_x[k] / d T_i``.
    """
    N = problem.n_knots
    Ni = problem.knots[problem.phase_of_knot].astype(float)[:, None]
    h = problem.h[:, None]
    semi = problem.dynamics.integrator == "semi_implicit"
    f_z = duration_rates(problem, X, lin)
    f_xz = np.zeros((N, NX, NX))
    f_uz = np.zeros((N, NX, NU))
    hh = h[:, :, None]
    N3 = Ni[:, :, None]
    f_xz[:, NQ:, :NQ] = lin.a_q[:N] / N3
    f_xz[:, NQ:, NQ:] = lin.a_v[:N] / N3
    f_uz[:, NQ:, :] = lin.a_tau[:N, :, 3:] / N3
    if semi:
        f_xz[:, :NQ, :NQ] = 2.0 * hh * lin.a_q[:N] / N3
        f_xz[:, :NQ, NQ:] = (np.eye(NQ) + 2.0 * hh * lin.a_v[:N]) / N3
        f_uz[:, :NQ, :] = 2.0 * hh * lin.a_tau[:N, :, 3:] / N3
    else:
        f_xz[:, :NQ, NQ:] = np.eye(NQ) / N3
    return f_z, f_xz, f_uz


def time_derivatives(solver: HSDDP, problem: HybridProblem, feedback: bool = True, mu: float = 0.0,
                     second_order: bool = False, fd_step: float = 1e-6) -> TimeDerivatives:
    """V_z, V_zz at the solver's current nominal trajectory (linearized at it by the last ``solve``).

    Args:
        solver: an [`HSDDP`][HSDDP] that has just solved ``problem`` (its workspace holds the linearization).
        feedback: HS-DDP (True) or the open-loop baseline (False).
        second_order: add the dynamics' (and ground-force cost's) second-order terms contracted with the
            value gradient, as full DDP does (paper eq. 5 with the tensor terms); iLQR, the paper's choice,
            omits them. Pinocchio has no second derivatives of constrained dynamics, so each contraction
            is a central difference (step ``fd_step``) of the *analytical* first derivatives: 36 extra
            linearizations per knot. With it, V_zz is the exact Hessian of the objective under the fixed
            feedback policy; without it, V_zz is iLQR's Gauss-Newton approximation (a few % off).
    """
    ws = solver._ws
    if ws is None or solver.last_problem is not problem or solver.last_objective is None:
        raise ValueError("solver has no linearization of this problem; call solver.solve(problem, ...) first")
    tr = ws.nominal
    lin = ws.lin
    N, n = problem.n_knots, problem.n_phases
    ph = problem.phase_of_knot
    Ni = problem.knots[ph].astype(float)[:, None]
    Ti = problem.schedule.durations[ph][:, None]
    f_z, f_xz, f_uz = time_scaled_jacobians(problem, tr.X, lin)
    obj = solver.last_objective
    L_x, L_u = obj.task_running_gradients(tr.X, tr.U, tr.GRF, lin.grf_x[:N], lin.grf_u[:N])
    l_z = obj.running_rates(tr.X, tr.U, tr.GRF) / Ni[:, 0]
    l_xz = L_x / Ti
    l_uz = L_u / Ti
    K_x = np.zeros((N, NU, NX))
    K_z = np.zeros((N, NU, n))
    k_ff = np.zeros((N, NU))
    knot_tensor = reset_tensor = None
    if second_order:
        knot_tensor, reset_tensor = _tensor_terms(problem, tr, obj._gy, fd_step)
    mu_try = mu
    for _ in range(40):
        try:
            ok, Vx, Vz, Vxx, Vxz, Vzz, dV1, dV2 = backward_pass_time(
                lin.f_x[:N], lin.f_u[:N], f_z, f_xz, f_uz, ws.l_x, ws.l_u, ws.l_xx, ws.l_uu, ws.l_ux, l_z, l_xz,
                l_uz, ws.Phi_x, ws.Phi_xx, ws.P_x, problem.phase_start, ph, n, feedback, mu_try, K_x, K_z, k_ff,
                knot_tensor, reset_tensor)
            if np.all(np.isfinite(Vzz)):
                break
        except np.linalg.LinAlgError:  # Q_uu singular: regularize more
            pass
        mu_try = max(1e-6, 4.0 * mu_try)
    else:
        raise RuntimeError("time-augmented backward pass failed (Q_uu singular at every regularization)")
    return TimeDerivatives(V_z=Vz, V_zz=Vzz, V_xz=Vxz, K_x=K_x, K_z=K_z, k_ff=k_ff, dV1=dV1, dV2=dV2)


def duration_gradient(solver: HSDDP, problem: HybridProblem) -> np.ndarray:
    """``V_z (n,)``: the first-order derivative of the objective w.r.t. each phase duration at the solver's nominal
    trajectory, from the value gradients of its last backward pass (the envelope theorem: at an optimum the
    feedback terms of [`time_derivatives`][time_derivatives] vanish and ``dJ/dT_i = sum_k (l_z[k] + V_x[k+1] . f_z[k])``
    over the knots of phase ``i``, with ``V_x`` taken through the reset map at the phase's end).

    Vectorized over the horizon (no per-knot Python): about 50 times cheaper than
    [`time_derivatives`][time_derivatives], which also gives ``V_zz`` and the time-augmented gains. Exact at a converged
    solve; after a single DDP iteration (the MPC's re-plans) it is the gradient of the quadratic model the iteration
    stopped at. """
    ws = solver._ws
    if ws is None or solver.last_problem is not problem or solver.last_objective is None:
        raise ValueError("solver has no linearization of this problem; call solver.solve(problem, ...) first")
    tr, lin = ws.nominal, ws.lin
    N, n = problem.n_knots, problem.n_phases
    ph = problem.phase_of_knot
    f_z = duration_rates(problem, tr.X, lin)
    l_z = solver.last_objective.running_rates(tr.X, tr.U, tr.GRF) / problem.knots[ph]
    lam = ws.V_x[1:N + 1].copy()  # value gradient after each knot
    ends = problem.phase_start[1:n] - 1  # the last knot of every phase but the final one: through the reset map
    lam[ends] = ws.Phi_x[:n - 1] + np.einsum("iab,ia->ib", ws.P_x[:n - 1], ws.V_x[ends + 1])
    per_knot = l_z + np.einsum("ka,ka->k", f_z, lam)
    return np.bincount(ph, weights=per_knot, minlength=n)


def _tensor_terms(problem: HybridProblem, tr: _Traj, g_grf: np.ndarray, step: float):
    """Second-order contractions by central differences of the analytical first derivatives.

    For knot k: ``psi(x, u) = lam^T f(x, u) + g_grf[k]^T grf(x, u)`` with ``lam`` the next value gradient;
    its Hessian over ``(x, u)`` is returned split as ``(T_xx, T_ux, T_uu)``. For the reset of phase i:
    the Hessian of ``lam^T P(x)``.
    """
    dyn = problem.dynamics
    semi = dyn.integrator == "semi_implicit"
    bufs = [np.empty((NQ, NQ)), np.empty((NQ, NQ)), np.empty((NQ, NU)), np.empty((4, NQ)), np.empty((4, NQ)),
            np.empty((4, NU))]
    nz = NX + NU

    def grad(x, u, mode, w_a, g):
        a_q, a_v, a_u, l_q, l_v, l_u = bufs
        dyn.raw_derivatives(x, u, mode, a_q, a_v, a_u, l_q, l_v, l_u)
        out = np.empty(nz)
        out[:NQ] = a_q.T @ w_a + l_q.T @ g
        out[NQ:NX] = a_v.T @ w_a + l_v.T @ g
        out[NX:] = a_u.T @ w_a + l_u.T @ g
        return out

    def knot_tensor(k, lam):
        h = problem.h[k]
        w_a = h * lam[NQ:] + (h * h * lam[:NQ] if semi else 0.0)
        g = g_grf[k]
        x0, u0 = tr.X[k], tr.U[k]
        mode = int(problem.modes[k])
        H = np.empty((nz, nz))
        for j in range(nz):
            xp, up = x0.copy(), u0.copy()
            xm, um = x0.copy(), u0.copy()
            if j < NX:
                xp[j] += step
                xm[j] -= step
            else:
                up[j - NX] += step
                um[j - NX] -= step
            H[:, j] = (grad(xp, up, mode, w_a, g) - grad(xm, um, mode, w_a, g)) / (2.0 * step)
        H = 0.5 * (H + H.T)
        return H[:NX, :NX], H[NX:, :NX], H[NX:, NX:]

    def reset_tensor(i, lam_plus):
        x0 = tr.X_pre[i]
        mode_after = problem.schedule.next_mode(i)
        H = np.empty((NX, NX))
        P = np.empty((NX, NX))
        for j in range(NX):
            xp, xm = x0.copy(), x0.copy()
            xp[j] += step
            xm[j] -= step
            dyn._reset_jacobian(xp, mode_after, problem.restitution, P)
            gp = P.T @ lam_plus
            dyn._reset_jacobian(xm, mode_after, problem.restitution, P)
            H[:, j] = (gp - P.T @ lam_plus) / (2.0 * step)
        return 0.5 * (H + H.T)

    return knot_tensor, reset_tensor


def rollout_time_policy(problem_new: HybridProblem, nominal: _Traj, deriv: TimeDerivatives, dz: np.ndarray,
                        feedback: bool, out: _Traj, eps: float = 0.0) -> bool:
    """Roll out on ``problem_new`` (new durations, same knots) with ``u = U + eps k + K_x dx + K_z dz``
    (``feedback``) or ``u = U`` (open loop)."""
    if feedback:
        U_ref = nominal.U + np.einsum("nuz,z->nu", deriv.K_z, dz)
        return rollout_policy(problem_new, out, U_ref, nominal.X, deriv.K_x, deriv.k_ff, eps)
    return rollout_policy(problem_new, out, nominal.U)


def _bound_value(value, name: str):
    """A duration bound as given to [`STOOptions`][STOOptions]: a number, or one number per phase (a tuple)."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number or a sequence of numbers [s], got {value!r}")
    if isinstance(value, (int, float, np.integer, np.floating)):
        out = float(value)
        arr = np.array([out])
    else:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number or a sequence of numbers [s], got {value!r}") from None
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(f"{name} must be a number or a 1-D sequence (one bound per phase) [s], got {value!r}")
        out = tuple(float(v) for v in arr)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ValueError(f"{name} must be finite and > 0 [s], got {value!r}")
    return out


@dataclasses.dataclass(frozen=True)
class STOOptions:
    """Options of Algorithm 2.

    Attributes:
        method: ``"hsddp"`` (feedback policy, the paper) or ``"open-loop"`` (Xu & Antsaklis).
        iterations: STO iterations (paper: 30).
        min_duration, max_duration: bounds on the mode durations [s]: one number for every phase, or a
            sequence with one number per phase (checked against the problem in
            [`optimize_switching_times`][optimize_switching_times]). Not from the paper, which gives none: the default
            minimum 0.02 s (a quarter of the initial 72-80 ms phases; each phase keeps its knots, so its step
            ``h_i = T_i / N_i`` stays >= 0.25 ms) keeps a phase from collapsing, the maximum 0.2 s keeps
            the Euler step <= 2.8 ms. Neither is active in the paper's task 2.
        step_factor, min_step: backtracking on eps_z. armijo: sufficient decrease fraction.
        tolerance: stop when the accepted duration change is below it [s] (max norm).
        second_order: exact V_zz with the dynamics' second-order terms (see [`time_derivatives`][time_derivatives]);
            default False: iLQR's Gauss-Newton V_zz, as in the paper.
        solver: Algorithm 1's options for the inner re-solves.
    """

    method: str = "hsddp"
    iterations: int = 30
    min_duration: float | tuple = 0.02
    max_duration: float | tuple = 0.2
    step_factor: float = 0.5
    min_step: float = 1e-3
    armijo: float = 1e-4
    tolerance: float = 1e-6
    second_order: bool = False
    solver: SolverOptions = SolverOptions()

    def __post_init__(self) -> None:
        if self.method not in STO_METHODS:
            raise ValueError(f"method must be one of {STO_METHODS}, got {self.method!r}")
        if isinstance(self.iterations, bool) or not (isinstance(self.iterations, int) and self.iterations >= 0):
            raise ValueError(f"iterations must be an integer >= 0, got {self.iterations!r}")
        if not (0.0 < self.step_factor < 1.0):
            raise ValueError(f"step_factor must be in (0, 1), got {self.step_factor!r}")
        if not (0.0 < self.min_step <= 1.0):
            raise ValueError(f"min_step must be in (0, 1], got {self.min_step!r}")
        if not (self.tolerance > 0.0 and np.isfinite(self.tolerance)):
            raise ValueError(f"tolerance must be finite and > 0, got {self.tolerance!r}")
        if not (0.0 <= self.armijo < 1.0):
            raise ValueError(f"armijo must be in [0, 1), got {self.armijo!r}")
        if not isinstance(self.second_order, (bool, np.bool_)):
            raise TypeError(f"second_order must be a bool, got {type(self.second_order).__name__}")
        if not isinstance(self.solver, SolverOptions):
            raise TypeError(f"solver must be a SolverOptions, got {type(self.solver).__name__}")
        lo = _bound_value(self.min_duration, "min_duration")
        hi = _bound_value(self.max_duration, "max_duration")
        object.__setattr__(self, "min_duration", lo)
        object.__setattr__(self, "max_duration", hi)
        lo_a, hi_a = np.atleast_1d(lo), np.atleast_1d(hi)
        if lo_a.size > 1 and hi_a.size > 1 and lo_a.size != hi_a.size:
            raise ValueError(f"min_duration and max_duration give bounds for {lo_a.size} and {hi_a.size} phases")
        if not np.all(lo_a < hi_a):
            raise ValueError(f"need 0 < min_duration < max_duration (per phase), got {lo}, {hi}")

    def bounds(self, n_phases: int) -> tuple[np.ndarray, np.ndarray]:
        """``(lower (n,), upper (n,))`` duration bounds [s] for a problem with ``n_phases`` phases."""
        out = []
        for name in ("min_duration", "max_duration"):
            b = np.atleast_1d(np.asarray(getattr(self, name), dtype=np.float64))
            if b.size == 1:
                b = np.full(n_phases, b[0])
            elif b.size != n_phases:
                raise ValueError(f"{name} has {b.size} per-phase bounds, the problem has {n_phases} phases")
            out.append(b)
        return out[0], out[1]


def duration_step(V_z: np.ndarray, V_zz: np.ndarray, z: np.ndarray, lower: np.ndarray, upper: np.ndarray
                  ) -> tuple[np.ndarray, bool, np.ndarray]:
    """The duration step of eq. 31, ``dz = -V_zz^-1 V_z``, made safe for bounds and a non-PD ``V_zz``.

    * Bounds (projected Newton, Bertsekas 1982): a duration at its lower bound with ``V_z > 0`` (the
      descent direction would push it below) or at its upper bound with ``V_z < 0`` is held, ``dz_i = 0``;
      the Newton system is solved on the remaining (free) durations F: ``dz_F = -V_zz[F, F]^-1 V_z[F]``.
      Clipping the full Newton step instead would move the free durations by an amount that assumes the
      held ones move too. The caller still clips ``z + eps dz`` into the bounds in its line search.
    * Fallback: when ``V_zz[F, F]`` is not positive definite (an eigenvalue <= ``floor = max(1e-8,
      1e-6 max|w|)``), its eigenvalues ``w`` are replaced by ``max(|w|, floor)``. The direction is then a
      descent direction, ``V_z . dz < 0`` unless ``V_z[F] = 0``, with Newton's length scale.

    Args:
        V_z (n,), V_zz (n, n): derivatives of the objective w.r.t. the durations.
        z (n,): current durations [s]. lower, upper (n,): their bounds [s].
    Returns:
        ``(dz (n,), pd, free (n,) bool)``: the direction, whether ``V_zz[F, F]`` was positive definite
        (True when no duration is free), and the free set.
    """
    V_z = np.asarray(V_z, dtype=np.float64)
    n = V_z.shape[0]
    V_zz = np.asarray(V_zz, dtype=np.float64)
    if V_zz.shape != (n, n):
        raise ValueError(f"V_zz must have shape ({n}, {n}), got {V_zz.shape}")
    if not (np.all(np.isfinite(V_z)) and np.all(np.isfinite(V_zz))):
        raise ValueError("V_z and V_zz must be finite")
    held = ((z <= lower) & (V_z > 0.0)) | ((z >= upper) & (V_z < 0.0))
    free = ~held
    dz = np.zeros(n)
    if not free.any():
        return dz, True, free
    H = V_zz[np.ix_(free, free)]
    w, Q = np.linalg.eigh(0.5 * (H + H.T))
    floor = max(1e-8, 1e-6 * float(np.max(np.abs(w))))
    pd = bool(np.all(w > floor))
    w_safe = w if pd else np.maximum(np.abs(w), floor)
    dz[free] = -(Q @ ((Q.T @ V_z[free]) / w_safe))
    return dz, pd, free


@dataclasses.dataclass
class STOResult:
    """Result of Algorithm 2: the final [`Solution`][Solution], the duration history ``(iters+1, n)``, the
    objective after each iteration, and per-iteration records."""

    solution: Solution
    durations: np.ndarray
    objectives: np.ndarray
    costs: np.ndarray
    records: list
    initial_durations: np.ndarray
    solve_time: float

    @property
    def total_time(self) -> float:
        return float(self.durations[-1].sum())

    @property
    def reduction(self) -> float:
        return 1.0 - self.total_time / float(self.initial_durations.sum())


def optimize_switching_times(problem: HybridProblem, U_init: np.ndarray, options: STOOptions = STOOptions(),
                             callback=None) -> STOResult:
    """Algorithm 2 (HS-DDP) or the open-loop baseline on ``problem`` (its durations are the start).

    Each iteration: V_z, V_zz at the current solution ([`time_derivatives`][time_derivatives]), the direction of
    [`duration_step`][duration_step], a backtracking search on ``eps_z`` (durations ``clip(z + eps_z dz)``, rolled out
    with the time-augmented feedback policy or, open loop, the controls as they are) that accepts only a
    decrease of the objective, then Algorithm 1 re-solved on the new durations from the accepted rollout's
    controls, continuing the outer-loop state (multipliers, penalty, barrier parameters) -- for both methods.

    Args:
        problem: the hybrid OCP; its knots per phase stay fixed, their step scales with the duration.
        U_init: warm start controls ``(N, 4)``.
        options: an [`STOOptions`][STOOptions].
        callback: called with each iteration's record dict.
    Returns:
        An [`STOResult`][STOResult]. Its records have ``iteration``, ``V_z``, ``V_zz``, ``V_zz_pd``, ``free``
        (durations not held at a bound), ``direction`` (the projected Newton direction ``dz``),
        ``line_search`` (every trial in order: ``{"eps", "objective", "predicted"}``, the objective of the
        trial's rollout, NaN if it diverged, and the quadratic model's change; the first trial is
        ``eps = 1``, each next one ``step_factor`` times the previous), ``step`` (the accepted eps_z, 0 if
        none), ``objective_before`` and ``status``:
        ``"accepted"`` (then also ``durations``, ``total_time``, ``objective_rollout``, ``predicted``,
        ``objective_after_resolve``, ``cost``, ``switching_violation``), ``"converged"`` (the full projected
        Newton step is below ``tolerance``) or ``"no_decrease"`` (no decrease down to ``min_step``); the
        last two end the run.
    Raises:
        TypeError: ``problem`` or ``options`` of the wrong type. ValueError: initial durations outside the
            bounds, per-phase bounds of the wrong length, or a bad ``U_init`` (see [`HSDDP.solve`][HSDDP.solve]).
    """
    if not isinstance(problem, HybridProblem):
        raise TypeError(f"problem must be a HybridProblem, got {type(problem).__name__}")
    if not isinstance(options, STOOptions):
        raise TypeError(f"options must be an STOOptions, got {type(options).__name__}")
    warm_up()  # numba compile / cache load, outside solve_time
    t0 = time.perf_counter()
    feedback = options.method == "hsddp"
    z = problem.schedule.durations.copy()
    lower, upper = options.bounds(problem.n_phases)
    if np.any(z < lower) or np.any(z > upper):
        raise ValueError(f"initial durations {z} outside [min_duration, max_duration] = [{lower}, {upper}]")
    pr = HybridProblem(problem.dynamics, problem.schedule, problem.costs, problem.x0, problem.constraints,
                       problem.restitution, knots=problem.knots, terrain=problem.terrain)
    solver = HSDDP(options.solver)
    sol = solver.solve(pr, U_init)
    history = [z.copy()]
    objectives = [sol.objective]
    costs = [sol.cost]
    records = []
    cand = _Traj(pr.n_knots, pr.n_phases)
    for it in range(options.iterations):
        cs = solver.last_constraint_state
        deriv = time_derivatives(solver, pr, feedback=feedback, second_order=options.second_order)
        Vz, Vzz = deriv.V_z, deriv.V_zz
        dz, pd, free = duration_step(Vz, Vzz, z, lower, upper)
        current = solver._evaluate(solver.last_objective, solver._ws.nominal, cs).total
        eps = 1.0
        accepted = None
        stop = "no_decrease"
        trials = []
        while eps >= options.min_step:
            z_new = np.clip(z + eps * dz, lower, upper)
            step = z_new - z
            if np.max(np.abs(step)) < options.tolerance:
                if eps == 1.0:
                    stop = "converged"  # the full (projected) Newton step is below the tolerance
                break
            pr_new = pr.with_durations(z_new)
            ok = rollout_time_policy(pr_new, solver._ws.nominal, deriv, step, feedback, cand)
            predicted = float(Vz @ step + 0.5 * step @ Vzz @ step)
            new = Objective(pr_new).evaluate(cand.X, cand.X_pre, cand.U, cand.GRF, cs).total if ok else float("nan")
            trials.append({"eps": eps, "objective": float(new), "predicted": predicted})
            if ok and np.isfinite(new) and new < current + options.armijo * min(predicted, 0.0) and new < current:
                accepted = (z_new, pr_new, new, predicted)
                break
            eps *= options.step_factor
        rec = {"iteration": it + 1, "V_z": Vz.tolist(), "V_zz": Vzz.tolist(), "V_zz_pd": pd, "free": free.tolist(),
               "direction": dz.tolist(), "line_search": trials, "step": eps if accepted else 0.0,
               "objective_before": current}
        if accepted is None:
            rec["status"] = stop
            records.append(rec)
            if callback:
                callback(rec)
            break
        z, pr, obj_rollout, predicted = accepted
        sol = solver.solve(pr, cand.U.copy(), constraint_state=cs)
        history.append(z.copy())
        objectives.append(sol.objective)
        costs.append(sol.cost)
        rec.update(status="accepted", durations=z.tolist(), total_time=float(z.sum()), objective_rollout=obj_rollout,
                   predicted=predicted, objective_after_resolve=sol.objective, cost=sol.cost,
                   switching_violation=sol.switching_violation)
        records.append(rec)
        if callback:
            callback(rec)
    return STOResult(solution=sol, durations=np.array(history), objectives=np.array(objectives),
                     costs=np.array(costs), records=records, initial_durations=problem.schedule.durations.copy(),
                     solve_time=time.perf_counter() - t0)


def step_size_study(solver: HSDDP, problem: HybridProblem, U_nominal: np.ndarray, steps, feedback: bool = True
                    ) -> dict:
    """Paper Fig. 8: actual and predicted objective change against the step size for a control step only
    (``eps = s, eps_z = 0``), a duration step only (``eps = 0, eps_z = s``) and both (``eps = eps_z = s``),
    around the open-loop rollout of ``U_nominal`` on ``problem`` (a point where the control is not yet
    optimal, so both steps act).

    The prediction is DDP's quadratic model at the initial knot:
    ``eps dV1 + eps^2/2 dV2 + eps_z V_z^T dz + eps_z^2/2 dz^T V_zz dz``.

    Args:
        solver: an [`HSDDP`][HSDDP] whose options and outer-loop state (``last_constraint_state``) are used;
            its workspace is replaced by this study's (the nominal rollout of ``U_nominal``).
    Returns:
        ``{"steps": [...], "dz": [...], "<case>": {"actual": [...], "predicted": [...]}}`` for the cases
        ``"control"``, ``"durations"``, ``"both"``.
    """
    from hsddp_gym.planners.optimizer.hsddp import Workspace

    cs = solver.last_constraint_state
    if cs is None:
        raise ValueError("solver has no outer-loop state; solve a problem with it first")
    ws = Workspace(problem)
    solver._ws = ws  # the solver's workspace now holds this study's nominal (documented side effect)
    solver.last_objective = Objective(problem)
    solver.last_problem = problem
    if not rollout_policy(problem, ws.nominal, U_nominal):
        raise ValueError("U_nominal gives a non-finite rollout")
    timings = {"linearize": 0.0, "reset_jacobians": 0.0, "cost_derivatives": 0.0}
    solver._linearize(problem, solver.last_objective, cs, timings)
    d = time_derivatives(solver, problem, feedback=feedback)
    w, Q = np.linalg.eigh(0.5 * (d.V_zz + d.V_zz.T))
    dz = -(Q @ ((Q.T @ d.V_z) / np.maximum(np.abs(w), 1e-8 * np.max(np.abs(w)))))
    J0 = solver._evaluate(solver.last_objective, ws.nominal, cs).total
    out = {"steps": [float(s) for s in steps], "dz": dz.tolist(), "objective": J0}
    cand = _Traj(problem.n_knots, problem.n_phases)
    for case, (use_eps, use_z) in {"control": (True, False), "durations": (False, True), "both": (True, True)}.items():
        actual, predicted = [], []
        for s in steps:
            eps = s if use_eps else 0.0
            ez = s if use_z else 0.0
            step = ez * dz
            z_new = problem.schedule.durations + step
            if np.any(z_new <= 0):
                actual.append(float("nan"))
                predicted.append(float("nan"))
                continue
            pr_new = problem.with_durations(z_new)
            U_ref = ws.nominal.U + np.einsum("nuz,z->nu", d.K_z, step)
            ok = rollout_policy(pr_new, cand, U_ref, ws.nominal.X, d.K_x, d.k_ff, eps)
            J = Objective(pr_new).evaluate(cand.X, cand.X_pre, cand.U, cand.GRF, cs).total if ok else float("nan")
            actual.append(float(J - J0))
            predicted.append(float(eps * d.dV1 + 0.5 * eps * eps * d.dV2 + d.V_z @ step + 0.5 * step @ d.V_zz @ step))
        out[case] = {"actual": actual, "predicted": predicted}
    return out
