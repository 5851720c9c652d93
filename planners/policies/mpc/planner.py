"""The MPC's planner: an HS-DDP plan of a contact schedule from a state, warm-started from the previous plan.

[`MPCPlanner.plan`][MPCPlanner.plan] builds the bounding problem of the schedule (the authors' later cost weights and
their +-1 m/s vertical-velocity references, the plans' friction margin, reference heights on the plan's ground), shifts
the previous plan onto it ([`shift_plan`][hsddp_gym.planners.policies.mpc.warm_start.shift_plan]) and runs HS-DDP (AL on
the switching constraints, relaxed barriers on torques and ground forces):

* a warm-started periodic re-plan takes ``replan.iterations`` DDP iterations (one: a real-time iteration) with the
  multipliers and penalty of the plan it shifts, no outer-loop update;
* a plan from scratch (the episode's first, or one the previous plan cannot warm-start) starts from the rollout of
  the heuristic controller and takes ``replan.warmup_iterations`` iterations with the solver's own outer loop;
* a *feedback* re-plan (made at once because the feedback law would saturate) is solved further:
  ``feedback_iterations`` DDP iterations in each of ``feedback_al_iterations`` outer iterations; the plan is kept,
  its outer-loop updates are not (the re-plans after it start from the multipliers it was warm-started with);
* a warm-started plan whose objective ends above ``restart_ratio`` times the previous plan's is solved again from
  scratch and the better of the two kept.

A failed plan (an exception of the solver, a non-finite trajectory, a diverged solve) returns None and is counted;
the MPC's previous plan keeps acting.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.planners.optimizer.hold import held_feedforward, held_input_gains
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.objective import ConstraintState
from hsddp_gym.planners.optimizer.problem import ConstraintSpec, HybridProblem
from hsddp_gym.planners.optimizer.solution import Solution, SolverOptions
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController, HeuristicGains
from hsddp_gym.planners.policies.mpc.ground import GroundModel
from hsddp_gym.planners.policies.mpc.options import PlanOptions, ReplanOptions
from hsddp_gym.planners.policies.mpc.warm_start import shift_plan
from hsddp_gym.planners.policies.tracking import PlanTracker

SIGMA_MAX = 500.0
"""The cap of the augmented-Lagrangian penalty a warm-started re-plan starts with."""
REB_DELTA = 0.2
"""The relaxed barriers' relaxation in every re-plan (the one-shot solve's shrinking one would make warm-started
re-plans needlessly stiff)."""
REB_EPS = 1e-4
"""The relaxed barriers' weight in every re-plan."""
WARM_START_KD = 0.1
"""Joint damping [N m s/rad] of the heuristic whose rollout starts a plan from scratch (the heuristic's 1 N m s/rad
is unstable for explicit integration at steps above about 1.5 ms)."""
WARM_UP_AL_ITERATIONS = 4
"""Outer iterations of a plan from scratch."""
PERIODIC_AL_ITERATIONS = 2
"""The outer-iteration cap of a warm-started periodic re-plan (it stops after its DDP iterations first)."""
PLAN_FAILURES = (RuntimeError, ValueError, ArithmeticError, np.linalg.LinAlgError)
"""What a re-plan that fails raises; the failure is counted and the previous plan keeps acting."""


@dataclasses.dataclass
class Plan:
    """A plan the MPC acts on.

    Attributes:
        tracker: its feedback law with a cursor ([`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker]).
        solution: the HS-DDP solution. problem: the problem it solves.
        multipliers: ``(n,)`` the AL multipliers per phase the next re-plan is warm-started with (None: none).
    """

    tracker: PlanTracker
    solution: Solution
    problem: HybridProblem
    multipliers: np.ndarray | None


class MPCPlanner:
    """Plans of contact schedules from states (see the module docstring).

    Args:
        plan: [`PlanOptions`][hsddp_gym.planners.policies.mpc.options.PlanOptions].
        replan: [`ReplanOptions`][hsddp_gym.planners.policies.mpc.options.ReplanOptions].
        torque_limit: the motors' limit [N m].
        target_speed: the target forward speed [m/s] of the heuristic that starts a plan from scratch.
        ground: the terrain ([`GroundModel`][hsddp_gym.planners.policies.mpc.ground.GroundModel]).

    Attributes:
        dynamics: the planner's hybrid model (semi-implicit Euler at ``plan.planner_dt``).
        stats: ``replans``, ``restarts``, ``restarts_kept``, ``planner_failures``, ``solve_ms`` (list),
            ``iterations`` (list), ``time_budget_stops`` since `reset`.
        last_failure: the last failure's exception, as text (None: none).
    """

    def __init__(self, plan: PlanOptions, replan: ReplanOptions, torque_limit: float, target_speed: float,
                 ground: GroundModel) -> None:
        self.plan_options = plan
        self.replan_options = replan
        self.torque_limit = float(torque_limit)
        self.ground = ground
        self.dynamics = HybridDynamics(dt=plan.planner_dt, integrator="semi_implicit")
        params = self.dynamics.robot.params
        self.constraints = None if plan.friction is None else ConstraintSpec(torque_limit=params.torque_limit,
                                                                             friction=plan.friction)
        self.touchdown = None
        """The touchdown rule of the plans' trackers (None: every contact flag counts)."""
        self.barrier = None
        """The relaxed barriers' ``(delta_torque, delta_grf, eps_torque, eps_grf)`` in every warm-started re-plan (None:
        [`REB_DELTA`][REB_DELTA] and [`REB_EPS`][REB_EPS])."""
        self.hold = 1
        """Knots per control period the plans' feedback laws hold their control over (1: per-knot gains, the
        bound's; above 1: [`held_input_gains`][hsddp_gym.planners.optimizer.hold.held_input_gains] and
        [`held_feedforward`][hsddp_gym.planners.optimizer.hold.held_feedforward])."""
        self.cold_start = None
        """None, or a function ``problem -> (U (N, 4), X (N+1, 14) or None, K (N, 4, 14) or None)``: the guess a plan
        from scratch starts from, with the feedback law of its first rollout when ``X`` and ``K`` are given (default:
        the bounding heuristic's rollout's controls)."""
        self._warm_controller = HeuristicBoundingController(
            gains=HeuristicGains(speed=target_speed, kd=(WARM_START_KD,) * 4), height_offset=plan.height_offset)
        self.reset()

    def reset(self, constraint_state: ConstraintState | None = None) -> None:
        """Forget the episode; the first warm-started re-plan continues from ``constraint_state`` (the AL penalty and
        the barriers of a plan solved offline; None: the solver's defaults)."""
        self._solver = HSDDP(SolverOptions())
        self._restart_solver = HSDDP(SolverOptions())
        """Solves the restarts; swapped with [`_solver`][_solver] when its plan is kept, so that [`_solver`][_solver]
        always holds the kept plan's backward pass and outer-loop state."""
        self._cs: ConstraintState | None = None if constraint_state is None else constraint_state.copy()
        self.last_failure: str | None = None
        self.stats = {"replans": 0, "restarts": 0, "restarts_kept": 0, "planner_failures": 0, "solve_ms": [],
                      "iterations": [], "time_budget_stops": 0}

    # ------------------------------------------------------------------ a plan
    def problem(self, x: np.ndarray, schedule: ModeSchedule, speed: float, height: float) -> HybridProblem:
        """The bounding problem of ``schedule`` from ``x`` (14,) at ``speed`` [m/s], its ground ``height`` [m] above
        the terrain ([`GroundModel.for_plan`][GroundModel.for_plan])."""
        h = self.plan_options.planner_dt
        knots = np.array([max(1, round(d / h)) for d in schedule.durations], dtype=np.int64)
        ground, terrain = self.ground.for_plan(schedule, float(x[0]), speed, height)
        return HybridProblem.bounding(schedule=schedule, x0=x, speed=speed, dynamics=self.dynamics,
                                      constraints=self.constraints, z_velocity="code", weights="later", knots=knots,
                                      height_offset=self.plan_options.height_offset, ground=ground, terrain=terrain)

    def plan(self, x: np.ndarray, schedule: ModeSchedule, speed: float, height: float, previous: Plan | None,
             feedback: bool = False) -> Plan | None:
        """A plan of ``schedule`` from ``x`` (14,) (see [`problem`][problem]), warm-started from ``previous`` (its
        tracker's cursor is now); ``feedback``: a feedback re-plan, solved further when warm-started. None when it
        fails (counted in `stats`, the reason in `last_failure`)."""
        return self.solve(self.problem(x, schedule, speed, height), x, previous, feedback)

    def solve(self, problem: HybridProblem, x: np.ndarray, previous: Plan | None, feedback: bool = False
              ) -> Plan | None:
        """A plan of ``problem`` (from ``x`` (14,)), warm-started from ``previous`` shifted onto it (its tracker's
        cursor is now; None or a plan that does not cover the problem: from scratch, ``cold_start``);
        ``feedback``: a feedback re-plan, solved further when warm-started. None when it fails (counted in `stats`,
        the reason in `last_failure`)."""
        o = self.replan_options
        t0 = time.perf_counter()
        try:
            ws = None if previous is None else shift_plan(problem, x, previous.tracker, previous.solution,
                                                          previous.multipliers, previous.problem)
        except ValueError:
            ws = None
        cold = ws is None
        iters = o.warmup_iterations if cold else o.iterations
        outer, total = (WARM_UP_AL_ITERATIONS if cold else PERIODIC_AL_ITERATIONS), iters
        further = feedback and not cold and o.feedback_iterations is not None
        if further:  # far from the plan: solve further, onto the switching constraints (outer-loop updates between)
            iters, outer = o.feedback_iterations, o.feedback_al_iterations
            total = iters * outer
        self._solver.options = SolverOptions(max_ddp_iterations=iters, max_total_ddp_iterations=total,
                                             time_limit=o.time_budget, max_al_iterations=outer)
        try:
            sol = self._solve(problem, ws)
            if (o.restart_ratio is not None and not cold
                    and not (sol.objective <= o.restart_ratio * max(previous.solution.objective, 1.0))):
                sol = self._restart(problem, sol)
            if not (np.all(np.isfinite(sol.X)) and np.all(np.isfinite(sol.K))) or sol.status == "diverged":
                raise RuntimeError(f"planner status {sol.status}")
        except PLAN_FAILURES as exc:
            self.last_failure = f"{type(exc).__name__}: {exc}"
            self.stats["planner_failures"] += 1
            self.stats["solve_ms"].append(1e3 * (time.perf_counter() - t0))
            return None
        cs = self._solver.last_constraint_state
        if further and cs is not None and self._cs is not None:
            # keep the plan, not its outer-loop updates: the next re-plans start from this one's warm start (also
            # when a restart from scratch was kept: its multipliers are this state's updates too)
            cs = cs.copy()
            cs.lam = ws[3].copy()
            cs.sigma = min(self._cs.sigma, SIGMA_MAX)
        self._cs = cs
        self.stats["replans"] += 1
        self.stats["time_budget_stops"] += int(sol.status == "time_limit")
        self.stats["solve_ms"].append(1e3 * (time.perf_counter() - t0))
        self.stats["iterations"].append(sol.ddp_iterations)
        law = sol
        if self.hold > 1:  # the law of a control held over the control period (the solver just made sol)
            law = dataclasses.replace(sol, K=held_input_gains(self._solver, problem, self.hold),
                                      U=held_feedforward(sol.U, problem.phase_start, self.hold))
        return Plan(PlanTracker.from_solution(law, problem, touchdown=self.touchdown), sol, problem,
                    cs.lam.copy() if cs is not None else None)

    def _solve(self, problem: HybridProblem, ws) -> Solution:
        """Solve from the shifted plan ``ws`` (``(U, X, K, lam)``), most informed first: with its feedback law, then
        open loop; from scratch when there is none or neither rolls out."""
        if ws is not None:
            U, X, K, lam = ws
            cs = self._cs.copy() if self._cs is not None else None
            if cs is not None:
                cs.lam = lam
                cs.sigma = min(cs.sigma, SIGMA_MAX)
                if self.barrier is None:
                    cs.delta_torque = cs.delta_grf = REB_DELTA
                    cs.eps_torque = cs.eps_grf = REB_EPS
                else:
                    cs.delta_torque, cs.delta_grf, cs.eps_torque, cs.eps_grf = self.barrier
            U = np.clip(U, -self.torque_limit, self.torque_limit)
            for X_init, K_init in ((X, K), (None, None)):
                try:
                    return self._solver.solve(problem, U, X_init=X_init, K_init=K_init, constraint_state=cs)
                except ValueError:
                    pass
        return self._solver.solve(problem, *self._cold_start(problem))

    def _cold_start(self, problem: HybridProblem) -> tuple:
        """``(U (N, 4), X_init, K_init)`` to solve ``problem`` from scratch: ``cold_start(problem)`` when set, else the
        warm-start heuristic's rollout's controls (zero torques if that rollout diverges from this state), no
        feedback law."""
        from hsddp_gym.core.rollout import rollout

        if self.cold_start is not None:
            return self.cold_start(problem)
        ctrl = self._warm_controller.as_schedule_controller(problem.schedule)
        try:
            # the planner's dynamics do not depend on the ground's height: the heuristic acts from its level
            traj = rollout(problem.dynamics, problem.schedule, self.ground.level(problem.x0), controller=ctrl)
        except RuntimeError:
            traj = None
        if traj is None or not traj.is_finite or traj.U.shape[0] != problem.n_knots:
            return np.zeros((problem.n_knots, NU)), None, None
        return traj.U, None, None

    def _restart(self, problem: HybridProblem, sol: Solution) -> Solution:
        """Solve ``problem`` again from scratch after the warm-started ``sol`` ended far above the previous plan's
        objective; the plan with the lower objective is returned, and [`_solver`][_solver] is the solver that made it. A
        restart whose warm start cannot be rolled out (ValueError) or that diverges keeps ``sol``: it counts in
        ``stats["restarts"]`` and not in ``stats["restarts_kept"]``."""
        self.stats["restarts"] += 1
        solver = self._restart_solver
        n = self.replan_options.warmup_iterations
        solver.options = SolverOptions(max_ddp_iterations=n, max_total_ddp_iterations=n,
                                       time_limit=self.replan_options.time_budget,
                                       max_al_iterations=WARM_UP_AL_ITERATIONS)
        try:
            fresh = solver.solve(problem, *self._cold_start(problem))
        except ValueError:
            return sol
        if (fresh.status != "diverged" and np.all(np.isfinite(fresh.X)) and np.all(np.isfinite(fresh.K))
                and fresh.objective < sol.objective):
            self.stats["restarts_kept"] += 1
            self._solver, self._restart_solver = solver, self._solver
            return fresh
        return sol
