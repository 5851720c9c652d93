"""Following a planned trajectory with its feedback law while the real contacts decide the phase.

A [`PlanTracker`][PlanTracker] holds a plan (``X (N+1, 14)``, ``U (N, 4)``, ``K (N, 4, 14)``, the phase layout and each
phase's step) and a cursor in plan time. The control at the cursor is the plan's feedback law
(paper eq. 8 with ``eps = 0``)::

    u = U[k] + K[k] (x - X[k])        (the trunk x position is not fed back: x[0] := X[k][0])

**Synchronization rule** (the robot, not the schedule, decides touchdowns):

* *Early touchdown*: when a foot is on the ground that the plan's current phase has in the air and the next
  phase has on the ground, the cursor jumps to the start of the next phase, if the tracker's touchdown rule counts
  that foot's flag ([`hsddp_gym.planners.policies.touchdown`][hsddp_gym.planners.policies.touchdown]; the default
  [`ContactFlags`][ContactFlags] counts every flag).
* *Late touchdown*: the cursor never leaves a phase that ends in a touchdown before that touchdown is seen;
  it waits on the phase's last knot (its feedback law keeps acting).
* *Lift-off* follows plan time: the plan's own controls lift the foot, so a stance phase ends on schedule
  even if the foot still reads as touching (resting feet are flagged as in contact).
* *End*: the plan is `finished` when the touchdown that ends its last phase is seen (a
  plan ending in flight), or when plan time runs out (a plan ending in stance).
* *Cycle* (``loop_phase``): the tracker never finishes; when the cursor would enter phase ``loop_end`` (None: the
  end of the plan) it returns to the start of phase ``loop_phase`` instead (a phase of the same mode), so that the
  cycle ``loop_phase .. loop_end - 1`` of a plan that goes on in a steady gait is played periodically.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.planners.policies.touchdown import ContactFlags, TouchdownRule
from hsddp_gym.util.validation import check_int, check_positive


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
        touchdown: which flagged touchdowns count (None: [`ContactFlags`][ContactFlags], every flag).
        loop_phase: None (the plan finishes) or the phase the cursor returns to (module docstring, *Cycle*).
        loop_end: the phase whose start sends the cursor back to ``loop_phase`` (None: the end of the plan).
    """

    def __init__(self, X, U, K, phase_start, modes, phase_dt, next_mode, touchdown: TouchdownRule | None = None,
                 loop_phase: int | None = None, loop_end: int | None = None) -> None:
        self.X = np.asarray(X, dtype=np.float64)
        self.U = np.asarray(U, dtype=np.float64)
        self.K = np.asarray(K, dtype=np.float64)
        self.phase_start = np.asarray(phase_start, dtype=np.int64)
        self.modes = tuple(Mode(m) for m in modes)
        self.phase_dt = np.asarray(phase_dt, dtype=np.float64)
        self.n_phases = len(self.modes)
        self.next_modes = self.modes[1:] + (Mode(next_mode),)
        if touchdown is not None and not isinstance(touchdown, TouchdownRule):
            raise TypeError(f"touchdown must be a TouchdownRule or None, got {type(touchdown).__name__}")
        self.touchdown = touchdown if touchdown is not None else ContactFlags()
        self.loop_phase, self.loop_end = self._check_loop(loop_phase, loop_end)
        self.phase = 0
        self.local_time = 0.0
        """Time since the start of the cursor's phase [s]."""
        self.finished = False
        self.loops = 0
        """How many times the cursor returned to ``loop_phase``."""
        self._seen = [False, False]  # per foot: the touchdown rule's evidence during phase _phase_seen
        self._phase_seen = 0

    def _check_loop(self, loop_phase, loop_end) -> tuple[int | None, int | None]:
        loop_phase = None if loop_phase is None else check_int(loop_phase, "loop_phase", minimum=0)
        loop_end = None if loop_end is None else check_int(loop_end, "loop_end", minimum=1)
        if loop_end is not None and (loop_phase is None or not loop_phase < loop_end < self.n_phases):
            raise ValueError(f"loop_end must index a phase after loop_phase ({loop_phase!r}) and before "
                             f"{self.n_phases}, got {loop_end!r}")
        end_mode = self.next_modes[-1] if loop_end is None else self.modes[loop_end]
        if loop_phase is not None and (loop_phase >= self.n_phases or self.modes[loop_phase] != end_mode):
            raise ValueError(f"loop_phase must index a phase in [0, {self.n_phases - 1}] of the mode "
                             f"{end_mode.name} the loop ends in, got {loop_phase!r}")
        return loop_phase, loop_end

    @classmethod
    def from_solution(cls, solution, problem=None, touchdown: TouchdownRule | None = None,
                      loop_phase: int | None = None, loop_end: int | None = None) -> PlanTracker:
        """Tracker of a [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] (phase steps from ``problem`` when
        given, else ``durations / knots``); the other arguments are the constructor's."""
        knots = np.diff(solution.phase_start)
        phase_dt = problem.phase_dt if problem is not None else solution.schedule.durations / knots
        return cls(solution.X, solution.U, solution.K, solution.phase_start, solution.schedule.modes, phase_dt,
                   solution.schedule.final_mode, touchdown, loop_phase, loop_end)

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

    @property
    def waiting(self) -> bool:
        """Whether the cursor waits on its phase's last knot for a touchdown that has not come (a late landing)."""
        i = self.phase
        return (not self.finished and self._ends_in_touchdown(i)
                and self.local_time >= self._phase_length(i) - 0.5 * self.phase_dt[i] - 1e-12)

    def _ends_in_touchdown(self, i: int) -> bool:
        before, after = self.modes[i], self.next_modes[i]
        return any(after.in_contact(f) and not before.in_contact(f) for f in (0, 1))

    def _phase_length(self, i: int) -> float:
        return (self.phase_start[i + 1] - self.phase_start[i]) * self.phase_dt[i]

    def sync(self, mode: Mode, x: np.ndarray | None = None) -> None:
        """Apply the synchronization rule (module docstring) for the contact ``mode`` observed now and the observed
        state ``x (14,)`` (None: not given; only rules that look at the state need it)."""
        if self.finished:
            return
        if self.phase != self._phase_seen:
            self._phase_seen = self.phase
            self._seen = [False, False]
        for f, shown in enumerate(self.touchdown.evidence(mode, x)):
            if shown:
                self._seen[f] = True
        i = self.phase
        plan_mode = self.modes[i]
        if mode != plan_mode:
            late = self.touchdown.late_fraction
            late = late is not None and self.local_time >= late * self._phase_length(i)
            early = [f for f in (0, 1) if mode.in_contact(f) and not plan_mode.in_contact(f)
                     and (self._seen[f] or late)]
            if early and all(self.next_modes[i].in_contact(f) for f in early):
                if i + 1 < self.n_phases:
                    self.phase = i + 1
                    self.local_time = 0.0
                else:  # the touchdown that ends the plan: hand over (the cursor stays on the last knot)
                    self.finished = True
        self._loop()

    def carry_evidence(self, other: PlanTracker) -> None:
        """Start this tracker's first phase with the touchdown evidence ``other`` holds for its current phase (a
        re-plan that begins in the phase ``other``'s cursor is in: a foot seen clear before it still counts)."""
        self._phase_seen = self.phase
        self._seen = list(other._seen) if other._phase_seen == other.phase else [False, False]

    def advance(self, dt: float) -> None:
        """Move the cursor by ``dt`` seconds of plan time (waiting before touchdowns, returning to ``loop_phase`` at
        the end of the cycle when it is set)."""
        dt = check_positive(dt, "dt")
        while dt > 0 and not self.finished:
            i = self.phase
            length = self._phase_length(i)
            remaining = length - self.local_time
            if dt < remaining - 1e-12:
                self.local_time += dt
                break
            if self._ends_in_touchdown(i):
                # wait on the last knot for the touchdown
                self.local_time = max(self.local_time, length - 0.5 * self.phase_dt[i])
                break
            dt -= remaining
            if i + 1 >= self.n_phases:
                self.local_time = length - 0.5 * self.phase_dt[i]
                self.finished = True
                break
            self.phase = i + 1
            self.local_time = 0.0
        self._loop()

    def _loop(self) -> None:
        if self.loop_phase is None:
            return
        if self.finished or (self.loop_end is not None and self.phase == self.loop_end):
            self.finished = False
            self.phase = self.loop_phase
            self.local_time = 0.0
            self.loops += 1

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


__all__ = ["PlanTracker", "tracking_error"]
