"""The motions the MPC re-plans online: each motion's reference on the MPC's knot grid, and its MPC.

[`motion_reference`][motion_reference] solves a motion's problem ([`hsddp_gym.planners.motions.problems`]
[hsddp_gym.planners.motions.problems]) on the plans' grid (semi-implicit Euler steps of ``planner_dt``, as every plan
of the MPC) and in their friction cone, with the motion's solver options, once per process and arguments. Its guess is
the motion's heuristic rollout on that grid; where that rollout diverges (the bound's heuristic is too stiff for
explicit steps of 2.5 ms), the motion solved on the experts' 1 ms grid, sampled onto the plans' knots with its feedback
law. [`motion_mpc_policy`][motion_mpc_policy] builds the
[`MotionMPCPolicy`][hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy] of a motion for an env (the ``mpc`` of a
task with a ``motion``, ``hsddp_gym.registry.Task.motion``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import NamedTuple

from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.planners.motions.problems import (
    BACKFLIP_OPTIONS,
    backflip_problem,
    jump_problem,
    motion_warm_start,
    pronk_problem,
    transition_problem,
)
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.experts import JUMP_LOOP, PRONK_LOOP_PHASE, TRANSITION_LOOPS
from hsddp_gym.planners.policies.mpc.motion import MotionMPCPolicy, MotionReference, held_knots, reference_from_solve
from hsddp_gym.planners.policies.mpc.options import MPCOptions
from hsddp_gym.planners.policies.mpc.warm_start import shift_plan
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.planners.tasks import WarmStartDivergedError
from hsddp_gym.util.validation import check_int, check_positive


class Motion(NamedTuple):
    """A motion the MPC re-plans online."""

    build: Callable
    """``(dynamics, **kwargs) -> (problem, phases)``: its problem (``kwargs``: the task's plan arguments,
    ``hsddp_gym.registry.Task.plan_kwargs``, e.g. the cycles of bounding before the stop)."""
    options: SolverOptions
    """The solver options of its reference."""
    hand_over: int | None = None
    """The phase at which the bounding MPC takes over (``MotionReference.hand_over``; None: the motion's last stance
    is held)."""
    loop_phase: int | None = None
    """A periodic gait's phase to go on at after its last (``MotionReference.loop_phase``; None: not periodic)."""


def _pronk(dynamics: HybridDynamics, cycles: int = 4, speed: float = 1.0):
    return pronk_problem(cycles, speed, dynamics=dynamics)


def _at_1_m_s(problem, name: str):
    """A builder of the motion ``name`` of ``problem`` (a jump or a gait transition) at 1 m/s (the tasks' speed)."""
    def build(dynamics: HybridDynamics, cycles: int = 2):
        return problem(name, 1.0, cycles, dynamics)
    return build


MOTION_PROBLEMS = {"backflip": Motion(backflip_problem, BACKFLIP_OPTIONS),
                   "pronk": Motion(_pronk, SolverOptions(), loop_phase=PRONK_LOOP_PHASE),
                   "gap_jump": Motion(_at_1_m_s(jump_problem, "gap_jump"), SolverOptions(), JUMP_LOOP[0]),
                   "box_jump": Motion(_at_1_m_s(jump_problem, "box_jump"), SolverOptions(), JUMP_LOOP[0]),
                   "bound_to_stop": Motion(_at_1_m_s(transition_problem, "bound_to_stop"), SolverOptions()),
                   "stand_to_bound": Motion(_at_1_m_s(transition_problem, "stand_to_bound"), SolverOptions(),
                                            TRANSITION_LOOPS["stand_to_bound"][0]),
                   "bound_pronk_bound": Motion(_at_1_m_s(transition_problem, "bound_pronk_bound"), SolverOptions(),
                                               TRANSITION_LOOPS["bound_pronk_bound"][0])}
"""The motions with an MPC, by name. The jumps and the transitions into a bound are handed to the bounding MPC at their
first steady bounding cycle (the cycle their experts loop, ``hsddp_gym.planners.policies.experts.JUMP_LOOP`` and
``TRANSITION_LOOPS``); the backflip and bound to stop end standing; the pronk is periodic from its second cycle
(``PRONK_LOOP_PHASE``, the cycle its expert loops), at the env's target speed."""


def motion_reference(name: str, planner_dt: float, hold: int, friction: float | None = None,
                     **kwargs) -> MotionReference:
    """The reference of motion ``name`` (a key of [`MOTION_PROBLEMS`][MOTION_PROBLEMS]; ``kwargs``: its problem's
    arguments) on a grid of ``planner_dt`` [s], its law for a control held over ``hold`` knots, its ground forces in a
    friction cone of ``friction`` (None: the model's; the MPC's plans: ``PlanOptions.friction``, a margin); cached per
    process and arguments.

    Raises:
        ValueError: an unknown motion. RuntimeError: the motion's solve does not converge on that grid.
    """
    if name not in MOTION_PROBLEMS:
        raise ValueError(f"name must be one of {tuple(MOTION_PROBLEMS)}, got {name!r}")
    friction = None if friction is None else float(check_positive(friction, "friction"))
    return _reference(name, float(check_positive(planner_dt, "planner_dt")), check_int(hold, "hold", minimum=1),
                      friction, tuple(sorted(kwargs.items())))


@functools.lru_cache(maxsize=8)
def _reference(name: str, planner_dt: float, hold: int, friction: float | None, kwargs: tuple) -> MotionReference:
    build, options, hand_over, loop_phase = MOTION_PROBLEMS[name]
    problem, phases = build(HybridDynamics(dt=planner_dt, integrator="semi_implicit"), **dict(kwargs))
    if friction is not None:
        problem = problem.with_constraints(dataclasses.replace(problem.constraints, friction=friction))
    solver = HSDDP(options)
    try:
        guess = {"U_init": motion_warm_start(problem, phases).U}
    except WarmStartDivergedError:
        guess = _fine_guess(problem, build(HybridDynamics(), **dict(kwargs)), options)
    solution = solver.solve(problem, **guess)
    return reference_from_solve(name, problem, solver, solution, hold, hand_over, loop_phase)


def _fine_guess(problem: HybridProblem, fine, options: SolverOptions) -> dict:
    """The motion ``fine = (problem, phases)`` on the 1 ms grid, solved from its heuristic rollout and sampled onto
    ``problem``'s knots phase by phase: ``{"U_init", "X_init", "K_init"}`` (its controls, states and feedback law)."""
    fine_problem, fine_phases = fine
    solution = HSDDP(options).solve(fine_problem, motion_warm_start(fine_problem, fine_phases).U)
    shifted = shift_plan(problem, problem.x0, PlanTracker.from_solution(solution, fine_problem), solution, None)
    if shifted is None:
        raise RuntimeError("the motion's 1 ms plan does not cover its problem on the plans' grid")
    U, X, K, _ = shifted
    return {"U_init": U, "X_init": X, "K_init": K}


def motion_mpc_policy(interface: EnvInterface, motion: str, options: MPCOptions = MPCOptions(),
                      **kwargs) -> MotionMPCPolicy:
    """The MPC of motion ``motion`` (``kwargs``: its problem's arguments) for an env of ``interface`` with ``options``
    (its reference on the grid of ``options.plan.planner_dt``, which must divide the control period, in the plans'
    friction cone, ``options.plan.friction``)."""
    if not isinstance(options, MPCOptions):
        raise TypeError(f"options must be an MPCOptions, got {type(options).__name__}")
    if not isinstance(interface, EnvInterface):
        raise TypeError(f"interface must be an EnvInterface, got {type(interface).__name__}")
    hold = held_knots(interface.control_dt, options.plan.planner_dt)
    reference = motion_reference(motion, options.plan.planner_dt, hold, options.plan.friction, **kwargs)
    return MotionMPCPolicy(interface, reference, options)


__all__ = ["Motion", "MOTION_PROBLEMS", "motion_reference", "motion_mpc_policy"]
