"""The gait-transition experts: an HS-DDP transition plan tracked with its feedback law, then its bounding cycle
repeated (stand to bound; bound, pronk, bound) or its last posture held (bound to stop).

:class:`TransitionExpert` tracks a transition plan (``hsddp_gym.planners.motions.plan_transition_held``: 1 m/s, two
cycles per gait segment, with the feedback gains of a control held for the env's 5 ms control period) with ``u = U_k
+ K_k (x - X_k)`` (paper eq. 8, eps = 0, the trunk's x not fed back), synchronized as the jumps' and the backflip's
experts (:class:`~hsddp_gym.planners.policies.tracking.ClearancePlanTracker`: touchdowns count for feet seen 2 cm
clear of the ground; lift-offs follow plan time; late touchdowns wait on the phase's last knot). After the plan
(:data:`LOOPS`):

* ``"stand_to_bound"``: the first bounding cycle at 1 m/s (phases 5-8 of a plan with a third cycle,
  :data:`PLAN_CYCLES`) is played periodically (looping the plan's last cycle, which ends on a terminal cost, not on a
  periodic state, falls within two loops);
* ``"bound_pronk_bound"``: the first bounding cycle after the pronk (phases 13-16) is played periodically, as the
  jumps' expert loops its first cycle after the jump (the plan's last cycle ends on a terminal cost);
* ``"bound_to_stop"``: the plan's last control plus a joint PD to its last knot's joint angles, the backflip
  expert's hold (:meth:`~hsddp_gym.planners.policies.backflip.BackflipExpert.after_plan`).

Touchdowns: the pronk's 80 ms flights lift the feet only about 1 cm (the plan's), so no foot is ever seen 2 cm
clear during them, no touchdown counts and the cursor waits on the flight's last knot while the robot, landed,
sinks (a fall after the first pronk flight). The expert's tracker therefore takes a clearance from its plan
(:func:`plan_clearance`): ``TOUCHDOWN_CLEARANCE`` (2 cm) or, if lower, half the lowest peak height the landing
feet reach during a flight of the plan (a few mm for the pronk; the bound's flights keep 2 cm).

No re-planning.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies.backflip import HOLD_KD, HOLD_KP, BackflipExpert
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.tracking import TOUCHDOWN_CLEARANCE, ClearancePlanTracker, HeldPlanExpert
from hsddp_gym.util.validation import check_positive

LOOPS = {"stand_to_bound": (5, 9), "bound_pronk_bound": (13, 17), "bound_to_stop": (None, None)}
"""Per task, the tracker's ``(loop_phase, loop_end)`` (``(None, None)``: the plan finishes, then the hold)."""
PLAN_CYCLES = {"stand_to_bound": 3, "bound_pronk_bound": 2, "bound_to_stop": 2}
"""Per task, the plan's cycles per gait segment (``plan_transition_held(task, hold, cycles=...)``): stand to bound
plans a third cycle at 1 m/s so that the looped cycle (phases 5-8) is not the plan's last (its schedule and speed
profile are those of the two-cycle plan with its last cycle repeated, what the env rewards)."""


def plan_clearance(solution, robot: CheetahModel | None = None, clearance: float = TOUCHDOWN_CLEARANCE) -> float:
    """The touchdown clearance [m] for tracking ``solution``: ``clearance``, or, if lower, half the lowest over the
    phases that end in a touchdown of the peak height the landing feet reach during the phase (a touchdown counts
    only for a foot seen that clear, :class:`~hsddp_gym.planners.policies.tracking.ClearancePlanTracker`, and one
    landing foot seen clear is enough to move on)."""
    robot = robot if robot is not None else CheetahModel()
    modes = [Mode(m) for m in solution.schedule.modes]
    nxt = modes[1:] + [Mode(solution.schedule.final_mode)]
    peaks = []
    for i, (before, after) in enumerate(zip(modes, nxt)):
        lo, hi = int(solution.phase_start[i]), int(solution.phase_start[i + 1])
        landing = [f for f in (0, 1) if after.in_contact(f) and not before.in_contact(f)]
        if landing:
            heights = np.array([robot.foot_heights(solution.X[k, :NQ]) for k in range(lo, hi + 1)])
            peaks.append(float(heights[:, landing].max()))
    return float(min([clearance] + [0.5 * p for p in peaks]))


class TransitionExpert(HeldPlanExpert):
    """Tracks an HS-DDP transition plan (module docstring) from observations only, then loops its bounding cycle or
    holds its last posture (:class:`~hsddp_gym.planners.policies.tracking.HeldPlanExpert`).

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution` of ``task``
            (``hsddp_gym.planners.motions.plan_transition_held`` with ``hold`` = control period / 1 ms); the env
            should start at its ``X[0]`` (the transition envs do, up to their reset noise).
        task: ``"stand_to_bound"``, ``"bound_pronk_bound"`` or ``"bound_to_stop"`` (:data:`LOOPS`).
        hold_kp: joint stiffness of the hold after the stop's plan [N m/rad] (the backflip's ``HOLD_KP``).
        hold_kd: joint damping of that hold [N m s/rad] (the backflip's ``HOLD_KD``).
    """

    plan_name = "transition plan"
    after_plan = BackflipExpert.after_plan

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, task: str = "stand_to_bound",
                 hold_kp: float = HOLD_KP, hold_kd: float = HOLD_KD) -> None:
        if task not in LOOPS:
            raise ValueError(f"task must be one of {tuple(LOOPS)}, got {task!r}")
        self.task = task
        self.hold_kp = check_positive(hold_kp, "hold_kp", allow_zero=True)
        self.hold_kd = check_positive(hold_kd, "hold_kd", allow_zero=True)
        self.clearance = plan_clearance(solution) if solution is not None else TOUCHDOWN_CLEARANCE
        super().__init__(interface, solution, *LOOPS[task])
        self._x_end = np.asarray(solution.X[-1], dtype=np.float64).copy()
        self._u_end = np.asarray(solution.U[-1], dtype=np.float64).copy()


    def reset(self) -> None:
        self.tracker = ClearancePlanTracker.from_solution(self.solution, robot=self._robot, clearance=self.clearance,
                                                          loop_phase=self.loop_phase, loop_end=self.loop_end)
        self.errors = []


__all__ = ["LOOPS", "PLAN_CYCLES", "plan_clearance", "TransitionExpert"]
