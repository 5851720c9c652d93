"""The MPC's policy between re-plans: the latest plan's feedback law, queried at the control rate.

As in MuJoCo MPC, the planner optimizes and the policy is read from the latest plan: ``u = U_k + K_k (x - X_k)`` at
the plan's cursor ([`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker]; the real contacts move the cursor
over touchdowns), projected onto the torques with which every planned stance foot pushes on the ground inside the plans'
friction cone (``min_stance_force``,
[`PushingTorques`][hsddp_gym.planners.policies.contact_consistency.PushingTorques]): far from the plan the linear law
can ask a stance leg to pull its foot off the ground or slide it. """

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.planners.policies.contact_consistency import PushingTorques
from hsddp_gym.planners.policies.mpc.ground import GroundModel
from hsddp_gym.planners.policies.mpc.planner import Plan


class FeedbackLaw:
    """The feedback law of the plan the MPC acts on (see the module docstring).

    Args:
        torque_limit: the motors' limit [N m].
        min_stance_force: the least normal force [N] of a planned stance foot (None: no projection).
        friction: the friction coefficient of the projection's cone.
        ground: the terrain (its surface normals under the feet; None terrain: flat).
        robot: the model (foot positions).

    Attributes:
        plan: the plan acted on (a [`Plan`][hsddp_gym.planners.policies.mpc.planner.Plan]; None before the first).
    """

    def __init__(self, torque_limit: float, min_stance_force: float | None, friction: float, ground: GroundModel,
                 robot) -> None:
        self.torque_limit = float(torque_limit)
        self.pushing = None if min_stance_force is None else PushingTorques(torque_limit, min_stance_force, friction)
        self.ground = ground
        self.robot = robot
        self.plan: Plan | None = None

    def sync(self, mode: Mode) -> None:
        """The phase's contact ``mode`` now: a touchdown the plan expects later moves its cursor on."""
        if self.plan is not None:
            self.plan.tracker.sync(mode)

    def control(self, x: np.ndarray) -> np.ndarray:
        """The law's torques (4,) [N m] at the cursor for the state ``x`` (14,), before the projection."""
        return self.plan.tracker.control(x)

    def saturates(self, u: np.ndarray, threshold: float) -> bool:
        """Whether the feedback term ``K_k (x - X_k)`` of the law's torques ``u`` (4,) asks any motor for more than
        ``threshold`` times the torque limit."""
        tracker = self.plan.tracker
        return bool(np.abs(u - tracker.U[tracker.knot]).max() > threshold * self.torque_limit)

    def project(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``u`` (4,) projected onto the torques with which the plan's stance feet push (unchanged in a planned
        flight or without ``min_stance_force``)."""
        tracker = self.plan.tracker
        plan_mode = tracker.modes[tracker.phase]
        if self.pushing is None or plan_mode == Mode.FLIGHT:
            return u
        terrain = self.ground.terrain
        normals = None if terrain is None else terrain.surface_normals(self.robot.foot_positions(x[:NQ])[:, 0])
        return self.pushing(x, u, plan_mode, normals)

    def advance(self, dt: float) -> None:
        """Move the cursor by ``dt`` [s] of plan time."""
        self.plan.tracker.advance(dt)


def feedback_torques(law: FeedbackLaw, x: np.ndarray, threshold: float | None, replan) -> tuple[np.ndarray, bool]:
    """The torques (4,) the MPC sends for the state ``x`` (14,): ``law``'s at its cursor, projected
    ([`FeedbackLaw.project`][FeedbackLaw.project]). When the feedback term alone asks a motor for more than
    ``threshold`` times the torque limit, the state is too far from the plan for its linearization: ``replan(x)``
    (True on success; None: no re-plan allowed now) plans again from it first, and the new plan's law acts. Returns
    ``(torques, whether a feedback re-plan was tried)``."""
    u = law.control(x)
    tried = replan is not None and threshold is not None and law.saturates(u, threshold)
    if tried and replan(x):
        u = law.control(x)
    return law.project(x, u), tried
