"""HS-DDP Algorithm 1: impact-aware iLQR inside an augmented-Lagrangian / relaxed-barrier outer loop.

``solve(problem, ...)`` runs (paper Alg. 1, Sec. IV-B to IV-D):

1. roll out the warm start (controls, optionally with a feedback law around a state trajectory);
2. DDP to convergence on the current objective: linearize the dynamics along the nominal trajectory
   (Pinocchio analytical derivatives), differentiate the objective (vectorized over the horizon),
   run the impact-aware backward pass ([`hsddp_gym.planners.optimizer.riccati`][hsddp_gym.planners.optimizer.riccati]),
   and a backtracking line search on the policy ``u = u_hat + eps k + K (x - x_hat)`` (eq. 8) that accepts a step only
   if the actual decrease is at least ``armijo`` times the expected one; non-finite rollouts are failed trials;
3. update the AL multipliers and penalty (eq. 24: ``lam <- lam + sigma g``, then ``sigma <- beta sigma``),
   shrink the barrier relaxations (``delta <- delta_factor delta``) and grow their weights, until
   ``sum g^2 <= al_tolerance`` (and, with ``al_max_abs_tolerance`` set, ``max |g| <= al_max_abs_tolerance``).

The workspace (per-horizon arrays) is allocated with room to spare and reused by later solves that fit in it.
Solves are deterministic: the same inputs give bit-identical outputs.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.core.conventions import NGRF, NU, NV, NX
from hsddp_gym.core.dynamics import Linearization, grf_from_lambda
from hsddp_gym.core.planar_dynamics import rollout_phase
from hsddp_gym.planners.optimizer.callbacks import Callback, InMemoryLogger, VerbosePrinter
from hsddp_gym.planners.optimizer.objective import ConstraintState, CostBreakdown, Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem, first_non_finite_knot
from hsddp_gym.planners.optimizer.riccati import backward_pass, warm_up
from hsddp_gym.planners.optimizer.solution import IterationRecord, Solution, SolverOptions
from hsddp_gym.util.validation import check_array


class _Traj:
    """Arrays of one trajectory: X (N+1, 14), X_pre (n, 14), U (N, 4), GRF (N, 4), for N = ``n_knots`` knots and
    n = ``n_phases`` phases, or fewer ([`resize`][resize]: they are the leading views of buffers of that capacity).
    """

    def __init__(self, n_knots: int, n_phases: int) -> None:
        self._X = np.zeros((n_knots + 1, NX))
        self._X_pre = np.zeros((n_phases, NX))
        self._U = np.zeros((n_knots, NU))
        self._GRF = np.zeros((n_knots, NGRF))
        self.resize(n_knots, n_phases)

    def resize(self, n_knots: int, n_phases: int) -> None:
        """Make ``X``, ``X_pre``, ``U``, ``GRF`` the views of ``n_knots`` knots and ``n_phases`` phases (within the
        capacity, else ``ValueError``)."""
        if not (1 <= n_knots <= self._U.shape[0] and 1 <= n_phases <= self._X_pre.shape[0]):
            raise ValueError(f"n_knots, n_phases must be in 1 .. {self._U.shape[0]}, 1 .. {self._X_pre.shape[0]} "
                             f"(the capacity), got {n_knots}, {n_phases}")
        self.X = self._X[:n_knots + 1]
        self.X_pre = self._X_pre[:n_phases]
        self.U = self._U[:n_knots]
        self.GRF = self._GRF[:n_knots]


@dataclasses.dataclass
class LoopState:
    """Where a solve stands: what the outer (augmented-Lagrangian) loop and its DDP iterations share."""

    al_iteration: int = 0
    """The outer iteration in progress (0-based)."""
    ddp_iterations: int = 0
    """Accepted DDP steps so far, over all outer iterations."""
    mu: float = 0.0
    """The backward pass's regularization: grown after a failed backward pass or line search, shrunk after a step."""
    status: str = "running"
    """``"running"`` until a stop: ``"time_limit"``, ``"iteration_limit"``, ``"diverged"`` or ``"gains_failed"``."""
    step_gains: bool = False
    """Whether the workspace's gains ``K``, ``k_ff`` are the backward pass that made the last accepted step."""


class Workspace:
    """Everything a solve allocates, for problems of up to ``knot_capacity`` knots and ``phase_capacity`` phases
    (default: ``problem``'s size). Its arrays are the leading views of one problem's size ([`use`][use]), so one
    workspace serves solves of varying sizes (MPC re-plans) without allocating."""

    _SHAPES = {"l_x": (0, NX), "l_u": (0, NU), "l_xx": (0, NX, NX), "l_uu": (0, NU, NU), "l_ux": (0, NU, NX),
               "Phi_x": (1, NX), "Phi_xx": (1, NX, NX), "P_x": (1, NX, NX), "k_ff": (0, NU), "K": (0, NU, NX),
               "V_x": (2, NX), "V_xx": (2, NX, NX), "lam6": (0, 6)}
    """Array name -> (0: N rows, 1: n rows, 2: N + 1 rows; then the shape of a row)."""

    def __init__(self, problem: HybridProblem, knot_capacity: int | None = None,
                 phase_capacity: int | None = None) -> None:
        n = problem.n_knots if knot_capacity is None else max(int(knot_capacity), problem.n_knots)
        m = problem.n_phases if phase_capacity is None else max(int(phase_capacity), problem.n_phases)
        self.knot_capacity, self.phase_capacity = n, m
        self.nominal = _Traj(n, m)
        self.candidate = _Traj(n, m)
        self.lin = Linearization(n)
        self.lin_candidate = Linearization(n)
        self._buffers = {name: np.zeros(((n, m, n + 1)[rows], *shape))
                         for name, (rows, *shape) in self._SHAPES.items()}
        self.use(problem)

    def fits(self, problem: HybridProblem) -> bool:
        """Whether ``problem`` is within the capacity."""
        return problem.n_knots <= self.knot_capacity and problem.n_phases <= self.phase_capacity

    def use(self, problem: HybridProblem) -> None:
        """Size the workspace's arrays for ``problem`` (within the capacity: else ``ValueError``); forgets the
        linearization (``lin_valid``)."""
        if not self.fits(problem):
            raise ValueError(f"problem has {problem.n_knots} knots and {problem.n_phases} phases, more than the "
                             f"workspace's capacity ({self.knot_capacity}, {self.phase_capacity})")
        n, m = problem.n_knots, problem.n_phases
        self.n_knots, self.n_phases = n, m
        self.nominal.resize(n, m)
        self.candidate.resize(n, m)
        self.lin_valid = False
        """True when ``lin`` already holds the dynamics derivatives at ``nominal`` (speculative rollout)."""
        for name, (rows, *_) in self._SHAPES.items():
            setattr(self, name, self._buffers[name][:(n, m, n + 1)[rows]])


# stand-ins for the arrays a rollout without feedback or derivatives does not use (compiled code wants arrays)
_NO_GAINS = np.zeros((1, NU, NX))
_SCRATCH = (np.zeros((1, NV, NV)), np.zeros((1, NV, NV)), np.zeros((1, NV, NV)), np.zeros((1, 6, NV)),
            np.zeros((1, 6, NV)), np.zeros((1, 6, NV)), np.zeros((1, NV)))


def _check_guess_finite(problem: HybridProblem, value, shape: tuple, name: str) -> None:
    """Raise a ValueError naming the first non-finite row of an initial guess ``value`` of ``shape`` (a diverged
    warm start), with its time, cycle and phase; anything else is left to ``check_array``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return
    if arr.shape != shape or np.all(np.isfinite(arr)):
        return
    k = int(np.flatnonzero(~np.all(np.isfinite(arr.reshape(shape[0], -1)), axis=1))[0])
    raise ValueError(f"{name} must be finite, but {name}[{k}] is not ({problem.describe_knot(k)}): the initial guess "
                     "diverged there (a rollout that blew up?); see hsddp_gym.planners.tasks.bounding_warm_start for "
                     "a warm start that stays finite on long horizons")


def rollout_policy(problem: HybridProblem, out: _Traj, U_ref: np.ndarray, X_ref: np.ndarray | None = None,
                   K: np.ndarray | None = None, k_ff: np.ndarray | None = None, eps: float = 0.0,
                   lam6: np.ndarray | None = None, lin: Linearization | None = None) -> bool:
    """Roll out ``u_k = U_ref[k] + eps k_ff[k] + K[k] (x_k - X_ref[k])`` (eq. 8) through the hybrid system.

    The affine part is folded once per rollout, ``c_k = U_ref[k] + eps k_ff[k] - K[k] X_ref[k]``; each phase is
    one compiled call ([`hsddp_gym.core.planar_dynamics.rollout_phase`][hsddp_gym.core.planar_dynamics.rollout_phase]:
    the feedback law, the mode's dynamics and, with ``lin``, their derivatives, the integrator step), and the reset map
    between phases is Pinocchio's. Writes ``out``; returns False (leaving NaNs) as soon as a phase ends in a non-finite
    state.

    Args:
        lam6: optional ``(N, 6)`` scratch for the contact forces (Pinocchio's ``lambda_c`` layout).
        lin: when given, also linearize the dynamics at every knot of the new trajectory into it (the
            same numbers as [`HybridDynamics.linearize`][hsddp_gym.core.dynamics.HybridDynamics.linearize]; the solver's
            speculative first trial, which saves a second pass over the horizon when the full step is accepted).
    """
    dyn = problem.dynamics
    N = problem.n_knots
    X, U = out.X, out.U
    feedback = K is not None
    if feedback:
        c = U_ref - np.einsum("nux,nx->nu", K, X_ref[:N])
        if k_ff is not None and eps != 0.0:
            c += eps * k_ff
    else:
        c = U_ref if (k_ff is None or eps == 0.0) else U_ref + eps * k_ff
        K = _NO_GAINS
    c = np.ascontiguousarray(c, dtype=np.float64)
    derivs = lin is not None
    if derivs:
        a_q, a_v, a_t, l_q, l_v, l_t, lam, acc = (lin.a_q, lin.a_v, lin.a_tau, lin.lam6_q, lin.lam6_v, lin.lam6_tau,
                                                  lin.lam6, lin.acc)
    else:
        lam = np.zeros((N, 6)) if lam6 is None else lam6
        a_q, a_v, a_t, l_q, l_v, l_t, acc = _SCRATCH
    X[0] = problem.x0
    ps = problem.phase_start
    e = problem.restitution
    semi = dyn.integrator == "semi_implicit"
    p, ws, tau = dyn.kernel_params, dyn.scratch.arrays, dyn._tau
    modes, h_phase = problem.schedule.modes, problem.phase_dt
    for i in range(problem.n_phases):
        k0, k1 = int(ps[i]), int(ps[i + 1])
        failed = rollout_phase(X, U, K, c, feedback, k0, k1, int(modes[i]), float(h_phase[i]), semi, p, derivs,
                               ws, tau, lam, acc, a_q, a_v, a_t, l_q, l_v, l_t)
        x = X[k1]
        if failed >= 0 or not np.isfinite(x).all():
            X[(failed + 1 if failed >= 0 else k1):] = np.nan
            return False
        out.X_pre[i] = x
        if i + 1 < problem.n_phases:
            X[k1], _ = dyn._reset(x, problem.schedule.next_mode(i), e)
    if lin is not None:
        lin.finish(N, problem.modes, problem.h, dyn.integrator, dyn._contact)
        out.GRF[:] = lin.grf[:N]
    else:
        grf_from_lambda(lam, problem.modes, dyn._contact, out.GRF)
    return True


def constraint_metrics(problem: HybridProblem, U: np.ndarray, GRF: np.ndarray) -> tuple[float, float, float]:
    """``(max torque violation [N m], min stance normal force [N], max friction violation [N])``."""
    umax = problem.constraints.torque_limit
    mu = problem.constraints.friction
    tau = float(max(np.max(np.abs(U)) - umax, 0.0))
    fz = np.where(problem.stance, GRF[:, 1::2], np.inf)
    min_fz = float(np.min(fz)) if problem.stance_any.any() else float("nan")
    fric = np.where(problem.stance, np.abs(GRF[:, 0::2]) - mu * GRF[:, 1::2], -np.inf)
    max_fric = float(np.max(fric)) if problem.stance_any.any() else float("nan")
    return tau, min_fz, max_fric


class HSDDP:
    """The HS-DDP solver (Algorithm 1). Reusable: keeps its workspace between solves of equal size.

    Args:
        options: [`SolverOptions`][SolverOptions].
        callbacks: extra callables receiving each [`IterationRecord`][IterationRecord]; the in-memory log always runs
            and ``verbose=True`` adds a [`VerbosePrinter`][VerbosePrinter].
        verbose: print a table row per iteration.
    """

    def __init__(self, options: SolverOptions = SolverOptions(), callbacks: list[Callback] | None = None,
                 verbose: bool = False) -> None:
        if not isinstance(options, SolverOptions):
            raise TypeError(f"options must be a SolverOptions, got {type(options).__name__}")
        self.options = options
        self.callbacks = list(callbacks or [])
        warm_up()  # numba: compile or load the kernels now, not inside a timed solve
        if verbose:
            self.callbacks.append(VerbosePrinter())
        self._ws: Workspace | None = None
        self.last_constraint_state: ConstraintState | None = None
        """Outer-loop state at the end of the last solve (warm start for the next one)."""
        self.last_objective: Objective | None = None
        self.last_problem: HybridProblem | None = None
        """The problem the workspace's nominal trajectory and linearization belong to."""

    # ------------------------------------------------------------------ public API
    def solve(self, problem: HybridProblem, U_init: np.ndarray, X_init: np.ndarray | None = None,
              K_init: np.ndarray | None = None, multipliers: np.ndarray | None = None, sigma: float | None = None,
              constraint_state: ConstraintState | None = None) -> Solution:
        """Solve ``problem`` from a warm start.

        Args:
            problem: the hybrid OCP.
            U_init: ``(N, 4)`` initial controls (e.g. the heuristic controller's).
            X_init: optional ``(N+1, 14)`` states; with ``K_init`` the first rollout uses
                ``u = U_init + K_init (x - X_init)`` (warm start from a previous solution).
            K_init: optional ``(N, 4, 14)`` gains (together with ``X_init``).
            multipliers: ``(m,)`` initial AL multipliers, one per switching-constraint row (``m =
                problem.n_switching``, the phases ``n`` unless feet land together; default ``lambda0``).
            sigma: initial penalty (default ``sigma0``).
            constraint_state: continue from a previous solve's outer-loop state (multipliers, penalty,
                barrier relaxations and weights: ``HSDDP.last_constraint_state``); overrides the two above.
        Returns:
            A [`Solution`][Solution].
        """
        if not isinstance(problem, HybridProblem):
            raise TypeError(f"problem must be a HybridProblem, got {type(problem).__name__}")
        opt = self.options
        N = problem.n_knots
        _check_guess_finite(problem, U_init, (N, NU), "U_init")
        U_init = check_array(U_init, (N, NU), "U_init")
        if (X_init is None) != (K_init is None):
            raise ValueError("X_init and K_init go together (a feedback warm start); pass both or neither")
        if X_init is not None:
            _check_guess_finite(problem, X_init, (N + 1, NX), "X_init")
            X_init = check_array(X_init, (N + 1, NX), "X_init")
            _check_guess_finite(problem, K_init, (N, NU, NX), "K_init")
            K_init = check_array(K_init, (N, NU, NX), "K_init")
        m = problem.n_switching
        lam = np.full(m, opt.lambda0) if multipliers is None else check_array(multipliers, (m,), "multipliers").copy()
        if sigma is None:
            sigma = opt.sigma0
        elif isinstance(sigma, bool) or not isinstance(sigma, (int, float, np.floating)) or not (
                np.isfinite(sigma) and sigma > 0):
            raise ValueError(f"sigma must be a finite number > 0, got {sigma!r}")
        sigma = float(sigma)
        if self._ws is None or not self._ws.fits(problem):
            # room for a quarter more knots and phases: the next problems (MPC re-plans) vary in size
            self._ws = Workspace(problem, problem.n_knots + problem.n_knots // 4, problem.n_phases + 2)
        else:
            self._ws.use(problem)
        ws = self._ws
        objective = Objective(problem)
        cs = ConstraintState(sigma=sigma, lam=lam, use_al=opt.use_al, use_reb=opt.use_reb,
                             delta_torque=opt.delta_torque0, delta_grf=opt.delta_grf0,
                             eps_torque=opt.eps_torque, eps_grf=opt.eps_grf)
        if constraint_state is not None:
            if constraint_state.lam.shape != (m,):
                raise ValueError(f"constraint_state.lam must have shape ({m},), got {constraint_state.lam.shape}")
            cs = constraint_state.copy()
        logger = InMemoryLogger()
        callbacks = [logger, *self.callbacks]
        timings = {"linearize": 0.0, "cost_derivatives": 0.0, "backward": 0.0, "line_search": 0.0,
                   "reset_jacobians": 0.0, "line_search_trials": 0}
        t0 = time.perf_counter()
        # a diverging rollout overflows on its way to the non-finite state it is rejected for
        with np.errstate(over="ignore", invalid="ignore"):
            ok = rollout_policy(problem, ws.nominal, U_init, X_init, K_init, lin=ws.lin)
        ws.lin_valid = ok
        if not ok:
            k = first_non_finite_knot(ws.nominal.X[:N + 1])
            where = f": X[{k}] is not finite ({problem.describe_knot(k)})" if k is not None else ""
            raise ValueError("the warm start (U_init" + (", X_init, K_init" if K_init is not None else "")
                             + f") produces a diverging rollout{where}")
        state = LoopState()

        def record(event, costs: CostBreakdown, step=0.0, expected=0.0):
            tr = ws.nominal
            g = objective.switching_values(tr.X_pre)
            tau, min_fz, fric = constraint_metrics(problem, tr.U, tr.GRF)
            r = IterationRecord(al_iteration=state.al_iteration, ddp_iteration=state.ddp_iterations,
                                objective=costs.total, cost=costs.task, al=costs.al, barrier=costs.barrier,
                                switching_violation=float(np.sum(g * g)), max_torque_violation=tau,
                                min_normal_grf=min_fz, max_friction_violation=fric, step=step, mu=state.mu,
                                expected=expected, wall_time=time.perf_counter() - t0, event=event)
            for cb in callbacks:
                cb(r)
            return r

        with np.errstate(over="ignore", invalid="ignore"):
            costs = self._evaluate(objective, ws.nominal, cs)
        if not np.isfinite(costs.total):
            raise ValueError(f"the warm start (U_init, X_init, K_init) has a non-finite objective ({costs.total}): "
                             "its torques or ground forces overflow the barrier terms")
        record("init", costs)
        converged = False
        for al_iter in range(opt.max_al_iterations):
            state.al_iteration = al_iter
            costs = self._evaluate(objective, ws.nominal, cs)
            if al_iter > 0:
                record("al_update", costs)
            costs = self._ddp(problem, objective, cs, costs, state, record, timings, t0)
            g = objective.switching_values(ws.nominal.X_pre)
            viol = float(np.sum(g * g))
            if state.status in ("time_limit", "iteration_limit", "diverged"):
                break
            if opt.max_total_ddp_iterations is not None and state.ddp_iterations >= opt.max_total_ddp_iterations:
                state.status = "iteration_limit"
                break
            if opt.time_limit is not None and time.perf_counter() - t0 > opt.time_limit:
                state.status = "time_limit"
                break
            max_g = float(np.max(np.abs(g), initial=0.0))
            if not opt.use_al or (viol <= opt.al_tolerance and (opt.al_max_abs_tolerance is None
                                                                or max_g <= opt.al_max_abs_tolerance)):
                converged = True
                break
            if al_iter == opt.max_al_iterations - 1:
                break  # keep the outer-loop state that was actually solved
            # Algorithm 1, line 9 (eq. 24 uses the penalty before its growth)
            cs.lam = cs.lam + cs.sigma * g
            cs.sigma *= opt.beta
            cs.delta_torque = max(opt.delta_min, cs.delta_torque * opt.delta_factor)
            cs.delta_grf = max(opt.delta_min, cs.delta_grf * opt.delta_factor)
            cs.eps_torque *= opt.eps_growth
            cs.eps_grf *= opt.eps_growth
        status = "converged" if converged else (state.status if state.status != "running"
                                                else "al_iteration_limit")
        if opt.refresh_gains or not state.step_gains:
            # gains consistent with the final trajectory: one more linearization + backward pass (no step)
            self._backward_at_nominal(problem, objective, cs, state, timings)
        if state.status == "gains_failed":
            status, converged = "gains_failed", False
        tr = ws.nominal
        final = self._evaluate(objective, tr, cs)
        g = objective.switching_values(tr.X_pre)
        solve_time = time.perf_counter() - t0
        self.last_constraint_state = cs.copy()
        self.last_objective = objective
        self.last_problem = problem
        return Solution(X=tr.X.copy(), X_pre=tr.X_pre.copy(), U=tr.U.copy(), GRF=tr.GRF.copy(), K=ws.K.copy(),
                        k_ff=ws.k_ff.copy(), modes=problem.modes.copy(), phase_start=problem.phase_start.copy(),
                        schedule=problem.schedule, dt=problem.dt, switching=g, multipliers=cs.lam.copy(),
                        sigma=cs.sigma, cost=final.task, objective=final.total, status=status, converged=converged,
                        al_iterations=state.al_iteration + 1, ddp_iterations=state.ddp_iterations,
                        solve_time=solve_time, log=logger.records, timings=timings, options=opt,
                        V_x0=ws.V_x[0].copy(), V_xx0=ws.V_xx[0].copy())

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _evaluate(objective: Objective, tr: _Traj, cs: ConstraintState) -> CostBreakdown:
        return objective.evaluate(tr.X, tr.X_pre, tr.U, tr.GRF, cs)

    def _linearize(self, problem, objective, cs, timings):
        ws = self._ws
        tr = ws.nominal
        t = time.perf_counter()
        if not ws.lin_valid:
            problem.dynamics.linearize(tr.X, tr.U, problem.modes, ws.lin, problem.h)
        t2 = time.perf_counter()
        dyn = problem.dynamics
        e = problem.restitution
        for i in range(problem.n_phases - 1):
            dyn._reset_jacobian(tr.X_pre[i], problem.schedule.next_mode(i), e, ws.P_x[i])
        t3 = time.perf_counter()
        # a warm start far off (an MPC re-plan after a push) can overflow the barrier terms: the non-finite
        # derivatives then fail the backward pass, which the solver's status reports (no warning spam)
        with np.errstate(over="ignore", invalid="ignore"):
            N = problem.n_knots
            objective.derivatives(tr.X, tr.X_pre, tr.U, tr.GRF, ws.lin.grf_x[:N], ws.lin.grf_u[:N], cs, ws.l_x,
                                  ws.l_u, ws.l_xx, ws.l_uu, ws.l_ux, ws.Phi_x, ws.Phi_xx)
        t4 = time.perf_counter()
        timings["linearize"] += t2 - t
        timings["reset_jacobians"] += t3 - t2
        timings["cost_derivatives"] += t4 - t3

    def _backward(self, problem, mu, timings):
        ws = self._ws
        t = time.perf_counter()
        N = problem.n_knots
        out = backward_pass(ws.lin.f_x[:N], ws.lin.f_u[:N], ws.l_x, ws.l_u, ws.l_xx, ws.l_uu, ws.l_ux, ws.Phi_x,
                            ws.Phi_xx, ws.P_x, problem.phase_start, mu, ws.k_ff, ws.K, ws.V_x, ws.V_xx)
        timings["backward"] += time.perf_counter() - t
        return out

    def _backward_at_nominal(self, problem, objective, cs, state: LoopState, timings):
        self._linearize(problem, objective, cs, timings)
        mu = state.mu
        for _ in range(60):
            ok, _, _, _ = self._backward(problem, mu, timings)
            if ok:
                return
            mu = max(self.options.mu_min, mu * self.options.mu_growth)
        self._ws.K[:] = 0.0
        self._ws.k_ff[:] = 0.0
        state.status = "gains_failed"

    def _ddp(self, problem, objective, cs, costs, state: LoopState, record, timings, t0):
        opt = self.options
        ws = self._ws
        for _ in range(opt.max_ddp_iterations):
            if opt.time_limit is not None and time.perf_counter() - t0 > opt.time_limit:
                state.status = "time_limit"
                return costs
            if opt.max_total_ddp_iterations is not None and state.ddp_iterations >= opt.max_total_ddp_iterations:
                state.status = "iteration_limit"
                return costs
            self._linearize(problem, objective, cs, timings)
            # the last iteration allowed needs no linearization of its step unless the gains are refreshed there
            last = (opt.max_total_ddp_iterations is not None
                    and state.ddp_iterations + 1 >= opt.max_total_ddp_iterations)
            speculate = opt.refresh_gains or not last
            accepted = False
            while not accepted:
                state.step_gains = False
                ok, _, dV1, dV2 = self._backward(problem, state.mu, timings)
                if not ok:
                    state.mu = max(opt.mu_min, state.mu * opt.mu_growth)
                    if state.mu > opt.mu_max:
                        state.status = "diverged"
                        return costs
                    continue
                if dV1 > -1e-12 * max(1.0, abs(costs.total)):
                    return costs  # no descent direction left: converged for this objective
                t = time.perf_counter()
                eps = 1.0
                new_costs = None
                cand_linearized = False
                while eps >= opt.min_step:
                    timings["line_search_trials"] += 1
                    # the full step is usually accepted: linearize along it on the way (speculative)
                    cand_linearized = eps == 1.0 and speculate
                    with np.errstate(over="ignore", invalid="ignore"):
                        ok = rollout_policy(problem, ws.candidate, ws.nominal.U, ws.nominal.X, ws.K, ws.k_ff, eps,
                                            ws.lam6, ws.lin_candidate if cand_linearized else None)
                    if ok:
                        # a trial far off the nominal may overflow the barrier: an inf cost is a failed trial
                        with np.errstate(over="ignore", invalid="ignore"):
                            cand = self._evaluate(objective, ws.candidate, cs)
                        expected = eps * dV1 + 0.5 * eps * eps * dV2
                        if np.isfinite(cand.total) and expected < 0 and \
                                (cand.total - costs.total) <= opt.armijo * expected:
                            new_costs = cand
                            break
                    eps *= opt.step_factor
                timings["line_search"] += time.perf_counter() - t
                if new_costs is None:
                    state.mu = max(opt.mu_min, state.mu * opt.mu_growth)
                    if state.mu > opt.mu_max:
                        state.status = "diverged"
                        return costs
                    continue
                accepted = True
            decrease = costs.total - new_costs.total
            ws.nominal, ws.candidate = ws.candidate, ws.nominal
            if cand_linearized:
                ws.lin, ws.lin_candidate = ws.lin_candidate, ws.lin
            ws.lin_valid = cand_linearized
            costs = new_costs
            state.step_gains = True
            state.mu = state.mu / opt.mu_growth
            if state.mu < opt.mu_min:
                state.mu = 0.0
            state.ddp_iterations += 1
            record("ddp", costs, step=eps, expected=float(-(eps * dV1 + 0.5 * eps * eps * dV2)))
            if decrease < opt.ddp_tolerance:
                return costs
        return costs


def solve(problem: HybridProblem, U_init: np.ndarray, options: SolverOptions = SolverOptions(),
          X_init: np.ndarray | None = None, K_init: np.ndarray | None = None,
          multipliers: np.ndarray | None = None, callbacks: list[Callback] | None = None, verbose: bool = False,
          sigma: float | None = None, constraint_state: ConstraintState | None = None) -> Solution:
    """Solve ``problem`` with HS-DDP Algorithm 1 (see [`HSDDP.solve`][HSDDP.solve])."""
    return HSDDP(options, callbacks, verbose).solve(problem, U_init, X_init, K_init, multipliers, sigma,
                                                    constraint_state)
