"""Hybrid dynamics of the planar Mini Cheetah: per-mode KKT dynamics, the discrete step, reset maps, and
their analytical first derivatives (Pinocchio).

Continuous dynamics (paper eq. 11), for the feet ``c`` in contact in a mode::

    M(q) a + b(q, v) = S^T u + J_c(q)^T lam,      J_c a + dJ_c v = 0

solved with Pinocchio's ``constraintDynamics`` (3D point contacts in the x-z plane; the y row is
identically zero, handled by the proximal solver) -- or plain ABA in flight. Over a horizon (the solver's rollouts
and [`HybridDynamics.linearize`][HybridDynamics.linearize]) the same equations and their derivatives run compiled
([`hsddp_gym.core.planar_dynamics`][hsddp_gym.core.planar_dynamics], checked against Pinocchio to rounding); the
single-step methods stay Pinocchio's, the reference. ``lam`` is the force of the
ground on the robot in the world frame. Discrete step ``f_i`` with step ``h``:

* ``"euler"`` (paper): ``q+ = q + h v``, ``v+ = v + h a``;
* ``"semi_implicit"``: ``v+ = v + h a``, ``q+ = q + h v+``.

Reset map at touchdown (paper eqs. 12-13): positions unchanged, ``v+`` from the impulse problem
``M (v+ - v-) = J^T Lambda``, ``J v+ = -e J v-`` over every foot in contact *after* the switch
(restitution ``e``, default 0). Lift-off is the identity.

Pinocchio leaves derivative state in a ``Data``; each algorithm here owns its own ``Data`` objects
(free-flight ABA, one per contact set for constraint dynamics, one per contact set for impulses).
"""

from __future__ import annotations

import numba
import numpy as np
import pinocchio as pin

from hsddp_gym.core.conventions import NGRF, NQ, NU, NV, NX, Mode, as_mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.planar_dynamics import Scratch, kernel_params, linearize_knots
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector

INTEGRATORS = ("euler", "semi_implicit")


class _ContactSet:
    """Constraint models and a private Data for one set of feet in contact."""

    def __init__(self, robot: CheetahModel, feet: tuple[int, ...]) -> None:
        model = robot.model
        self.feet = feet
        self.models = pin.StdVec_RigidConstraintModel()
        self.datas = pin.StdVec_RigidConstraintData()
        for foot in feet:
            frame = model.frames[robot.foot_frame_ids[foot]]
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, frame.parentJoint, frame.placement,
                                          pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            self.models.append(cm)
            self.datas.append(cm.createData())
        self.data = model.createData()
        pin.initConstraintDynamics(model, self.data, self.models, self.datas)
        # rows of Pinocchio's lambda (3 per contact: x, y, z) -> rows of our grf (4,)
        self.lam_rows = np.array([3 * c + r for c in range(len(feet)) for r in (0, 2)], dtype=np.intp)
        self.grf_rows = np.array([2 * f + r for f in feet for r in (0, 1)], dtype=np.intp)


def _proximal(mu: float = 1e-8) -> pin.ProximalSettings:
    # The planar model's y contact row is zero, so the Delassus matrix is singular: a tiny proximal
    # regularization converges in a few iterations (mu = 0 gives NaN). For constraintDynamics mu = 1e-8
    # matches the exact 2D KKT solution to ~1e-13 (stack_notes §2). impulseDynamics does a single
    # regularized solve without refinement, so its error is O(mu): it gets mu = 1e-12 (error ~1e-11).
    return pin.ProximalSettings(1e-12, mu, 20)


class HybridDynamics:
    """Discrete hybrid dynamics ``x+ = f_mode(x, u)`` and reset maps, with derivatives.

    Args:
        robot: the model (default: the paper's robot).
        dt: integration step ``h`` [s] (paper: 1e-3).
        integrator: ``"euler"`` (paper) or ``"semi_implicit"``.

    Shapes: ``x (14,)``, ``u (4,)``, ``grf (4,)``, ``f_x (14, 14)``, ``f_u (14, 4)``,
    ``grf_x (4, 14)``, ``grf_u (4, 4)``, ``P_x (14, 14)``.
    """

    def __init__(self, robot: CheetahModel | None = None, dt: float = 1e-3, integrator: str = "euler") -> None:
        self.robot = robot if robot is not None else CheetahModel()
        if not isinstance(self.robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(self.robot).__name__}")
        self.dt = check_positive(dt, "dt")
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
        self.integrator = integrator
        self.model = self.robot.model
        self._free = self.model.createData()
        self._contact = {m: _ContactSet(self.robot, m.feet) for m in Mode if m != Mode.FLIGHT}
        self._impulse = {m: _ContactSet(self.robot, m.feet) for m in Mode if m != Mode.FLIGHT}
        self._prox = _proximal()
        self._prox_impulse = _proximal(1e-12)
        self._tau = np.zeros(NV)
        self._zero_u = np.zeros(NU)
        self.kernel_params = kernel_params(self.robot)
        """``(13,)``: the model of the compiled dynamics
        ([`hsddp_gym.core.planar_dynamics`][hsddp_gym.core.planar_dynamics]: the rollouts)."""
        self.scratch = Scratch()
        """Work arrays of the compiled dynamics (one per ``HybridDynamics``, like its Pinocchio ``Data``)."""

    # ------------------------------------------------------------------ validation helpers
    @staticmethod
    def _mode(mode, name: str = "mode") -> Mode:
        return as_mode(mode, name)

    # ------------------------------------------------------------------ continuous dynamics
    def accelerations(self, x: np.ndarray, u: np.ndarray, mode: Mode) -> tuple[np.ndarray, np.ndarray]:
        """Continuous dynamics of a mode (paper eq. 11).

        Args:
            x: state (14,). u: joint torques (4,). mode: contact mode.
        Returns:
            ``(a (7,), grf (4,))``: generalized accelerations and ground forces on the robot.
        """
        x = check_vector(x, NX, "x")
        u = check_vector(u, NU, "u")
        return self._accelerations(x, u, self._mode(mode))

    def _accelerations(self, x, u, mode):
        tau = self._tau
        tau[3:] = u
        grf = np.zeros(NGRF)
        if mode == Mode.FLIGHT:
            a = pin.aba(self.model, self._free, x[:NQ], x[NQ:], tau).copy()
            return a, grf
        cs = self._contact[mode]
        a = pin.constraintDynamics(self.model, cs.data, x[:NQ], x[NQ:], tau, cs.models, cs.datas, self._prox).copy()
        grf[cs.grf_rows] = cs.data.lambda_c[cs.lam_rows]
        return a, grf

    # ------------------------------------------------------------------ discrete step
    def step(self, x: np.ndarray, u: np.ndarray, mode: Mode) -> tuple[np.ndarray, np.ndarray]:
        """One integration step ``x+ = f_mode(x, u)``.

        Returns:
            ``(x_next (14,), grf (4,))`` with the ground force acting during the step.
        """
        x = check_vector(x, NX, "x")
        u = check_vector(u, NU, "u")
        return self._step(x, u, self._mode(mode))

    def _step(self, x, u, mode):
        a, grf = self._accelerations(x, u, mode)
        return self._integrate(x, a), grf

    def _integrate(self, x, a):
        h = self.dt
        out = np.empty(NX)
        out[NQ:] = x[NQ:] + h * a
        if self.integrator == "euler":
            out[:NQ] = x[:NQ] + h * x[NQ:]
        else:
            out[:NQ] = x[:NQ] + h * out[NQ:]
        return out

    # ------------------------------------------------------------------ derivatives
    def raw_derivatives(self, x: np.ndarray, u: np.ndarray, mode: Mode, a_q: np.ndarray, a_v: np.ndarray,
                        a_u: np.ndarray, lam_q: np.ndarray, lam_v: np.ndarray, lam_u: np.ndarray) -> np.ndarray:
        """Continuous-time derivatives written into caller-owned buffers (the solver's hot path).

        No input checks. Writes ``a_q, a_v (7, 7)``, ``a_u (7, 4)``, ``lam_q, lam_v (4, 7)``,
        ``lam_u (4, 4)`` (rows of feet not in contact are zeroed) and returns ``(a (7,), grf (4,))``
        packed as one (11,) array ``[a, grf]``.
        """
        tau = self._tau
        tau[3:] = u
        q = x[:NQ]
        v = x[NQ:]
        out = np.zeros(NV + NGRF)
        if mode == Mode.FLIGHT:
            dq, dv, minv = pin.computeABADerivatives(self.model, self._free, q, v, tau)
            a_q[:] = dq
            a_v[:] = dv
            a_u[:] = minv[:, 3:]
            out[:NV] = self._free.ddq
            lam_q[:] = 0.0
            lam_v[:] = 0.0
            lam_u[:] = 0.0
            return out
        cs = self._contact[mode]
        data = cs.data
        out[:NV] = pin.constraintDynamics(self.model, data, q, v, tau, cs.models, cs.datas, self._prox)
        dq, dv, dtau, lq, lv, ltau = pin.computeConstraintDynamicsDerivatives(self.model, data, cs.models,
                                                                              cs.datas, self._prox)
        a_q[:] = dq
        a_v[:] = dv
        a_u[:] = dtau[:, 3:]
        rows = cs.lam_rows
        if len(cs.feet) == 2:
            lam_q[:] = lq[rows]
            lam_v[:] = lv[rows]
            lam_u[:] = ltau[rows, 3:]
        else:
            lam_q[:] = 0.0
            lam_v[:] = 0.0
            lam_u[:] = 0.0
            g = cs.grf_rows
            lam_q[g] = lq[rows]
            lam_v[g] = lv[rows]
            lam_u[g] = ltau[rows, 3:]
        out[NV + cs.grf_rows] = data.lambda_c[rows]
        return out

    def step_derivatives(self, x: np.ndarray, u: np.ndarray, mode: Mode):
        """The discrete step and its analytical Jacobians.

        Returns:
            ``(x_next (14,), grf (4,), f_x (14, 14), f_u (14, 4), grf_x (4, 14), grf_u (4, 4))``.
        """
        x = check_vector(x, NX, "x")
        u = check_vector(u, NU, "u")
        mode = self._mode(mode)
        a_q, a_v, a_u = np.empty((NV, NQ)), np.empty((NV, NV)), np.empty((NV, NU))
        l_q, l_v, l_u = np.empty((NGRF, NQ)), np.empty((NGRF, NV)), np.empty((NGRF, NU))
        packed = self.raw_derivatives(x, u, mode, a_q, a_v, a_u, l_q, l_v, l_u)
        f_x, f_u = np.empty((1, NX, NX)), np.empty((1, NX, NU))
        assemble_step_jacobians(a_q[None], a_v[None], a_u[None], self.dt, self.integrator, f_x, f_u)
        grf_x = np.concatenate([l_q, l_v], axis=1)
        return self._integrate(x, packed[:NV]), packed[NV:].copy(), f_x[0], f_u[0], grf_x, l_u

    # ------------------------------------------------------------------ horizon (hot path)
    def linearize(self, X: np.ndarray, U: np.ndarray, modes: np.ndarray, out: Linearization,
                  h: np.ndarray | float | None = None) -> None:
        """Derivatives of the discrete steps along a trajectory, written into ``out``.

        Knot ``k`` steps ``X[k] -> X[k+1]`` with ``U[k]`` in ``modes[k]``. The per-knot loop is compiled
        ([`hsddp_gym.core.planar_dynamics.linearize_knots`][hsddp_gym.core.planar_dynamics.linearize_knots]: Pinocchio's
        derivatives to rounding, tested); discrete Jacobians and ground-force rows are assembled over the horizon
        afterwards.

        Args:
            X: states ``(N+1, 14)`` (only ``X[:N]`` is read). U: controls ``(N, 4)``.
            modes: contact mode per knot ``(N,)`` (ints). out: a [`Linearization`][Linearization] of length ``>= N``.
            h: step per knot ``(N,)`` or a scalar (default: ``self.dt``); time-scaled problems (switching-time
                optimization) give each phase its own step.

        Raises:
            ValueError: naming the argument, for wrong shapes, non-finite states or controls, unknown modes, a too
                small ``out`` or non-positive steps (checks are O(N) numpy calls, a few us).
            TypeError: ``out`` is not a [`Linearization`][Linearization].
        """
        X, U, modes, h = _check_horizon(X, U, modes, out, h)
        n = U.shape[0]
        failed = linearize_knots(np.ascontiguousarray(X), np.ascontiguousarray(U),
                                 np.ascontiguousarray(modes, dtype=np.int64), self.kernel_params, self.scratch.arrays,
                                 self._tau, out.lam6, out.acc, out.a_q, out.a_v, out.a_tau, out.lam6_q, out.lam6_v,
                                 out.lam6_tau)
        if failed >= 0:  # pragma: no cover - M and J_c M^-1 J_c^T are positive definite at every finite state
            raise ArithmeticError(f"the dynamics at knot {failed} are singular")
        out.finish(n, modes, self.dt if h is None else h, self.integrator, self._contact)

    def simulate_step(self, x: np.ndarray, u: np.ndarray, mode: int, x_next: np.ndarray, grf: np.ndarray) -> None:
        """Unchecked step writing ``x_next (14,)`` and ``grf (4,)`` in place (the rollout hot path)."""
        tau = self._tau
        tau[3:] = u
        q = x[:NQ]
        v = x[NQ:]
        h = self.dt
        if mode == 0:
            a = pin.aba(self.model, self._free, q, v, tau)
            grf[:] = 0.0
        else:
            cs = self._contact[mode]
            a = pin.constraintDynamics(self.model, cs.data, q, v, tau, cs.models, cs.datas, self._prox)
            lam = cs.data.lambda_c
            if mode == 3:
                grf[0] = lam[0]
                grf[1] = lam[2]
                grf[2] = lam[3]
                grf[3] = lam[5]
            else:
                grf[:] = 0.0
                r = cs.grf_rows[0]
                grf[r] = lam[0]
                grf[r + 1] = lam[2]
        vn = x_next[NQ:]
        np.multiply(a, h, out=vn)
        vn += v
        if self.integrator == "euler":
            np.multiply(v, h, out=x_next[:NQ])
        else:
            np.multiply(vn, h, out=x_next[:NQ])
        x_next[:NQ] += q

    # ------------------------------------------------------------------ reset maps
    def reset_map(self, x: np.ndarray, mode_after: Mode, restitution: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Touchdown reset map ``x+ = P(x-)`` into ``mode_after`` (paper eqs. 12-13).

        Every foot in contact in ``mode_after`` gets post-impact velocity ``-e`` times its pre-impact
        velocity. ``mode_after = FLIGHT`` is a lift-off: the identity.

        Returns:
            ``(x_plus (14,), impulse (4,))`` with the ground impulse on the robot [N s].
        """
        x = check_vector(x, NX, "x")
        e = check_in_range(restitution, 0.0, 1.0, "restitution")
        return self._reset(x, self._mode(mode_after, "mode_after"), e)

    def _reset(self, x, mode_after, e):
        impulse = np.zeros(NGRF)
        if mode_after == Mode.FLIGHT:
            return x.copy(), impulse
        cs = self._impulse[mode_after]
        out = x.copy()
        out[NQ:] = pin.impulseDynamics(self.model, cs.data, x[:NQ], x[NQ:], cs.models, cs.datas, e,
                                       self._prox_impulse)
        impulse[cs.grf_rows] = cs.data.impulse_c[cs.lam_rows]
        return out, impulse

    def reset_map_jacobian(self, x: np.ndarray, mode_after: Mode, restitution: float = 0.0):
        """The reset map and its Jacobian.

        Returns:
            ``(x_plus (14,), P_x (14, 14), impulse (4,))``.
        """
        x = check_vector(x, NX, "x")
        e = check_in_range(restitution, 0.0, 1.0, "restitution")
        P = np.empty((NX, NX))
        x_plus, impulse = self._reset_jacobian(x, self._mode(mode_after, "mode_after"), e, P)
        return x_plus, P, impulse

    def _reset_jacobian(self, x, mode_after, e, P):
        x_plus, impulse = self._reset(x, mode_after, e)
        P[:] = 0.0
        if mode_after == Mode.FLIGHT:
            np.fill_diagonal(P, 1.0)
            return x_plus, impulse
        cs = self._impulse[mode_after]
        # Pinocchio 4.1 writes only the contact leg's columns of dvc_dq and then corrects all of them:
        # without this reset the other columns accumulate across calls (found by tests/test_reset.py).
        cs.data.dvc_dq[:] = 0.0
        pin.computeImpulseDynamicsDerivatives(self.model, cs.data, cs.models, cs.datas, e, self._prox_impulse)
        P[:NQ, :NQ] = np.eye(NQ)
        P[NQ:, :NQ] = cs.data.ddq_dq
        P[NQ:, NQ:] = cs.data.ddq_dv  # Pinocchio stores dv+/dv- - I here (stack_notes §2)
        P[NQ:, NQ:] += np.eye(NV)
        return x_plus, impulse


_MODE_VALUES = tuple(int(m) for m in Mode)


def _check_horizon(X, U, modes, out, h):
    """Validate the arguments of [`HybridDynamics.linearize`][HybridDynamics.linearize]; returns ``(X, U, modes, h)`` as
    arrays (no copies of float64 / integer inputs)."""
    U = np.asarray(U, dtype=np.float64)
    if U.ndim != 2 or U.shape[1] != NU or U.shape[0] < 1:
        raise ValueError(f"U must have shape (N, {NU}) with N >= 1, got {U.shape}")
    n = U.shape[0]
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != NX or X.shape[0] < n:
        raise ValueError(f"X must have shape (N+1, {NX}) with N = {n} (the length of U), got {X.shape}")
    if not (np.isfinite(X[:n]).all() and np.isfinite(U).all()):
        raise ValueError("X and U must be finite (found NaN or inf in X[:N] or U)")
    modes = np.asarray(modes)
    if modes.shape != (n,) or not np.issubdtype(modes.dtype, np.integer):
        raise ValueError(f"modes must be an integer array of shape ({n},), got {modes.dtype} {modes.shape}")
    if modes.min() < min(_MODE_VALUES) or modes.max() > max(_MODE_VALUES):
        raise ValueError(f"modes must hold contact modes {list(_MODE_VALUES)}, got values "
                         f"{sorted(set(modes.tolist()) - set(_MODE_VALUES))}")
    if not isinstance(out, Linearization):
        raise TypeError(f"out must be a Linearization, got {type(out).__name__}")
    if out.capacity < n:
        raise ValueError(f"out has capacity {out.capacity} < N = {n} knots")
    if h is not None:
        ha = np.asarray(h, dtype=np.float64)
        if ha.shape not in ((), (n,)):
            raise ValueError(f"h must be a scalar or have shape ({n},), got {ha.shape}")
        if not (np.isfinite(ha).all() and (ha > 0.0).all()):
            raise ValueError("h must be finite and > 0")
        h = ha if ha.ndim else float(ha)
    return X, U, modes, h


def assemble_step_jacobians(a_q: np.ndarray, a_v: np.ndarray, a_u: np.ndarray, h, integrator: str,
                            f_x: np.ndarray, f_u: np.ndarray) -> None:
    """Discrete Jacobians for a batch of knots from the continuous ones (vectorized over knots).

    Args:
        a_q: ``(N, 7, 7)``.
        a_v: ``(N, 7, 7)``.
        a_u: ``(N, 7, 4)``.
        h: step, a scalar or ``(N,)``.
        integrator: see `INTEGRATORS`.
        f_x: output ``(N, 14, 14)``.
        f_u: output ``(N, 14, 4)``.
    """
    eye = np.eye(NV)
    h = np.asarray(h, dtype=np.float64)
    hk = h[:, None, None] if h.ndim == 1 else h
    f_x[:, NQ:, :NQ] = hk * a_q
    f_x[:, NQ:, NQ:] = eye + hk * a_v
    f_u[:, NQ:, :] = hk * a_u
    if integrator == "euler":
        f_x[:, :NQ, :NQ] = eye
        f_x[:, :NQ, NQ:] = hk * eye
        f_u[:, :NQ, :] = 0.0
    else:
        f_x[:, :NQ, :NQ] = eye + (hk * hk) * a_q
        f_x[:, :NQ, NQ:] = hk * eye + (hk * hk) * a_v
        f_u[:, :NQ, :] = (hk * hk) * a_u


class Linearization:
    """Pre-allocated derivatives of the discrete dynamics over a horizon of ``capacity`` knots.

    Filled by [`HybridDynamics.linearize`][HybridDynamics.linearize]. Public results (first ``N`` knots valid):

    * ``f_x (N, 14, 14)``, ``f_u (N, 14, 4)``: discrete step Jacobians;
    * ``grf (N, 4)``, ``grf_x (N, 4, 14)``, ``grf_u (N, 4, 4)``: ground force during each step and its
      Jacobians (zero rows for feet in the air).

    The continuous-time derivatives (``a_q, a_v, a_tau (N, 7, 7)``, ``lam6_* (N, 6, 7)``, ``lam6 (N, 6)``,
    ``acc (N, 7)``, in the layout of Pinocchio's derivative functions) stay available for callers that need them.
    """

    def __init__(self, capacity: int) -> None:
        n = check_int(capacity, "capacity", minimum=1)
        self.capacity = n
        self.a_q = np.zeros((n, NV, NQ))
        self.a_v = np.zeros((n, NV, NV))
        self.a_tau = np.zeros((n, NV, NV))
        self.lam6_q = np.zeros((n, 6, NQ))
        self.lam6_v = np.zeros((n, 6, NV))
        self.lam6_tau = np.zeros((n, 6, NV))
        self.lam6 = np.zeros((n, 6))
        self.acc = np.zeros((n, NV))
        self.f_x = np.zeros((n, NX, NX))
        self.f_u = np.zeros((n, NX, NU))
        self.grf = np.zeros((n, NGRF))
        self.grf_x = np.zeros((n, NGRF, NX))
        self.grf_u = np.zeros((n, NGRF, NU))

    def finish(self, n: int, modes: np.ndarray, h, integrator: str, contact_sets: dict) -> None:
        """Assemble discrete Jacobians and ground-force rows for the first ``n`` knots: one compiled pass
        ([`assemble_linearization`][assemble_linearization]), the numbers of
        [`assemble_step_jacobians`][assemble_step_jacobians] and [`grf_from_lambda`][grf_from_lambda]."""
        if not 0 <= n <= self.capacity:
            raise ValueError(f"n must be in 0 .. {self.capacity} (the capacity), got {n}")
        h = np.asarray(h, dtype=np.float64)
        h = np.full(n, float(h)) if h.ndim == 0 else np.ascontiguousarray(h[:n])
        if h.shape != (n,):
            raise ValueError(f"h must be a scalar or hold at least n = {n} steps, got shape {h.shape}")
        modes = np.ascontiguousarray(modes[:n], dtype=np.int64)
        if modes.shape != (n,) or (n and (modes.min() < min(_MODE_VALUES) or modes.max() > max(_MODE_VALUES))):
            raise ValueError(f"modes must hold at least n = {n} contact modes {list(_MODE_VALUES)}, got {modes!r}")
        row_map = np.zeros((len(_MODE_VALUES), NGRF, 2), dtype=np.int64)
        n_rows = np.zeros(len(_MODE_VALUES), dtype=np.int64)
        for mode, cs in contact_sets.items():
            k = len(cs.grf_rows)
            n_rows[int(mode)] = k
            row_map[int(mode), :k, 0] = cs.grf_rows
            row_map[int(mode), :k, 1] = cs.lam_rows
        assemble_linearization(self.a_q, self.a_v, self.a_tau, self.lam6, self.lam6_q, self.lam6_v, self.lam6_tau,
                               modes, h, integrator != "euler", row_map, n_rows, self.f_x, self.f_u, self.grf,
                               self.grf_x, self.grf_u)


@numba.njit(cache=True, error_model="numpy")
def assemble_linearization(a_q, a_v, a_tau, lam6, lam6_q, lam6_v, lam6_tau, modes, h, semi_implicit, row_map, n_rows,
                           f_x, f_u, grf, grf_x, grf_u):
    """[`Linearization.finish`][Linearization.finish] compiled: for each knot ``k < n = len(modes)`` (``modes (n,)``
    int64, steps ``h (n,)``), the discrete Jacobians ``f_x (., 14, 14)``, ``f_u (., 14, 4)`` from ``a_q, a_v, a_tau
    (., 7, 7)`` (elementwise the operations of [`assemble_step_jacobians`][assemble_step_jacobians], so bit-identical to
    it) and the ground forces ``grf (., 4)`` with their Jacobians ``grf_x (., 4, 14)``, ``grf_u (., 4, 4)`` copied from
    the rows of ``lam6 (., 6)``, ``lam6_q, lam6_v, lam6_tau (., 6, 7)`` (zero for feet in the air): mode ``m`` has
    ``n_rows[m]`` rows, ``row_map[m, j] = (grf row, Pinocchio row)``."""
    for k in range(modes.shape[0]):
        hk = h[k]
        hh = hk * hk
        for i in range(NV):
            for j in range(NQ):
                e = 1.0 if i == j else 0.0
                f_x[k, NQ + i, j] = hk * a_q[k, i, j]
                f_x[k, NQ + i, NQ + j] = e + hk * a_v[k, i, j]
                if semi_implicit:
                    f_x[k, i, j] = e + hh * a_q[k, i, j]
                    f_x[k, i, NQ + j] = hk * e + hh * a_v[k, i, j]
                else:
                    f_x[k, i, j] = e
                    f_x[k, i, NQ + j] = hk * e
            for j in range(NU):
                f_u[k, NQ + i, j] = hk * a_tau[k, i, 3 + j]
                f_u[k, i, j] = hh * a_tau[k, i, 3 + j] if semi_implicit else 0.0
        for g in range(NGRF):
            grf[k, g] = 0.0
            for j in range(NX):
                grf_x[k, g, j] = 0.0
            for j in range(NU):
                grf_u[k, g, j] = 0.0
        m = modes[k]
        for j in range(n_rows[m]):
            g = row_map[m, j, 0]
            r = row_map[m, j, 1]
            grf[k, g] = lam6[k, r]
            for c in range(NQ):
                grf_x[k, g, c] = lam6_q[k, r, c]
            for c in range(NV):
                grf_x[k, g, NQ + c] = lam6_v[k, r, c]
            for c in range(NU):
                grf_u[k, g, c] = lam6_tau[k, r, 3 + c]


def grf_from_lambda(lam6: np.ndarray, modes: np.ndarray, contact_sets: dict, out: np.ndarray) -> None:
    """Convert Pinocchio's stacked contact forces to our ``grf`` layout, vectorized over knots.

    Args:
        lam6: ``(N, 6)`` Pinocchio ``lambda_c`` per knot (3 rows per contact in the contact set's order,
            unused rows ignored). modes: ``(N,)``. contact_sets: ``HybridDynamics._contact``.
        out: ``(N, 4)`` ground forces (zero for feet in the air).
    """
    out[:] = 0.0
    modes = np.asarray(modes)
    for mode, cs in contact_sets.items():
        idx = np.flatnonzero(modes == int(mode))
        if idx.size:
            out[np.ix_(idx, cs.grf_rows)] = lam6[np.ix_(idx, cs.lam_rows)]
