"""The MPC after a pitch kick: a second step of the foot on the ground side when the ballistic flight takes the
landing hip out of reach (``ScheduleOptions.restep``, ``GaitClock.restep_foot``), torques that never pull a stance
foot off the ground or out of the friction cone (``MPCOptions.min_stance_force``, ``FeedbackLaw.project``), and a
re-plan at once, solved further, when the feedback law far from its plan would saturate the motors
(``ReplanOptions.feedback_threshold``, ``feedback_iterations``). How often the MPC falls with and without each is in
the results store."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IZ, NQ, Mode
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.planners.policies.mpc import GaitClock, MPCOptions, MPCPolicy, ScheduleOptions

NO_DOUBLE = ScheduleOptions(double_stance=None, lost_stance_steps=0)
"""The clock's rules but the re-step off (its own tests)."""

def _flight_after_front_stance(clock: GaitClock) -> None:
    clock.update(Mode.FRONT_STANCE, 0.0)
    while clock.phase == 2:
        clock.tick()
        clock.update(Mode.FRONT_STANCE, 0.0)
    for _ in range(6):  # 30 ms of the flight that lands the back foot: the front foot has swung
        clock.tick()
        assert clock.update(Mode.FLIGHT, 0.0) == Mode.FLIGHT
    assert clock.phase == 3


def test_a_planned_restep_ends_the_flight_at_the_other_foots_first_contact():
    clock = GaitClock(PAPER_BOUNDING_DURATIONS, 0.005, NO_DOUBLE)
    _flight_after_front_stance(clock)
    twin = clock.copy()
    clock.restep_foot = FRONT
    assert clock.copy().restep_foot == FRONT
    clock.tick()
    assert clock.update(Mode.FRONT_STANCE, 0.0) == Mode.FRONT_STANCE  # one contact step is enough: it was planned
    assert clock.phase == 2 and clock.tau == 0.0 and clock.resynced and clock.restep_foot is None
    # not planned: the landing is debounced (one contact step could be a graze)
    twin.tick()
    assert twin.update(Mode.FRONT_STANCE, 0.0) == Mode.FLIGHT and twin.phase == 3
    twin.tick()
    assert twin.update(Mode.FRONT_STANCE, 0.0) == Mode.FRONT_STANCE and twin.phase == 2
    # the planned foot must be the foot of the stance before the flight
    other = GaitClock(PAPER_BOUNDING_DURATIONS, 0.005, NO_DOUBLE)
    _flight_after_front_stance(other)
    other.restep_foot = BACK
    other.tick()
    assert other.update(Mode.FRONT_STANCE, 0.0) == Mode.FLIGHT
    # a clock without restep ignores the plan
    off = GaitClock(PAPER_BOUNDING_DURATIONS, 0.005, ScheduleOptions(restep=False))
    _flight_after_front_stance(off)
    off.restep_foot = FRONT
    for _ in range(3):
        off.tick()
        assert off.update(Mode.FRONT_STANCE, 0.0) == Mode.FLIGHT


def _policy_in_flight_3(options: MPCOptions = MPCOptions(), tau: float = 0.02) -> MPCPolicy:
    policy = MPCPolicy(options=options)
    policy.clock.phase, policy.clock.tau = 3, tau
    return policy


def _flight_state(pitch_rate: float) -> np.ndarray:
    x = paper_initial_state().copy()
    x[IZ], x[IPITCH] = 0.31, 0.0
    x[NQ:] = 0.0
    x[NQ] = 1.0
    x[NQ + IPITCH] = pitch_rate
    return x


def test_restep_is_planned_only_when_the_landing_hip_leaves_reach_and_the_other_stays_in_it():
    policy = _policy_in_flight_3()
    schedule = policy.schedule
    nominal = schedule.schedule(_flight_state(-2.5))  # the flight before the back stance of unperturbed bounding
    assert list(nominal.modes[:2]) == [Mode.FLIGHT, Mode.BACK_STANCE] and schedule.restep_foot is None
    kicked = schedule.schedule(_flight_state(6.0))  # nose-down: the back hip rises, the front hip stays low
    assert list(kicked.modes[:4]) == [Mode.FLIGHT, Mode.FRONT_STANCE, Mode.FLIGHT, Mode.BACK_STANCE]
    assert schedule.restep_foot == FRONT and policy.clock.restep_foot == FRONT  # the clock is told
    assert kicked.durations[0] == pytest.approx(nominal.durations[0])  # the landing keeps the flight's nominal end
    off = _policy_in_flight_3(MPCOptions().replace(restep=False))
    late = off.schedule.schedule(_flight_state(6.0))
    assert list(late.modes[:2]) == [Mode.FLIGHT, Mode.BACK_STANCE]  # the plans wait for the back foot
    up = _flight_state(0.0)
    up[NQ + IZ] = 2.0  # thrown up level: both hips leave reach, neither foot can land sooner
    stretched = schedule.schedule(up)
    assert list(stretched.modes[:2]) == [Mode.FLIGHT, Mode.BACK_STANCE] and schedule.restep_foot is None
    assert schedule.reach_time(up, Mode.BACK_STANCE, 0.052) > 0.052  # the back hip is out of reach at the end


def test_neither_mechanism_acts_in_unpushed_bounding_on_seed_1():
    env = gym.make("hsddp_gym/Bounding-v0")
    actions = []
    for options in (MPCOptions(), MPCOptions().replace(restep=False, min_stance_force=None)):
        policy = MPCPolicy.from_env(env, options=options)
        obs, _ = env.reset(seed=1)
        policy.reset()
        run = []
        for _ in range(300):
            run.append(policy(obs))
            obs, _, terminated, _, _ = env.step(run[-1])
            assert not terminated
        actions.append(np.array(run))
    env.close()
    np.testing.assert_array_equal(actions[0], actions[1])


def test_each_copy_projects_with_its_own_model_and_none_is_off():
    policy = MPCPolicy(options=MPCOptions())
    twin = policy.spawn()
    pushing = policy.law.pushing
    assert twin.law.pushing is not pushing and twin.law.pushing._dynamics is not pushing._dynamics
    assert twin.estimator is not policy.estimator and twin.planner is not policy.planner
    assert twin.ground is not policy.ground and twin.law.ground is twin.ground
    assert pushing.friction == policy.options.plan.friction
    assert MPCPolicy(options=MPCOptions().replace(min_stance_force=None)).law.pushing is None


def test_the_law_projects_the_torques_of_a_planned_stance_only():
    """``FeedbackLaw.project``: in a planned stance the torques are those the projection gives (a stance foot pushes
    inside the cone); in a planned flight, or without ``min_stance_force``, the law's torques as they are."""
    env = gym.make("hsddp_gym/Bounding-v0")
    policy = MPCPolicy.from_env(env)
    obs, _ = env.reset(seed=0)
    policy(obs)  # the first plan: from the paper's start, mid back stance
    tracker = policy.law.plan.tracker
    assert tracker.modes[tracker.phase] == Mode.BACK_STANCE
    x = policy.last_prediction.copy()
    pull = np.array([0.0, 0.0, 30.0, -30.0])  # back hip and knee torques that lift the stance foot
    projected = policy.law.project(x, pull)
    assert np.abs(projected - pull).max() > 1.0
    assert np.array_equal(projected, policy.law.pushing(x, pull, Mode.BACK_STANCE))
    off = MPCPolicy.from_env(env, options=MPCOptions().replace(min_stance_force=None))
    off.law.plan = policy.law.plan
    assert np.array_equal(off.law.project(x, pull), pull)
    while tracker.modes[tracker.phase] != Mode.FLIGHT:
        tracker.advance(0.005)
    assert np.array_equal(policy.law.project(x, pull), pull)
    env.close()


KICK = {"delta_v": [0.0, 0.0, 6.0], "time": 1.0}
"""A nose-down pitch kick of 6 rad/s at 1 s (reset option ``push``), on seed 1 of the default env."""


def _kicked(env, options: MPCOptions, on_step, steps: int = 220) -> MPCPolicy:
    """The MPC with ``options`` through :data:`KICK` on seed 1 of ``env`` for ``steps`` control steps (220: to 1.1 s),
    none of which may end the episode; after each step ``on_step(k, policy, before)`` with ``before`` the policy's
    stats before that step (list entries as their lengths)."""
    policy = MPCPolicy.from_env(env, options=options)
    obs, _ = env.reset(seed=1, options={"push": KICK})
    policy.reset()
    for k in range(steps):
        before = {key: len(v) if isinstance(v, list) else v for key, v in policy.stats.items()}
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
        on_step(k, policy, before)
    return policy


def test_a_push_triggers_a_replan_at_once_and_none_waits_for_the_period():
    env = gym.make("hsddp_gym/Bounding-v0")
    counts = {}
    try:
        for name, options in (("default", MPCOptions()), ("off", MPCOptions().replace(replan_feedback=None))):
            at_1s = {}

            def record(k, policy, before, at_1s=at_1s):
                if k == 200:
                    at_1s["feedback_replans"] = before["feedback_replans"]

            policy = _kicked(env, options, record)
            counts[name] = (at_1s["feedback_replans"], policy.stats["feedback_replans"], policy.stats["replans"])
    finally:
        env.close()
    before, after, replans = counts["default"]
    assert after > before  # the push's first 0.1 s made re-plans at once
    assert counts["off"][:2] == (0, 0)
    assert replans > counts["off"][2]


def test_feedback_replans_are_solved_further_and_none_solves_them_as_periodic_ones():
    """After a pitch kick, each re-plan made at once runs more than one DDP iteration (at most feedback_iterations *
    feedback_al_iterations) and updates the multipliers between its outer iterations; a periodic re-plan runs one.
    With feedback_iterations=None every warm-started re-plan runs one (a kept restart, solved from scratch, is left
    out of both)."""
    env = gym.make("hsddp_gym/Bounding-v0")
    kinds = {}
    try:
        for name, options in (("default", MPCOptions()), ("off", MPCOptions().replace(feedback_iterations=None))):
            feedback, periodic = [], []

            def sort(k, policy, before, feedback=feedback, periodic=periodic):
                # after the start-up's plans from scratch; a kept restart is solved from scratch too
                if k >= 100 and policy.stats["replans"] > before["replans"] \
                        and policy.stats["restarts_kept"] == before["restarts_kept"]:
                    made = policy.stats["iterations"][before["replans"]:]
                    fed_back = policy.stats["feedback_replans"] > before["feedback_replans"]
                    (feedback if fed_back else periodic).extend(made)

            _kicked(env, options, sort)
            kinds[name] = (feedback, periodic)
    finally:
        env.close()
    feedback, periodic = kinds["default"]
    o = MPCOptions().replan
    assert feedback and max(feedback) > o.feedback_iterations  # an outer-loop update and more iterations after it
    assert all(1 < n <= o.feedback_iterations * o.feedback_al_iterations for n in feedback)
    assert periodic and set(periodic) == {o.iterations}
    feedback_off, periodic_off = kinds["off"]
    assert feedback_off and set(feedback_off) | set(periodic_off) == {o.iterations}


def test_recovery_options_are_validated():
    o = MPCOptions()
    with pytest.raises(TypeError, match="restep"):
        o.replace(restep=1)
    with pytest.raises(ValueError, match="min_stance_force"):
        o.replace(min_stance_force=-1.0)
    for bad in (0.0, -0.5):
        with pytest.raises(ValueError, match="feedback_threshold"):
            o.replace(replan_feedback=bad)
    assert o.replace(replan_feedback=None).replan.feedback_threshold is None
    for name in ("feedback_iterations", "feedback_al_iterations"):
        for bad in (0, 1.5, "3"):
            with pytest.raises((TypeError, ValueError), match=name):
                o.replace(**{name: bad})
    assert o.replace(feedback_iterations=None).replan.feedback_iterations is None
