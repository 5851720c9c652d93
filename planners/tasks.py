"""The paper's planning tasks as functions (used by the CLI and the experiment scripts)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.core.rollout import Trajectory, rollout
from hsddp_gym.planners.optimizer.callbacks import Callback
from hsddp_gym.planners.optimizer.hsddp import HSDDP, _Traj
from hsddp_gym.planners.optimizer.metrics import trajectory_summary
from hsddp_gym.planners.optimizer.problem import HybridProblem, first_non_finite_knot
from hsddp_gym.planners.optimizer.solution import Solution, SolverOptions
from hsddp_gym.planners.optimizer.sto import (
    STOOptions,
    duration_step,
    rollout_time_policy,
    step_size_study,
    time_derivatives,
)
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController

PLAN_METHODS = ("heuristic", "ddp", "al", "al-reb")


@dataclasses.dataclass
class PlanResult:
    """A planned trajectory: the problem, the warm start's rollout, the solution (None for "heuristic")
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


HEURISTIC_WARM_START_CYCLES = 5
"""Longest horizon [bounding cycles] warm-started by the heuristic controller's rollout alone (the paper's task).

In a single-leg stance the heuristic spends the horizontal ground force on the pitch moment, so the forward
speed is corrected only weakly (its ``kv`` and Raibert terms); on the paper's fixed schedule a nose-down pitch
then makes the front stance push instead of brake. From the paper's initial state the cycle-mean forward speed is
0.6-0.9 m/s in cycles 1-3 and then grows, 1.7 m/s in cycle 5, 3.6 m/s in cycle 7, while the mean pitch goes
nose-down (0.2 rad in cycle 5, 0.9 rad in cycle 8). In cycle 8 the front leg no longer catches the trunk (it falls
to 4.5 cm above the ground, torques reach 440 N m in cycle 9) and the rollout is no longer finite in cycle 10
(``X[2722]`` of the 10-cycle problem). Longer horizons are warm-started by
[`bounding_warm_start`][bounding_warm_start]."""

REPEATED_CYCLE = HEURISTIC_WARM_START_CYCLES - 1
"""The cycle (counted from 1) of the solved [`HEURISTIC_WARM_START_CYCLES`][HEURISTIC_WARM_START_CYCLES]-cycle plan that
[`bounding_warm_start`][bounding_warm_start] repeats: the last one the end of that plan's horizon does not shape."""


class WarmStartDivergedError(RuntimeError):
    """An initial guess whose rollout is no longer finite.

    Attributes:
        knot: the first knot ``k`` with a non-finite state ``X[k]`` (or control ``U[k]``).
        phase: its phase index (from 0).
        cycle: its gait cycle (counted from 1), or None when the schedule does not repeat the bounding cycle.
        time: its time [s].
    """

    def __init__(self, message: str, knot: int, phase: int, cycle: int | None, time: float) -> None:
        super().__init__(message)
        self.knot, self.phase, self.cycle, self.time = knot, phase, cycle, time


def check_warm_start(problem: HybridProblem, trajectory: Trajectory, what: str = "the warm start",
                     hint: str = "") -> Trajectory:
    """Return ``trajectory`` (a rollout on ``problem``'s knots) if it is finite, else raise
    [`WarmStartDivergedError`][WarmStartDivergedError] naming the cycle, phase, knot and time where it diverged.

    Args:
        problem: the problem whose knots, phases and cycles the message names.
        trajectory: the rollout (``X (N+1, 14)``, ``U (N, 4)``).
        what: how the message names the guess.
        hint: a sentence appended to the message.
    Raises:
        WarmStartDivergedError: ``X`` or ``U`` holds a NaN or an infinity.
    """
    k = first_non_finite_knot(trajectory.X, trajectory.U)
    if k is None:
        return trajectory
    phase = int(problem.phase_of_knot[min(k, problem.n_knots - 1)])
    cycle = problem.cycle_of_knot(k)
    where = f"in cycle {cycle}" if cycle is not None else f"in phase {phase + 1}"
    message = (f"{what} diverged {where}: X[{k}] of {problem.n_knots + 1} states is not finite "
               f"({problem.describe_knot(k)})" + (f". {hint}" if hint else ""))
    raise WarmStartDivergedError(message, k, phase, cycle, problem.knot_time(k))


def heuristic_warm_start(problem: HybridProblem, check: bool = True) -> Trajectory:
    """Roll out the heuristic bounding controller through the problem's schedule (the paper's warm start).

    Args:
        check: raise [`WarmStartDivergedError`][WarmStartDivergedError] (naming the cycle and knot) when the rollout
            diverges; with False the trajectory is returned with NaN from there on.
    Returns:
        A [`Trajectory`][hsddp_gym.core.rollout.Trajectory] (``X (N+1, 14)``, ``U (N, 4)``, ...).
    """
    controller = HeuristicBoundingController(problem.dynamics.robot)
    traj = rollout(problem.dynamics, problem.schedule, problem.x0,
                   controller=controller.as_schedule_controller(problem.schedule), restitution=problem.restitution)
    if check:
        check_warm_start(problem, traj, "the heuristic warm start",
                         f"The heuristic controller gains speed and pitches nose-down from cycle to cycle; horizons "
                         f"over {HEURISTIC_WARM_START_CYCLES} cycles are warm-started by bounding_warm_start")
    return traj


@dataclasses.dataclass
class WarmStart:
    """An initial guess for [`HSDDP.solve`][hsddp_gym.planners.optimizer.hsddp.HSDDP.solve].

    Attributes:
        trajectory: its rollout from the problem's ``x0`` (``X (N+1, 14)``, ``U (N, 4)``, ``GRF (N, 4)``, ...).
        K: ``(N, 4, 14)`` gains of the feedback law ``u = U[k] + K[k] (x - X[k])`` that made it, which the solver's
            first rollout follows (None: the open-loop controls ``U`` alone, the heuristic's warm start).
        source: ``"heuristic"`` or ``"repeated plan"``.
        seed: the solved plan whose cycle is repeated (None for ``"heuristic"``).
    """

    trajectory: Trajectory
    K: np.ndarray | None = None
    source: str = "heuristic"
    seed: Solution | None = None

    @property
    def U(self) -> np.ndarray:
        """``(N, 4)`` controls of the rollout."""
        return self.trajectory.U

    def solve_arguments(self) -> dict:
        """``U_init`` (and, with gains, ``X_init``, ``K_init``) for ``HSDDP.solve(problem, **arguments)``."""
        if self.K is None:
            return {"U_init": self.trajectory.U}
        return {"U_init": self.trajectory.U, "X_init": self.trajectory.X, "K_init": self.K}


def bounding_warm_start(problem: HybridProblem, options: SolverOptions | None = None) -> WarmStart:
    """A warm start for a bounding problem of any horizon that stays finite.

    Up to [`HEURISTIC_WARM_START_CYCLES`][HEURISTIC_WARM_START_CYCLES] cycles (and for a schedule that does not repeat
    the bounding cycle) it is the heuristic controller's rollout, [`heuristic_warm_start`][heuristic_warm_start],
    unchanged. On a longer horizon the heuristic drifts and tumbles (see
    [`HEURISTIC_WARM_START_CYCLES`][HEURISTIC_WARM_START_CYCLES]), so the guess is built from a solved plan instead:
    HS-DDP (``options``) solves the first [`HEURISTIC_WARM_START_CYCLES`][HEURISTIC_WARM_START_CYCLES] cycles from the
    heuristic's warm start; its cycles before [`REPEATED_CYCLE`][REPEATED_CYCLE] are kept and its cycle
    [`REPEATED_CYCLE`][REPEATED_CYCLE] (a bounding cycle the horizon's end does not shape) is repeated to the end of the
    horizon under its own feedback gains, ``u = U[k] + K[k] (x - X[k])``, each repetition re-anchored at the forward
    position it starts from. On the paper's problem the gains hold the rollout on a periodic bound at about 1 m/s.

    Args:
        problem: the bounding problem; a repeated cycle needs the same knots in every cycle.
        options: the solver options of the plan that is repeated (default ``SolverOptions()``).
    Returns:
        A [`WarmStart`][WarmStart]; pass ``**warm.solve_arguments()`` to the solver.
    Raises:
        WarmStartDivergedError: the guess diverges (naming the cycle and knot).
    """
    if not isinstance(problem, HybridProblem):
        raise TypeError(f"problem must be a HybridProblem, got {type(problem).__name__}")
    if options is not None and not isinstance(options, SolverOptions):
        raise TypeError(f"options must be a SolverOptions or None, got {type(options).__name__}")
    n = problem.cycle_length
    first = HEURISTIC_WARM_START_CYCLES * (n or 0)
    if n is None or problem.n_phases <= first:
        return WarmStart(heuristic_warm_start(problem))
    if any(problem.knots[i] != problem.knots[i % n] for i in range(problem.n_phases)):
        raise ValueError(f"problem must have the same knots in every cycle for a repeated-cycle warm start, got "
                         f"knots per phase {problem.knots.tolist()}")
    seed_problem = problem.sub_problem(0, first)
    seed = HSDDP(options if options is not None else SolverOptions()).solve(seed_problem,
                                                                            heuristic_warm_start(seed_problem).U)
    r0 = int(problem.phase_start[n * (REPEATED_CYCLE - 1)])
    period = int(problem.phase_start[n * REPEATED_CYCLE]) - r0
    k = np.arange(problem.n_knots)
    src = np.where(k < r0, k, r0 + (k - r0) % period)
    U_ref, X_ref, K_ref = seed.U[src], seed.X[src], seed.K[src]

    def controller(x, mode, phase, k):
        if k >= r0 and (k - r0) % period == 0:  # a repetition starts: re-anchor its forward position
            X_ref[k:k + period, 0] += x[0] - X_ref[k, 0]
        return U_ref[k] + K_ref[k] @ (x - X_ref[k])

    traj = rollout(problem.dynamics, problem.schedule, problem.x0, controller=controller,
                   restitution=problem.restitution)
    check_warm_start(problem, traj, f"the warm start (cycle {REPEATED_CYCLE} of the solved "
                     f"{HEURISTIC_WARM_START_CYCLES}-cycle plan repeated)")
    return WarmStart(traj, np.ascontiguousarray(K_ref), "repeated plan", seed)


def plan_bounding(method: str = "al-reb", cycles: int = 5, speed: float = 1.0, options: SolverOptions | None = None,
                  callbacks: list[Callback] | None = None, verbose: bool = False,
                  problem: HybridProblem | None = None) -> PlanResult:
    """Paper task 1: ``cycles`` bounding cycles, 80/72/72/72 ms, h = 1 ms, from the paper's initial state,
    warm-started by [`bounding_warm_start`][bounding_warm_start] (the heuristic controller up to
    [`HEURISTIC_WARM_START_CYCLES`][HEURISTIC_WARM_START_CYCLES] cycles, a repeated cycle of a solved plan beyond).

    Args:
        method: ``"heuristic"`` (the heuristic controller's rollout only), ``"ddp"``, ``"al"`` or ``"al-reb"``.
    Returns:
        A [`PlanResult`][PlanResult]; its summary has [`trajectory_summary`][trajectory_summary]'s fields, the
        iterations, the solve time and ``warm_start`` (``"heuristic"`` or ``"repeated plan"``), ``warm_start_time_s``.
    Raises:
        WarmStartDivergedError: the heuristic's rollout diverges (``method="heuristic"`` on a long horizon).
    """
    if method not in PLAN_METHODS:
        raise ValueError(f"method must be one of {PLAN_METHODS}, got {method!r}")
    problem = problem if problem is not None else HybridProblem.bounding(cycles, speed=speed)
    if method == "heuristic":
        warm = heuristic_warm_start(problem)
        summary = trajectory_summary(problem, warm.X, warm.X_pre, warm.U, warm.GRF)
        summary.update(method=method, al_iterations=0, ddp_iterations=0, solve_time_s=0.0,
                       time_per_ddp_iteration_s=None, status="heuristic", warm_start="heuristic")
        return PlanResult(method, problem, warm, None, summary)
    options = options if options is not None else SolverOptions()
    options = dataclasses.replace(options, method=method)
    t = time.perf_counter()
    guess = bounding_warm_start(problem, options)
    warm_time = time.perf_counter() - t
    solver = HSDDP(options, callbacks, verbose)  # compiles / loads the numba kernels outside the timing
    t = time.perf_counter()
    sol = solver.solve(problem, **guess.solve_arguments())
    elapsed = time.perf_counter() - t
    summary = trajectory_summary(problem, sol.X, sol.X_pre, sol.U, sol.GRF)
    summary.update(method=method, al_iterations=sol.al_iterations, ddp_iterations=sol.ddp_iterations,
                   solve_time_s=elapsed, time_per_ddp_iteration_s=elapsed / max(sol.ddp_iterations, 1),
                   status=sol.status, objective=sol.objective, warm_start=guess.source, warm_start_time_s=warm_time,
                   timings={k: (float(v) if not isinstance(v, int) else v) for k, v in sol.timings.items()})
    return PlanResult(method, problem, guess.trajectory, sol, summary)


def finite(x) -> bool:
    return bool(np.all(np.isfinite(x)))


Z_VELOCITY_VARIANTS = ("paper", "code")
"""Vertical-velocity references at the phase ends: 0 (the paper's text) or the authors' +-1 m/s."""


def _check_flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {value!r} ({type(value).__name__})")
    return bool(value)


def sto_problem(cycles: int = 1, durations=None, z_velocity: str = "paper", grf_tracking: bool = True,
                terminal_half: bool = True, periodic: bool = False, periodic_weight: float = 1e5) -> HybridProblem:
    """The problem of paper task 2 and its variants (see [`run_sto`][run_sto])."""
    if z_velocity not in Z_VELOCITY_VARIANTS:
        raise ValueError(f"z_velocity must be one of {Z_VELOCITY_VARIANTS}, got {z_velocity!r}")
    _check_flag(grf_tracking, "grf_tracking")
    _check_flag(terminal_half, "terminal_half")
    if _check_flag(periodic, "periodic"):
        if cycles != 1:
            raise ValueError(f"cycles must be 1 for the periodic task, got {cycles!r}")
        kw = {} if durations is None else {"durations": durations}
        return HybridProblem.bounding_periodic(periodic_weight=periodic_weight, z_velocity=z_velocity,
                                               grf_tracking=grf_tracking, terminal_half=terminal_half, **kw)
    return HybridProblem.bounding(cycles, durations=durations, z_velocity=z_velocity, grf_tracking=grf_tracking,
                                  terminal_half=terminal_half)


def gait_metrics(problem: HybridProblem, X: np.ndarray, X_pre: np.ndarray, GRF: np.ndarray, periodic: bool = False
                 ) -> dict:
    """Whether a cycle can be repeated, from a trajectory on ``problem`` (``X (N+1, 14)``, ``X_pre (n, 14)``,
    ``GRF (N, 4)``).

    Returns a dict: the vertical velocity at the start and at the end of the last phase (``X[-1]``, before
    any switch after it) [m/s]; ``mean_normal_grf``, the total normal ground force averaged over the cycle,
    and ``mean_stance_normal_grf``, averaged over the stance knots only, against the robot's ``weight`` [N];
    the landing feet's heights ``touchdown_heights`` (the paper's g, one per touchdown) [m] and their largest
    magnitude ``max_touchdown_error`` [m]; with ``periodic``, ``periodicity_error = X[-1] - x0`` without x
    (13,) and its largest position (z, pitch, joints [m, rad]) and velocity [m/s, rad/s] entries.
    """
    from hsddp_gym.core.conventions import IVZ

    robot = problem.dynamics.robot
    g = [float(robot.foot_heights(X_pre[i, :7])[foot]) for i, foot in enumerate(problem.touchdown) if foot >= 0]
    normal = GRF[:, 1] + GRF[:, 3]
    st = problem.stance_any
    p = robot.params
    out = {
        "initial_vertical_velocity": float(X[0, IVZ]),
        "final_vertical_velocity": float(X[-1, IVZ]),
        "mean_normal_grf": float(problem.h @ normal / problem.schedule.total_time),
        "mean_stance_normal_grf": float(problem.h[st] @ normal[st] / np.sum(problem.h[st])) if st.any() else 0.0,
        "weight": float(p.total_mass * p.gravity),
        "touchdown_heights": g,
        "max_touchdown_error": float(np.max(np.abs(g))) if g else 0.0,
    }
    if periodic:
        err = (X[-1] - problem.x0)[1:]
        out.update(periodicity_error=err.tolist(), max_periodicity_error_position=float(np.max(np.abs(err[:6]))),
                   max_periodicity_error_velocity=float(np.max(np.abs(err[6:]))))
    return out


def run_sto(method: str = "hsddp", iterations: int = 30, cycles: int = 1, durations=None,
            second_order: bool = False, solver_options: SolverOptions | None = None, callback=None,
            min_duration=None, max_duration=None, z_velocity: str = "paper", grf_tracking: bool = True,
            terminal_half: bool = True, periodic: bool = False, periodic_weight: float = 1e5):
    """Paper task 2: switching-time optimization of ``cycles`` bounding cycles (default: one, 80/72/72/72 ms,
    the same costs, AL parameters and heuristic warm start as task 1).

    Args:
        min_duration: lower duration bound [s] (a number or one per phase; None:
            [`hsddp_gym.planners.optimizer.sto.STOOptions`][hsddp_gym.planners.optimizer.sto.STOOptions]' default).
        max_duration: upper duration bound [s] (the same forms).
        z_velocity: vertical-velocity references at the phase ends, ``"paper"`` (0, the paper's text) or
            ``"code"`` (the authors' code: +1 m/s after a stance, -1 m/s before a touchdown).
        grf_tracking: the authors' ground-force tracking term in the running cost (the paper has none).
        terminal_half: the authors' ``1/2`` in the terminal costs (the paper's eq. 33 has none).
        periodic: the periodic task ([`HybridProblem.bounding_periodic`][HybridProblem.bounding_periodic]: five phases
            ending in the start
            state up to x, a terminal penalty of scale ``periodic_weight``); ``durations`` then has 5 entries.
        solver_options: Algorithm 1's options (e.g. ``al_max_abs_tolerance``).

    Returns:
        ``(STOResult, summary dict)``; the summary has ``initial_total_time``, ``total_time``, ``reduction``
        (fraction), ``mode_durations``, ``iterations``, ``final_cost``, ``switching_violation``, the variant
        (``z_velocity``, ``grf_tracking``, ``terminal_half``, ``periodic``), the solver's stopping tolerances,
        and [`gait_metrics`][gait_metrics] of the final solution (``touchdown_heights``, ``max_touchdown_error``, ...).
    """
    from hsddp_gym.planners.optimizer.sto import STOOptions, optimize_switching_times

    problem = sto_problem(cycles, durations, z_velocity, grf_tracking, terminal_half, periodic, periodic_weight)
    warm = heuristic_warm_start(problem)
    bounds = {k: v for k, v in (("min_duration", min_duration), ("max_duration", max_duration)) if v is not None}
    solver_options = solver_options if solver_options is not None else SolverOptions()
    opts = STOOptions(method=method, iterations=iterations, second_order=second_order, solver=solver_options,
                      **bounds)
    res = optimize_switching_times(problem, warm.U, opts, callback=callback)
    sol = res.solution
    final_problem = problem.with_durations(res.durations[-1])
    summary = {
        "method": method,
        "z_velocity": z_velocity,
        "grf_tracking": bool(grf_tracking),
        "terminal_half": bool(terminal_half),
        "periodic": bool(periodic),
        "periodic_weight": float(periodic_weight) if periodic else None,
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
        "switching_violation": sol.switching_violation,
        "al_tolerance": solver_options.al_tolerance,
        "al_max_abs_tolerance": solver_options.al_max_abs_tolerance,
        "al_iterations_final_solve": sol.al_iterations,
        "total_time_history": res.durations.sum(axis=1).tolist(),
        "cost_history": res.costs.tolist(),
        "solve_time_s": res.solve_time,
        "second_order": second_order,
    }
    summary.update(gait_metrics(final_problem, sol.X, sol.X_pre, sol.GRF, periodic))
    return res, summary


def fig8_study(problem: HybridProblem, steps, fraction: float = 0.1, solver_options: SolverOptions | None = None,
               U_warm: np.ndarray | None = None, options: STOOptions | None = None) -> dict:
    """The point and the study of paper Fig. 8 ([`step_size_study`][step_size_study]): Algorithm 1 solves ``problem``
    (from ``U_warm (N, 4)``; default the heuristic warm start), then ``fraction`` of Algorithm 2's first Newton step
    on the durations is rolled out with the feedback policy, the way Algorithm 2 moves the durations before
    Algorithm 1 re-optimizes the controls. The default tenth is about the step that Algorithm 2's line search
    accepts first on the paper's task 2; there both the control and the duration step change the objective.

    Returns [`step_size_study`][step_size_study]'s dict plus ``"z0"``, ``"z1"`` (the durations before and at the point).
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
