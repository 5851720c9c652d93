"""Following a planned trajectory with its feedback law while the real contacts decide the phase.

A :class:`PlanTracker` holds a plan (``X (N+1, 14)``, ``U (N, 4)``, ``K (N, 4, 14)``, the phase layout and each
phase's step) and a cursor in plan time. The control at the cursor is the plan's feedback law
(paper eq. 8 with ``eps = 0``)::

    u = U[k] + K[k] (x - X[k])        (the trunk x position is not fed back: x[0] := X[k][0])

**Synchronization rule** (the robot, not the schedule, decides touchdowns):

* *Early touchdown*: when a foot is on the ground that the plan's current phase has in the air and the next
  phase has on the ground, the cursor jumps to the start of the next phase.
* *Late touchdown*: the cursor never leaves a phase that ends in a touchdown before that touchdown is seen;
  it waits on the phase's last knot (its feedback law keeps acting).
* *Lift-off* follows plan time: the plan's own controls lift the foot, so a stance phase ends on schedule
  even if the foot still reads as touching (resting feet are flagged as in contact).
* *End*: the plan is :attr:`~PlanTracker.finished` when the touchdown that ends its last phase is seen (a
  plan ending in flight), or when plan time runs out (a plan ending in stance).
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.util.validation import check_positive


class PlanTracker:
    """Cursor-based tracking of one plan.

    Args:
        X: plan states ``(N+1, 14)``.
        U: plan controls ``(N, 4)``.
        K: plan gains ``(N, 4, 14)``.
        phase_start: ``(n+1,)`` first knot of each phase.
        modes: ``(n,)`` phase modes.
        phase_dt: ``(n,)`` step of each phase [s].
        next_mode: mode after the last phase.
    """

    def __init__(self, X, U, K, phase_start, modes, phase_dt, next_mode) -> None:
        self.X = np.asarray(X, dtype=np.float64)
        self.U = np.asarray(U, dtype=np.float64)
        self.K = np.asarray(K, dtype=np.float64)
        self.phase_start = np.asarray(phase_start, dtype=np.int64)
        self.modes = tuple(Mode(m) for m in modes)
        self.phase_dt = np.asarray(phase_dt, dtype=np.float64)
        self.n_phases = len(self.modes)
        self.next_modes = self.modes[1:] + (Mode(next_mode),)
        self.phase = 0
        self.local_time = 0.0
        """Time since the start of the cursor's phase [s]."""
        self.finished = False

    @classmethod
    def from_solution(cls, solution, problem=None) -> PlanTracker:
        """Tracker of a :class:`~hsddp_gym.planners.optimizer.solution.Solution` (phase steps from ``problem`` when
        given, else ``durations / knots``)."""
        knots = np.diff(solution.phase_start)
        phase_dt = problem.phase_dt if problem is not None else solution.schedule.durations / knots
        return cls(solution.X, solution.U, solution.K, solution.phase_start, solution.schedule.modes, phase_dt,
                   solution.schedule.final_mode)

    # ------------------------------------------------------------------ cursor
    @property
    def knot(self) -> int:
        """The plan knot under the cursor."""
        i = self.phase
        n_i = self.phase_start[i + 1] - self.phase_start[i]
        j = min(int(self.local_time / self.phase_dt[i] + 1e-9), n_i - 1)
        return int(self.phase_start[i] + j)

    @property
    def time(self) -> float:
        """Plan time at the cursor [s]."""
        return float(np.sum((np.diff(self.phase_start) * self.phase_dt)[:self.phase]) + self.local_time)

    def _ends_in_touchdown(self, i: int) -> bool:
        before, after = self.modes[i], self.next_modes[i]
        return any(after.in_contact(f) and not before.in_contact(f) for f in (0, 1))

    def sync(self, mode: Mode) -> None:
        """Apply the synchronization rule for the contact ``mode`` observed now."""
        i = self.phase
        plan_mode = self.modes[i]
        if mode == plan_mode or self.finished:
            return
        early = [f for f in (0, 1) if mode.in_contact(f) and not plan_mode.in_contact(f)]
        if early and all(self.next_modes[i].in_contact(f) for f in early):
            if i + 1 < self.n_phases:
                self.phase = i + 1
                self.local_time = 0.0
            else:  # the touchdown that ends the plan: hand over (the cursor stays on the last knot)
                self.finished = True

    def advance(self, dt: float) -> None:
        """Move the cursor by ``dt`` seconds of plan time (waiting before touchdowns)."""
        dt = check_positive(dt, "dt")
        while dt > 0 and not self.finished:
            i = self.phase
            length = (self.phase_start[i + 1] - self.phase_start[i]) * self.phase_dt[i]
            remaining = length - self.local_time
            if dt < remaining - 1e-12:
                self.local_time += dt
                return
            if self._ends_in_touchdown(i):
                # wait on the last knot for the touchdown
                self.local_time = max(self.local_time, length - 0.5 * self.phase_dt[i])
                return
            dt -= remaining
            if i + 1 >= self.n_phases:
                self.local_time = length - 0.5 * self.phase_dt[i]
                self.finished = True
                return
            self.phase = i + 1
            self.local_time = 0.0

    # ------------------------------------------------------------------ control
    def control(self, x: np.ndarray) -> np.ndarray:
        """The feedback law at the cursor: torques (4,) for state ``x`` (14,)."""
        k = self.knot
        dx = np.asarray(x, dtype=np.float64) - self.X[k]
        dx[0] = 0.0
        return self.U[k] + self.K[k] @ dx

    def nominal(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x_nominal (14,), u_nominal (4,))`` at the cursor."""
        k = self.knot
        return self.X[k].copy(), self.U[k].copy()


def tracking_error(x: np.ndarray, x_nominal: np.ndarray) -> float:
    """Euclidean distance of the generalized positions ``q`` (7,) of ``x`` (14,) from those of ``x_nominal``
    (14,), the trunk x position excluded (it is not observed) [m and rad mixed, as in ``q``]."""
    d = np.asarray(x, dtype=np.float64)[1:NQ] - np.asarray(x_nominal, dtype=np.float64)[1:NQ]
    return float(np.linalg.norm(d))
