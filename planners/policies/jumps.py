"""The jump experts: an HS-DDP jump plan (over a gap, onto a box) tracked with its feedback law, its last steady
bounding cycle repeated after the plan.

:class:`JumpExpert` tracks a jump plan (``hsddp_gym.planners.motions.plan_jump_held``: from the paper's initial
state two bounding cycles at 1 m/s, the jump ``BS(80 ms) FL(250 ms) FS(72 ms) FL(72 ms)`` and two bounding cycles on
the far side, with the feedback gains of a control held for the env's 5 ms control period) with ``u = U_k + K_k
(x - X_k)`` (paper eq. 8, eps = 0, the trunk's x not fed back). The observation has no world x: the expert, like the
plan, places its feet by time, so the env must put the terrain where the plan has it (``hsddp_gym/GapJump-v0`` and
``hsddp_gym/BoxJump-v0`` do). Synchronization is the backflip's
(:class:`~hsddp_gym.planners.policies.tracking.ClearancePlanTracker`: touchdowns count for feet seen 2 cm clear of
the ground; lift-offs follow plan time; late touchdowns wait on the phase's last knot). The first bounding cycle after
the jump (phases :data:`LOOP_PHASE` to :data:`LOOP_END` - 1) is then played periodically: at the touchdown that ends
it the cursor returns to its back stance, so the robot bounds on over the far side with the plan's own gains. The
plan's last cycle is never played: it ends on a terminal cost, not on a periodic state (its landing is about 5 cm
lower than the cycle's), and a loop from there starts every cycle 0.3 rad of joint error off the plan (twice the
tracking error, and the trunk sagging to 0.15 m in the MuJoCo twin). No re-planning.
"""

from __future__ import annotations

from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.tracking import HeldPlanExpert

LOOP_PHASE = 12
"""The phase the cursor returns to: the back stance of the first bounding cycle after the jump (two cycles of 4
phases, then the jump's 4 phases: phases 12-15 are a steady cycle on the far side)."""
LOOP_END = 16
"""The phase whose start (the back foot's touchdown that ends the cycle) sends the cursor back to :data:`LOOP_PHASE`:
the start of the plan's last cycle."""


class JumpExpert(HeldPlanExpert):
    """Tracks an HS-DDP jump plan (module docstring) from observations only, then bounds on with its cycle after
    the jump (:class:`~hsddp_gym.planners.policies.tracking.HeldPlanExpert` with a looping tracker).

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution` of a jump
            (``hsddp_gym.planners.motions.plan_jump_held`` with ``hold`` = control period / 1 ms); the env should
            start at its ``X[0]`` over the plan's terrain.
        loop_phase: the phase the cursor returns to (None: :data:`LOOP_PHASE`).
        loop_end: the phase whose start sends it back (None: :data:`LOOP_END`).
    """

    plan_name = "jump plan"

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, loop_phase: int | None = None,
                 loop_end: int | None = None) -> None:
        super().__init__(interface, solution, LOOP_PHASE if loop_phase is None else loop_phase,
                         LOOP_END if loop_end is None else loop_end)


__all__ = ["LOOP_PHASE", "LOOP_END", "JumpExpert"]
