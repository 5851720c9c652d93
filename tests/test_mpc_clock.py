"""The MPC's gait clock (hsddp_gym.planners.policies.mpc.GaitClock): its rules and that a learner can rebuild it
from observations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.conventions import Mode
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.learning.features import gait_clock_features, make_gait_clock
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.mpc import DOUBLE_STANCE_PHASE, GaitClock, MPCOptions, MPCPolicy, ScheduleOptions

OFF = {"lost_stance_steps": 0, "double_stance": None, "restep": False}
"""The clock's rules that each test turns on by itself."""


def _clock(durations, dt, **settings) -> GaitClock:
    """A clock with ``settings`` (``ScheduleOptions`` fields) and the other rules off."""
    return GaitClock(durations, dt, ScheduleOptions(**{**OFF, **settings}))


def test_clock_rules():
    c = _clock((0.02, 0.02, 0.02, 0.02), 0.005, debounce_steps=2, min_flight=0.3)
    assert c.update(Mode.BACK_STANCE, 0.0) == Mode.BACK_STANCE and c.phase == 0
    for _ in range(4):  # stance ends on time
        c.tick()
        c.update(Mode.BACK_STANCE, 0.0)
    assert c.phase == 1 and c.tau == 0.0
    # late touchdown: the flight waits past its nominal end, and its landing (front) foot's first contact ends it
    for _ in range(6):
        c.tick()
        c.update(Mode.FLIGHT, 0.0)
    assert c.phase == 1
    c.tick()
    c.update(Mode.FRONT_STANCE, 0.0)
    assert c.phase == 2
    # early touchdown of the landing (back) foot ends flight 3 after debounce_steps contact steps
    for _ in range(4):
        c.tick()
        c.update(Mode.BACK_STANCE, 0.0)
    assert c.phase == 3
    c.tick()
    c.update(Mode.BACK_STANCE, 0.0)
    assert c.phase == 3  # one contact step only
    c.tick()
    c.update(Mode.BACK_STANCE, 0.0)
    assert c.phase == 0
    f = c.features()
    assert f.shape == (7,) and f[0] == 1.0 and f[4] == 0.0 and np.isclose(f[6], 1.0)
    c.reset()
    assert c.phase is None and not c.features().any()
    with pytest.raises(ValueError):
        GaitClock((0.1, 0.1, 0.1), 0.005)


def _stance_then(clock, mode_before, steps_on, mode_after, steps_off):
    for _ in range(steps_on):
        clock.tick()
        clock.update(mode_before, 0.0)
    for _ in range(steps_off):
        clock.tick()
        clock.update(mode_after, 0.0)


def test_lost_stance_rule():
    durs = (0.04, 0.03, 0.04, 0.03)
    # early in the back stance the back foot leaves the ground: back to the flight that lands it
    c = _clock(durs, 0.005, lost_stance_steps=2)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, Mode.BACK_STANCE, 1, Mode.FLIGHT, 1)
    assert c.phase == 0 and not c.resynced  # one step in the air is not enough
    c.tick()
    assert c.update(Mode.FLIGHT, 0.0) == Mode.FLIGHT
    assert c.phase == 3 and c.resynced and c.tau == pytest.approx(0.5 * durs[3])
    c.tick()
    c.update(Mode.FLIGHT, 0.0)
    assert not c.resynced  # set for one update only
    # ... which ends when the back foot lands again (debounced)
    _stance_then(c, Mode.BACK_STANCE, 2, Mode.BACK_STANCE, 0)
    assert c.phase == 0
    # late in the front stance (tau >= half of it): the stance simply ends
    c = _clock(durs, 0.005, lost_stance_steps=2)
    c.update(Mode.FRONT_STANCE, 0.0)
    _stance_then(c, Mode.FRONT_STANCE, 4, Mode.FLIGHT, 2)
    assert c.phase == 3 and c.tau == 0.0 and not c.resynced
    # with the rule off a stance is never lost
    c = _clock(durs, 0.005, lost_stance_steps=0)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, Mode.BACK_STANCE, 1, Mode.FLIGHT, 3)
    assert c.phase == 0 and not c.resynced
    assert c.copy().lost_stance_steps == 0 and _clock(durs, 0.005, lost_stance_steps=3).copy().lost_stance_steps == 3
    with pytest.raises(ValueError, match="lost_stance_steps"):
        _clock(durs, 0.005, lost_stance_steps=-1)


@pytest.mark.slow
def test_features_rebuilt_from_observations_match_the_mpc_clock():
    """The learners' clock reads the observations' contact flags. The MPC's late-landing rule (``touchdown_height``)
    reads its estimate's foot heights, which the learners do not rebuild: off here, the clocks agree step for step
    (with it, seed 3 lands the MPC's clock one step early three times in 120)."""
    env = gym.make("hsddp_gym/Bounding-v0")
    options = MPCOptions().replace(warmup_iterations=5, max_iterations=1, touchdown_height=None)
    mpc = MPCPolicy.from_env(env, options=options)
    obs, _ = env.reset(seed=3)
    mpc.reset()
    O, live = [], []
    for _ in range(120):
        a = mpc(obs)
        O.append(obs)
        live.append((mpc.clock.phase, mpc.clock.tau - mpc.clock.dt))
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    env.close()
    clock = make_gait_clock(EnvInterface.from_env(env))
    feats = gait_clock_features(np.array(O), clock)
    phases = [p for p, _ in live]
    assert len(set(phases)) >= 3  # the episode went through several phases
    np.testing.assert_array_equal(feats[:, :4].argmax(axis=1), phases)
    taus = np.array([t for _, t in live])
    np.testing.assert_allclose(feats[:, 4], np.minimum(taus / np.array(clock.durations)[phases], 2.0), atol=1e-9)


def test_double_stance_rule():
    durs = (0.04, 0.03, 0.04, 0.03)
    ds = Mode.DOUBLE_STANCE
    # off (the default): a swing foot landing in a stance does not change the phase
    c = _clock(durs, 0.005)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, ds, 3, ds, 0)
    assert c.phase == 0 and c.mode == Mode.BACK_STANCE
    # on: the front foot lands in the back stance (debounced, after a swing of min_flight of its flight, 9 ms)
    # -> double stance, then front stance
    c = _clock(durs, 0.005, double_stance=0.02)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, Mode.BACK_STANCE, 1, ds, 1)
    assert c.phase == 0  # one contact step of the front foot is not enough
    c.tick()
    assert c.update(ds, 0.0) == ds
    assert c.phase == DOUBLE_STANCE_PHASE and c.after_double == 2 and c.resynced and c.tau == 0.0
    twin = c.copy()
    assert twin.phase == DOUBLE_STANCE_PHASE and twin.after_double == 2 and twin.double_duration == 0.02
    f = c.features()  # read as the start of the front stance
    assert f[2] == 1.0 and f[4] == 0.0
    # ... which ends when the back foot has lifted off (debounced)
    _stance_then(c, Mode.FRONT_STANCE, 1, Mode.FRONT_STANCE, 0)
    assert c.phase == DOUBLE_STANCE_PHASE
    c.tick()
    assert c.update(Mode.FRONT_STANCE, 0.0) == Mode.FRONT_STANCE and c.phase == 2 and c.tau == 0.0
    # ... or after its duration, both feet still down; the duration is the one set when it started
    c = _clock(durs, 0.005, double_stance=0.02)
    c.update(Mode.FRONT_STANCE, 0.0)
    _stance_then(c, Mode.FRONT_STANCE, 1, ds, 2)
    assert c.phase == DOUBLE_STANCE_PHASE and c.after_double == 0
    c.double_stance = 0.0  # the one entered lasts its own duration
    _stance_then(c, ds, 3, ds, 0)
    assert c.phase == DOUBLE_STANCE_PHASE
    _stance_then(c, ds, 1, ds, 0)
    assert c.phase == 0 and c.mode == Mode.BACK_STANCE
    # in a flight whose lift-off is late: the landing foot touches while the other foot is still down
    c = _clock(durs, 0.005, double_stance=0.02, min_flight=0.0)
    c.update(Mode.FLIGHT, 1.0)  # flight 1 (lands the front foot)
    _stance_then(c, Mode.BACK_STANCE, 1, ds, 2)
    assert c.phase == DOUBLE_STANCE_PHASE and c.after_double == 2
    # a scuff is not a landing: a foot in the air for less than min_flight of its flight (one step, 5 ms) touches
    c = _clock(durs, 0.005, double_stance=0.02)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, ds, 3, ds, 0)
    assert c.phase == 0 and c.mode == Mode.BACK_STANCE
    with pytest.raises(ValueError, match="double_stance"):
        _clock(durs, 0.005, double_stance=-0.01)


def test_double_stance_starts_only_at_a_touchdown():
    """A double stance that ends on its duration with both feet still down is followed by the stance of the foot
    that landed, which plans the other foot's lift-off: the foot that stayed down is not a new touchdown (else
    the clock would go from one double stance to the next, swapping which stance follows). Nor is a scuff: that foot
    lifting off for less than ``min_flight`` of its flight and touching again. Once it has swung that long and lands,
    it is a touchdown."""
    durs = (0.1, 0.03, 0.1, 0.03)
    ds = Mode.DOUBLE_STANCE
    c = _clock(durs, 0.005, double_stance=0.02)
    c.update(Mode.BACK_STANCE, 0.0)
    _stance_then(c, Mode.BACK_STANCE, 2, ds, 2)  # the front foot lands in the back stance: double stance, front next
    assert c.phase == DOUBLE_STANCE_PHASE and c.after_double == 2
    _stance_then(c, ds, 4, ds, 0)  # both feet down for its whole duration
    assert c.phase == 2
    _stance_then(c, ds, 10, ds, 0)  # the back foot never lifts: still the front stance
    assert c.phase == 2 and c.mode == Mode.FRONT_STANCE
    twin = c.copy()
    _stance_then(c, Mode.FRONT_STANCE, 1, ds, 2)  # it lifts off for a step and touches again: a scuff, not a landing
    assert c.phase == 2
    _stance_then(c, Mode.FRONT_STANCE, 2, ds, 2)  # in the air for 10 ms (min_flight of its 30 ms flight): a landing
    assert c.phase == DOUBLE_STANCE_PHASE and c.after_double == 0
    _stance_then(twin, ds, 3, ds, 0)  # the copy keeps the count of the phase's observations
    assert twin.phase == 2


def test_mpc_double_stance_option_plans_the_clock_s_double_stance():
    """``double_stance=0.04`` (the default): the MPC's clock always has that double stance, and a plan's schedule
    built while the clock is in it starts with it, then the stance of the foot that landed; with None the MPC never
    enters one. The learner's rebuilt clock keeps the setting."""
    ds = Mode.DOUBLE_STANCE
    policy = MPCPolicy(EnvInterface(), MPCOptions().replace(double_stance=0.04))
    assert policy.clock.double_stance == 0.04
    policy.clock.update(Mode.BACK_STANCE, 0.0)
    _stance_then(policy.clock, Mode.BACK_STANCE, 4, ds, 2)  # the front foot lands in the back stance (debounced)
    assert policy.clock.phase == DOUBLE_STANCE_PHASE and policy.clock.after_double == 2
    schedule = policy.schedule.schedule(paper_initial_state())
    assert schedule.modes[0] == ds and schedule.modes[1] == Mode.FRONT_STANCE
    assert schedule.durations[0] == pytest.approx(0.04)
    assert GaitClock.from_settings(policy.clock.settings()).double_stance == 0.04
    assert MPCOptions().schedule.double_stance == 0.04 and MPCPolicy(EnvInterface()).clock.double_stance == 0.04
    # None: no double stance, the clock stays in the back stance and so does the plan
    off = MPCPolicy(EnvInterface(), MPCOptions().replace(double_stance=None))
    assert off.clock.double_stance == 0.0
    off.clock.update(Mode.BACK_STANCE, 0.0)
    _stance_then(off.clock, ds, 2, ds, 0)
    assert off.clock.phase == 0 and off.schedule.schedule(paper_initial_state()).modes[0] == Mode.BACK_STANCE
    for bad in (0.0, -0.01):
        with pytest.raises(ValueError, match="double_stance"):
            MPCOptions().replace(double_stance=bad)


def test_a_flight_waits_for_its_landing_foot_however_late():
    """The clock never moves into a stance whose foot is in the air, and a late flight ends at the landing foot's
    first contact step (a flickering soft contact)."""
    durs = (0.04, 0.03, 0.04, 0.03)
    c = _clock(durs, 0.005)
    c.update(Mode.FLIGHT, 1.0)  # flight 1 (lands the front foot)
    assert c.phase == 1
    _stance_then(c, Mode.FLIGHT, 40, Mode.FLIGHT, 0)  # 0.2 s, almost 7 nominal flights
    assert c.phase == 1 and c.tau == pytest.approx(0.2)
    _stance_then(c, Mode.FRONT_STANCE, 1, Mode.FRONT_STANCE, 0)  # one contact step past the nominal end
    assert c.phase == 2 and c.tau == 0.0
    early = _clock(durs, 0.005)
    early.update(Mode.FLIGHT, 1.0)
    _stance_then(early, Mode.FLIGHT, 2, Mode.FRONT_STANCE, 1)  # before the nominal end one step is a graze
    assert early.phase == 1
    _stance_then(early, Mode.FRONT_STANCE, 1, Mode.FRONT_STANCE, 0)
    assert early.phase == 2


def test_saved_clock_settings_round_trip_and_refuse_a_flight_time_limit():
    """:meth:`GaitClock.settings` / :meth:`GaitClock.from_settings` (saved with a learner): the same clock back; a
    saved ``"max_wait": None`` is accepted, a time limit on a flight is refused (flights wait for their touchdown)."""
    params = MPCPolicy(EnvInterface()).clock.settings()
    assert "max_wait" not in params
    rebuilt = GaitClock.from_settings(params)
    assert rebuilt.settings() == params
    # every setting of the MPC's clock comes back, so the features a learner acts on are those it was trained on
    for name in ("lost_stance_steps", "double_stance", "restep", "debounce_steps", "min_flight", "durations", "dt"):
        assert getattr(rebuilt, name) == getattr(MPCPolicy(EnvInterface()).clock, name), name
    assert rebuilt.restep is True
    assert GaitClock.from_settings({k: v for k, v in params.items() if k != "restep"}).restep is False  # saved before
    assert GaitClock.from_settings({**params, "max_wait": None}).settings() == params
    with pytest.raises(ValueError, match="max_wait"):
        GaitClock.from_settings({**params, "max_wait": 0.03})


def test_a_foot_that_bounces_off_at_touchdown_is_a_lost_stance():
    """A stance entered at its foot's touchdown counts as touched: if the foot leaves the ground again early in the
    stance, the clock goes back to the flight that lands it (and the MPC does not plan the stance on a foot in the
    air)."""
    durs = (0.08, 0.072, 0.072, 0.072)
    c = _clock(durs, 0.005, lost_stance_steps=2)
    c.update(Mode.FLIGHT, -1.0)  # flight 3 (lands the back foot)
    _stance_then(c, Mode.FLIGHT, 10, Mode.BACK_STANCE, 2)  # touchdown, debounced: back stance
    assert c.phase == 0 and c.tau == 0.0
    _stance_then(c, Mode.FLIGHT, 2, Mode.FLIGHT, 0)  # the foot bounced off at once
    assert c.phase == 3 and c.resynced and c.tau == pytest.approx(0.5 * durs[3])


def test_clock_starts_a_stance_where_the_foot_under_the_hip_says():
    """A start-up that does not assume a phase has just begun: the paper's initial state is mid back stance
    (the foot under the hip), so the clock starts there with about half the stance gone; a foot ahead of the hip
    is early in the stance, one behind it late. Flights and a double stance start at 0."""
    from hsddp_gym.planners.policies.mpc import stance_elapsed

    policy = MPCPolicy(EnvInterface(), MPCOptions())
    robot = policy.planner.dynamics.robot
    x = paper_initial_state()
    T = policy.durations[0]
    mid = stance_elapsed(robot, x, 0, T)
    assert 0.4 * T < mid < 0.6 * T
    ahead, behind = x.copy(), x.copy()
    ahead[5] -= 0.3  # the back hip turned: the foot ahead of the hip
    behind[5] += 0.3
    feet = [robot.foot_positions(s[:7])[1, 0] - robot.hip_positions(s[:7])[1, 0] for s in (ahead, x, behind)]
    assert feet[0] > feet[1] > feet[2]
    assert stance_elapsed(robot, ahead, 0, T) < mid < stance_elapsed(robot, behind, 0, T)
    assert stance_elapsed(robot, x, 1, 0.072) == 0.0
    # the MPC's clock uses it on the first observation only
    policy.schedule.observe(x, Mode.BACK_STANCE, None)
    assert policy.clock.phase == 0 and policy.clock.tau == pytest.approx(mid)
    policy.schedule.observe(behind, Mode.BACK_STANCE, None)  # later observations do not move it
    assert policy.clock.tau == pytest.approx(mid)
    clock = _clock(policy.durations, 0.005)
    clock.update(Mode.DOUBLE_STANCE, 0.0, elapsed=lambda phase, duration: 0.03)
    assert clock.tau == 0.0
    for bad in (float("nan"), -0.01, 1.0):
        with pytest.raises(ValueError, match="elapsed"):
            _clock(policy.durations, 0.005).update(Mode.BACK_STANCE, 0.0, elapsed=lambda phase, duration, b=bad: b)
    with pytest.raises(ValueError, match="x"):
        _clock(policy.durations, 0.005).observe(Mode.BACK_STANCE, np.zeros(3))


def test_a_flight_is_planned_until_the_landing_hip_can_reach_the_ground():
    """``flight_reach`` (default 0.85): a flight is planned to last at least until the hip of the foot that lands
    is within ``flight_reach`` leg lengths of the ground, the trunk flying ballistically. The reach time is the
    ballistic fall time (to a knot); a robot at bounding height gets no longer flight; high above the ground, the
    plan's flight lasts the fall and not ``min_phase`` (after the nominal end); None plans ``min_phase``."""
    from hsddp_gym.core.conventions import IPITCH, IZ, NQ

    policy = MPCPolicy(EnvInterface())
    o = policy.options
    assert o.schedule.flight_reach == 0.85
    params = policy.planner.dynamics.robot.params
    reach = o.schedule.flight_reach * params.leg_length
    h = o.plan.planner_dt
    x = np.zeros(14)
    x[IZ] = reach + 0.10  # level trunk, both hips 10 cm above their reach, at rest
    fall = np.sqrt(2 * 0.10 / params.gravity)
    for stance in (Mode.FRONT_STANCE, Mode.BACK_STANCE):
        assert abs(policy.schedule.reach_time(x, stance) - fall) <= h
    # pitched nose-up (negative pitch): the front hip is higher than the back one and reaches later
    x[IPITCH] = -0.3
    reach_time = policy.schedule.reach_time
    assert reach_time(x, Mode.FRONT_STANCE) > fall + 0.02 > reach_time(x, Mode.BACK_STANCE) + 0.02
    # the hip heights are the model's (forward kinematics), for a pitched trunk at rest: the fall time of each hip
    from hsddp_gym.core.model import CheetahModel

    x[IZ], x[IPITCH] = reach + 0.05, 0.25
    hips = CheetahModel().hip_positions(x[:NQ])  # (front, back) x (x, z)
    for stance, hip_z in ((Mode.FRONT_STANCE, hips[0, 1]), (Mode.BACK_STANCE, hips[1, 1])):
        expected = np.sqrt(2 * max(hip_z - reach, 0.0) / params.gravity)
        assert abs(policy.schedule.reach_time(x, stance) - expected) <= h
    # moving up at 0.5 m/s: the ballistic time, longer than the fall from rest
    x[IZ], x[IPITCH], x[NQ + IZ] = reach + 0.10, 0.0, 0.5
    up = (0.5 + np.sqrt(0.25 + 2 * params.gravity * 0.10)) / params.gravity
    assert up > fall + 0.05 and abs(policy.schedule.reach_time(x, Mode.BACK_STANCE) - up) <= h
    # at bounding height (0.29 m) the hips are within reach: no delay
    x[IZ], x[NQ + IZ] = 0.29, 0.0
    assert policy.schedule.reach_time(x, Mode.FRONT_STANCE) == 0.0
    # never within the horizon: the horizon
    x[IZ] = 3.0
    assert policy.schedule.reach_time(x, Mode.FRONT_STANCE) == pytest.approx(policy.schedule.horizon, abs=h)

    # the plan's schedule: a flight 60 ms past its nominal end, the robot high above the ground
    x[IZ] = reach + 0.10
    off = MPCPolicy(EnvInterface(), MPCOptions().replace(flight_reach=None))
    for p in (policy, off):
        p.clock.update(Mode.FLIGHT, 1.0)  # flight 1 (lands the front foot)
        _stance_then(p.clock, Mode.FLIGHT, int(round((p.durations[1] + 0.06) / 0.005)), Mode.FLIGHT, 0)
        assert p.clock.phase == 1
    planned = policy.schedule.schedule(x)
    assert planned.modes[0] == Mode.FLIGHT and planned.modes[1] == Mode.FRONT_STANCE
    assert abs(planned.durations[0] - fall) <= h
    assert off.schedule.schedule(x).durations[0] == pytest.approx(o.plan.min_phase)
    # the clock is not changed, nor a plan from bounding height
    assert policy.clock.phase == 1
    x[IZ] = 0.29
    assert policy.schedule.schedule(x).durations[0] == pytest.approx(o.plan.min_phase)
    for bad in (0.0, -0.1, 1.5):
        with pytest.raises(ValueError, match="flight_reach"):
            MPCOptions().replace(flight_reach=bad)
    with pytest.raises(TypeError, match="flight_reach"):
        MPCOptions().replace(flight_reach="high")


def test_a_foot_that_lands_again_in_the_flight_after_its_stance_starts_that_stance_again():
    """``restep``: in a flight, the foot of the stance before it back on the ground after a swing of ``min_flight``
    of its flight, debounced, starts its stance again (the cycle goes on from there, ``resynced``). A foot that
    never left the ground or only scuffs it does not; without ``restep`` (the learners' clock) the flight goes on."""
    durs = (0.08, 0.072, 0.072, 0.072)
    bs, fl = Mode.BACK_STANCE, Mode.FLIGHT
    c = _clock(durs, 0.005, restep=True)
    assert c.copy().restep and not _clock(durs, 0.005).restep
    c.update(fl, 1.0)  # flight 1: after the back stance, lands the front foot
    assert c.phase == 1
    _stance_then(c, fl, 6, bs, 1)  # 35 ms in the air, then the back foot touches: not yet debounced
    assert c.phase == 1
    c.tick()
    assert c.update(bs, 0.0) == bs and c.phase == 0 and c.tau == 0.0 and c.resynced
    # the stance gets its nominal duration, then the flight that lands the front foot
    _stance_then(c, bs, 15, bs, 0)
    assert c.phase == 0
    _stance_then(c, bs, 1, fl, 0)
    assert c.phase == 1
    # without restep: the flight goes on
    w = _clock(durs, 0.005)
    w.update(fl, 1.0)
    _stance_then(w, fl, 6, bs, 4)
    assert w.phase == 1 and w.mode == fl
    # a scuff: 10 ms after the back stance ended, 10 ms in the air
    s = _clock(durs, 0.005, restep=True)
    s.update(bs, 0.0)
    _stance_then(s, bs, 16, bs, 0)  # the back stance ends on time with the foot still down
    assert s.phase == 1
    _stance_then(s, bs, 1, fl, 2)
    _stance_then(s, bs, 3, bs, 0)
    assert s.phase == 1
    # a foot that stays down from the stance into the flight
    d = _clock(durs, 0.005, restep=True)
    d.update(bs, 0.0)
    _stance_then(d, bs, 20, bs, 0)
    assert d.phase == 1
    with pytest.raises(TypeError, match="restep"):
        _clock(durs, 0.005, restep="yes")
    assert MPCPolicy(EnvInterface()).clock.restep
    assert not MPCPolicy(EnvInterface(), MPCOptions().replace(restep=False)).clock.restep
