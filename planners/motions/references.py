"""The motions the MPC re-plans online: each motion's reference on the MPC's knot grid, and its MPC.

[`motion_reference`][motion_reference] solves a motion's problem ([`hsddp_gym.planners.motions.problems`]
[hsddp_gym.planners.motions.problems]) on the plans' grid (semi-implicit Euler steps of ``planner_dt``, as every plan
of the MPC) and in their friction cone, from the motion's warm start with the motion's solver options, once per process
and arguments;
[`motion_mpc_policy`][motion_mpc_policy] builds the
[`MotionMPCPolicy`][hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy] of a motion for an env (the ``mpc`` of a
task with a ``motion``, ``hsddp_gym.registry.Task.motion``).
"""

from __future__ import annotations

import dataclasses
import functools

from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.planners.motions.problems import BACKFLIP_OPTIONS, backflip_problem, motion_warm_start
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.mpc.motion import MotionMPCPolicy, MotionReference, held_knots, reference_from_solve
from hsddp_gym.planners.policies.mpc.options import MPCOptions
from hsddp_gym.util.validation import check_int, check_positive

MOTION_PROBLEMS = {"backflip": (backflip_problem, BACKFLIP_OPTIONS)}
"""The motions with an MPC: name -> (the function ``dynamics -> (problem, phases)`` building its problem, its solver
options)."""


def motion_reference(name: str, planner_dt: float, hold: int, friction: float | None = None) -> MotionReference:
    """The reference of motion ``name`` (a key of [`MOTION_PROBLEMS`][MOTION_PROBLEMS]) on a grid of ``planner_dt``
    [s], its law for a control held over ``hold`` knots, its ground forces in a friction cone of ``friction`` (None:
    the model's; the MPC's plans: ``PlanOptions.friction``, a margin); cached per process and arguments.

    Raises:
        ValueError: an unknown motion. RuntimeError: the motion's solve does not converge on that grid.
    """
    if name not in MOTION_PROBLEMS:
        raise ValueError(f"name must be one of {tuple(MOTION_PROBLEMS)}, got {name!r}")
    friction = None if friction is None else float(check_positive(friction, "friction"))
    return _reference(name, float(check_positive(planner_dt, "planner_dt")), check_int(hold, "hold", minimum=1),
                      friction)


@functools.lru_cache(maxsize=8)
def _reference(name: str, planner_dt: float, hold: int, friction: float | None) -> MotionReference:
    build, options = MOTION_PROBLEMS[name]
    problem, phases = build(HybridDynamics(dt=planner_dt, integrator="semi_implicit"))
    if friction is not None:
        problem = problem.with_constraints(dataclasses.replace(problem.constraints, friction=friction))
    solver = HSDDP(options)
    solution = solver.solve(problem, motion_warm_start(problem, phases).U)
    return reference_from_solve(name, problem, solver, solution, hold)


def motion_mpc_policy(interface: EnvInterface, motion: str, options: MPCOptions = MPCOptions()) -> MotionMPCPolicy:
    """The MPC of motion ``motion`` for an env of ``interface`` with ``options`` (its reference on the grid of
    ``options.plan.planner_dt``, which must divide the control period, in the plans' friction cone,
    ``options.plan.friction``)."""
    if not isinstance(options, MPCOptions):
        raise TypeError(f"options must be an MPCOptions, got {type(options).__name__}")
    if not isinstance(interface, EnvInterface):
        raise TypeError(f"interface must be an EnvInterface, got {type(interface).__name__}")
    hold = held_knots(interface.control_dt, options.plan.planner_dt)
    return MotionMPCPolicy(interface, motion_reference(motion, options.plan.planner_dt, hold, options.plan.friction),
                           options)


__all__ = ["MOTION_PROBLEMS", "motion_reference", "motion_mpc_policy"]
