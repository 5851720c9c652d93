"""Planning the motions of [`hsddp_gym.planners.motions.problems`][hsddp_gym.planners.motions.problems] with HS-DDP: the
limits every plan is checked against, the plans of the pronk, the gait transitions and the jumps
([`plan_motion`][plan_motion] by name), and the plans held over a control period (the experts' plans:
``plan_*_held``)."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from hsddp_gym.core.conventions import IPITCH, IVX, NQ
from hsddp_gym.core.task_constants import JUMPS, PRONK_DURATIONS
from hsddp_gym.planners.motions.problems import (
    BACKFLIP_OPTIONS,
    JOINT_LIMITS,
    MOTIONS,
    SWITCHING_TOLERANCE,
    MotionPhase,
    backflip_problem,
    jump_problem,
    motion_warm_start,
    pronk_problem,
    transition_problem,
)
from hsddp_gym.planners.optimizer.callbacks import Callback
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.metrics import trajectory_summary
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import PlanResult
from hsddp_gym.util.validation import check_int


# --------------------------------------------------------------------------------------------------- limits
def motion_limits(problem: HybridProblem, X: np.ndarray, X_pre: np.ndarray, U: np.ndarray, GRF: np.ndarray
                  ) -> dict:
    """Every limit of a planned motion, measured (``X (N+1, 14)``, ``X_pre (n, 14)``, ``U (N, 4)``, ``GRF (N, 4)``).

    Returns a dict: ``max_abs_torque`` [N m] against ``torque_limit``; ``min_normal_grf`` [N] over stance feet
    (>= 0); ``max_friction_violation`` ``max(|f_x| - mu f_z)`` over stance feet [N] (<= 0); ``hip_range``,
    ``knee_range`` ``[min, max]`` over both legs [rad] against [`JOINT_LIMITS`][JOINT_LIMITS]; ``switching_violation``
    ``sum g^2`` [m^2] (<= [`SWITCHING_TOLERANCE`][SWITCHING_TOLERANCE]) and ``max_touchdown_error`` ``max |g|`` [m];
    ``ok`` (all met) and ``violated`` (the names of those not met). On a terrain that is not flat (``problem.terrain``),
    also ``stance_knots_over_gap`` (knots at which a stance foot is over a gap, check ``gap``: 0),
    ``min_terrain_clearance`` [m] (the lowest foot above the solid terrain under it over every knot, check
    ``terrain_clearance``: ``>= -sqrt(SWITCHING_TOLERANCE)``, no foot through a box), ``landing_feet_x`` [m] (x of every
    landing foot) and ``terrain`` (its description). On a problem that keeps its knees off the ground
    (``problem.constraints.knee_clearance``, the backflip), also ``min_knee_height`` [m] (the lowest knee over every
    knot, check ``knee_clearance``: >= 0).
    """
    s = trajectory_summary(problem, X, X_pre, U, GRF)
    hips = X[:, [3, 5]]
    knees = X[:, [4, 6]]
    (h_lo, h_hi), (k_lo, k_hi) = JOINT_LIMITS
    out = {
        "torque_limit": problem.constraints.torque_limit,
        "friction": problem.constraints.friction,
        "max_abs_torque": s["max_abs_torque"],
        "min_normal_grf": s["min_normal_grf"],
        "max_friction_violation": s["max_friction_violation"],
        "hip_range": [float(hips.min()), float(hips.max())],
        "knee_range": [float(knees.min()), float(knees.max())],
        "joint_limits": [list(JOINT_LIMITS[0]), list(JOINT_LIMITS[1])],
        "switching_violation": s["switching_violation"],
        "max_touchdown_error": s["max_touchdown_error"],
        "touchdowns": len(s["touchdown_foot_heights"]),
    }
    checks = {
        "torque": out["max_abs_torque"] <= out["torque_limit"],
        "normal_force": out["min_normal_grf"] >= 0.0,
        "friction": out["max_friction_violation"] <= 0.0,
        "hip_range": h_lo <= out["hip_range"][0] and out["hip_range"][1] <= h_hi,
        "knee_range": k_lo <= out["knee_range"][0] and out["knee_range"][1] <= k_hi,
        "switching": out["switching_violation"] <= SWITCHING_TOLERANCE,
    }
    if problem.constraints.knee_clearance is not None:  # a problem that keeps its knees and lifted feet off the ground
        robot = problem.dynamics.robot
        points = np.array([robot.link_points(X[k, :NQ]) for k in range(problem.n_knots)])  # (N, 2, 4, 2)
        swing = np.where(problem.stance, np.inf, points[:, :, 2, 1])
        out["min_knee_height"] = float(points[:, :, 1, 1].min())
        out["min_swing_foot_height"] = float(swing.min())
        checks["knee_clearance"] = out["min_knee_height"] >= 0.0
        checks["swing_foot_clearance"] = out["min_swing_foot_height"] >= -math.sqrt(SWITCHING_TOLERANCE)
    terrain = problem.terrain
    if terrain is not None and not terrain.is_flat:
        # every foot at every knot [m]: the stance feet off any gap, no foot below the terrain under it
        robot = problem.dynamics.robot
        feet = np.array([robot.foot_positions(X[k, :NQ]) for k in range(problem.n_knots)])  # (N, 2, 2)
        stance = problem.stance
        over = terrain.over_gap(feet[:, :, 0]) & stance
        solid = ~terrain.over_gap(feet[:, :, 0])
        clearance = (feet[:, :, 1] - terrain.heights(feet[:, :, 0]))[solid]
        out["terrain"] = terrain.describe()
        out["stance_knots_over_gap"] = int(over.sum())
        out["min_terrain_clearance"] = float(clearance.min()) if clearance.size else float("nan")
        landing = [float(robot.foot_positions(X_pre[i, :NQ])[f, 0])
                   for i, f in zip(problem.switch_phase, problem.switch_foot) if f >= 0]
        out["landing_feet_x"] = landing
        checks["gap"] = out["stance_knots_over_gap"] == 0
        checks["terrain_clearance"] = out["min_terrain_clearance"] >= -math.sqrt(SWITCHING_TOLERANCE)
    out["violated"] = [name for name, ok in checks.items() if not ok]
    out["ok"] = not out["violated"]
    return out


# --------------------------------------------------------------------------------------------------- planning
def _plan(motion: str, problem: HybridProblem, phases: list[MotionPhase], options: SolverOptions | None,
          callbacks, verbose: bool, speed: float) -> PlanResult:
    if options is not None and not isinstance(options, SolverOptions):
        raise TypeError(f"options must be a SolverOptions or None, got {type(options).__name__}")
    options = options if options is not None else SolverOptions()
    t = time.perf_counter()
    warm = motion_warm_start(problem, phases)
    warm_time = time.perf_counter() - t
    solver = HSDDP(options, callbacks, verbose)  # compiles / loads the numba kernels outside the timing
    t = time.perf_counter()
    sol = solver.solve(problem, warm.U)
    elapsed = time.perf_counter() - t
    summary = trajectory_summary(problem, sol.X, sol.X_pre, sol.U, sol.GRF)
    summary.update(motion=motion, method=options.method, target_speed=speed,
                   modes=[m.short for m in problem.schedule.modes], final_mode=problem.schedule.final_mode.short,
                   durations=problem.schedule.durations.tolist(), gaits=[p.gait for p in phases],
                   al_iterations=sol.al_iterations, ddp_iterations=sol.ddp_iterations, solve_time_s=elapsed,
                   status=sol.status, converged=sol.converged, objective=sol.objective, warm_start="heuristic",
                   warm_start_time_s=warm_time, final_speed=float(sol.X[-1, IVX]),
                   final_max_abs_velocity=float(np.max(np.abs(sol.X[-1, NQ:]))),
                   final_pitch=float(sol.X[-1, IPITCH]), limits=motion_limits(problem, sol.X, sol.X_pre, sol.U,
                                                                               sol.GRF))
    return PlanResult(options.method, problem, warm, sol, summary)


def plan_backflip(options: SolverOptions | None = None, callbacks: list[Callback] | None = None,
                  verbose: bool = False) -> PlanResult:
    """Plan a backflip from standing at rest with HS-DDP (AL + ReB).

    Schedule: ``DS(250 ms) BS(100 ms) FL(400 ms) DS(300 ms) -> DS``
    ([`BACKFLIP_DURATIONS`][hsddp_gym.planners.motions.problems.BACKFLIP_DURATIONS]): both feet push and pitch the trunk
    nose-up, the front feet lift off, the back feet push off, a flight through ``-2 pi`` of pitch (nose-up is negative
    pitch, [`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]), a landing on both feet and a double stance that
    ends at rest. References: end of the push, both feet under the hips, pitch
    [`BACKFLIP_PITCH`][hsddp_gym.planners.motions.problems.BACKFLIP_PITCH] ``[0]`` and pitch rate
    [`BACKFLIP_PITCH_RATE`][hsddp_gym.planners.motions.problems.BACKFLIP_PITCH_RATE] ``[0]``; take-off, the back foot
    under its hip, pitch ``[1]``, pitch rate ``[1]``, vertical speed ``g T_f / 2``; touchdown, the standing posture at
    pitch ``-2 pi``, ``-g T_f / 2``; rest, standing at ``-2 pi``, every velocity 0
    ([`STOP_TERMINAL_WEIGHTS`][hsddp_gym.planners.motions.problems.STOP_TERMINAL_WEIGHTS]). The running cost also keeps
    the joints in [`JOINT_LIMITS`][JOINT_LIMITS], the knees
    [`BACKFLIP_KNEE_CLEARANCE`][hsddp_gym.planners.motions.problems.BACKFLIP_KNEE_CLEARANCE] and the lifted feet
    [`BACKFLIP_FOOT_CLEARANCE`][hsddp_gym.planners.motions.problems.BACKFLIP_FOOT_CLEARANCE] above the ground (quadratic
    penalties, ``ConstraintSpec``). Warm start: ``_FlipWarmStart`` (see [`motion_warm_start`][motion_warm_start]).

    Args:
        options: solver options (default [`BACKFLIP_OPTIONS`][BACKFLIP_OPTIONS]: AL + ReB, up to 30 DDP iterations per
            AL iteration).
    Returns:
        A [`PlanResult`][hsddp_gym.planners.tasks.PlanResult], summary as [`plan_pronk`][plan_pronk]'s; ``limits`` adds
        ``min_knee_height`` and ``min_swing_foot_height`` ([`motion_limits`][motion_limits]).
    """
    problem, phases = backflip_problem()
    return _plan("backflip", problem, phases, BACKFLIP_OPTIONS if options is None else options, callbacks, verbose,
                 0.0)


def plan_pronk(cycles: int = 4, speed: float = 1.0, durations=PRONK_DURATIONS, options: SolverOptions | None = None,
               callbacks: list[Callback] | None = None, verbose: bool = False) -> PlanResult:
    """Plan a pronk with HS-DDP (AL on the double touchdowns, ReB on torque, normal force and friction cone).

    Schedule: ``DS(T_s/2) FL (DS FL) x (cycles - 1) -> DS``, from mid stance at ``speed``
    ([`pronk_problem`][pronk_problem]).

    Args:
        cycles: pronk cycles (>= 1).
        speed: target forward speed in [`SPEED_RANGE`][hsddp_gym.core.task_constants.SPEED_RANGE] [m/s].
        durations: ``(T_s, T_f)`` double stance and flight [s] (default [`PRONK_DURATIONS`][PRONK_DURATIONS]).
        options: solver options (default ``SolverOptions()``: AL + ReB).
    Returns:
        A [`PlanResult`][hsddp_gym.planners.tasks.PlanResult] (the type of ``plan_bounding``); its summary has
        [`trajectory_summary`][hsddp_gym.planners.optimizer.metrics.trajectory_summary]'s fields, the schedule
        (``modes``, ``durations``), iterations, ``solve_time_s`` [s] and ``limits`` ([`motion_limits`][motion_limits]).
    """
    problem, phases = pronk_problem(cycles, speed, durations)
    return _plan("pronk", problem, phases, options, callbacks, verbose, float(speed))


def plan_transition(motion: str, speed: float = 1.0, cycles: int = 2, options: SolverOptions | None = None,
                    callbacks: list[Callback] | None = None, verbose: bool = False) -> PlanResult:
    """Plan a gait transition with HS-DDP (AL + ReB).

    Schedules (``c = cycles``; BS back stance, FL flight, FS front stance, DS double stance):

    * ``"stand_to_bound"``: from standing at rest, ``DS(250 ms) (BS FL FS FL) x c -> BS``; the reference speed
      ramps from ``0.4 speed`` at the end of the double stance to ``speed`` over the first two cycles;
    * ``"bound_pronk_bound"``: from the paper's initial state, ``(BS FL FS FL) x c`` whose last flight lands both
      feet, ``(DS FL) x c``, ``DS(T_s/2)`` (the front foot lifts off), ``(BS FL FS FL) x c -> BS``, all at ``speed``;
    * ``"bound_to_stop"``: from the paper's initial state, ``(BS FL FS FL) x c`` slowing from ``speed`` to
      ``0.4 speed`` whose last flight lands both feet, then ``DS(400 ms) -> DS`` ending at rest (standing
      reference, every velocity 0).

    Args:
        motion: one of [`TRANSITIONS`][hsddp_gym.core.task_constants.TRANSITIONS].
        speed: bounding speed in [`SPEED_RANGE`][hsddp_gym.core.task_constants.SPEED_RANGE] [m/s].
        cycles: bounding (and pronk) cycles per gait segment (>= 1).
        options: solver options (default ``SolverOptions()``: AL + ReB).
    Returns:
        A [`PlanResult`][hsddp_gym.planners.tasks.PlanResult], summary as [`plan_pronk`][plan_pronk]'s.
    """
    problem, phases = transition_problem(motion, speed, cycles)
    return _plan(motion, problem, phases, options, callbacks, verbose, float(speed))


def plan_jump(motion: str, speed: float = 1.0, cycles: int = 2, options: SolverOptions | None = None,
              callbacks: list[Callback] | None = None, verbose: bool = False) -> PlanResult:
    """Plan a jump from a bound with HS-DDP (AL + ReB), on a terrain
    ([`jump_terrain`][hsddp_gym.core.task_constants.jump_terrain]).

    Schedule (``c = cycles``): from the paper's initial state, ``(BS FL FS FL) x c`` at ``speed``, the jump
    ``BS(80 ms) FL(250 ms) FS(72 ms) FL(72 ms)`` (references of a bound
    [`JUMP_SPEED_FACTOR`][hsddp_gym.planners.motions.problems.JUMP_SPEED_FACTOR] times faster), ``(BS FL FS FL) x c ->
    BS`` at ``speed``:

    * ``"gap_jump"``: over a gap of [`GAP_WIDTH`][hsddp_gym.core.task_constants.GAP_WIDTH] (0.3 m); the last landings
    before it and the first after it
      have foot placement references ([`LANDING_MARGIN`][hsddp_gym.planners.motions.problems.LANDING_MARGIN]) short of
      its near edge and beyond its far edge;
    * ``"box_jump"``: onto a box of [`BOX_HEIGHT`][hsddp_gym.core.task_constants.BOX_HEIGHT] (0.1 m); the same placement
    references around its near edge,
      and every reference after the take-off [`BOX_HEIGHT`][hsddp_gym.core.task_constants.BOX_HEIGHT] higher (bounding
      on the box).

    Args:
        motion: one of [`JUMPS`][JUMPS].
        speed: bounding speed in [`SPEED_RANGE`][hsddp_gym.core.task_constants.SPEED_RANGE] [m/s].
        cycles: bounding cycles before and after the jump (>= 1).
        options: solver options (default ``SolverOptions()``: AL + ReB).
    Returns:
        A [`PlanResult`][hsddp_gym.planners.tasks.PlanResult], summary as [`plan_pronk`][plan_pronk]'s; ``limits`` adds
        the terrain's checks ([`motion_limits`][motion_limits]).
    """
    problem, phases = jump_problem(motion, speed, cycles)
    return _plan(motion, problem, phases, options, callbacks, verbose, float(speed))


def plan_motion(motion: str, speed: float = 1.0, cycles: int | None = None, options: SolverOptions | None = None,
                verbose: bool = False) -> PlanResult:
    """[`plan_pronk`][plan_pronk] (``cycles`` default 4), [`plan_transition`][plan_transition] (default 2),
    [`plan_jump`][plan_jump] (default 2) or [`plan_backflip`][plan_backflip] (no cycles, no speed) by name
    ([`MOTIONS`][MOTIONS])."""
    if motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {motion!r}")
    if motion == "pronk":
        return plan_pronk(4 if cycles is None else cycles, speed, options=options, verbose=verbose)
    if motion in JUMPS:
        return plan_jump(motion, speed, 2 if cycles is None else cycles, options=options, verbose=verbose)
    if motion == "backflip":
        return plan_backflip(options=options, verbose=verbose)
    return plan_transition(motion, speed, 2 if cycles is None else cycles, options=options, verbose=verbose)


def _solve_held(problem: HybridProblem, phases: list[MotionPhase], options: SolverOptions, hold: int):
    """``problem`` solved once from its heuristic warm start, with its gains ``K`` replaced by the held-input gains
    of the same backward pass and its controls ``U`` by their means over the held knots (``hold`` knots per
    control)."""
    from hsddp_gym.planners.optimizer.hold import held_feedforward, held_input_gains

    warm = motion_warm_start(problem, phases)
    solver = HSDDP(options)
    sol = solver.solve(problem, warm.U)
    return dataclasses.replace(sol, K=held_input_gains(solver, problem, hold),
                               U=held_feedforward(sol.U, problem.phase_start, hold))


def _check_options(options) -> None:
    if options is not None and not isinstance(options, SolverOptions):
        raise TypeError(f"options must be a SolverOptions or None, got {type(options).__name__}")


def plan_backflip_held(hold: int = 5, options: SolverOptions | None = None):
    """The backflip plan for a controller that holds each control for ``hold`` knots (the envs' 5 ms control period
    over the plan's 1 ms knots: ``hold = 5``): [`plan_backflip`][plan_backflip]'s problem, warm start and options,
    solved once; the [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] with its gains ``K`` replaced by the
    held-input gains of the same backward pass
    ([`held_input_gains`][hsddp_gym.planners.optimizer.hold.held_input_gains]) and its controls ``U`` by their means
    over the held knots ([`held_feedforward`][hsddp_gym.planners.optimizer.hold.held_feedforward]); ``hold = 1`` leaves
    the plan as solved. Its ``X`` is the solved trajectory. Used by the backflip expert
    ([`backflip_expert`][hsddp_gym.planners.policies.experts.backflip_expert])."""
    m = check_int(hold, "hold", minimum=1)
    _check_options(options)
    problem, phases = backflip_problem()
    return _solve_held(problem, phases, BACKFLIP_OPTIONS if options is None else options, m)


def plan_jump_held(motion: str, hold: int = 5, speed: float = 1.0, cycles: int = 2,
                   options: SolverOptions | None = None):
    """The plan of a jump ([`JUMPS`][JUMPS], [`plan_jump`][plan_jump]'s problem, warm start and default options) for a
    controller that holds each control for ``hold`` knots, as [`plan_backflip_held`][plan_backflip_held]: the solved
    [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] with the held-input gains and the held controls' means.
    Used by the jump expert ([`jump_expert`][hsddp_gym.planners.policies.experts.jump_expert])."""
    m = check_int(hold, "hold", minimum=1)
    _check_options(options)
    problem, phases = jump_problem(motion, speed, cycles)
    return _solve_held(problem, phases, SolverOptions() if options is None else options, m)


def plan_transition_held(motion: str, hold: int = 5, speed: float = 1.0, cycles: int = 2,
                         options: SolverOptions | None = None):
    """The plan of a gait transition ([`TRANSITIONS`][hsddp_gym.core.task_constants.TRANSITIONS],
    [`plan_transition`][plan_transition]'s problem, warm start and default options) for a controller that holds each
    control for ``hold`` knots, as [`plan_jump_held`][plan_jump_held]: the solved
    [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] with the held-input gains and the held controls' means.
    Used by the transition expert ([`transition_expert`][hsddp_gym.planners.policies.experts.transition_expert])."""
    m = check_int(hold, "hold", minimum=1)
    _check_options(options)
    problem, phases = transition_problem(motion, speed, cycles)
    return _solve_held(problem, phases, SolverOptions() if options is None else options, m)


__all__ = ["motion_limits", "plan_backflip", "plan_pronk", "plan_transition", "plan_jump", "plan_motion",
           "plan_backflip_held", "plan_jump_held", "plan_transition_held"]
