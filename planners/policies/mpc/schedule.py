"""The contact-schedule estimator: the current contact phase from the state and the contact flags, and the phases
ahead.

A plan is a contact schedule ([`ModeSchedule`][hsddp_gym.core.schedule.ModeSchedule]) from the current state. The
nominal bounding cycle says which phases come and how long they last; a robot that is pushed, lands late on a stiff
contact, loses a stance foot or lands on both feet does not follow it.
[`ContactScheduleEstimator`][ContactScheduleEstimator] keeps the schedule consistent with the state, in three steps that
every control step and every re-plan go through:

1. **Contact evidence** ([`evidence`][ContactScheduleEstimator.evidence]): which feet are on the ground. The flags say
it, sampled at the end of each control step; from a flight's nominal end on, its landing foot that the state puts
   within ``touchdown_height`` of the ground (once the feet have calibrated where the measurement puts the ground) is
   on it too: on a stiff contact a landing foot can bounce at the control rate and never be flagged.
2. **The phase** ([`GaitClock`][hsddp_gym.planners.policies.mpc.clock.GaitClock]): the evidence moves the phase on its
   events. A touchdown ends a flight (debounced early, at once when late); a stance whose foot has left the ground is
   lost (``lost_stance_steps``); a touchdown that finds the other foot down starts a double stance
   (``double_stance``); the foot of the stance before a flight that lands again starts that stance again (``restep``).
3. **The phases ahead** ([`schedule`][ContactScheduleEstimator.schedule]): the current phase for the rest of its nominal
   duration (at least ``min_phase``); a flight lasts at least until its landing hip, the trunk flying ballistically,
   is within ``flight_reach`` leg lengths of the ground, and is planned as a second step of the other foot when that
   hip leaves reach while the other comes within it (``restep``); then the bounding cycle until ``horizon`` is
   covered. Before the feet have measured where the ground is, a late flight's plans lower the ground its landing
   foot is to meet at ``ground_search_speed`` ([`plan_height`][ContactScheduleEstimator.plan_height]).

Over an action delay the phase is advanced on a copy of the clock with the contacts the state estimator predicts
([`predict`][ContactScheduleEstimator.predict]): the schedule is for the state at which the plan's first action will
act. """

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IZ, NQ, Mode
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.planners.policies.estimation import MeasurementBias, terrain_clearance
from hsddp_gym.planners.policies.mpc.clock import CYCLE, DOUBLE_STANCE_PHASE, GaitClock, stance_elapsed
from hsddp_gym.planners.policies.mpc.ground import GroundModel
from hsddp_gym.planners.policies.mpc.options import PlanOptions, ScheduleOptions


def late_landing(clock: GaitClock, mode: Mode, x: np.ndarray, robot, touchdown_height: float | None,
                 terrain=None, ground_offset=None) -> Mode:
    """``mode`` with the landing foot of a late flight added when the state ``x`` (14,) puts it within
    ``touchdown_height`` [m] of the ground (None: ``mode`` as it is): the plane ``z = 0``, or with a ``terrain``
    (the state in the world frame) its surface under the foot, raised by ``ground_offset(q, foot)`` [m] (where the
    measurement puts a foot on the ground,
    [`MeasurementBias.ground_offset`][hsddp_gym.planners.policies.estimation.MeasurementBias.ground_offset]; None: 0),
    evaluated only for a late flight's landing foot.

    A contact flag is a sample: it says whether the foot pushed on the ground at the end of the control step. On a
    stiff contact a landing foot can touch and leave within every step, so no flag ever reports the touchdown, the
    clock waits in the flight and the plans keep the leg in its touchdown posture while the trunk sinks. From the
    flight's nominal end on, a landing foot at the ground is taken for the touchdown the flags missed; before it the
    flags alone decide (a foot swung low is not a landing)."""
    if touchdown_height is None or clock.phase not in (1, 3):
        return mode
    if clock.tau < clock.durations[clock.phase] - 1e-9:
        return mode
    landing = FRONT if clock.phase == 1 else BACK
    if mode.in_contact(landing):
        return mode
    offset = 0.0 if ground_offset is None else float(ground_offset(x[:NQ], landing))
    if terrain_clearance(robot, x[:NQ], landing, terrain) - offset < touchdown_height:
        return Mode(int(mode) | (1 << landing))
    return mode


class ContactScheduleEstimator:
    """The current and the next contact phases of the MPC's plans (see the module docstring).

    Args:
        durations: the nominal (back stance, flight, front stance, flight) durations [s].
        control_dt: the control period [s].
        options: [`ScheduleOptions`][hsddp_gym.planners.policies.mpc.options.ScheduleOptions].
        plan: [`PlanOptions`][hsddp_gym.planners.policies.mpc.options.PlanOptions] (``horizon``, ``planner_dt``,
            ``min_phase``).
        robot: the model (leg length, hip offset, kinematics).
        ground: the terrain the feet are measured from
            ([`GroundModel`][hsddp_gym.planners.policies.mpc.ground.GroundModel]).

    Attributes:
        clock: the phase of the observed state. plan_clock: the phase of the state a plan starts from (``clock``
            advanced over the action delay).
        restep_foot: the foot (``FRONT`` or ``BACK``) the latest schedule plans a second step with (None: none).
    """

    def __init__(self, durations, control_dt: float, options: ScheduleOptions, plan: PlanOptions, robot,
                 ground: GroundModel) -> None:
        self.options = options
        self.durations = tuple(float(d) for d in durations)
        self.horizon = plan.horizon if plan.horizon is not None else float(sum(self.durations))
        self.planner_dt = plan.planner_dt
        self.min_phase = plan.min_phase
        self.robot = robot
        self.ground = ground
        self.clock = GaitClock(self.durations, control_dt, options)
        # times [s] at which the landing hip's reach is looked for: the plan's knots over its horizon
        self._reach_grid = np.arange(0.0, self.horizon + 0.5 * plan.planner_dt, plan.planner_dt)
        self.reset()

    def reset(self) -> None:
        self.clock.reset()
        self.plan_clock = self.clock
        self.restep_foot: int | None = None

    # ------------------------------------------------------------------ 1 and 2: evidence and phase
    def evidence(self, x: np.ndarray, mode: Mode, bias: MeasurementBias | None) -> Mode:
        """The feet on the ground: the flags' ``mode`` and a late flight's landing foot at the ground (step 1). The
        state says where a foot is relative to the ground once the feet on it have calibrated the measured height
        (``bias``; without a bias estimate, from the start; before the first stance of an episode, the flags alone)."""
        calibrated = bias is None or bias.calibrated
        height = self.options.touchdown_height if calibrated else None
        offset = None if bias is None else bias.ground_offset
        return late_landing(self.clock, Mode(mode), x, self.robot, height, self.ground.terrain, offset)

    def observe(self, x: np.ndarray, mode: Mode, bias: MeasurementBias | None) -> Mode:
        """Advance the phase by one observation: the estimate ``x`` (14,) and the flags' contact ``mode`` (steps 1 and
        2); returns the current phase's mode. On the first observation a stance's elapsed time comes from where its
        foot is under the hip ([`stance_elapsed`][hsddp_gym.planners.policies.mpc.clock.stance_elapsed])."""
        clock = self.clock
        mode = self.evidence(x, mode, bias)
        return clock.update(mode, float(x[NQ + IPITCH]), elapsed=None if clock.phase is not None else
                            (lambda phase, duration: stance_elapsed(self.robot, x, phase, duration)))

    def predict(self, steps: list | None) -> Mode:
        """The phase of the state a plan starts from: the clock advanced over the predicted ``steps``
        (``[(x (14,), mode), ...]`` from the state estimator; empty or None, failed: the clock itself). Returns its
        mode."""
        self.plan_clock = self.clock
        if steps:
            clock = self.clock.copy()
            for x, mode in steps:
                clock.tick()
                clock.update(mode, float(x[NQ + IPITCH]))
            self.plan_clock = clock
        return self.plan_clock.mode

    @property
    def resynced(self) -> bool:
        """Whether the last observation moved the phase against the cycle (a lost stance, a double stance, a second
        step): the plan's schedule no longer holds, and the MPC re-plans at once."""
        return self.clock.resynced or self.plan_clock.resynced

    def tick(self) -> None:
        """One control period has passed."""
        self.clock.tick()

    # ------------------------------------------------------------------ 3: the phases ahead
    def schedule(self, x: np.ndarray) -> ModeSchedule:
        """The schedule of a plan from the state ``x`` (14,) (step 3 of the module docstring); every duration on the
        ``planner_dt`` grid. Tells the clock which foot it plans a second step with (`GaitClock.restep_foot`)."""
        o = self.options
        clock = self.plan_clock
        j, tau = clock.phase, clock.tau
        self.restep_foot = None
        if j == DOUBLE_STANCE_PHASE:  # the double stance, then the cycle from the stance that follows it
            j = clock.after_double
            modes = [Mode.DOUBLE_STANCE, CYCLE[j]]
            durs = [max(clock.double_duration - tau, self.min_phase), self.durations[j]]
        else:
            modes, durs = [CYCLE[j]], [max(self.durations[j] - tau, self.min_phase)]
            restep = False
            if CYCLE[j] == Mode.FLIGHT and o.flight_reach is not None:
                # a flight lasts at least until the landing foot can reach the ground
                if o.restep:
                    end = self.reach_time(x, CYCLE[(j + 1) % 4], durs[0])
                    restep = end > self.reach_time(x, CYCLE[(j - 1) % 4], durs[0])
                if not restep:
                    durs[0] = max(durs[0], self.reach_time(x, CYCLE[(j + 1) % 4]))
            self.restep_foot = (BACK if j == 1 else FRONT) if restep else None
            if restep:
                # the landing hip is out of reach at the flight's end and the other one is within it: step again
                # with the other foot (the stance before this flight, then this flight again)
                j = (j - 1) % 4
                modes, durs = [Mode.FLIGHT, CYCLE[j]], [durs[0], self.durations[j]]
        while sum(durs) < self.horizon - 1e-9 or CYCLE[j] == Mode.FLIGHT:
            j = (j + 1) % 4
            modes.append(CYCLE[j])
            durs.append(self.durations[j])
        h = self.planner_dt
        durs = [max(1, round(d / h)) * h for d in durs]
        self.clock.restep_foot = self.restep_foot
        return ModeSchedule(modes, durs, final_mode=CYCLE[(j + 1) % 4])

    def reach_time(self, x: np.ndarray, stance: Mode, after: float = 0.0) -> float:
        """The time [s] from state ``x`` (14,) until the hip of the foot that lands in ``stance`` is within
        ``flight_reach`` leg lengths of the ground, the trunk flying ballistically (its velocity, gravity, its pitch
        rate held); 0 when it already is, the plan's horizon when it is not within it. With ``after`` [s], the first
        such time at or after it (``after`` itself when the hip is within reach then)."""
        params = self.robot.params
        side = 1.0 if stance == Mode.FRONT_STANCE else -1.0  # the front hip is at +hip_offset along the trunk
        reach = self.options.flight_reach * params.leg_length
        t = self._reach_grid
        if after > 0.0:
            t = t[t >= after - 1e-9]
            if not t.size:
                return float(self._reach_grid[-1])
        z = x[IZ] + x[NQ + IZ] * t - 0.5 * params.gravity * t * t - side * params.hip_offset * np.sin(
            x[IPITCH] + x[NQ + IPITCH] * t)
        terrain = self.ground.terrain
        if terrain is not None:  # the hip's height above the terrain under it
            z = z - terrain.support_heights(x[0] + x[NQ] * t + side * params.hip_offset * np.cos(
                x[IPITCH] + x[NQ + IPITCH] * t))
        below = np.flatnonzero(z <= reach)
        return float(t[below[0]]) if below.size else float(t[-1])

    def plan_height(self, bias: MeasurementBias | None) -> float:
        """The height [m] at which a plan made now puts the ground in the measurement's frame, above the flat ground
        (or the terrain): with a calibrated bias estimate, its height bias (where the measurement puts a foot that
        stands on the ground); before the calibration, 0, lowered in a flight past its nominal end by
        ``ground_search_speed`` times the lateness, at most the estimate's height bound (the search for the ground);
        0 without an estimate."""
        if bias is None:
            return 0.0
        if bias.calibrated:
            return float(bias.bias[IZ])
        speed, clock = self.options.ground_search_speed, self.clock
        if speed is None or clock.phase not in (1, 3):
            return 0.0
        late = clock.tau - clock.durations[clock.phase]
        if late < -1e-9:
            return 0.0
        return -float(min(speed * max(late, 0.0), bias.limit[0]))
