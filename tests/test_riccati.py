"""The numba impact-aware backward pass (paper eqs. 5, 7 and 22) against independent references:

* one phase, linear-quadratic: the textbook discrete-time Riccati recursion (gains, feed-forward, V_x, V_xx
  at every knot) and the optimum of the condensed (batch) QP -- one full step of the policy reaches it;
* two or more phases with linear resets ``x+ = P x-`` and terminal costs at every phase end: V_x, V_xx at
  knot 0 and at the first knot after a reset are the derivatives of the optimal cost-to-go J*(x) (central
  differences of the batch optimum, exact for LQ);
* a nonlinear system with a nonlinear reset: V_x (mu = 0) is the gradient of the cost of the fixed
  feedback policy ``u = u_hat + K (x - x_hat)``, whatever the dynamics (a first-order identity).

Every array passed to ``backward_pass`` is C-contiguous float64 (``phase_start`` int64, ``mu`` float) so that
the cached numba specialization is reused.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.riccati import backward_pass

# ----------------------------------------------------------------------------------------- LQ machinery


@dataclasses.dataclass
class HybridLQ:
    """A hybrid affine time-varying system with quadratic costs.

    Knot k (phase i owns ``phase_start[i] .. phase_start[i+1]-1``): ``x+ = A[k] x + B[k] u + c[k]``, running
    cost ``1/2 x'Q x + 1/2 u'R u + u'S x + q'x + r'u``. At the end of phase i: terminal cost
    ``1/2 x'W[i] x + w[i]'x`` of the pre-reset state, then ``x+ = P[i] x-`` (no reset after the last phase).
    """

    A: np.ndarray
    B: np.ndarray
    c: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray
    q: np.ndarray
    r: np.ndarray
    W: np.ndarray
    w: np.ndarray
    P: np.ndarray
    phase_start: np.ndarray

    @property
    def N(self) -> int:
        return self.A.shape[0]

    @property
    def nx(self) -> int:
        return self.A.shape[1]

    @property
    def nu(self) -> int:
        return self.B.shape[2]

    @property
    def n_phases(self) -> int:
        return self.phase_start.shape[0] - 1

    def running(self, k, x, u) -> float:
        return float(0.5 * x @ self.Q[k] @ x + 0.5 * u @ self.R[k] @ u + u @ self.S[k] @ x + self.q[k] @ x
                     + self.r[k] @ u)

    def terminal(self, i, x) -> float:
        return float(0.5 * x @ self.W[i] @ x + self.w[i] @ x)

    def simulate(self, x0, control, first_phase: int = 0):
        """Roll out from phase ``first_phase`` with ``u_k = control(k, x_k)``; returns (X, X_pre, U, cost)."""
        N, nx, nu = self.N, self.nx, self.nu
        X = np.full((N + 1, nx), np.nan)
        X_pre = np.full((self.n_phases, nx), np.nan)
        U = np.full((N, nu), np.nan)
        k0 = self.phase_start[first_phase]
        X[k0] = x0
        cost = 0.0
        for i in range(first_phase, self.n_phases):
            for k in range(self.phase_start[i], self.phase_start[i + 1]):
                U[k] = control(k, X[k])
                cost += self.running(k, X[k], U[k])
                X[k + 1] = self.A[k] @ X[k] + self.B[k] @ U[k] + self.c[k]
            ke = self.phase_start[i + 1]
            X_pre[i] = X[ke]
            cost += self.terminal(i, X_pre[i])
            if i + 1 < self.n_phases:
                X[ke] = self.P[i] @ X_pre[i]
        return X, X_pre, U, cost

    def derivatives(self, X, X_pre, U):
        """The arrays ``backward_pass`` takes, along the trajectory (X, X_pre, U)."""
        l_x = np.einsum("kab,kb->ka", self.Q, X[:-1]) + np.einsum("kua,ku->ka", self.S, U) + self.q
        l_u = np.einsum("kab,kb->ka", self.R, U) + np.einsum("kua,ka->ku", self.S, X[:-1]) + self.r
        Phi_x = np.einsum("iab,ib->ia", self.W, X_pre) + self.w
        return dict(f_x=self.A.copy(), f_u=self.B.copy(), l_x=l_x, l_u=l_u,
                    l_xx=self.Q.copy(), l_uu=self.R.copy(), l_ux=self.S.copy(), Phi_x=Phi_x, Phi_xx=self.W.copy(),
                    P_x=self.P.copy())

    def batch_optimum(self, x0, first_phase: int = 0):
        """Minimum of the cost from ``x0`` at the start of ``first_phase`` over all controls, by condensing the
        states (``x_k = a_k + G_k U``) into one quadratic in U and solving its normal equations.

        Returns ``(J*, U* (m, nu))`` with m the knots from the start of ``first_phase``."""
        nx, nu = self.nx, self.nu
        k0 = int(self.phase_start[first_phase])
        m = self.N - k0
        a = np.asarray(x0, dtype=float).copy()
        G = np.zeros((nx, m * nu))
        H = np.zeros((m * nu, m * nu))
        g = np.zeros(m * nu)
        const = 0.0

        def add_state_quadratic(M, v, a, G):
            nonlocal const
            Ma = M @ a + v
            H[:] += G.T @ M @ G
            g[:] += G.T @ Ma
            const += 0.5 * a @ M @ a + v @ a

        for i in range(first_phase, self.n_phases):
            for k in range(self.phase_start[i], self.phase_start[i + 1]):
                j = slice((k - k0) * nu, (k - k0 + 1) * nu)
                add_state_quadratic(self.Q[k], self.q[k], a, G)
                H[j, j] += self.R[k]
                g[j] += self.r[k]
                SG = self.S[k] @ G  # u' S x = u' S a + u' S G U
                H[j, :] += SG
                H[:, j] += SG.T
                g[j] += self.S[k] @ a
                a, G = self.A[k] @ a + self.c[k], self.A[k] @ G
                G[:, j] += self.B[k]
            add_state_quadratic(self.W[i], self.w[i], a, G)
            if i + 1 < self.n_phases:
                a, G = self.P[i] @ a, self.P[i] @ G
        U = -np.linalg.solve(H, g)
        J = const + 0.5 * g @ U  # = const + g'U + 1/2 U'HU at the minimum
        return float(J), U.reshape(m, nu)


def run_backward(d: dict, phase_start: np.ndarray, mu: float = 0.0):
    N, nx = d["f_x"].shape[0], d["f_x"].shape[1]
    nu = d["f_u"].shape[2]
    k_ff = np.zeros((N, nu))
    K = np.zeros((N, nu, nx))
    V_x = np.zeros((N + 1, nx))
    V_xx = np.zeros((N + 1, nx, nx))
    args = [np.ascontiguousarray(d[name], dtype=np.float64) for name in
            ("f_x", "f_u", "l_x", "l_u", "l_xx", "l_uu", "l_ux", "Phi_x", "Phi_xx", "P_x")]
    ok, knot, dV1, dV2 = backward_pass(*args, np.ascontiguousarray(phase_start, dtype=np.int64), float(mu),
                                       k_ff, K, V_x, V_xx)
    return dict(ok=bool(ok), knot=int(knot), dV1=float(dV1), dV2=float(dV2), k=k_ff, K=K, V_x=V_x, V_xx=V_xx)


def random_spd(rng, n, scale=1.0, floor=0.0):
    M = rng.normal(size=(n, n))
    return scale * (M @ M.T / n + floor * np.eye(n))


def random_lq(rng, nx, nu, knots, dt=0.05) -> HybridLQ:
    """A random LTV system (stable-ish A = I + dt M) with PSD stage Hessians [[Q, S'], [S, R]], R > 0;
    one phase per entry of ``knots`` with random reset matrices and terminal costs."""
    N = int(sum(knots))
    phase_start = np.concatenate([[0], np.cumsum(knots)]).astype(np.int64)
    n = len(knots)
    A = np.eye(nx) + dt * rng.normal(size=(N, nx, nx)) / np.sqrt(nx)
    B = dt * rng.normal(size=(N, nx, nu))
    c = dt * rng.normal(size=(N, nx))
    H = np.stack([random_spd(rng, nx + nu, dt) for _ in range(N)])
    H[:, nx:, nx:] += dt * np.eye(nu)
    W = np.stack([random_spd(rng, nx, 1.0) for _ in range(n)])
    P = np.eye(nx) + 0.3 * rng.normal(size=(n, nx, nx)) / np.sqrt(nx)
    P[-1] = np.nan  # never used: there is no reset after the last phase
    return HybridLQ(A=A, B=B, c=c, Q=np.ascontiguousarray(H[:, :nx, :nx]), R=np.ascontiguousarray(H[:, nx:, nx:]),
                    S=np.ascontiguousarray(H[:, nx:, :nx]), q=dt * rng.normal(size=(N, nx)),
                    r=dt * rng.normal(size=(N, nu)), W=W, w=rng.normal(size=(n, nx)), P=P, phase_start=phase_start)


def textbook_riccati(d: dict):
    """The discrete-time Riccati recursion in matrix form (single phase, mu = 0)::

        Q_x = l_x + A'V_x,  Q_u = l_u + B'V_x,  Q_xx = l_xx + A'V_xx A,  Q_uu = l_uu + B'V_xx B,
        Q_ux = l_ux + B'V_xx A,  k = -Q_uu^-1 Q_u,  K = -Q_uu^-1 Q_ux,
        V_x <- Q_x - Q_ux' Q_uu^-1 Q_u,  V_xx <- Q_xx - Q_ux' Q_uu^-1 Q_ux.
    """
    N, nx = d["f_x"].shape[:2]
    nu = d["f_u"].shape[2]
    k_ff, K = np.zeros((N, nu)), np.zeros((N, nu, nx))
    V_x, V_xx = np.zeros((N + 1, nx)), np.zeros((N + 1, nx, nx))
    Vx, Vxx = d["Phi_x"][0].copy(), d["Phi_xx"][0].copy()
    V_x[N], V_xx[N] = Vx, Vxx
    dV1 = dV2 = 0.0
    for k in range(N - 1, -1, -1):
        A, B = d["f_x"][k], d["f_u"][k]
        Qx = d["l_x"][k] + A.T @ Vx
        Qu = d["l_u"][k] + B.T @ Vx
        Qxx = d["l_xx"][k] + A.T @ Vxx @ A
        Quu = d["l_uu"][k] + B.T @ Vxx @ B
        Qux = d["l_ux"][k] + B.T @ Vxx @ A
        k_ff[k] = -np.linalg.solve(Quu, Qu)
        K[k] = -np.linalg.solve(Quu, Qux)
        dV1 += k_ff[k] @ Qu
        dV2 += k_ff[k] @ Quu @ k_ff[k]
        Vx = Qx - Qux.T @ np.linalg.solve(Quu, Qu)
        Vxx = Qxx - Qux.T @ np.linalg.solve(Quu, Qux)
        Vxx = 0.5 * (Vxx + Vxx.T)
        V_x[k], V_xx[k] = Vx, Vxx
    return dict(k=k_ff, K=K, V_x=V_x, V_xx=V_xx, dV1=dV1, dV2=dV2)


def assert_rel(actual, expected, rtol, what=""):
    """``|actual - expected| <= rtol * max|expected|`` (a relative error on the array's scale)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    scale = max(float(np.max(np.abs(expected))), 1e-300)
    err = float(np.max(np.abs(actual - expected))) / scale
    assert err <= rtol, f"{what}: relative error {err:.3e} > {rtol:.1e}"


def policy(X_hat, U_hat, K, k_ff, eps):
    return lambda k, x: U_hat[k] + eps * k_ff[k] + K[k] @ (x - X_hat[k])


def fd_gradient_hessian(f, x0, h):
    """Central differences of a scalar function: gradient and Hessian (exact up to round-off for quadratics)."""
    n = x0.size
    E = h * np.eye(n)
    grad = np.array([(f(x0 + E[i]) - f(x0 - E[i])) / (2 * h) for i in range(n)])
    hess = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            v = (f(x0 + E[i] + E[j]) - f(x0 + E[i] - E[j]) - f(x0 - E[i] + E[j]) + f(x0 - E[i] - E[j])) / (4 * h * h)
            hess[i, j] = hess[j, i] = v
    return grad, hess


# ----------------------------------------------------------------------------------------- 1. LQ, one phase


@pytest.mark.parametrize("nx,nu", [(14, 4), (5, 6), (3, 1)])
def test_lq_backward_pass_equals_textbook_riccati(nx, nu, rng):
    lq = random_lq(rng, nx, nu, [30])
    x0 = rng.normal(size=nx)
    U_hat = rng.normal(size=(lq.N, nu))
    X_hat, X_pre, _, _ = lq.simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    out = run_backward(d, lq.phase_start, mu=0.0)
    ref = textbook_riccati(d)
    assert out["ok"] and out["knot"] == -1
    for name in ("k", "K", "V_x", "V_xx"):
        for kk in range(lq.N + (1 if name.startswith("V") else 0)):
            assert_rel(out[name][kk], ref[name][kk], 1e-9, f"{name}[{kk}]")
    assert out["dV1"] == pytest.approx(ref["dV1"], rel=1e-9)
    assert out["dV2"] == pytest.approx(ref["dV2"], rel=1e-9)
    # V_xx is symmetric at every knot
    np.testing.assert_array_equal(out["V_xx"], out["V_xx"].transpose(0, 2, 1))


@pytest.mark.parametrize("nx,nu", [(14, 4), (5, 6)])
def test_lq_full_step_reaches_the_batch_optimum(nx, nu, rng):
    lq = random_lq(rng, nx, nu, [30])
    x0 = rng.normal(size=nx)
    U_hat = 3.0 * rng.normal(size=(lq.N, nu))
    X_hat, X_pre, _, J_hat = lq.simulate(x0, lambda k, x: U_hat[k])
    out = run_backward(lq.derivatives(X_hat, X_pre, U_hat), lq.phase_start)
    assert out["ok"]
    assert out["dV1"] < 0
    X1, X1_pre, U1, J1 = lq.simulate(x0, policy(X_hat, U_hat, out["K"], out["k"], 1.0))
    J_star, U_star = lq.batch_optimum(x0)
    assert J1 == pytest.approx(J_star, rel=1e-8, abs=1e-8)
    assert_rel(U1, U_star, 1e-7, "U after one full step vs batch U*")
    assert J_star < J_hat
    # the expected change of a full step is exact for an LQ problem
    assert J1 - J_hat == pytest.approx(out["dV1"] + 0.5 * out["dV2"], rel=1e-8)
    # a second backward pass at the optimum: no feed-forward, no expected decrease
    out2 = run_backward(lq.derivatives(X1, X1_pre, U1), lq.phase_start)
    assert out2["ok"]
    assert np.max(np.abs(out2["k"])) <= 1e-8 * max(1.0, np.max(np.abs(U1)))
    assert abs(out2["dV1"]) <= 1e-10 * max(1.0, abs(J1))
    # the gains do not depend on the trajectory (LQ)
    assert_rel(out2["K"], out["K"], 1e-9, "K")
    assert_rel(out2["V_xx"], out["V_xx"], 1e-9, "V_xx")


def test_regularized_pass_uses_regularized_gains_with_exact_q_blocks(rng):
    """mu > 0 (Tassa et al. 2012, eq. 11): k, K from Q_uu + mu I; V from the exact Q blocks."""
    nx, nu, mu = 6, 3, 0.7
    lq = random_lq(rng, nx, nu, [12])
    x0 = rng.normal(size=nx)
    U_hat = rng.normal(size=(lq.N, nu))
    X_hat, X_pre, _, _ = lq.simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    out = run_backward(d, lq.phase_start, mu=mu)
    assert out["ok"]
    Vx, Vxx = d["Phi_x"][0], d["Phi_xx"][0]
    for k in range(lq.N - 1, -1, -1):
        A, B = d["f_x"][k], d["f_u"][k]
        Qx, Qu = d["l_x"][k] + A.T @ Vx, d["l_u"][k] + B.T @ Vx
        Qxx, Quu, Qux = d["l_xx"][k] + A.T @ Vxx @ A, d["l_uu"][k] + B.T @ Vxx @ B, d["l_ux"][k] + B.T @ Vxx @ A
        kk = -np.linalg.solve(Quu + mu * np.eye(nu), Qu)
        KK = -np.linalg.solve(Quu + mu * np.eye(nu), Qux)
        assert_rel(out["k"][k], kk, 1e-9, f"k[{k}]")
        assert_rel(out["K"][k], KK, 1e-9, f"K[{k}]")
        Vx = Qx + KK.T @ Quu @ kk + KK.T @ Qu + Qux.T @ kk
        Vxx = Qxx + KK.T @ Quu @ KK + KK.T @ Qux + Qux.T @ KK
        Vxx = 0.5 * (Vxx + Vxx.T)
        assert_rel(out["V_x"][k], Vx, 1e-9, f"V_x[{k}]")
        assert_rel(out["V_xx"][k], Vxx, 1e-9, f"V_xx[{k}]")


def test_indefinite_q_uu_reports_the_failing_knot(rng):
    nx, nu = 4, 2
    lq = random_lq(rng, nx, nu, [10])
    x0 = rng.normal(size=nx)
    U_hat = rng.normal(size=(lq.N, nu))
    X_hat, X_pre, _, _ = lq.simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    d["l_uu"][6] = -100.0 * np.eye(nu)
    out = run_backward(d, lq.phase_start, mu=0.0)
    assert not out["ok"] and out["knot"] == 6
    # enough regularization makes it positive definite again
    assert run_backward(d, lq.phase_start, mu=1e3)["ok"]


# ----------------------------------------------------------------------------------------- 2. hybrid, resets


def bouncing_mass(e=0.6, h=0.01, knots=(40, 35)) -> HybridLQ:
    """A point mass (height z, velocity v) pushed by a force u against gravity: phase 0 falls to a touchdown
    (terminal cost wants z- = 0, v- = -1.5), the reset ``v+ = -e v-`` bounces it, phase 1 ends at z = 0.4."""
    N = sum(knots)
    A = np.tile(np.array([[1.0, h], [0.0, 1.0]]), (N, 1, 1))
    B = np.tile(np.array([[0.0], [h]]), (N, 1, 1))
    c = np.tile(np.array([0.0, -9.81 * h]), (N, 1))
    Qd = h * np.diag([2.0, 0.1])
    z_ref = np.array([0.3, 0.0])
    Q = np.tile(Qd, (N, 1, 1))
    q = np.tile(-Qd @ z_ref, (N, 1))
    R = np.tile(h * np.array([[0.05]]), (N, 1, 1))
    S = np.zeros((N, 1, 2))
    r = np.zeros((N, 1))
    W = np.stack([np.diag([200.0, 5.0]), np.diag([50.0, 2.0])])
    xf = np.array([[0.0, -1.5], [0.4, 0.0]])
    w = -np.einsum("iab,ib->ia", W, xf)
    P = np.stack([np.array([[1.0, 0.0], [0.0, -e]]), np.full((2, 2), np.nan)])
    return HybridLQ(A=A, B=B, c=c, Q=Q, R=R, S=S, q=q, r=r, W=W, w=w, P=P,
                    phase_start=np.array([0, knots[0], N], dtype=np.int64))


def _check_value_derivatives_against_optimal_cost_to_go(lq: HybridLQ, x0, U_hat, fd_step):
    X_hat, X_pre, _, _ = lq.simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    assert np.all(np.isfinite(d["Phi_x"])) and np.any(d["Phi_x"][0] != 0) and np.any(d["Phi_xx"][0] != 0)
    out = run_backward(d, lq.phase_start)
    assert out["ok"]
    for key in ("k", "K", "V_x", "V_xx"):
        assert np.all(np.isfinite(out[key])), f"{key} is not finite: the last phase's P_x (NaN) leaked in"
    for i in range(lq.n_phases):
        k0 = int(lq.phase_start[i])
        x_start = X_hat[k0]  # knot 0, or the post-reset state of phase i

        def J_star(x, i=i):
            return lq.batch_optimum(x, first_phase=i)[0]

        grad, hess = fd_gradient_hessian(J_star, x_start, fd_step)
        assert_rel(out["V_x"][k0], grad, 1e-6, f"V_x at knot {k0} (phase {i})")
        assert_rel(out["V_xx"][k0], hess, 1e-5, f"V_xx at knot {k0} (phase {i})")
    # the affine policy of one backward pass is the optimal feedback law across the reset: from perturbed
    # initial states its rollout cost is the batch optimum
    rng = np.random.default_rng(0)
    for _ in range(3):
        dx = 0.1 * rng.normal(size=lq.nx)
        J_pol = lq.simulate(x0 + dx, policy(X_hat, U_hat, out["K"], out["k"], 1.0))[3]
        assert J_pol == pytest.approx(lq.batch_optimum(x0 + dx)[0], rel=1e-8)
    return out, d, X_hat


def test_bouncing_mass_value_derivatives_across_the_reset(rng):
    lq = bouncing_mass()
    x0 = np.array([1.0, 0.0])
    U_hat = rng.normal(0.0, 2.0, (lq.N, 1))
    out, d, X_hat = _check_value_derivatives_against_optimal_cost_to_go(lq, x0, U_hat, fd_step=1e-2)
    # the reset matters: ignoring it (P_x = I in eq. 22) gives a different V_x at knot 0
    d_wrong = dict(d, P_x=np.stack([np.eye(2), np.eye(2)]))
    wrong = run_backward(d_wrong, lq.phase_start)
    assert np.max(np.abs(wrong["V_x"][0] - out["V_x"][0])) > 1e-2 * np.max(np.abs(out["V_x"][0]))
    # and so does the phase-0 terminal cost (Phi_x, Phi_xx of eq. 22)
    d_noterm = dict(d, Phi_x=d["Phi_x"] * np.array([[0.0], [1.0]]), Phi_xx=d["Phi_xx"] * np.array([[[0.0]], [[1.0]]]))
    noterm = run_backward(d_noterm, lq.phase_start)
    assert np.max(np.abs(noterm["V_xx"][0] - out["V_xx"][0])) > 1e-2 * np.max(np.abs(out["V_xx"][0]))


def test_random_three_phase_lq_value_derivatives(rng):
    lq = random_lq(rng, 4, 2, [9, 7, 8])
    x0 = rng.normal(size=4)
    U_hat = rng.normal(size=(lq.N, 2))
    _check_value_derivatives_against_optimal_cost_to_go(lq, x0, U_hat, fd_step=1e-2)


# ----------------------------------------------------------------------------------------- nonlinear reset


def _nl_step(x, u, h):
    z, v = x
    a = u[0] - 9.81 - 0.4 * v - 3.0 * np.sin(2.0 * z) - 0.5 * v ** 3
    return np.array([z + h * v, v + h * a])


def _nl_step_jac(x, h):
    z, v = x
    A = np.array([[1.0, h], [-6.0 * h * np.cos(2.0 * z), 1.0 + h * (-0.4 - 1.5 * v ** 2)]])
    B = np.array([[0.0], [h]])
    return A, B


def _nl_reset(x):
    z, v = x
    return np.array([z + 0.1 * z * v, -0.6 * v + 0.8 * z ** 2 + 0.3 * np.sin(v)])


def _nl_reset_jac(x):
    z, v = x
    return np.array([[1.0 + 0.1 * v, 0.1 * z], [1.6 * z, -0.6 + 0.3 * np.cos(v)]])


def _two_phase_bounce(rng):
    """``(h, lq, phase_start, N, x0, U_hat)``: the bouncing mass's two phases of 30 and 25 knots at h = 0.01 (its
    quadratic costs reused by the nonlinear-reset tests), a start state and random nominal controls."""
    h = 0.01
    lq = bouncing_mass(h=h, knots=(30, 25))
    return h, lq, lq.phase_start, lq.N, np.array([0.8, 0.3]), rng.normal(0.0, 3.0, (lq.N, 1))


def test_nonlinear_reset_v_x_is_the_gradient_of_the_fixed_feedback_policy_cost(rng):
    """With mu = 0, V_x = Q_x + K'Q_u satisfies the chain rule of J_pol(x0), the cost of rolling out
    ``u = u_hat + K (x - x_hat)`` on the nonlinear system, through the nonlinear reset (eq. 22c is exact to
    first order) -- no second-order information is involved."""
    h, lq, ps, N, x0, U_hat = _two_phase_bounce(rng)

    def simulate(x_start, control, first_phase=0):
        X = np.full((N + 1, 2), np.nan)
        X_pre = np.full((2, 2), np.nan)
        U = np.full((N, 1), np.nan)
        X[ps[first_phase]] = x_start
        cost = 0.0
        for i in range(first_phase, 2):
            for k in range(ps[i], ps[i + 1]):
                U[k] = control(k, X[k])
                cost += lq.running(k, X[k], U[k])
                X[k + 1] = _nl_step(X[k], U[k], h)
            X_pre[i] = X[ps[i + 1]]
            cost += lq.terminal(i, X_pre[i])
            if i == 0:
                X[ps[1]] = _nl_reset(X_pre[0])
        return X, X_pre, U, cost

    X_hat, X_pre, _, _ = simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    for k in range(N):
        d["f_x"][k], d["f_u"][k] = _nl_step_jac(X_hat[k], h)
    d["P_x"] = np.stack([_nl_reset_jac(X_pre[0]), np.full((2, 2), np.nan)])
    out = run_backward(d, ps)
    assert out["ok"]
    fb = policy(X_hat, U_hat, out["K"], out["k"], 0.0)
    # eps = 0 from x_hat reproduces the nominal
    np.testing.assert_allclose(simulate(x0, fb)[0], X_hat, rtol=0, atol=1e-14)
    for i in range(2):
        xs = X_hat[ps[i]]
        grad = np.array([(simulate(xs + e, fb, i)[3] - simulate(xs - e, fb, i)[3]) / 2e-6
                         for e in 1e-6 * np.eye(2)])
        assert_rel(out["V_x"][ps[i]], grad, 1e-6, f"V_x at knot {ps[i]}")
    # a wrong reset Jacobian is detected
    d_wrong = dict(d, P_x=np.stack([np.array([[1.0, 0.0], [0.0, -0.6]]), np.full((2, 2), np.nan)]))
    wrong = run_backward(d_wrong, ps)
    assert np.max(np.abs(wrong["V_x"][0] - out["V_x"][0])) > 1e-3 * np.max(np.abs(out["V_x"][0]))


def _nl_reset_curvature(x, lam):
    """``sum_j lam_j d^2 P_j / dx^2`` of :func:`_nl_reset` at ``x`` (analytical)."""
    z, v = x
    return lam[0] * np.array([[0.0, 0.1], [0.1, 0.0]]) + lam[1] * np.array([[1.6, 0.0], [0.0, -0.3 * np.sin(v)]])


def test_nonlinear_reset_v_xx_is_the_hessian_of_the_fixed_feedback_policy_cost(rng):
    """V_xx across a nonlinear reset: linear dynamics in both phases (so the knots add no curvature), the
    nonlinear reset of :func:`_nl_reset` between them. The Hessian of the cost-to-go just before the reset is
    ``Phi_xx + P_x' V_xx+ P_x + sum_j (V_x+)_j d^2 P_j``; eq. 22 (Gauss-Newton) has the first two terms, so the
    reset's curvature (analytical, contracted with the V_x+ of a first pass) is added to ``Phi_xx`` of phase 0.
    Then V_xx at knot 0 and at the knot before the reset are the Hessians of the cost of rolling out the fixed
    policy ``u = u_hat + K (x - x_hat)`` (4-point central differences), and V_xx after the reset is that of the
    second phase. A pass that drops P_x from the V_xx update at the reset (but keeps it in V_x) fails here; the
    V_x test above cannot see it."""
    h, lq, ps, N, x0, U_hat = _two_phase_bounce(rng)

    def simulate(x_start, control, first_knot=0):
        X = np.full((N + 1, 2), np.nan)
        X[first_knot] = x_start
        X_pre = np.full((2, 2), np.nan)
        cost = 0.0
        for i in range(2):
            for k in range(max(ps[i], first_knot), ps[i + 1]):
                u = control(k, X[k])
                cost += lq.running(k, X[k], u)
                X[k + 1] = lq.A[k] @ X[k] + lq.B[k] @ u + lq.c[k]
            if ps[i + 1] > first_knot:
                X_pre[i] = X[ps[i + 1]]
                cost += lq.terminal(i, X_pre[i])
                if i == 0:
                    X[ps[1]] = _nl_reset(X_pre[0])
        return X, X_pre, cost

    X_hat, X_pre, _ = simulate(x0, lambda k, x: U_hat[k])
    d = lq.derivatives(X_hat, X_pre, U_hat)
    d["P_x"] = np.stack([_nl_reset_jac(X_pre[0]), np.full((2, 2), np.nan)])
    first = run_backward(d, ps)
    assert first["ok"]
    T = _nl_reset_curvature(X_pre[0], first["V_x"][ps[1]])
    d_full = dict(d, Phi_xx=d["Phi_xx"] + np.stack([T, np.zeros((2, 2))]))
    out = run_backward(d_full, ps)
    assert out["ok"]
    np.testing.assert_array_equal(out["V_xx"][ps[1]:N], first["V_xx"][ps[1]:N])  # phase 1 does not see Phi_0
    fb = policy(X_hat, U_hat, out["K"], out["k"], 0.0)
    np.testing.assert_allclose(simulate(x0, fb)[0], X_hat, rtol=0, atol=1e-13)
    for k in (0, ps[1] - 1, ps[1]):
        def J(x, k=k):
            return simulate(x, fb, k)[2]

        grad, hess = fd_gradient_hessian(J, X_hat[k], 1e-3)
        assert_rel(out["V_x"][k], grad, 1e-5, f"V_x at knot {k}")
        assert_rel(out["V_xx"][k], hess, 1e-5, f"V_xx at knot {k}")
    # without the reset's curvature V_xx before the reset is measurably not the Hessian (the check is sensitive)
    gn = first["V_xx"][ps[1] - 1]
    _, hess_gn = fd_gradient_hessian(lambda x: simulate(x, policy(X_hat, U_hat, first["K"], first["k"], 0.0),
                                                        ps[1] - 1)[2], X_hat[ps[1] - 1], 1e-3)
    print(f"\nGauss-Newton V_xx before the reset vs the Hessian: relative error "
          f"{np.max(np.abs(gn - hess_gn)) / np.max(np.abs(hess_gn)):.1e}")
    assert np.max(np.abs(gn - hess_gn)) > 1e-3 * np.max(np.abs(hess_gn))


def test_cholesky_rejects_non_finite_matrices():
    """A NaN Q_uu (derivatives that overflowed) is not positive definite: the sweep must fail, not emit NaN gains."""
    from hsddp_gym.core.small_linalg import cholesky_solve

    L, out, B = np.zeros((4, 4)), np.zeros((4, 1)), np.ones((4, 1))
    assert cholesky_solve(np.eye(4), B, L, out) and np.allclose(out, 1.0)
    for bad in (np.nan, np.inf):
        A = np.eye(4)
        A[2, 2] = bad
        assert not cholesky_solve(A, B, L, out)
