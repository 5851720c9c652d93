"""The paper's planning tasks as functions (used by the CLI and the experiment scripts)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.rollout import Trajectory, rollout
from planners.callbacks import Callback
from planners.heuristic import HeuristicBoundingController
from planners.hsddp import HSDDP
from planners.metrics import trajectory_summary
from planners.problem import HybridProblem
from planners.solution import Solution, SolverOptions

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
    t = time.perf_counter()
    sol = HSDDP(options, callbacks, verbose).solve(problem, warm.U)
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
    :class:`planners.sto.STOOptions`' defaults).

    Returns:
        ``(STOResult, summary dict)``; the summary has ``initial_total_time``, ``total_time``, ``reduction``
        (fraction), ``mode_durations``, ``iterations``, ``final_cost``, ``switching_violation``.
    """
    from planners.sto import STOOptions, optimize_switching_times

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
