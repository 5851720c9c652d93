"""The backflip expert: the HS-DDP backflip plan tracked with its feedback law, then a standing hold.

:class:`BackflipExpert` tracks a backflip plan (``hsddp_gym.planners.motions.plan_backflip_held``: ``DS(250 ms)
BS(100 ms) FL(400 ms) DS(300 ms)`` with the feedback gains of a control held for the env's 5 ms control period)
with ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0). When the plan runs out (its last double stance ends at rest,
pitch ``-2 pi``) it holds the plan's last posture: the plan's last control plus a joint PD to the last knot's joint
angles (:data:`HOLD_KP`, :data:`HOLD_KD`). No re-planning.

Synchronization (:class:`FlipPlanTracker`, a :class:`~hsddp_gym.planners.policies.tracking.ClearancePlanTracker`,
shared with the jumps' expert) is :class:`~hsddp_gym.planners.policies.tracking.PlanTracker`'s rule with one change
the flip needs: a foot that has just pushed off is still flagged as touching for a moment (the flag says the ground
pushed the foot during the last 1 ms step), and the take-off leaves the back feet skimming the ground for a few ms
(the plan keeps them 1 mm clear); a flight that ends in a double stance would read either as an early touchdown and
jump to the landing. A touchdown therefore counts only for a foot seen at least :data:`TOUCHDOWN_CLEARANCE` above
the ground during the current phase (its height from the observed state by the robot's kinematics). Lift-offs follow
plan time, late touchdowns wait on the phase's last knot, as before.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.tracking import TOUCHDOWN_CLEARANCE, ClearancePlanTracker, HeldPlanExpert
from hsddp_gym.util.validation import check_positive

HOLD_KP = 50.0
"""Joint stiffness [N m/rad] of the hold after the plan."""
HOLD_KD = 0.8
"""Joint damping [N m s/rad] of the hold after the plan (the feet on the ground carry the trunk, so more than a
swinging leg's 0.4 at 200 Hz is stable)."""


class FlipPlanTracker(ClearancePlanTracker):
    """The backflip's tracker: a :class:`~hsddp_gym.planners.policies.tracking.ClearancePlanTracker` that finishes at
    the end of the plan (module docstring); :meth:`sync` takes the observed state as well as the contact mode."""


class BackflipExpert(HeldPlanExpert):
    """Tracks an HS-DDP backflip plan (module docstring) from observations only, then holds its last posture
    (:class:`~hsddp_gym.planners.policies.tracking.HeldPlanExpert`).

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution` of the backflip
            (``hsddp_gym.planners.motions.plan_backflip_held`` with ``hold`` = control period / 1 ms); the env
            should start at its ``X[0]`` (``hsddp_gym/Backflip-v0`` does, up to its reset noise).
        hold_kp: joint stiffness of the hold [N m/rad] (:data:`HOLD_KP`).
        hold_kd: joint damping of the hold [N m s/rad] (:data:`HOLD_KD`).
    """

    plan_name = "backflip plan"

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, hold_kp: float = HOLD_KP,
                 hold_kd: float = HOLD_KD) -> None:
        self.hold_kp = check_positive(hold_kp, "hold_kp", allow_zero=True)
        self.hold_kd = check_positive(hold_kd, "hold_kd", allow_zero=True)
        super().__init__(interface, solution)
        self._x_end = np.asarray(solution.X[-1], dtype=np.float64).copy()
        self._u_end = np.asarray(solution.U[-1], dtype=np.float64).copy()

    def reset(self) -> None:
        self.tracker = FlipPlanTracker.from_solution(self.solution, robot=self._robot)
        self.errors = []

    def after_plan(self, x: np.ndarray) -> np.ndarray:
        """The plan's last control plus a joint PD to its last knot's joint angles."""
        return self._u_end + self.hold_kp * (self._x_end[3:NQ] - x[3:NQ]) - self.hold_kd * x[NQ + 3:]


__all__ = ["TOUCHDOWN_CLEARANCE", "HOLD_KP", "HOLD_KD", "FlipPlanTracker", "BackflipExpert"]
