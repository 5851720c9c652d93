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
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.validation import check_int, check_positive

TOUCHDOWN_CLEARANCE = 0.02
""":class:`ClearancePlanTracker`: a touchdown counts only for a foot seen at least this high [m] during the current
phase."""


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


class ClearancePlanTracker(PlanTracker):
    """A :class:`PlanTracker` whose touchdowns count only for feet seen clear of the ground, optionally looping.

    A foot that has just pushed off is still flagged as touching for a moment (the flag says the ground pushed the
    foot during the last 1 ms step), and a take-off can leave a foot skimming the ground for a few ms; a flight would
    read either as an early touchdown and jump to the next stance. A touchdown therefore counts only for a foot seen
    at least ``clearance`` above ``z = 0`` during the current phase (its height from the observed state by the
    robot's kinematics; the observation has no world x, so on a terrain the heights are above the start's ground).
    Lift-offs follow plan time, late touchdowns wait on the phase's last knot, as :class:`PlanTracker`'s rule.

    With ``loop_phase`` the tracker never finishes: when the cursor would enter phase ``loop_end`` (None: at the end
    of the plan) it returns to the start of phase ``loop_phase`` instead (a phase of the same mode), so that the
    cycle ``loop_phase .. loop_end - 1`` of a plan that goes on in a steady gait is played periodically.

    The arguments are :class:`PlanTracker`'s, plus:

    Args:
        robot: the kinematics for the feet's heights (None: the default model).
        clearance: :data:`TOUCHDOWN_CLEARANCE` [m].
        loop_phase: None (finish at the end of the plan) or the phase the cursor returns to.
        loop_end: the phase whose start sends the cursor back to ``loop_phase`` (None: the end of the plan).
    """

    def __init__(self, X, U, K, phase_start, modes, phase_dt, next_mode, robot: CheetahModel | None = None,
                 clearance: float = TOUCHDOWN_CLEARANCE, loop_phase: int | None = None,
                 loop_end: int | None = None) -> None:
        super().__init__(X, U, K, phase_start, modes, phase_dt, next_mode)
        self.robot = robot if robot is not None else CheetahModel()
        self.clearance = check_positive(clearance, "clearance")
        self.loop_phase = None if loop_phase is None else check_int(loop_phase, "loop_phase", minimum=0)
        self.loop_end = None if loop_end is None else check_int(loop_end, "loop_end", minimum=1)
        if self.loop_end is not None and (self.loop_phase is None or not self.loop_phase < self.loop_end
                                          < self.n_phases):
            raise ValueError(f"loop_end must index a phase after loop_phase ({loop_phase!r}) and before "
                             f"{self.n_phases}, got {loop_end!r}")
        end_mode = self.next_modes[-1] if self.loop_end is None else self.modes[self.loop_end]
        if self.loop_phase is not None and (self.loop_phase >= self.n_phases
                                            or self.modes[self.loop_phase] != end_mode):
            raise ValueError(f"loop_phase must index a phase in [0, {self.n_phases - 1}] of the mode "
                             f"{end_mode.name} the loop ends in, got {loop_phase!r}")
        self.loops = 0
        """How many times the cursor returned to ``loop_phase``."""
        self._clear = [False, False]
        self._phase_seen = 0

    @classmethod
    def from_solution(cls, solution, problem=None, robot: CheetahModel | None = None,
                      clearance: float = TOUCHDOWN_CLEARANCE, loop_phase: int | None = None,
                      loop_end: int | None = None):
        knots = np.diff(solution.phase_start)
        phase_dt = problem.phase_dt if problem is not None else solution.schedule.durations / knots
        return cls(solution.X, solution.U, solution.K, solution.phase_start, solution.schedule.modes, phase_dt,
                   solution.schedule.final_mode, robot, clearance, loop_phase, loop_end)

    def _loop(self) -> None:
        if self.loop_phase is None:
            return
        if self.finished or (self.loop_end is not None and self.phase == self.loop_end):
            self.finished = False
            self.phase = self.loop_phase
            self.local_time = 0.0
            self.loops += 1

    def sync(self, mode: Mode, x: np.ndarray | None = None) -> None:
        """Apply the synchronization rule for the observed contact ``mode`` and state ``x (14,)`` (class docstring);
        without ``x`` no foot is seen clear, so no early touchdown counts."""
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
        if mode != plan_mode:
            early = [f for f in (0, 1) if mode.in_contact(f) and not plan_mode.in_contact(f) and self._clear[f]]
            if early and all(self.next_modes[i].in_contact(f) for f in early):
                if i + 1 < self.n_phases:
                    self.phase = i + 1
                    self.local_time = 0.0
                else:
                    self.finished = True
        self._loop()

    def advance(self, dt: float) -> None:
        """Move the cursor by ``dt`` seconds of plan time (waiting before touchdowns, looping at the end if
        ``loop_phase`` is set)."""
        super().advance(dt)
        self._loop()


class HeldPlanExpert(Policy):
    """The base of the experts that track one HS-DDP plan solved for a held control (the backflip's, the jumps'):
    ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0) with a :class:`ClearancePlanTracker`, from observations only.
    While the plan lasts it is tracked; afterwards (:attr:`holding`) :meth:`after_plan` acts (subclasses: a posture
    hold, a looped cycle never gets there).

    Args:
        solution: the plan, a :class:`~hsddp_gym.planners.optimizer.solution.Solution` (its gains for the env's
            control period); the env should start at its ``X[0]``.
        loop_phase: the tracker's ``loop_phase`` (None: the plan finishes).
        loop_end: the tracker's ``loop_end`` (None: the loop starts at the end of the plan).
    """

    plan_name = "plan"

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None, loop_phase: int | None = None,
                 loop_end: int | None = None) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError(f"solution must be a Solution (the {self.plan_name} to track)")
        self.solution = solution
        self.loop_phase = loop_phase
        self.loop_end = loop_end
        self._robot = CheetahModel()
        self._duration = float(np.sum(solution.schedule.durations))
        self.tracker: ClearancePlanTracker | None = None
        self.errors: list[float] = []
        """Per control step while tracking: :func:`tracking_error`."""
        self.reset()

    def reset(self) -> None:
        self.tracker = ClearancePlanTracker.from_solution(self.solution, robot=self._robot,
                                                          loop_phase=self.loop_phase, loop_end=self.loop_end)
        self.errors = []

    @property
    def holding(self) -> bool:
        """The plan has run out (never with ``loop_phase``)."""
        if self.loop_phase is not None:
            return False
        return self.tracker.finished or self.tracker.time >= self._duration - 1e-9

    def after_plan(self, x: np.ndarray) -> np.ndarray:
        """Torques (4,) once the plan has run out, for the observed state ``x (14,)``."""
        raise NotImplementedError

    def act(self, obs: np.ndarray) -> np.ndarray:
        x, mode, _ = self._parse(obs)
        self.tracker.sync(mode, x)
        if self.holding:
            u = self.after_plan(x)
        else:
            x_nom, _ = self.tracker.nominal()
            self.errors.append(tracking_error(x, x_nom))
            u = self.tracker.control(x)
            self.tracker.advance(self.interface.control_dt)
        return self.interface.action_from_torque(u)


__all__ = ["TOUCHDOWN_CLEARANCE", "PlanTracker", "tracking_error", "ClearancePlanTracker", "HeldPlanExpert"]
