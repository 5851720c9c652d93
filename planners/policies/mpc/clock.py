"""The gait clock: the contact-schedule estimator's phase machine.

[`GaitClock`][GaitClock] holds the bounding phase (back stance, flight, front stance, flight, or a double stance) and
the time spent in it, a deterministic function of the observed contact modes: it is the part of the MPC's schedule
estimator ([`hsddp_gym.planners.policies.mpc.schedule`][hsddp_gym.planners.policies.mpc.schedule]) that learners rebuild
from observations alone ([`GaitClock.features`][GaitClock.features],
[`hsddp_gym.learning.features.gait_clock_features`][hsddp_gym.learning.features.gait_clock_features]). Its settings are
the clock's fields of [`ScheduleOptions`][hsddp_gym.planners.policies.mpc.options.ScheduleOptions], the one shape they
have (saved with a learner as [`GaitClock.settings`][GaitClock.settings]). """

from __future__ import annotations

import functools
import math

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, NQ, NX, Mode
from hsddp_gym.planners.policies.mpc.options import ScheduleOptions
from hsddp_gym.util.validation import check_positive, check_vector

CYCLE = (Mode.BACK_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.FLIGHT)
"""The bounding cycle's phases 0-3 (back stance, flight, front stance, flight)."""
DOUBLE_STANCE_PHASE = 4
"""`GaitClock.phase` of a double stance (outside the bounding cycle's phases 0-3)."""
CLOCK_SETTINGS = ("debounce_steps", "min_flight", "lost_stance_steps", "double_stance", "restep")
"""The fields of [`ScheduleOptions`][ScheduleOptions] the clock uses."""
_OFF = {"lost_stance_steps": 0, "double_stance": None, "restep": False}
"""The clock settings a learner saved before they existed had in effect (off)."""


class GaitClock:
    """The MPC's gait clock: the bounding phase ``phase`` (index into (back stance, flight, front stance,
    flight)) and the time ``tau`` spent in it, a deterministic function of the observation history.

    The plan's phase follows the contacts: a stance ends on time, a flight ends when its landing foot has touched
    for ``debounce_steps`` control steps (early, once ``min_flight`` of it has passed), or, from its nominal end on,
    at the landing foot's first contact step, however late (the clock never assumes a touchdown that has not
    happened); grazes of the other foot are ignored. A stance is *lost* when its
    foot, having touched, is off the ground for ``lost_stance_steps`` control steps (0: never): in the second
    half of the stance the stance ends; in the first half the clock goes back to the flight that lands that
    foot, with half of its nominal duration to go, and `resynced` is set for that update (the MPC then
    re-plans at once). With ``double_stance > 0``, a *double stance* (``phase`` =
    [`DOUBLE_STANCE_PHASE`][DOUBLE_STANCE_PHASE]) starts at a touchdown that finds the other foot on the ground: both
    feet touch and the one that touched down in the current phase, after a swing of at least ``min_flight`` of the
    flight that lands it, has touched for ``debounce_steps`` (in a flight, once ``min_flight`` of it has passed).
    It lasts ``double_stance`` seconds or until the other foot has lifted off for ``debounce_steps``, then the
    stance of the foot that landed follows (`resynced` is set when it starts); a foot still down when that
    stance starts does not start another double stance until it has lifted off and touched down again. With
    ``restep``, a *re-step*: in a flight, the foot of the stance before it that lands again (after a swing of at
    least ``min_flight`` of its flight, for ``debounce_steps``; at its first contact step when the planner has planned
    it, `restep_foot`) starts its stance again, `resynced` set, and the cycle goes on from there (without
    ``restep`` the clock waits for the landing foot whatever the other foot does). The first
    observation picks the phase from the contacts (and, in flight, the sign of the pitch rate).

    Because late touchdowns stretch the cycle, this clock drifts from the env's observation clock
    (``2 pi t / gait_period``): on seed 0 of the default env the MPC's phase slips by about 0.2 cycles per
    second, i.e. through a whole cycle in a 5 s episode. A learner that imitates the MPC needs this clock
    ([`features`][features]), which it can rebuild from the observations alone
    ([`gait_clock_features`][hsddp_gym.learning.features.gait_clock_features]).

    Args:
        durations: nominal (back stance, flight, front stance, flight) durations [s].
        dt: control period [s] (``tau`` advances by ``dt`` at every [`tick`][tick]).
        options: the clock's settings, the [`CLOCK_SETTINGS`][CLOCK_SETTINGS] fields of a ``ScheduleOptions`` (the MPC's
            own by
            default; learners that rebuild the clock from observations keep the MPC's, saved as [`settings`][settings]).
    """

    def __init__(self, durations, dt: float, options: ScheduleOptions = ScheduleOptions()) -> None:
        if isinstance(durations, str) or len(durations) != 4 or any(not (float(d) > 0) for d in durations):
            raise ValueError(f"durations must be 4 positive numbers [s], got {durations!r}")
        if not isinstance(options, ScheduleOptions):
            raise TypeError(f"options must be a ScheduleOptions, got {type(options).__name__}")
        self.durations = tuple(float(d) for d in durations)
        self.dt = check_positive(dt, "dt")
        self.options = options
        self.debounce_steps = options.debounce_steps
        self.min_flight = float(options.min_flight)
        self.lost_stance_steps = options.lost_stance_steps
        self.double_stance = float(options.double_stance or 0.0)
        """Duration [s] of a double stance entered now (0: the clock never enters one)."""
        self.restep = bool(options.restep)
        self.reset()

    def settings(self) -> dict:
        """The clock as JSON-ready values (saved with a learner): ``durations``, ``dt`` and
        [`CLOCK_SETTINGS`][CLOCK_SETTINGS]."""
        return {"durations": list(self.durations), "dt": self.dt,
                **{k: getattr(self.options, k) for k in CLOCK_SETTINGS}}

    @classmethod
    def from_settings(cls, settings: dict) -> GaitClock:
        """The clock of [`settings`][settings]. Settings saved by earlier versions load too: a clock setting they lack
        was off then (no lost stance, double stance or re-step); their ``"max_wait": None`` is ignored, any other
        ``max_wait`` refused (the clock's flights always wait for their touchdown)."""
        if not isinstance(settings, dict):
            raise TypeError(f"settings must be a dict, got {type(settings).__name__}")
        if settings.get("max_wait") is not None:
            raise ValueError(f"the gait clock's max_wait setting is not supported, got {settings['max_wait']!r}")
        missing = [k for k in ("durations", "dt") if k not in settings]
        if missing:
            raise ValueError(f"settings must hold {missing} (a GaitClock.settings() dict), got keys {sorted(settings)}")
        fields = {k: settings.get(k, _OFF.get(k)) for k in CLOCK_SETTINGS if k in settings or k in _OFF}
        if fields.get("double_stance") == 0.0:
            fields["double_stance"] = None
        return cls(tuple(settings["durations"]), settings["dt"], ScheduleOptions(**fields))

    def reset(self) -> None:
        self.phase: int | None = None
        self.tau = 0.0
        self._contact_steps = [0, 0]
        self._air_steps = [0, 0]
        self._phase_updates = 0
        """Observations since the current phase began (0 at the observation that began it)."""
        self._swing_steps = [0, 0]
        """Per foot, the observations it was in the air before its current (or last) contact began."""
        self._stance_touched = False
        self.after_double: int | None = None
        """In a double stance, the phase (0 or 2) of the single stance that follows it."""
        self.double_duration = 0.0
        """The duration [s] of the current double stance (``double_stance`` when it started)."""
        self.resynced = False
        """True when the last [`update`][update] moved the phase against the cycle (a lost stance)."""
        self.restep_foot: int | None = None
        """Set by the planner in a flight: the foot of the stance before it, when the plans put it on the ground
        again (a planned re-step, ``ScheduleOptions.restep``): with ``restep``, its first contact step then starts its
        stance. Cleared at every phase change."""

    def copy(self) -> GaitClock:
        twin = GaitClock(self.durations, self.dt, self.options)
        twin.after_double, twin.double_duration = self.after_double, self.double_duration
        twin.phase, twin.tau, twin._contact_steps = self.phase, self.tau, list(self._contact_steps)
        twin._air_steps, twin.resynced, twin._stance_touched = list(self._air_steps), self.resynced, \
            self._stance_touched
        twin._phase_updates, twin._swing_steps = self._phase_updates, list(self._swing_steps)
        twin.restep_foot = self.restep_foot
        return twin

    def update(self, mode: Mode, pitch_rate: float, elapsed=None) -> Mode:
        """Advance by the observed contact ``mode``; return the mode of the current gait phase.

        ``elapsed``: on the first observation, a function ``elapsed(phase, duration) -> float`` giving the time [s]
        already spent in the phase the observation starts (e.g. [`stance_elapsed`][stance_elapsed] of the state); None:
        0 (the phase has just begun). Ignored afterwards."""
        before = self.phase
        self._phase_updates += 1
        mode = self._update(mode, pitch_rate, elapsed)
        if self.phase != before:
            self._phase_updates = 0
            self.restep_foot = None
        return mode

    def observe(self, mode: Mode, x: np.ndarray, robot=None) -> Mode:
        """[`update`][update] from the contact ``mode`` and the state ``x`` (14,): its pitch rate, and on the first
        observation the time already spent in a stance ([`stance_elapsed`][stance_elapsed], with ``robot``, default the
        nominal model). Returns the mode of the current phase."""
        x = check_vector(x, NX, "x")
        if self.phase is None and robot is None:
            robot = nominal_robot()
        return self.update(Mode(mode), float(x[NQ + IPITCH]), elapsed=None if self.phase is not None else
                           (lambda phase, duration: stance_elapsed(robot, x, phase, duration)))

    def _update(self, mode: Mode, pitch_rate: float, elapsed) -> Mode:
        self.resynced = False
        for foot in (FRONT, BACK):
            if mode.in_contact(foot) and not self._contact_steps[foot]:
                self._swing_steps[foot] = self._air_steps[foot]
            self._contact_steps[foot] = self._contact_steps[foot] + 1 if mode.in_contact(foot) else 0
            self._air_steps[foot] = 0 if mode.in_contact(foot) else self._air_steps[foot] + 1
        if self.phase is None:
            if mode == Mode.FLIGHT:
                self.phase = 1 if pitch_rate > 0 else 3
            else:
                self.phase = 0 if mode.in_contact(BACK) and not mode.in_contact(FRONT) else (
                    2 if not mode.in_contact(BACK) else 0)
            self.tau = 0.0
            if elapsed is not None and mode != Mode.DOUBLE_STANCE:
                duration = self.durations[self.phase]
                tau = float(elapsed(self.phase, duration))
                if not (0.0 <= tau <= duration):
                    raise ValueError(f"elapsed must give a time in [0, {duration}] s for phase {self.phase}, "
                                     f"got {tau!r}")
                self.tau = tau
            return CYCLE[self.phase]
        j = self.phase
        if j == DOUBLE_STANCE_PHASE:
            # ends when the foot that does not stay has lifted off, or after its duration
            leaving = BACK if self.after_double == 2 else FRONT
            if self._air_steps[leaving] >= self.debounce_steps or self.tau >= self.double_duration - 1e-9:
                self.phase, self.tau, self.after_double = self.after_double, 0.0, None
                self._stance_touched = True
            return self.mode
        nominal = self.durations[j]
        if self.double_stance and self._double_starts(j, mode):
            # a swing foot landed while the stance foot is down (a stance, or a flight whose lift-off is late)
            self.after_double = 2 if CYCLE[j] == Mode.BACK_STANCE or j == 1 else 0
            self.double_duration = self.double_stance
            self.phase, self.tau, self.resynced = DOUBLE_STANCE_PHASE, 0.0, True
            return self.mode
        touched = False
        if CYCLE[j] == Mode.FLIGHT:
            landing = FRONT if j == 1 else BACK
            other = 1 - landing
            if self.restep and ((self.restep_foot == other and self._contact_steps[other]) or self._landed(other)):
                # a re-step: the foot of the stance before this flight is down again, its stance starts again
                self.phase, self.tau, self.resynced, self._stance_touched = (j - 1) % 4, 0.0, True, True
                return CYCLE[self.phase]
            # debounced early in the flight (a graze is not a touchdown); from its nominal end on, any contact is
            touched = self._contact_steps[landing] >= (self.debounce_steps if self.tau < nominal - 1e-9 else 1)
            advance = touched and self.tau >= self.min_flight * self.durations[j]
        else:
            stance_foot = BACK if j == 0 else FRONT
            advance = self.tau >= nominal - 1e-9
            self._stance_touched |= mode.in_contact(stance_foot)
            if (not advance and self.lost_stance_steps and self._stance_touched
                    and self._air_steps[stance_foot] >= self.lost_stance_steps):
                # the stance foot left the ground (a push, a slip): late in the stance, the stance is over;
                # early in it, the foot has to land again, so the clock goes back to the flight that lands
                # it, with half of that flight still to come
                if self.tau >= 0.5 * nominal:
                    advance = True
                else:
                    self.phase = (j - 1) % 4
                    self.tau = 0.5 * self.durations[self.phase]
                    self._stance_touched = False
                    self.resynced = True
        if advance:
            self.phase = (j + 1) % 4
            self.tau = 0.0
            # a stance that starts at its foot's touchdown has touched: if the foot bounces off, it is lost
            self._stance_touched = touched
        return CYCLE[self.phase]

    def _landed(self, foot: int) -> bool:
        """Whether ``foot`` has landed in the current phase: its contact began in this phase, after a swing of at
        least ``min_flight`` of the flight that lands it, and has lasted ``debounce_steps`` (a scuff, or a foot that
        stayed down from an earlier phase, has not)."""
        landing_flight = 1 if foot == FRONT else 3
        swung = self._swing_steps[foot] * self.dt >= self.min_flight * self.durations[landing_flight] - 1e-9
        return swung and self.debounce_steps <= self._contact_steps[foot] <= self._phase_updates

    @property
    def mode(self) -> Mode:
        """The contact mode of the current phase."""
        return Mode.DOUBLE_STANCE if self.phase == DOUBLE_STANCE_PHASE else CYCLE[self.phase]

    def _double_starts(self, j: int, mode: Mode) -> bool:
        """Whether the observation starts a double stance in phase ``j``: a touchdown in this phase finds the other
        foot on the ground. In a stance, the swing foot has touched for ``debounce_steps`` while the stance foot
        touches; in a flight (once ``min_flight`` of it has passed), the landing foot has while the foot of the
        stance before it still touches. A touchdown is a landing, as for a flight's end: the touching foot's contact
        must have begun in this phase, after a swing of at least ``min_flight`` of the flight that lands it. A foot
        that has stayed down since a double stance ended on its duration is not a new touchdown (the stance that
        follows plans its lift-off instead of one double stance after another), nor is a scuff of the foot that
        has just lifted off (it would swap the gait's order: the clock would skip the stance and flight ahead)."""
        if mode != Mode.DOUBLE_STANCE:
            return False
        if CYCLE[j] == Mode.FLIGHT:
            foot = FRONT if j == 1 else BACK
            if self.tau < self.min_flight * self.durations[j]:
                return False
        else:
            foot = FRONT if j == 0 else BACK
        return self._landed(foot)

    def tick(self) -> None:
        """One control period has passed."""
        self.tau += self.dt

    N_FEATURES = 7

    def features(self) -> np.ndarray:
        """(7,): one-hot of the phase (4), ``tau / nominal duration`` (clipped to [0, 2]) and sin, cos of the
        cycle fraction ``(start of the phase + tau) / cycle duration``; zeros before the first update."""
        f = np.zeros(self.N_FEATURES)
        if self.phase is None:
            return f
        j = self.phase
        tau = self.tau
        if j == DOUBLE_STANCE_PHASE:  # read as the start of the stance that follows
            j, tau = self.after_double, 0.0
        f[j] = 1.0
        f[4] = min(tau / self.durations[j], 2.0)
        frac = (sum(self.durations[:j]) + min(tau, self.durations[j])) / sum(self.durations)
        f[5], f[6] = math.sin(2 * math.pi * frac), math.cos(2 * math.pi * frac)
        return f


def stance_elapsed(robot, x: np.ndarray, phase: int, duration: float, min_speed: float = 0.25) -> float:
    """The time [s] already spent in bounding ``phase`` (0 back stance, 2 front stance; 0 for a flight) of nominal
    ``duration`` [s] at state ``x`` (14,), from where the stance foot is relative to its hip: a bounding stance sweeps
    its foot backward under the hip at the forward speed, symmetric about it (Raibert's neutral point), so
    ``duration / 2 - (x_foot - x_hip) / vx`` (``vx`` at least ``min_speed``), clipped to ``[0, 0.9 duration]``.
    The gait clock's start from a stance: the paper's initial state is mid back stance, not its start."""
    if CYCLE[phase] == Mode.FLIGHT:
        return 0.0
    foot = BACK if phase == 0 else FRONT
    q = x[:NQ]
    offset = float(robot.foot_positions(q)[foot, 0] - robot.hip_positions(q)[foot, 0])
    tau = 0.5 * duration - offset / max(float(x[NQ]), min_speed)
    return float(min(max(tau, 0.0), 0.9 * duration))



@functools.lru_cache(maxsize=1)
def nominal_robot():
    """The nominal robot model (built once per process)."""
    from hsddp_gym.core.model import CheetahModel

    return CheetahModel()
