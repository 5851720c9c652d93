"""The backflip expert: the HS-DDP backflip plan tracked with its feedback law, then a standing hold.

:class:`BackflipExpert` tracks a backflip plan (``hsddp_gym.planners.motions.plan_backflip_held``: ``DS(250 ms)
BS(100 ms) FL(400 ms) DS(300 ms)`` with the feedback gains of a control held for the env's 5 ms control period)
with ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0). When the plan runs out (its last double stance ends at rest,
pitch ``-2 pi``) it holds the plan's last posture: the plan's last control plus a joint PD to the last knot's joint
angles (:data:`HOLD_KP`, :data:`HOLD_KD`). No re-planning.

Synchronization (:class:`FlipPlanTracker`) is :class:`~hsddp_gym.planners.policies.tracking.PlanTracker`'s rule with
one change the flip needs: a foot that has just pushed off is still flagged as touching for a moment (the flag says
the ground pushed the foot during the last 1 ms step), and the take-off leaves the back feet skimming the ground for a
few ms (the plan keeps them 1 mm clear); a flight that ends in a double stance would read either as an early
touchdown and jump to the landing. A touchdown therefore counts only for a foot seen at least
:data:`TOUCHDOWN_CLEARANCE` above the ground during the current phase (its height from the observed state by the
robot's kinematics). Lift-offs follow plan time, late touchdowns wait on the phase's last knot, as before.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.tracking import PlanTracker, tracking_error
from hsddp_gym.util.validation import check_positive

TOUCHDOWN_CLEARANCE = 0.02
"""A touchdown counts only for a foot seen at least this high [m] during the current phase."""
HOLD_KP = 50.0
"""Joint stiffness [N m/rad] of the hold after the plan."""
HOLD_KD = 0.8
"""Joint damping [N m s/rad] of the hold after the plan (the feet on the ground carry the trunk, so more than a
swinging leg's 0.4 at 200 Hz is stable)."""


class FlipPlanTracker(PlanTracker):
    """A :class:`~hsddp_gym.planners.policies.tracking.PlanTracker` whose touchdowns count only for feet seen clear of
    the ground (module docstring); :meth:`sync` takes the observed state as well as the contact mode.

    The arguments are :class:`~hsddp_gym.planners.policies.tracking.PlanTracker`'s, plus:

    Args:
        robot: the kinematics for the feet's heights (None: the default model).
        clearance: :data:`TOUCHDOWN_CLEARANCE` [m].
    """

    def __init__(self, X, U, K, phase_start, modes, phase_dt, next_mode, robot: CheetahModel | None = None,
                 clearance: float = TOUCHDOWN_CLEARANCE) -> None:
        super().__init__(X, U, K, phase_start, modes, phase_dt, next_mode)
        self.robot = robot if robot is not None else CheetahModel()
        self.clearance = check_positive(clearance, "clearance")
        self._clear = [False, False]
        self._phase_seen = 0

    @classmethod
    def from_solution(cls, solution, problem=None, robot: CheetahModel | None = None,
                      clearance: float = TOUCHDOWN_CLEARANCE) -> FlipPlanTracker:
        knots = np.diff(solution.phase_start)
        phase_dt = problem.phase_dt if problem is not None else solution.schedule.durations / knots
        return cls(solution.X, solution.U, solution.K, solution.phase_start, solution.schedule.modes, phase_dt,
                   solution.schedule.final_mode, robot, clearance)

    def sync(self, mode: Mode, x: np.ndarray | None = None) -> None:
        """Apply the synchronization rule for the observed contact ``mode`` and state ``x (14,)`` (module
        docstring); without ``x`` no foot is seen clear, so no early touchdown counts."""
        if self.finished:
            return
        if self.phase != self._phase_seen:
            self._phase_seen = self.phase
            self._clear = [False, False]
        if x is not None:
            heights = self.robot.foot_heights(np.asarray(x, dtype=np.float64)[:NQ])
            for f in (0, 1):
                if heights[f] >= self.clearance:
                    self._clear[f] = True
        i = self.phase
        plan_mode = self.modes[i]
        if mode == plan_mode:
            return
        early = [f for f in (0, 1) if mode.in_contact(f) and not plan_mode.in_contact(f) and self._clear[f]]
        if early and all(self.next_modes[i].in_contact(f) for f in early):
            if i + 1 < self.n_phases:
                self.phase = i + 1
                self.local_time = 0.0
            else:
                self.finished = True


class BackflipExpert(Policy):
    """Tracks an HS-DDP backflip plan (module docstring) from observations only, then holds its last posture.

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution` of the backflip
            (``hsddp_gym.planners.motions.plan_backflip_held`` with ``hold`` = control period / 1 ms); the env
            should start at its ``X[0]`` (``hsddp_gym/Backflip-v0`` does, up to its reset noise).
        hold_kp: joint stiffness of the hold [N m/rad] (:data:`HOLD_KP`).
        hold_kd: joint damping of the hold [N m s/rad] (:data:`HOLD_KD`).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, hold_kp: float = HOLD_KP,
                 hold_kd: float = HOLD_KD) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError("solution must be a Solution (the backflip plan to track)")
        self.solution = solution
        self.hold_kp = check_positive(hold_kp, "hold_kp", allow_zero=True)
        self.hold_kd = check_positive(hold_kd, "hold_kd", allow_zero=True)
        self._robot = CheetahModel()
        self._x_end = np.asarray(solution.X[-1], dtype=np.float64).copy()
        self._u_end = np.asarray(solution.U[-1], dtype=np.float64).copy()
        self._duration = float(np.sum(solution.schedule.durations))
        self.tracker: FlipPlanTracker | None = None
        self.errors: list[float] = []
        """Per control step while tracking: :func:`~hsddp_gym.planners.policies.tracking.tracking_error`."""
        self.reset()

    def reset(self) -> None:
        self.tracker = FlipPlanTracker.from_solution(self.solution, robot=self._robot)
        self.errors = []

    @property
    def holding(self) -> bool:
        """The plan has run out: the expert holds its last posture."""
        return self.tracker.finished or self.tracker.time >= self._duration - 1e-9

    def act(self, obs: np.ndarray) -> np.ndarray:
        x, mode, _ = self._parse(obs)
        self.tracker.sync(mode, x)
        if self.holding:
            u = self._u_end + self.hold_kp * (self._x_end[3:NQ] - x[3:NQ]) - self.hold_kd * x[NQ + 3:]
        else:
            x_nom, _ = self.tracker.nominal()
            self.errors.append(tracking_error(x, x_nom))
            u = self.tracker.control(x)
            self.tracker.advance(self.interface.control_dt)
        return self.interface.action_from_torque(u)


__all__ = ["TOUCHDOWN_CLEARANCE", "HOLD_KP", "HOLD_KD", "FlipPlanTracker", "BackflipExpert"]
