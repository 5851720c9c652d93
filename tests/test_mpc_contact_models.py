"""The MPC on contact models it was not built on (the MuJoCo twin's contact corners), the gait clock's late
landing from the state (``MPCOptions.touchdown_height``, ``late_landing``) and the state filter's restart on a
persistent innovation only (``MPCOptions.filter_restart_steps``); the closed-loop tests are skipped without
mujoco."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, NQ, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.planners.policies import MPCOptions, MPCPolicy
from hsddp_gym.planners.policies.estimation import ContactModelPredictor, StateFilter
from hsddp_gym.planners.policies.mpc import GaitClock, late_landing, update_gait_clock
from hsddp_gym.rollout.episodes import run_episode

STIFF_SEED = 40011
"""A seed on which the MPC without the late-landing rule falls within 1 s in the stiffest corner (at 0.91 s) and the
default bounds. (On 40003 the flags reported no debounced touchdown of the back foot and the trunk sank to 0.13 m
while the clock waited 260 ms in the flight; since the plans put the ground where the feet measure it, the MPC
without the rule bounds its first 2 s there, and on 40007 since the state filter's model stands on that ground too.)"""
SOFT_SEED = 9125
"""A softest-corner seed on which the MPC with the paper's weights whose filter restarts at every innovation beyond
the gate (feedback re-plans solved as periodic ones, ``feedback_iterations=None``) fell at 1.23 s. Since the plans put
the ground where the feet measure it, that variant falls neither here nor on any of the seeds 9120-9276 (3 s each);
what remains is the mechanism: restarting at once takes about twice as many observations whole."""
STEPS_2S = 400


def _run(condition: str, options: MPCOptions, seed: int, steps: int = STEPS_2S):
    pytest.importorskip("mujoco")
    from hsddp_gym.envs.perturbations import make_env

    env = make_env(condition)
    try:
        return run_episode(env, MPCPolicy.from_env(env, options=options), seed, max_steps=steps)
    finally:
        env.close()


def test_stiffest_corner_bounds_with_the_late_landing_rule_and_falls_without():
    flags_only = _run("contact_stiffest", MPCOptions(touchdown_height=None), STIFF_SEED)
    assert flags_only.fell and flags_only.simulated_time < 1.0
    result = _run("contact_stiffest", MPCOptions(), STIFF_SEED)
    assert not result.fell and result.length == STEPS_2S
    assert result.forward_speed > 0.5


def test_softest_corner_bounds_and_the_persistent_restart_leaves_single_outliers_to_the_gain():
    """In the softest corner nearly every impact is beyond the innovation gate. Restarting only on a persistent
    innovation (``filter_restart_steps=2``) corrects a single step's outlier with the filter's gain; restarting at once
    takes each of them whole, handing the measured velocities of the contact's vibration to the feedback law."""
    pytest.importorskip("mujoco")
    from hsddp_gym.envs.perturbations import make_env

    steps = 600  # 3 s
    env = make_env("contact_softest")
    try:
        restarts = {}
        for name, options in (("paper", MPCOptions(weights="paper")), ("default", MPCOptions()),
                              ("at once", MPCOptions(weights="paper", filter_restart_steps=1,
                                                     feedback_iterations=None))):
            policy = MPCPolicy.from_env(env, options=options)
            result = run_episode(env, policy, SOFT_SEED, max_steps=steps)
            assert not result.fell and result.length == steps
            restarts[name] = (policy._filter.restarts, policy._filter.outliers)
    finally:
        env.close()
    assert restarts["paper"][1] > 50 and restarts["default"][1] > 50  # single-step outliers, left to the gain
    assert restarts["at once"][1] == 0 and restarts["at once"][0] > 1.5 * restarts["paper"][0]


@pytest.mark.parametrize("condition", ["contact_softest", "contact_pyramidal", "contact_large_feet"])
def test_bounds_in_other_contact_corners(condition):
    result = _run(condition, MPCOptions(), 9002)
    assert not result.fell and result.length == STEPS_2S
    assert result.forward_speed > 0.5


# -- the rule itself ------------------------------------------------------------------------------------------------

def _clock_in_flight(landing_phase_elapsed: float) -> GaitClock:
    """A clock in the flight before the back stance (phase 3), ``landing_phase_elapsed`` seconds into it."""
    clock = GaitClock(PAPER_BOUNDING_DURATIONS, 0.005)
    clock.update(Mode.FLIGHT, -1.0)  # in flight with the nose going up: the flight before the back stance
    assert clock.phase == 3
    clock.tau = landing_phase_elapsed
    return clock


def _state_with_foot_at(robot: CheetahModel, foot: int, height: float) -> np.ndarray:
    """A bounding posture (14,) moved vertically so that ``foot`` is ``height`` [m] above the ground."""
    x = np.zeros(14)
    x[:NQ] = [0.0, 0.3, 0.0, -0.8, 1.6, -0.8, 1.6]
    x[1] -= robot.foot_height(x[:NQ], foot) - height
    return x


def test_late_landing_takes_a_foot_at_the_ground_after_the_nominal_flight_only():
    robot = CheetahModel()
    flight = PAPER_BOUNDING_DURATIONS[3]
    low = _state_with_foot_at(robot, BACK, 0.004)
    high = _state_with_foot_at(robot, BACK, 0.03)
    late = _clock_in_flight(flight + 0.01)
    assert late_landing(late, Mode.FLIGHT, low, robot, 0.01) == Mode.BACK_STANCE
    assert late_landing(late, Mode.FRONT_STANCE, low, robot, 0.01) == Mode.DOUBLE_STANCE  # the flags are kept
    assert late_landing(late, Mode.FLIGHT, high, robot, 0.01) == Mode.FLIGHT          # a foot in the air
    assert late_landing(late, Mode.FLIGHT, low, robot, None) == Mode.FLIGHT           # the rule off
    early = _clock_in_flight(0.5 * flight)
    assert late_landing(early, Mode.FLIGHT, low, robot, 0.01) == Mode.FLIGHT          # a low swing, not a landing
    # only the landing foot counts: the front foot at the ground in this flight is not a touchdown
    front_low = _state_with_foot_at(robot, FRONT, 0.004)
    if robot.foot_height(front_low[:NQ], BACK) >= 0.01:
        assert late_landing(late, Mode.FLIGHT, front_low, robot, 0.01) == Mode.FLIGHT


def test_update_gait_clock_ends_a_late_flight_on_a_bouncing_foot():
    """The flags never report the landing foot (it is in the air at every step's end), the state puts it at the
    ground every other step: with the rule the flight ends at the first such step past its nominal end; with the
    flags alone the clock waits in the flight."""
    robot = CheetahModel()
    low = _state_with_foot_at(robot, BACK, 0.003)
    high = _state_with_foot_at(robot, BACK, 0.02)
    flight = PAPER_BOUNDING_DURATIONS[3]
    with_rule, flags_only = _clock_in_flight(0.0), _clock_in_flight(0.0)
    ended_at = None
    for step in range(60):
        x = low if step % 2 else high
        for clock, height in ((with_rule, 0.01), (flags_only, None)):
            clock.tick()
            update_gait_clock(clock, Mode.FLIGHT, x, robot, touchdown_height=height)
        if ended_at is None and with_rule.phase == 0:
            ended_at = with_rule.tau
            assert (step + 1) * 0.005 >= flight - 1e-9
    assert ended_at is not None
    assert flags_only.phase == 3 and flags_only.tau > 0.25


def test_touchdown_height_is_validated():
    with pytest.raises(ValueError, match="touchdown_height"):
        MPCOptions(touchdown_height=0.0)
    assert MPCOptions(touchdown_height=None).touchdown_height is None


# -- the filter's restart ------------------------------------------------------------------------------------------

def _settled_filter(restart_steps: int):
    """A filter that has followed exact observations of a robot in free flight for 0.25 s, and that state."""
    pred = ContactModelPredictor(0.005)
    filt = StateFilter(pred, 0.01, 0.1, 3.0, 35.0, restart_steps=restart_steps)
    x = np.zeros(14)
    x[:NQ] = [0.0, 5.0, 0.0, -0.8, 1.6, -0.8, 1.6]  # high in the air: free flight for the whole test
    u = np.zeros(4)
    filt.update(x, Mode.FLIGHT, None)
    for _ in range(50):
        x, _ = pred.step(x, u)
        filt.update(x, Mode.FLIGHT, u)
    return filt, pred, x, u


def test_filter_corrects_a_single_outlier_and_restarts_on_a_persistent_innovation():
    filt, pred, x, u = _settled_filter(restart_steps=2)
    # one observation far beyond the gate (the vertical speed 2 m/s off: a normalized innovation squared of about
    # 300, against the gate's 35), then exact ones again: no restart, the estimate moved by the Kalman gain only
    x, _ = pred.step(x, u)
    y = x.copy()
    y[NQ + 1] += 2.0
    est = filt.update(y, Mode.FLIGHT, u)
    assert filt.restarts == 0 and filt.outliers == 1
    assert est[NQ + 1] - x[NQ + 1] == pytest.approx(filt.gain[1, 1] * 2.0, rel=0.3)
    assert abs(est[NQ + 1] - y[NQ + 1]) > 1.5  # not the observation
    for _ in range(5):
        x, _ = pred.step(x, u)
        filt.update(x, Mode.FLIGHT, u)
    assert filt.restarts == 0
    # a push: 0.8 m/s more forward speed from now on: the second observation beyond the gate restarts the estimate
    truth = x.copy()
    truth[NQ] += 0.8
    truth, _ = pred.step(truth, u)
    est = filt.update(truth, Mode.FLIGHT, u)
    assert filt.restarts == 0 and filt.outliers == 2
    assert est[NQ] < truth[NQ] - 0.4
    truth, _ = pred.step(truth, u)
    est = filt.update(truth, Mode.FLIGHT, u)
    assert filt.restarts == 1
    np.testing.assert_allclose(est[1:], truth[1:])


def test_filter_restart_steps_one_restarts_at_the_first_outlier():
    filt, pred, x, u = _settled_filter(restart_steps=1)
    x, _ = pred.step(x, u)
    y = x.copy()
    y[NQ + 6] += 5.0
    est = filt.update(y, Mode.FLIGHT, u)
    assert filt.restarts == 1 and filt.outliers == 0
    np.testing.assert_allclose(est[1:], y[1:])
    with pytest.raises(ValueError, match="restart_steps"):
        StateFilter(ContactModelPredictor(0.005), restart_steps=0)
    with pytest.raises(ValueError, match="filter_restart_steps"):
        MPCOptions(filter_restart_steps=0)
