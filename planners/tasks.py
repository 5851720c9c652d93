"""The paper's planning tasks as functions (used by the CLI and the experiment scripts)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from hsddp_gym.planners.optimizer.callbacks import Callback
from hsddp_gym.planners.optimizer.hsddp import HSDDP, _Traj
from hsddp_gym.planners.optimizer.metrics import trajectory_summary
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import Solution, SolverOptions
from hsddp_gym.planners.optimizer.sto import (
    STOOptions,
    duration_step,
    rollout_time_policy,
    step_size_study,
    time_derivatives,
)
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController

from hsddp_gym.core.rollout import Trajectory, rollout

PLAN_METHODS = ("heuristic", "ddp", "al", "al-reb")


@dataclasses.dataclass
class PlanResult:
    """A planned trajectory: the problem, the heuristic warm start, the solution (None for "heuristic")
    and the summary dict."""

    method: str
    problem: HybridProblem
    warm_start: Trajectory
    solution: Solution | None
    summary: dict

    @property
    def X(self):
        return self.solution.X if self.solution is not None else self.warm_start.X

    @property
    def X_pre(self):
        return self.solution.X_pre if self.solution is not None else self.warm_start.X_pre

    @property
    def U(self):
        return self.solution.U if self.solution is not None else self.warm_start.U

    @property
    def GRF(self):
        return self.solution.GRF if self.solution is not None else self.warm_start.GRF


def heuristic_warm_start(problem: HybridProblem) -> Trajectory:
    """Roll out the heuristic bounding controller through the problem's schedule (the paper's warm start)."""
    controller = HeuristicBoundingController(problem.dynamics.robot)
    return rollout(problem.dynamics, problem.schedule, problem.x0,
                   controller=controller.as_schedule_controller(problem.schedule), restitution=problem.restitution)


def plan_bounding(method: str = "al-reb", cycles: int = 5, speed: float = 1.0, options: SolverOptions | None = None,
                  callbacks: list[Callback] | None = None, verbose: bool = False,
                  problem: HybridProblem | None = None) -> PlanResult:
    """Paper task 1: ``cycles`` bounding cycles, 80/72/72/72 ms, h = 1 ms, from the paper's initial state,
    warm-started by the heuristic controller.

    Args:
        method: ``"heuristic"`` (the warm start only), ``"ddp"``, ``"al"`` or ``"al-reb"``.
    """
    if method not in PLAN_METHODS:
        raise ValueError(f"method must be one of {PLAN_METHODS}, got {method!r}")
    problem = problem if problem is not None else HybridProblem.bounding(cycles, speed=speed)
    warm = heuristic_warm_start(problem)
    if not warm.is_finite:
        raise RuntimeError("the heuristic warm start diverged")
    if method == "heuristic":
        summary = trajectory_summary(problem, warm.X, warm.X_pre, warm.U, warm.GRF)
        summary.update(method=method, al_iterations=0, ddp_iterations=0, solve_time_s=0.0,
                       time_per_ddp_iteration_s=None, status="heuristic")
        return PlanResult(method, problem, warm, None, summary)
    options = options if options is not None else SolverOptions()
    options = dataclasses.replace(options, method=method)
    solver = HSDDP(options, callbacks, verbose)  # compiles / loads the numba kernels outside the timing
    t = time.perf_counter()
    sol = solver.solve(problem, warm.U)
    elapsed = time.perf_counter() - t
    summary = trajectory_summary(problem, sol.X, sol.X_pre, sol.U, sol.GRF)
    summary.update(method=method, al_iterations=sol.al_iterations, ddp_iterations=sol.ddp_iterations,
                   solve_time_s=elapsed, time_per_ddp_iteration_s=elapsed / max(sol.ddp_iterations, 1),
                   status=sol.status, objective=sol.objective,
                   timings={k: (float(v) if not isinstance(v, int) else v) for k, v in sol.timings.items()})
    return PlanResult(method, problem, warm, sol, summary)


def finite(x) -> bool:
    return bool(np.all(np.isfinite(x)))


def run_sto(method: str = "hsddp", iterations: int = 30, cycles: int = 1, durations=None,
            second_order: bool = False, solver_options: SolverOptions | None = None, callback=None,
            min_duration=None, max_duration=None):
    """Paper task 2: switching-time optimization of ``cycles`` bounding cycles (default: one, 80/72/72/72 ms,
    the same costs, AL parameters and heuristic warm start as task 1).

    ``min_duration``, ``max_duration``: duration bounds [s] (a number or one per phase; None:
    :class:`hsddp_gym.planners.optimizer.sto.STOOptions`' defaults).

    Returns:
        ``(STOResult, summary dict)``; the summary has ``initial_total_time``, ``total_time``, ``reduction``
        (fraction), ``mode_durations``, ``iterations``, ``final_cost``, ``switching_violation``.
    """
    from hsddp_gym.planners.optimizer.sto import STOOptions, optimize_switching_times

    problem = HybridProblem.bounding(cycles, durations=durations)
    warm = heuristic_warm_start(problem)
    bounds = {k: v for k, v in (("min_duration", min_duration), ("max_duration", max_duration)) if v is not None}
    opts = STOOptions(method=method, iterations=iterations, second_order=second_order,
                      solver=solver_options if solver_options is not None else SolverOptions(), **bounds)
    res = optimize_switching_times(problem, warm.U, opts, callback=callback)
    summary = {
        "method": method,
        "initial_total_time": float(problem.schedule.total_time),
        "initial_durations": problem.schedule.durations.tolist(),
        "total_time": res.total_time,
        "reduction": res.reduction,
        "mode_durations": res.durations[-1].tolist(),
        "iterations": int(len(res.durations) - 1),
        "iteration_cap": iterations,
        "min_duration": opts.min_duration,
        "max_duration": opts.max_duration,
        "stopped": res.records[-1]["status"] if res.records else "no_iterations",
        "final_cost": float(res.costs[-1]),
        "initial_cost": float(res.costs[0]),
        "final_objective": float(res.objectives[-1]),
        "switching_violation": res.solution.switching_violation,
        "total_time_history": res.durations.sum(axis=1).tolist(),
        "cost_history": res.costs.tolist(),
        "solve_time_s": res.solve_time,
        "second_order": second_order,
    }
    return res, summary


def fig8_study(problem: HybridProblem, steps, fraction: float = 0.1, solver_options: SolverOptions | None = None,
               U_warm: np.ndarray | None = None, options: STOOptions | None = None) -> dict:
    """The point and the study of paper Fig. 8 (:func:`step_size_study`): Algorithm 1 solves ``problem`` (from
    ``U_warm (N, 4)``; default the heuristic warm start), then ``fraction`` of Algorithm 2's first Newton step
    on the durations is rolled out with the feedback policy, the way Algorithm 2 moves the durations before
    Algorithm 1 re-optimizes the controls. The default tenth is about the step that Algorithm 2's line search
    accepts first on the paper's task 2; there both the control and the duration step change the objective.

    Returns :func:`step_size_study`'s dict plus ``"z0"``, ``"z1"`` (the durations before and at the point).
    """
    from hsddp_gym.planners.tasks import heuristic_warm_start

    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must be in (0, 1], got {fraction!r}")
    options = options if options is not None else STOOptions()
    solver = HSDDP(solver_options if solver_options is not None else SolverOptions())
    U0 = heuristic_warm_start(problem).U if U_warm is None else U_warm
    solver.solve(problem, U0)
    d = time_derivatives(solver, problem)
    z0 = np.asarray(problem.schedule.durations, dtype=np.float64)
    lower, upper = options.bounds(problem.n_phases)
    dz, _, _ = duration_step(d.V_z, d.V_zz, z0, lower, upper)
    z1 = np.clip(z0 + fraction * dz, lower, upper)
    pr1 = problem.with_durations(z1)
    cand = _Traj(pr1.n_knots, pr1.n_phases)
    if not rollout_time_policy(pr1, solver._ws.nominal, d, z1 - z0, True, cand):
        raise RuntimeError("the feedback rollout to the Fig. 8 point is not finite")
    study = step_size_study(solver, pr1, cand.U.copy(), steps)
    study["z0"], study["z1"] = z0.tolist(), z1.tolist()
    return study
