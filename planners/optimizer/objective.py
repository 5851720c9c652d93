"""The objective HS-DDP minimizes: the task cost (eq. 18), the augmented-Lagrangian term on the switching
constraints (eq. 23) and relaxed barriers on the inequality constraints (eqs. 26-27) -- its value along a
trajectory and its derivatives, vectorized over the horizon.

Constraints (each ``c >= 0``), per knot:

* torque (eq. 17e), 8 rows: ``u_max - u_j`` and ``u_max + u_j``;
* ground force (eqs. 17f-g), 3 rows per stance foot: ``f_z``, ``mu f_z - f_x``, ``mu f_z + f_x``.

The ground force rows are linear in ``grf``, so their barrier enters through a gradient ``g_y (N, 4)``
and a Gauss-Newton Hessian ``W (N, 4, 4)`` in force space, mapped through ``grf_x``, ``grf_u``
together with the force-tracking term.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hsddp_gym.core.conventions import NGRF, NU, NX
from hsddp_gym.planners.optimizer.barrier import relaxed_barrier
from hsddp_gym.planners.optimizer.problem import HybridProblem


def friction_rows(mu: float) -> np.ndarray:
    """``(6, 4)`` matrix A with ``A @ grf`` = [f_z, mu f_z - f_x, mu f_z + f_x] for the front then back foot."""
    A = np.zeros((6, NGRF))
    for foot in (0, 1):
        ix, iz = 2 * foot, 2 * foot + 1
        A[3 * foot + 0, iz] = 1.0
        A[3 * foot + 1, ix], A[3 * foot + 1, iz] = -1.0, mu
        A[3 * foot + 2, ix], A[3 * foot + 2, iz] = 1.0, mu
    return A


@dataclasses.dataclass
class ConstraintState:
    """Multipliers and penalty/barrier parameters of the outer loop (Algorithm 1).

    Attributes:
        sigma: AL penalty (eq. 23 uses ``(sigma / 2)^2 g^2``).
        lam: AL multipliers ``(n,)`` per phase (only touchdown phases are used).
        use_al: add the AL term. use_reb: add the barriers.
        delta_torque, delta_grf: ReB relaxation of the torque and ground-force constraints.
        eps_torque, eps_grf: ReB weights per knot.
    """

    sigma: float
    lam: np.ndarray
    use_al: bool
    use_reb: bool
    delta_torque: float
    delta_grf: float
    eps_torque: float
    eps_grf: float

    def copy(self) -> ConstraintState:
        return dataclasses.replace(self, lam=self.lam.copy())


@dataclasses.dataclass
class CostBreakdown:
    """Objective parts [-]: ``task`` = running + terminal (eq. 18), ``al`` (eq. 23), ``barrier`` (eq. 26)."""

    running: float
    terminal: float
    al: float
    barrier: float

    @property
    def task(self) -> float:
        return self.running + self.terminal

    @property
    def total(self) -> float:
        return self.running + self.terminal + self.al + self.barrier


class Objective:
    """Evaluates the objective of a :class:`HybridProblem` and its derivatives along trajectories."""

    def __init__(self, problem: HybridProblem) -> None:
        self.problem = problem
        pr = problem
        self.h = pr.h  # (N,) per-knot steps
        self.A_grf = friction_rows(pr.constraints.friction)
        # (N, 6) mask: friction rows of stance feet only
        self.grf_mask = np.repeat(pr.stance, 3, axis=1).astype(float)
        self.robot = pr.dynamics.robot
        n = pr.n_knots
        self._gy = np.zeros((n, NGRF))
        self._W = np.zeros((n, NGRF, NGRF))

    # --------------------------------------------------------------- switching constraints
    def switching_values(self, X_pre: np.ndarray) -> np.ndarray:
        """``g (n,)``: height of the landing foot at the end of each phase (0 where no touchdown)."""
        g = np.zeros(self.problem.n_phases)
        for i, foot in enumerate(self.problem.touchdown):
            if foot >= 0:
                g[i] = self.robot.foot_heights(X_pre[i, :7])[foot]
        return g

    # --------------------------------------------------------------- values
    def evaluate(self, X: np.ndarray, X_pre: np.ndarray, U: np.ndarray, GRF: np.ndarray, cs: ConstraintState
                 ) -> CostBreakdown:
        """Objective of a trajectory (``X (N+1, 14)``, ``X_pre (n, 14)``, ``U (N, 4)``, ``GRF (N, 4)``)."""
        pr = self.problem
        running = float(self.h @ self.running_rates(X, U, GRF))
        dxf = X_pre - pr.XF
        terminal = 0.5 * float(np.einsum("ij,ij->", dxf * pr.QF, dxf))
        al = 0.0
        if cs.use_al and pr.constraints.switching:
            g = self.switching_values(X_pre)
            al = float(np.sum((cs.sigma / 2.0) ** 2 * g * g + cs.lam * g))
        barrier = 0.0
        if cs.use_reb:
            barrier = self._barrier_value(U, GRF, cs)
        return CostBreakdown(running, terminal, al, barrier)

    def running_rates(self, X: np.ndarray, U: np.ndarray, GRF: np.ndarray) -> np.ndarray:
        """``l (N,)``: the running cost rate of eq. 32 at each knot (the running cost is ``h_k l_k``)."""
        pr = self.problem
        n = pr.n_knots
        dx = X[:n] - pr.XR
        dy = GRF - pr.YR
        return (np.einsum("ij,ij->i", dx * pr.Qd, dx) + np.einsum("ij,ij->i", U * pr.Rd, U)
                + np.einsum("ij,ij->i", dy * pr.Sd, dy))

    def _torque_constraints(self, U):
        umax = self.problem.constraints.torque_limit
        return umax - U, umax + U

    def _barrier_value(self, U, GRF, cs):
        up, lo = self._torque_constraints(U)
        b_up = relaxed_barrier(up, cs.delta_torque)[0]
        b_lo = relaxed_barrier(lo, cs.delta_torque)[0]
        c = GRF @ self.A_grf.T
        b_f = relaxed_barrier(c, cs.delta_grf)[0]
        return float(cs.eps_torque * (b_up.sum() + b_lo.sum()) + cs.eps_grf * np.sum(b_f * self.grf_mask))

    def task_running_gradients(self, X, U, GRF, grf_x, grf_u) -> tuple[np.ndarray, np.ndarray]:
        """Gradients of the task running cost ``h_k l_k`` (no barrier): ``(L_x (N, 14), L_u (N, 4))``."""
        pr = self.problem
        n = pr.n_knots
        two_h = 2.0 * self.h[:, None]
        gy = (GRF - pr.YR) * (two_h * pr.Sd)
        L_x = (X[:n] - pr.XR) * (two_h * pr.Qd) + np.einsum("nyx,ny->nx", grf_x, gy)
        L_u = U * (two_h * pr.Rd) + np.einsum("nyu,ny->nu", grf_u, gy)
        return L_x, L_u

    # --------------------------------------------------------------- derivatives
    def derivatives(self, X, X_pre, U, GRF, grf_x, grf_u, cs: ConstraintState, l_x, l_u, l_xx, l_uu, l_ux,
                    Phi_x, Phi_xx) -> None:
        """Fill running-cost derivatives (``l_x (N, 14)``, ``l_u (N, 4)``, ``l_xx (N, 14, 14)``,
        ``l_uu (N, 4, 4)``, ``l_ux (N, 4, 14)``) and terminal ones (``Phi_x (n, 14)``,
        ``Phi_xx (n, 14, 14)``) including the AL and barrier terms (Gauss-Newton for the force terms)."""
        pr = self.problem
        h = self.h
        n = pr.n_knots
        two_h = 2.0 * h[:, None]
        # state / control quadratic terms
        np.multiply(X[:n] - pr.XR, two_h * pr.Qd, out=l_x)
        np.multiply(U, two_h * pr.Rd, out=l_u)
        l_xx[:] = 0.0
        l_uu[:] = 0.0
        idx_x = np.arange(NX)
        idx_u = np.arange(NU)
        l_xx[:, idx_x, idx_x] = two_h * pr.Qd
        l_uu[:, idx_u, idx_u] = two_h * pr.Rd
        # ground-force terms in force space
        gy = self._gy
        W = self._W
        np.multiply(GRF - pr.YR, two_h * pr.Sd, out=gy)
        W[:] = 0.0
        idx_y = np.arange(NGRF)
        W[:, idx_y, idx_y] = two_h * pr.Sd
        if cs.use_reb:
            up, lo = self._torque_constraints(U)
            _, d_up, dd_up = relaxed_barrier(up, cs.delta_torque)
            _, d_lo, dd_lo = relaxed_barrier(lo, cs.delta_torque)
            l_u += cs.eps_torque * (d_lo - d_up)
            l_uu[:, idx_u, idx_u] += cs.eps_torque * (dd_up + dd_lo)
            c = GRF @ self.A_grf.T
            _, dc, ddc = relaxed_barrier(c, cs.delta_grf)
            dc *= cs.eps_grf * self.grf_mask
            ddc *= cs.eps_grf * self.grf_mask
            gy += dc @ self.A_grf
            W += np.einsum("ji,nj,jk->nik", self.A_grf, ddc, self.A_grf)
        # map through the force Jacobians: l_x += grf_x^T gy, l_xx += grf_x^T W grf_x, ...
        gxT = grf_x.transpose(0, 2, 1)
        l_x += np.einsum("nyx,ny->nx", grf_x, gy)
        l_u += np.einsum("nyu,ny->nu", grf_u, gy)
        WGx = W @ grf_x
        l_xx += gxT @ WGx
        l_ux[:] = grf_u.transpose(0, 2, 1) @ WGx
        l_uu += grf_u.transpose(0, 2, 1) @ (W @ grf_u)
        # terminal costs
        np.multiply(X_pre - pr.XF, pr.QF, out=Phi_x)
        Phi_xx[:] = 0.0
        Phi_xx[:, idx_x, idx_x] = pr.QF
        if cs.use_al and pr.constraints.switching:
            w = (cs.sigma / 2.0) ** 2
            for i, foot in enumerate(pr.touchdown):
                if foot < 0:
                    continue
                g, g_x, g_xx = self.robot.foot_height_derivatives(X_pre[i, :7], int(foot))
                slope = 2.0 * w * g + cs.lam[i]
                Phi_x[i] += slope * g_x
                Phi_xx[i] += 2.0 * w * np.outer(g_x, g_x) + slope * g_xx
