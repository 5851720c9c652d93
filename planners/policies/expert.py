"""The plan-tracking expert: an offline HS-DDP plan tracked with its feedback law, then the MPC."""

from __future__ import annotations

import numpy as np

from hsddp_gym.planners.policies.base import EnvInterface, Policy


class PlanTrackingExpert(Policy):
    """Tracks one HS-DDP plan with its feedback law ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0).

    The plan's cursor advances by the env's control period and is kept in step with the env's contact
    events by :class:`hsddp_gym.planners.policies.tracking.PlanTracker` (early touchdown: jump to the next phase; late
    touchdown: wait on the flight phase's last knot; lift-off: plan time). The plan should start at the
    env's initial state (e.g. ``options={"state": plan.X[0]}`` at reset). When the plan ends (the touchdown
    after its last flight, or its last knot) the expert hands over to ``fallback``.

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution`.
        fallback: policy used after the plan ends (None: HS-DDP MPC with default options,
            :class:`hsddp_gym.planners.policies.mpc.MPCPolicy`, which picks up the gait from the observed contacts).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, fallback: Policy | None = None
                 ) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError("solution must be a Solution (the plan to track)")
        self.solution = solution
        if fallback is None:
            from hsddp_gym.planners.policies.mpc import MPCPolicy  # hsddp_gym.planners.policies.mpc imports this module

            fallback = MPCPolicy(interface)
        self.fallback = fallback
        self.tracker = None
        self.errors: list[float] = []
        """Per control step while tracking: :func:`hsddp_gym.planners.policies.tracking.tracking_error` to the plan."""
        self.nominal_states: list[np.ndarray] = []
        """Per control step while tracking: the plan's state (14,) at the cursor the action came from."""
        self.reset()

    def _reset_copy_state(self) -> None:
        self.fallback = self.fallback.spawn()

    def reset(self) -> None:
        from hsddp_gym.planners.policies.tracking import PlanTracker

        self.tracker = PlanTracker.from_solution(self.solution)
        self.errors = []
        self.nominal_states = []
        self.fallback.reset()

    @property
    def stats(self) -> dict | None:
        """The fallback's planner statistics (replans, failures, solve times), if it has any."""
        return getattr(self.fallback, "stats", None)

    @property
    def last_solution(self):
        """The fallback's latest plan, if it plans."""
        return getattr(self.fallback, "last_solution", None)

    def act(self, obs: np.ndarray) -> np.ndarray:
        from hsddp_gym.planners.policies.tracking import tracking_error

        x, mode, _ = self._parse(obs)
        if self.tracker.finished:
            return self.fallback.act(obs)
        self.tracker.sync(mode)
        x_nom, _ = self.tracker.nominal()
        self.errors.append(tracking_error(x, x_nom))
        self.nominal_states.append(x_nom)
        u = self.tracker.control(x)
        self.tracker.advance(self.interface.control_dt)
        return self.interface.action_from_torque(u)
