"""The pronking expert: one HS-DDP pronk plan tracked with its feedback law, its middle cycles repeated.

A pronk plan (:func:`hsddp_gym.planners.motions.plan_pronk`: ``DS(T_s/2) FL (DS FL) x (cycles - 1) -> DS``) covers
``cycles`` cycles; an episode of a few seconds needs many more. :class:`PronkingExpert` tracks the plan with
``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0) and, at the touchdown that ends the plan, moves the cursor back
to the start of one of its middle double stances (``loop_phase``): the plan's steady cycles, whose touchdown and
lift-off states repeat to a few mm and mrad, are played periodically. No re-planning, no fallback.

Synchronization (:class:`PeriodicPlanTracker`) is :class:`~hsddp_gym.planners.policies.tracking.PlanTracker`'s
rule with one change the pronk needs: right after a lift-off both feet are still flagged as touching (the flag
says the ground pushed the foot during the last 1 ms step), and a flight that ends in a double stance would read
that as an early touchdown. A touchdown is therefore accepted only for a foot seen off the ground during the
flight, or once half the flight's plan time has passed.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import Mode
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.tracking import PlanTracker, tracking_error
from hsddp_gym.util.validation import check_int


class PeriodicPlanTracker(PlanTracker):
    """A :class:`~hsddp_gym.planners.policies.tracking.PlanTracker` that never finishes: at the end of the plan the
    cursor goes back to the start of phase ``loop_phase``; touchdowns count only for feet seen airborne (or after
    half the phase), see the module docstring.

    The other arguments are :class:`~hsddp_gym.planners.policies.tracking.PlanTracker`'s.

    Args:
        loop_phase: the phase the cursor returns to (a double stance that follows a flight, ``0 < loop_phase <
            n_phases``).
    """

    def __init__(self, X, U, K, phase_start, modes, phase_dt, next_mode, loop_phase: int = 2) -> None:
        super().__init__(X, U, K, phase_start, modes, phase_dt, next_mode)
        self.loop_phase = check_int(loop_phase, "loop_phase", minimum=1)
        if self.loop_phase >= self.n_phases or self.modes[self.loop_phase] != self.next_modes[-1]:
            raise ValueError(f"loop_phase must index a phase in [1, {self.n_phases - 1}] of the plan's final mode "
                             f"{self.next_modes[-1].name}, got {loop_phase!r}")
        self.loops = 0
        """How many times the cursor went back to ``loop_phase``."""
        self._airborne = [False, False]
        self._phase_seen = 0

    @classmethod
    def from_solution(cls, solution, problem=None, loop_phase: int = 2) -> PeriodicPlanTracker:
        knots = np.diff(solution.phase_start)
        phase_dt = problem.phase_dt if problem is not None else solution.schedule.durations / knots
        return cls(solution.X, solution.U, solution.K, solution.phase_start, solution.schedule.modes, phase_dt,
                   solution.schedule.final_mode, loop_phase)

    def _loop(self) -> None:
        if self.finished:
            self.finished = False
            self.phase = self.loop_phase
            self.local_time = 0.0
            self.loops += 1

    def sync(self, mode: Mode) -> None:
        """Apply the synchronization rule for the observed contact ``mode`` (module docstring)."""
        if self.phase != self._phase_seen:
            self._phase_seen = self.phase
            self._airborne = [False, False]
        for f in (0, 1):
            if not mode.in_contact(f):
                self._airborne[f] = True
        i = self.phase
        plan_mode = self.modes[i]
        length = (self.phase_start[i + 1] - self.phase_start[i]) * self.phase_dt[i]
        late_enough = self.local_time >= 0.5 * length
        early = [f for f in (0, 1) if mode.in_contact(f) and not plan_mode.in_contact(f)
                 and (self._airborne[f] or late_enough)]
        if mode != plan_mode and early and all(self.next_modes[i].in_contact(f) for f in early):
            if i + 1 < self.n_phases:
                self.phase = i + 1
                self.local_time = 0.0
            else:
                self.finished = True
        self._loop()

    def advance(self, dt: float) -> None:
        """Move the cursor by ``dt`` seconds of plan time (waiting before touchdowns, looping at the end)."""
        super().advance(dt)
        self._loop()


class PronkingExpert(Policy):
    """Tracks an HS-DDP pronk plan periodically (module docstring) from observations only.

    Args:
        solution: a :class:`~hsddp_gym.planners.optimizer.solution.Solution` of
            :func:`~hsddp_gym.planners.motions.plan_pronk` (at least 3 cycles); the env should start at its
            ``X[0]`` (``hsddp_gym/Pronking-v0`` does, up to its reset noise, when planned at its target speed).
        loop_phase: the double stance the cursor returns to after the plan's last touchdown (None: the second
            cycle's, phase 2).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, loop_phase: int | None = None
                 ) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError("solution must be a Solution (the pronk plan to track)")
        self.solution = solution
        self.loop_phase = 2 if loop_phase is None else loop_phase
        self.tracker: PeriodicPlanTracker | None = None
        self.errors: list[float] = []
        """Per control step: :func:`~hsddp_gym.planners.policies.tracking.tracking_error` to the plan."""
        self.reset()

    def reset(self) -> None:
        self.tracker = PeriodicPlanTracker.from_solution(self.solution, loop_phase=self.loop_phase)
        self.errors = []

    def act(self, obs: np.ndarray) -> np.ndarray:
        x, mode, _ = self._parse(obs)
        self.tracker.sync(mode)
        x_nom, _ = self.tracker.nominal()
        self.errors.append(tracking_error(x, x_nom))
        u = self.tracker.control(x)
        self.tracker.advance(self.interface.control_dt)
        return self.interface.action_from_torque(u)


__all__ = ["PeriodicPlanTracker", "PronkingExpert"]
