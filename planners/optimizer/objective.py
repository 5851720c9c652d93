"""The objective HS-DDP minimizes: the task cost (eq. 18), the augmented-Lagrangian term on the switching
constraints (eq. 23) and relaxed barriers on the inequality constraints (eqs. 26-27) -- its value along a
trajectory and its derivatives, vectorized over the horizon.

Constraints (each ``c >= 0``), per knot:

* torque (eq. 17e), 8 rows: ``u_max - u_j`` and ``u_max + u_j``;
* ground force (eqs. 17f-g), 3 rows per stance foot: ``f_z``, ``mu f_z - f_x``, ``mu f_z + f_x``.

The ground force rows are linear in ``grf``, so their barrier enters through a gradient ``g_y (N, 4)``
and a Gauss-Newton Hessian ``W (N, 4, 4)`` in force space, mapped through ``grf_x``, ``grf_u``
together with the force-tracking term.

The elementwise parts (quadratic terms, barriers) run in the compiled kernels of
[`kernels`][hsddp_gym.planners.optimizer.kernels], bit-identical to the NumPy expressions they replace (those of
[`relaxed_barrier`][hsddp_gym.planners.optimizer.barrier.relaxed_barrier] for the barriers); products, contractions,
sums and logarithms stay in NumPy.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hsddp_gym.core.conventions import NGRF, NU, NX
from hsddp_gym.planners.optimizer import kernels as kernels
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
        lam: AL multipliers ``(m,)``, one per switching-constraint row (``HybridProblem.switch_phase``; ``m = n``
            phases unless feet land together; only rows with a landing foot are used).
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
    """Evaluates the objective of a [`HybridProblem`][HybridProblem] and its derivatives along trajectories."""

    def __init__(self, problem: HybridProblem) -> None:
        self.problem = problem
        pr = problem
        self.h = pr.h  # (N,) per-knot steps
        self.A_grf = friction_rows(pr.constraints.friction)
        # (N, 6) mask: friction rows of stance feet only
        self.grf_mask = np.repeat(pr.stance, 3, axis=1).astype(float)
        self.robot = pr.dynamics.robot
        self._umax = float(pr.constraints.torque_limit)
        n = pr.n_knots
        self._gy = np.zeros((n, NGRF))
        self._W = np.zeros((n, NGRF, NGRF))
        # scratch of the barrier kernels: slope / curvature of the force rows (N, 6); the value's two passes:
        # log-branch constraints (N, 14), then the barrier of the torque rows (N, 4) x 2 and force rows (N, 6)
        self._dc = np.empty((n, 6))
        self._ddc = np.empty((n, 6))
        self._safe = np.empty((n, 2 * NU + 6))
        self._b_up = np.empty((n, NU))
        self._b_lo = np.empty((n, NU))
        self._b_f = np.empty((n, 6))
        self._hxx = np.empty((n, NX, NX))  # grf_x^T W grf_x of the derivatives
        self._switching: tuple[np.ndarray, np.ndarray] | None = None  # (X_pre's bits, g) of the last call
        # the terrain of the switching constraints; None for a ground at one level (g = foot_z - level, the flat
        # problems' path; level 0 without a terrain)
        terrain = pr.terrain
        level = None if terrain is None else terrain.uniform_height
        self._terrain = None if terrain is None or level is not None else terrain
        self._level = 0.0 if level is None else level
        # the joint-range and ground-clearance penalties of the running cost (ConstraintSpec.joint_limits,
        # knee_clearance, swing_foot_clearance; None: none, the paper's problem). They are in evaluate() and
        # derivatives(), not in running_rates() / task_running_gradients() (the STO's rates)
        self._joint_bounds = pr.constraints.joint_bounds()
        self._clearance = pr.constraints.knee_clearance is not None or pr.constraints.swing_foot_clearance is not None

    # --------------------------------------------------------------- switching constraints
    def switching_values(self, X_pre: np.ndarray) -> np.ndarray:
        """``g (m,)``: height of the landing foot of each switching-constraint row (``problem.switch_phase``,
        ``problem.switch_foot``; row ``i < n`` is phase ``i``'s first landing foot, 0 where no touchdown, then the
        second feet of simultaneous touchdowns) above the terrain under it, ``foot_z - h(foot_x)``
        (``problem.terrain``; a ground at one level: ``foot_z - level``), for the pre-switch states
        ``X_pre (n, 14)`` [m]. The last ``X_pre`` and its ``g`` are remembered (compared bit for bit): the solver
        asks again for the trajectory it has just evaluated."""
        bits = np.ascontiguousarray(X_pre, dtype=np.float64).view(np.uint64)
        last = self._switching
        if last is not None and last[0].shape == bits.shape and (last[0] == bits).all():
            return last[1].copy()
        pr = self.problem
        g = np.zeros(pr.n_switching)
        terrain, level = self._terrain, self._level
        for r, (i, foot) in enumerate(zip(pr.switch_phase, pr.switch_foot)):
            if foot >= 0:
                if terrain is None:
                    g[r] = self.robot.foot_height(X_pre[i, :7], foot) - level
                else:
                    p = self.robot.foot_positions(X_pre[i, :7])[foot]
                    g[r] = p[1] - terrain.height(float(p[0]))
        self._switching = (bits.copy(), g.copy())
        return g

    # --------------------------------------------------------------- values
    def evaluate(self, X: np.ndarray, X_pre: np.ndarray, U: np.ndarray, GRF: np.ndarray, cs: ConstraintState
                 ) -> CostBreakdown:
        """Objective of a trajectory (``X (N+1, 14)``, ``X_pre (n, 14)``, ``U (N, 4)``, ``GRF (N, 4)``)."""
        pr = self.problem
        running = float(self.h @ self.running_rates(X, U, GRF))
        if self._joint_bounds is not None:
            d = self._joint_excess(X)
            running += float(self.problem.constraints.joint_limit_weight * (self.h @ np.sum(d * d, axis=1)))
        if self._clearance:
            d = self._clearance_deficit(X)[0]
            running += float(self.problem.constraints.clearance_weight * (self.h @ np.sum(d * d, axis=1)))
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

    def _joint_excess(self, X: np.ndarray) -> np.ndarray:
        """``d (N, 4)``: how far each joint ``q[3:7]`` is above its penalty bound (> 0) or below (< 0), 0 inside."""
        lo, hi = self._joint_bounds
        q = X[:self.problem.n_knots, 3:7]
        return np.maximum(q - hi, 0.0) + np.minimum(q - lo, 0.0)

    def _clearance_deficit(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``d (N, 4)``: how far the front knee, back knee, front foot, back foot are below their clearance
        (``knee_clearance``; ``swing_foot_clearance`` for a foot not in stance) above the flat ground (< 0; 0 above
        it, or without that clearance, or a stance foot), and ``J (N, 4, 4)`` the derivatives of their heights with
        respect to ``(z, pitch, hip, knee)`` of their leg.

        Heights: knee ``z - s l_h sin(pitch) - l_t cos(pitch + hip)``, foot that ``- l_s cos(pitch + hip + knee)``,
        ``s = +1`` front, ``-1`` back (positive pitch nose-down, positive hip swings the thigh backward; ``l_h`` the hip
        offset, ``l_t``, ``l_s`` the thigh and shank lengths)."""
        params = self.robot.params
        pr = self.problem
        n = pr.n_knots
        z, pitch = X[:n, 1], X[:n, 2]
        d = np.zeros((n, 4))
        J = np.zeros((n, 4, 4))
        knee_c, foot_c = pr.constraints.knee_clearance, pr.constraints.swing_foot_clearance
        for foot, (sign, hip) in enumerate(((1.0, 3), (-1.0, 5))):
            a = pitch + X[:n, hip]
            b = a + X[:n, hip + 1]
            knee = z - sign * params.hip_offset * np.sin(pitch) - params.thigh.length * np.cos(a)
            J[:, foot, 0] = J[:, 2 + foot, 0] = 1.0
            J[:, foot, 2] = params.thigh.length * np.sin(a)
            J[:, foot, 1] = -sign * params.hip_offset * np.cos(pitch) + J[:, foot, 2]
            J[:, 2 + foot, 3] = params.shank.length * np.sin(b)
            J[:, 2 + foot, 1:3] = J[:, foot, 1:3] + J[:, 2 + foot, 3:4]
            if knee_c is not None:
                d[:, foot] = np.minimum(knee - knee_c, 0.0)
            if foot_c is not None:
                height = knee - params.shank.length * np.cos(b)
                d[:, 2 + foot] = np.where(pr.stance[:, foot], 0.0, np.minimum(height - foot_c, 0.0))
        return d, J

    def _barrier_value(self, U, GRF, cs):
        """``eps_torque sum B(torque rows) + eps_grf sum mask B(force rows)`` for ``U``, ``GRF`` (N, 4)."""
        U = np.ascontiguousarray(U, dtype=np.float64)
        N = self.problem.n_knots
        _check_shapes(("U", U, (N, NU)), ("GRF", GRF, (N, NGRF)))
        d_t, d_f = _relaxation(cs.delta_torque, "delta_torque"), _relaxation(cs.delta_grf, "delta_grf")
        c = GRF @ self.A_grf.T
        safe, b_up, b_lo, b_f = self._safe, self._b_up, self._b_lo, self._b_f
        kernels.barrier_safe(U, c, self._umax, d_t, d_f, safe)
        np.log(safe, out=safe)
        kernels.barrier_values(U, c, self._umax, d_t, d_f, float(np.log(d_t)), float(np.log(d_f)), safe,
                               self.grf_mask, b_up, b_lo, b_f)
        return float(cs.eps_torque * (b_up.sum() + b_lo.sum()) + cs.eps_grf * b_f.sum())

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
        X, X_pre, U, GRF = (np.ascontiguousarray(a, dtype=np.float64) for a in (X, X_pre, U, GRF))
        N, n = pr.n_knots, pr.n_phases
        _check_shapes(("X", X[:N], (N, NX)), ("X_pre", X_pre, (n, NX)), ("U", U, (N, NU)), ("GRF", GRF, (N, NGRF)),
                      ("l_x", l_x, (N, NX)), ("l_u", l_u, (N, NU)), ("l_xx", l_xx, (N, NX, NX)),
                      ("l_uu", l_uu, (N, NU, NU)), ("Phi_x", Phi_x, (n, NX)), ("Phi_xx", Phi_xx, (n, NX, NX)))
        # quadratic terms (state, control, ground-force tracking in force space) and the terminal costs
        gy = self._gy
        W = self._W
        kernels.quadratic_derivatives(X, U, GRF, pr.XR, pr.YR, self.h, pr.Qd, pr.Rd, pr.Sd, X_pre, pr.XF, pr.QF, l_x,
                                      l_u, l_xx, l_uu, gy, W, Phi_x, Phi_xx)
        if cs.use_reb:
            d_t, d_f = _relaxation(cs.delta_torque, "delta_torque"), _relaxation(cs.delta_grf, "delta_grf")
            kernels.torque_barrier_derivatives(U, self._umax, d_t, float(cs.eps_torque), l_u, l_uu)
            c = GRF @ self.A_grf.T
            dc, ddc = self._dc, self._ddc
            kernels.force_barrier_derivatives(c, d_f, float(cs.eps_grf), self.grf_mask, dc, ddc)
            gy += dc @ self.A_grf
            W += np.einsum("ji,nj,jk->nik", self.A_grf, ddc, self.A_grf)
        # map through the force Jacobians: l_x += grf_x^T gy, l_xx += grf_x^T W grf_x, ...
        gxT = grf_x.transpose(0, 2, 1)
        l_x += np.einsum("nyx,ny->nx", grf_x, gy)
        l_u += np.einsum("nyu,ny->nu", grf_u, gy)
        WGx = W @ grf_x
        l_xx += np.matmul(gxT, WGx, out=self._hxx)  # a 0.3 MB temporary per call costs as much as the product
        np.matmul(grf_u.transpose(0, 2, 1), WGx, out=l_ux)
        l_uu += grf_u.transpose(0, 2, 1) @ (W @ grf_u)
        if self._joint_bounds is not None:  # the joint-range penalty: w d^2 per joint beyond its bound
            d = self._joint_excess(X)
            w2h = 2.0 * self.problem.constraints.joint_limit_weight * self.h[:, None]
            l_x[:, 3:7] += w2h * d
            idx = np.arange(3, 7)
            l_xx[:, idx, idx] += w2h * (d != 0.0)
        if self._clearance:  # the clearance penalty: w d^2 per knee / swing foot below it (Gauss-Newton)
            d, J = self._clearance_deficit(X)
            w2h = 2.0 * self.problem.constraints.clearance_weight * self.h
            for point in range(4):
                idx = np.array([1, 2, 3, 4]) + np.array([0, 0, 2, 2]) * (point % 2)
                active = d[:, point] != 0.0
                if not active.any():
                    continue
                Jp = J[:, point, :]
                l_x[:, idx] += Jp * (w2h * d[:, point])[:, None]
                l_xx[:, idx[:, None], idx[None, :]] += (Jp * (w2h * active)[:, None])[:, :, None] * Jp[:, None, :]
        # the augmented-Lagrangian term on the terminal costs
        if cs.use_al and pr.constraints.switching:
            w = (cs.sigma / 2.0) ** 2
            for r, (i, foot) in enumerate(zip(pr.switch_phase, pr.switch_foot)):
                if foot < 0:
                    continue
                g, g_x, g_xx = self.robot.foot_height_derivatives(X_pre[i, :7], int(foot))
                g -= self._level
                if self._terrain is not None:  # dh/dx = 0 off the edges of a level segment
                    terrain = self._terrain
                    fx = float(self.robot.foot_positions(X_pre[i, :7])[foot, 0])
                    g -= terrain.height(fx)
                    dhdx = terrain.slopes[int(np.searchsorted(terrain.edges, fx, side="right"))]
                    if dhdx != 0.0:  # a slope: g_x = d foot_z - dh/dx d foot_x (its Hessian: foot_z's)
                        g_x = g_x.copy()
                        g_x[:7] -= dhdx * self.robot.foot_jacobian(X_pre[i, :7], int(foot))[0]
                slope = 2.0 * w * g + cs.lam[r]
                Phi_x[i] += slope * g_x
                Phi_xx[i] += 2.0 * w * np.outer(g_x, g_x) + slope * g_xx


def _relaxation(delta, name: str) -> float:
    """A barrier relaxation of [`ConstraintState`][ConstraintState] as a float, checked finite and > 0 (``name`` in
    errors)."""
    d = float(delta)
    if not (0.0 < d < np.inf):
        raise ValueError(f"cs.{name} must be finite and > 0, got {delta!r}")
    return d


def _check_shapes(*arrays: tuple) -> None:
    """``(name, array, shape)`` triples: each array must have its shape (the compiled kernels do not bounds-check);
    ``ValueError`` naming the first that has not."""
    for name, arr, shape in arrays:
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
