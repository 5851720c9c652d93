"""Touchdown rules: which observed touchdowns move a [`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker]'s
cursor to the next phase.

A touchdown is *early* when a foot is flagged on the ground that the plan's current phase has in the air and the
next phase has on the ground; the tracker then jumps to the start of the next phase (late touchdowns wait on the
phase's last knot, lift-offs follow plan time, whatever the rule). The contact flag says that the ground pushed the
foot during the last 1 ms simulation step, so it also reads "touching" for a moment after a push-off, and for a foot
that skims the ground after a take-off: a flight that ends in a stance would read either as that stance's
touchdown. A rule says which flagged feet count:

* [`ContactFlags`][ContactFlags]: every flagged foot (the MPC's plans and the bounding expert's: their flights start
from a single stance, whose lifted foot is not the landing one);
* [`SeenAirborne`][SeenAirborne]: a foot seen unflagged during the current phase, or any flagged foot once a fraction of
the phase's plan time has passed (the pronk: right after a lift-off both feet are still flagged, and a flight that
  ends in a double stance would read that as its touchdown);
* [`FootClearance`][FootClearance]: a foot seen at least a clearance above ``z = 0`` during the current phase, its
height from
  the observed state by the robot's kinematics (the backflip, the jumps, the gait transitions: the take-off leaves
  the feet skimming the ground for a few ms, the plans keep them 1 mm clear; the observation has no world x, so on a
  terrain the heights are above the start's ground).

A rule is a stateless setting: the tracker keeps, per foot, whether the current phase has shown the evidence the rule
asks for ([`TouchdownRule.evidence`][TouchdownRule.evidence]), forgotten when the phase changes.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.util.validation import check_positive

TOUCHDOWN_CLEARANCE = 0.02
"""[`FootClearance`][FootClearance]'s default: a touchdown counts only for a foot seen at least this high [m] during the
current phase."""


class TouchdownRule:
    """Base class of the touchdown rules (module docstring).

    Attributes:
        late_fraction: None, or the fraction of the current phase's plan time after which every flagged foot counts
            (evidence or not).
    """

    late_fraction: float | None = None

    def evidence(self, mode: Mode, x: np.ndarray | None) -> tuple[bool, bool]:
        """Per foot (front, back): whether the observed contact ``mode`` and state ``x (14,)`` (None: not given)
        show the foot off the ground, so that a later flag of it during the phase counts as a touchdown."""
        raise NotImplementedError


class ContactFlags(TouchdownRule):
    """Every flagged foot counts: no evidence needed
    ([`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker]'s default)."""

    def evidence(self, mode: Mode, x: np.ndarray | None) -> tuple[bool, bool]:
        return True, True

    def __repr__(self) -> str:
        return "ContactFlags()"


class SeenAirborne(TouchdownRule):
    """A flagged foot counts if it was seen unflagged during the current phase, or once ``late_fraction`` of the
    phase's plan time has passed.

    Args:
        late_fraction: in ``(0, 1]`` (0.5: half the phase).
    """

    def __init__(self, late_fraction: float = 0.5) -> None:
        late_fraction = check_positive(late_fraction, "late_fraction")
        if late_fraction > 1.0:
            raise ValueError(f"late_fraction must be in (0, 1], got {late_fraction!r}")
        self.late_fraction = late_fraction

    def evidence(self, mode: Mode, x: np.ndarray | None) -> tuple[bool, bool]:
        return not mode.in_contact(0), not mode.in_contact(1)

    def __repr__(self) -> str:
        return f"SeenAirborne(late_fraction={self.late_fraction!r})"


class FootClearance(TouchdownRule):
    """A flagged foot counts if it was seen at least ``clearance`` above the ground during the current phase (its
    height from the observed state; without a state no foot is seen clear).

    Args:
        clearance: [m] ([`TOUCHDOWN_CLEARANCE`][TOUCHDOWN_CLEARANCE]; [`plan_clearance`][plan_clearance] for a plan
            whose flights are low).
        robot: the kinematics for the feet's heights (None: the default model).

    Attributes:
        ground: the ground's height [m] in the state's frame (0: ``z = 0``; a policy with a sensor-bias estimate sets
            it to where the measurement puts the ground).
    """

    def __init__(self, clearance: float = TOUCHDOWN_CLEARANCE, robot: CheetahModel | None = None) -> None:
        self.clearance = check_positive(clearance, "clearance")
        if robot is not None and not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel or None, got {type(robot).__name__}")
        self.robot = robot if robot is not None else CheetahModel()
        self._ground = 0.0

    @property
    def ground(self) -> float:
        return self._ground

    @ground.setter
    def ground(self, value: float) -> None:
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"ground must be a finite height [m], got {value!r}")
        self._ground = value

    def evidence(self, mode: Mode, x: np.ndarray | None) -> tuple[bool, bool]:
        if x is None:
            return False, False
        heights = self.robot.foot_heights(np.asarray(x, dtype=np.float64)[:NQ]) - self.ground
        return bool(heights[0] >= self.clearance), bool(heights[1] >= self.clearance)

    def __repr__(self) -> str:
        return f"FootClearance(clearance={self.clearance!r})"


def plan_clearance(solution, robot: CheetahModel | None = None, clearance: float = TOUCHDOWN_CLEARANCE) -> float:
    """The touchdown clearance [m] for tracking ``solution``: ``clearance``, or, if lower, half the lowest over the
    phases that end in a touchdown of the peak height the landing feet reach during the phase (a touchdown counts
    only for a foot seen that clear, [`FootClearance`][FootClearance], and one landing foot seen clear is enough to move
    on). A pronk's 80 ms flights lift the feet only about 1 cm: with 2 cm no foot would ever be seen clear."""
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


__all__ = ["TOUCHDOWN_CLEARANCE", "TouchdownRule", "ContactFlags", "SeenAirborne", "FootClearance", "plan_clearance"]
