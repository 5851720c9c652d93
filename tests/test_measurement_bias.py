"""The MPC's estimate of a constant bias of the measured trunk height and pitch from the feet on the ground
(``MeasurementBias``, ``MPCOptions.bias_memory``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.core.conventions import IPITCH, IVX, IZ, NQ, NX, Mode, mode_from_contacts
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies import MPCOptions, MPCPolicy
from hsddp_gym.planners.policies.estimation import MeasurementBias
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy


def _bounding(policy_class):
    """Exact states (n, 14) and contact modes of 2 s of ``policy_class.from_env`` bounding in Bounding-v0."""
    env = gym.make("hsddp_gym/Bounding-v0")
    policy = policy_class.from_env(env)
    obs, info = env.reset(seed=3)
    policy.reset()
    states, modes = [], []
    for _ in range(400):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        modes.append(mode_from_contacts(*info["contact"]))
        assert not (terminated or truncated)
    env.close()
    return np.array(states), modes


@pytest.fixture(scope="module")
def bounding_trajectory():
    """Exact states (n, 14) and contact modes of 2 s of the heuristic bounding in Bounding-v0."""
    return _bounding(HeuristicPolicy)


def _estimate(states, modes, bias, noise=0.0, seed=0, **kwargs):
    rng = np.random.default_rng(seed)
    est = MeasurementBias(CheetahModel(), 0.005, **kwargs)
    for x, m in zip(states, modes):
        y = x + bias + noise * rng.standard_normal(NX) * np.r_[np.full(NQ, 0.1), np.ones(NX - NQ)]
        est.update(y, m)
    return est


def test_a_constant_bias_of_height_and_pitch_is_recovered_whatever_the_velocity_bias(bounding_trajectory):
    states, modes = bounding_trajectory
    bias = np.zeros(NX)
    bias[[IZ, IPITCH, IVX, NQ + IZ, NQ + IPITCH]] = [-0.02, 0.03, 0.05, -0.04, 0.2]
    est = _estimate(states, modes, bias)
    assert est.samples > 200 and est.calibrated
    err = np.abs(est.bias - bias)
    assert err[IZ] < 1e-3 and err[IPITCH] < 2e-3
    assert not np.any(est.bias[NQ:])  # velocities are left alone
    corrected = est.correct(states[-1] + bias, modes[-1])
    assert abs(corrected[IZ] - states[-1][IZ]) < 1e-3


def test_exact_measurements_give_no_bias_and_noise_averages_out(bounding_trajectory):
    states, modes = bounding_trajectory
    exact = _estimate(states, modes, np.zeros(NX))
    assert np.max(np.abs(exact.bias)) < 1e-4
    noisy = _estimate(states, modes, np.zeros(NX), noise=0.1, seed=1)  # 1 cm on positions
    assert abs(noisy.bias[IZ]) < 3e-3 and abs(noisy.bias[IPITCH]) < 1e-2


def test_no_foot_on_the_ground_no_estimate(bounding_trajectory):
    states, _ = bounding_trajectory
    est = _estimate(states, [Mode.FLIGHT] * len(states), np.full(NX, 0.01))
    assert est.samples == 0 and not np.any(est.bias) and not est.calibrated


def test_outliers_are_not_used_and_estimates_are_bounded(bounding_trajectory):
    states, modes = bounding_trajectory
    bias = np.zeros(NX)
    bias[IZ] = -0.2  # beyond the gate plus the bound of every sample: nothing is learnt
    est = _estimate(states, modes, bias)
    assert est.samples == 0 and not np.any(est.bias)
    est = _estimate(states, modes, bias, gate=1.0)
    assert est.bias[IZ] == pytest.approx(-est.limit[0]) and est.limit[0] == 0.1  # the bound


@pytest.mark.parametrize("height", [-0.08, 0.08])
def test_a_height_bias_beyond_the_gate_is_found_and_a_jump_after_the_calibration_is_not(bounding_trajectory, height):
    """Before the calibration the gate is measured from the bound: a height bias of 8 cm, beyond the 5 cm gate, is
    estimated (measured from the zero prior, every sample was beyond the gate and the estimate stayed at 0). Once
    calibrated, the gate is measured from the estimate: a foot flagged on the ground 8 cm from where the estimate
    puts it is not used."""
    states, modes = bounding_trajectory
    bias = np.zeros(NX)
    bias[IZ] = height
    est = _estimate(states, modes, bias)
    assert est.calibrated and est.bias[IZ] == pytest.approx(height, abs=2e-3)
    est = MeasurementBias(CheetahModel(), 0.005)
    half = len(states) // 2
    for x, m in zip(states[:half], modes[:half]):  # exact: calibrated at 0
        est.update(x, m)
    assert est.calibrated and abs(est.bias[IZ]) < 1e-4
    used = est.samples
    for x, m in zip(states[half:], modes[half:]):
        est.update(x + bias, m)
    assert est.samples == used and abs(est.bias[IZ]) < 1e-4


def test_measurement_bias_validation_names_the_argument():
    robot = CheetahModel()
    with pytest.raises(ValueError, match="memory"):
        MeasurementBias(robot, 0.005, memory=0.0)
    with pytest.raises(ValueError, match="settle_steps"):
        MeasurementBias(robot, 0.005, settle_steps=0)
    with pytest.raises(ValueError, match="gate"):
        MeasurementBias(robot, 0.005, gate=0.0)
    with pytest.raises(ValueError, match="limit"):
        MeasurementBias(robot, 0.005, limit=(0.05, -1.0))
    with pytest.raises(TypeError, match="robot"):
        MeasurementBias(None, 0.005)
    with pytest.raises(ValueError, match="bias_memory"):
        MPCOptions().replace(bias_memory=-1.0)


def test_a_landing_foot_is_measured_from_where_the_measurement_puts_the_ground():
    from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
    from hsddp_gym.planners.policies.mpc import GaitClock, late_landing

    robot = CheetahModel()
    clock = GaitClock(PAPER_BOUNDING_DURATIONS, 0.005)
    clock.phase, clock.tau = 1, PAPER_BOUNDING_DURATIONS[1]  # a flight at its nominal end: the front foot lands
    q = robot.place_feet(np.array([0.0, 0.3, 0.0, -0.8, 1.6, -0.8, 1.6]), np.array([[0.2, 0.005], [-0.2, 0.1]]))
    x = np.r_[q, np.zeros(NX - NQ)]  # the measured state: the front foot 5 mm up
    assert late_landing(clock, Mode.FLIGHT, x, robot, 0.01) == Mode.FRONT_STANCE
    # the measurement puts a foot on the ground 2 cm low: this one is 2.5 cm above the ground
    assert late_landing(clock, Mode.FLIGHT, x, robot, 0.01, None, lambda q, foot: -0.02) == Mode.FLIGHT
    est = MeasurementBias(robot, 0.005)
    est.bias[IZ] = -0.02
    assert est.ground_offset(q, 0) == pytest.approx(-0.02)


def test_the_plans_put_the_ground_where_the_feet_put_it_and_search_for_it_before():
    """The plans' ground (``ContactScheduleEstimator.plan_height``): before a stance has calibrated the bias estimate,
    the measured ground, lowered from a flight's nominal end on by ``ground_search_speed`` times the lateness (at most
    the estimate's height bound); once calibrated, where the estimate puts a foot that stands on the ground. The
    switching constraints land the feet on it and the reference heights are measured from it."""
    env = gym.make("hsddp_gym/Bounding-v0")
    try:
        policy = MPCPolicy.from_env(env)
        obs, info = env.reset(seed=0)
        policy.act(obs)
        x = np.concatenate([info["qpos"], info["qvel"]])
        clock, bias, schedule = policy.clock, policy.estimator.bias, policy.schedule
        clock.phase, clock.tau = 1, clock.durations[1] - 0.01  # a flight before its nominal end: the measured ground
        assert schedule.plan_height(bias) == 0.0
        assert policy.replan(x)
        assert policy.law.plan.problem.terrain is None
        flat_refs = np.array([c.x_ref[IZ] for c in policy.law.plan.problem.costs])
        clock.tau = clock.durations[1] + 0.02  # 20 ms late
        assert schedule.plan_height(bias) == pytest.approx(-0.5 * 0.02)
        assert policy.replan(x)
        problem, sol = policy.law.plan.problem, policy.law.plan.solution
        assert problem.terrain.height(0.0) == pytest.approx(-0.01)
        later = [(p, f) for p, f in zip(problem.switch_phase, problem.switch_foot) if f >= 0][1:]
        robot = policy.planner.dynamics.robot
        assert later and all(robot.foot_height(sol.X_pre[p, :NQ], f) < -0.005 for p, f in later)
        assert np.allclose([c.x_ref[IZ] for c in problem.costs], flat_refs - 0.01)
        clock.tau = clock.durations[1] + 1.0  # at most the estimate's height bound
        assert schedule.plan_height(bias) == pytest.approx(-bias.limit[0])
        clock.phase = 0  # a stance: the measured ground
        assert schedule.plan_height(bias) == 0.0
        # calibrated: the ground where the feet put it, in every phase, and the model stands on it too
        assert policy.estimator.model_ground() == 0.0
        bias._info[0, 0] = MeasurementBias.CALIBRATION_STEPS
        bias.bias[IZ] = 0.03
        assert bias.calibrated and policy.estimator.model_ground() == 0.03
        for phase in (0, 1, 2, 3):
            clock.phase = phase
            assert schedule.plan_height(bias) == pytest.approx(0.03)
        assert policy.replan(x)
        assert policy.law.plan.problem.terrain.height(0.4) == pytest.approx(0.03)
        off = MPCPolicy.from_env(env, options=MPCOptions().replace(ground_search_speed=None))
        off.clock.phase, off.clock.tau = 1, clock.durations[1] + 0.02
        assert off.schedule.plan_height(off.estimator.bias) == 0.0
        bare = MPCPolicy.from_env(env, options=MPCOptions().replace(bias_memory=None))
        bare.clock.phase, bare.clock.tau = 1, clock.durations[1] + 0.02
        assert bare.estimator.bias is None and bare.schedule.plan_height(None) == 0.0
        assert bare.estimator.model_ground() == 0.0
        with pytest.raises(ValueError, match="ground_search_speed"):
            MPCOptions().replace(ground_search_speed=0.0)
    finally:
        env.close()


def test_the_late_landing_rule_waits_for_the_calibration():
    """Before the feet have calibrated where the measurement puts the ground, a late flight's landing foot near
    ``z = 0`` is no evidence of a touchdown (the ground may be centimetres away): the flags alone decide. Once
    calibrated, the foot is measured from the calibrated ground."""
    from hsddp_gym.core.conventions import FRONT

    policy = MPCPolicy()
    robot, schedule, bias = policy.planner.dynamics.robot, policy.schedule, policy.estimator.bias
    q = robot.place_feet(np.array([0.0, 0.3, 0.0, -0.8, 1.6, -0.8, 1.6]), np.array([[0.2, 0.005], [-0.2, 0.1]]))
    x = np.r_[q, np.zeros(NX - NQ)]  # the front foot 5 mm up
    policy.clock.phase, policy.clock.tau = 1, policy.clock.durations[1] + 0.01  # late: the front foot lands
    assert not bias.calibrated
    assert schedule.evidence(x, Mode.FLIGHT, bias) == Mode.FLIGHT
    assert schedule.evidence(x, Mode.FLIGHT, None) == Mode.FRONT_STANCE  # no estimate: the state from the start
    bias._info[0, 0] = MeasurementBias.CALIBRATION_STEPS
    assert schedule.evidence(x, Mode.FLIGHT, bias) == Mode.FRONT_STANCE
    bias.bias[IZ] = -0.02  # the measurement puts the ground 2 cm low: the foot is 2.5 cm above it
    assert schedule.evidence(x, Mode.FLIGHT, bias) == Mode.FLIGHT
    assert Mode.FRONT_STANCE.in_contact(FRONT)


def test_the_model_on_a_raised_ground_is_the_model_on_the_raised_terrain():
    """``ContactModelPredictor.step(..., ground=g)`` (the state lowered by ``g``, stepped, raised again) is the model
    whose ground is the terrain raised by ``g``, touchdowns and stance included; ``project_onto_contacts`` puts the
    stance feet on the raised ground."""
    from hsddp_gym.core.terrain import Terrain
    from hsddp_gym.planners.policies.estimation import ContactModelPredictor, project_onto_contacts

    robot = CheetahModel()
    flat, raised = ContactModelPredictor(0.005), ContactModelPredictor(0.005)
    g = -0.03
    raised.set_terrain(Terrain.flat().raised(g))
    x = np.r_[robot.place_feet(np.array([0.0, 0.3, 0.05, -0.8, 1.6, -0.8, 1.6]),
                               np.array([[0.2, 0.004], [-0.2, 0.03]])), np.zeros(NX - NQ)]
    x[NQ + IZ] = -0.4  # falling onto the front foot
    x[IZ] += g
    u = np.array([5.0, -10.0, 3.0, -6.0])
    xa, xb, modes = x.copy(), x.copy(), set()
    for _ in range(30):
        xa, ma = flat.step(xa, u, ground=g)
        xb, mb = raised.step(xb, u)
        assert ma == mb
        modes.add(ma)
    assert len(modes) > 1 and np.abs(xa - xb).max() < 1e-9
    y = x.copy()
    y[IZ] += 0.01  # the feet 1 cm above where the stance puts them
    p = project_onto_contacts(robot, y, Mode.DOUBLE_STANCE, None, g)
    assert np.allclose([robot.foot_height(p[:NQ], f) for f in (0, 1)], g, atol=1e-3)  # one Gauss-Newton step
    assert np.allclose(p, project_onto_contacts(robot, y, Mode.DOUBLE_STANCE, Terrain.flat().raised(g)), atol=1e-12)
    from hsddp_gym.planners.policies.estimation import StateFilter
    from hsddp_gym.planners.policies.latency import DelayEstimator

    filt, delay = StateFilter(ContactModelPredictor(0.005)), DelayEstimator(ContactModelPredictor(0.005), 1)
    for bad, error in ((float("nan"), ValueError), (float("inf"), ValueError), ("0", TypeError), (True, TypeError)):
        with pytest.raises(error, match="ground"):
            flat.step(x, u, ground=bad)
        with pytest.raises(error, match="ground"):
            project_onto_contacts(robot, y, Mode.FLIGHT, None, bad)
        with pytest.raises(error, match="ground"):
            filt.update(x, Mode.FLIGHT, None, bad)
        with pytest.raises(error, match="ground"):
            delay.update(x, x, np.zeros((delay.history, 4)), bad)


def test_the_state_filter_on_the_measured_ground_sees_a_biased_height_as_the_exact_one():
    """A height sensor 3 cm low: the filter told that the ground is 3 cm low (where the feet put it) gives the
    estimate of the exact measurements, 3 cm low, to round-off, restarting where they do. Told the ground is at 0, it
    holds each stance's feet at 0, 3 cm above where the measurement puts them, and restarts again and again. A ground
    that moves (the bias estimate's calibration) moves the estimate with it: a bias that appears with its ground
    halfway through gives the exact estimate from there on, 3 cm low."""
    from hsddp_gym.planners.policies.estimation import ContactModelPredictor, StateFilter

    env = gym.make("hsddp_gym/Bounding-v0")
    policy = HeuristicPolicy.from_env(env)
    obs, info = env.reset(seed=3)
    policy.reset()
    x_prev = np.concatenate([info["qpos"], info["qvel"]])
    states, modes, torques = [x_prev], [mode_from_contacts(*info["contact"])], []
    for _ in range(200):
        action = policy.act(obs)
        obs, _, _, _, info = env.step(action)
        torques.append(np.clip(action, -1, 1) * env.unwrapped.torque_limit)
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        modes.append(mode_from_contacts(*info["contact"]))
    env.close()
    shift = -0.03 * np.eye(NX)[IZ]
    n, half = len(states), len(states) // 2
    runs = {}
    for name, biased, ground in (("exact", [False] * n, 0.0), ("biased", [True] * n, shift[IZ]),
                                 ("biased, ground 0", [True] * n, 0.0),
                                 ("biased from halfway", [k >= half for k in range(n)], None)):
        filt = StateFilter(ContactModelPredictor(0.005))
        est = []
        for k in range(n):
            g = (shift[IZ] if biased[k] else 0.0) if ground is None else ground
            y = states[k] + shift if biased[k] else states[k]
            est.append(filt.update(y, modes[k], torques[k - 1] if k else None, g))
        runs[name] = (np.array(est), filt.restarts)
    exact = runs["exact"][0]
    assert np.abs(runs["biased"][0] - exact - shift).max() < 1e-9
    assert runs["biased"][1] == runs["exact"][1]
    assert runs["biased, ground 0"][1] > runs["exact"][1] + 5
    assert np.abs(runs["biased from halfway"][0][half:] - exact[half:] - shift).max() < 1e-9


@pytest.fixture(scope="module")
def mpc_bounding_trajectory():
    """Exact states (n, 14) and contact modes of 2 s of the bounding MPC in Bounding-v0 (its stance feet at rest to
    a few mm/s; the heuristic's back foot slips)."""
    return _bounding(MPCPolicy)


def _odometry(states, modes, speed_bias, noise=0.0, seed=0, **kwargs):
    from hsddp_gym.planners.policies.estimation import Odometry

    rng = np.random.default_rng(seed)
    odo = Odometry(CheetahModel(), 0.005, **kwargs)
    xs = []
    for x, m in zip(states, modes):
        y = x.copy()
        y[IVX] += speed_bias
        y[NQ:] += noise * rng.standard_normal(NX - NQ)
        xs.append(odo.update(y, m))
    return odo, np.array(xs)


@pytest.mark.parametrize("speed_bias", [0.0, 0.05, -0.1])
def test_odometry_takes_the_forward_speed_bias_the_stance_feet_show_out_of_the_whole_integral(mpc_bounding_trajectory,
                                                                                              speed_bias):
    """A foot on the ground is at rest: its forward velocity computed from the measurement is the measurement's
    forward-speed bias. The bias, once estimated, comes off the whole integral (the constant bias drifted it from the
    first observation on). The fit separates the bias from a foot's rolling only by how the shank's rate varies (it
    turns one way in every stance, at 4.4 +- 1.8 rad/s here): to 1 cm/s, and the trunk x within 2 cm over 2 s."""
    states, modes = mpc_bounding_trajectory
    odo, xs = _odometry(states, modes, speed_bias)
    assert odo.samples > 150
    assert odo.speed_bias == pytest.approx(speed_bias, abs=0.01) and abs(odo.rolling) < 5e-3
    travelled = states[:, 0] - states[0, 0]
    assert np.max(np.abs(xs[-100:] - travelled[-100:])) < 0.02
    plain, xs_plain = _odometry(states, modes, speed_bias, memory=None)  # not estimated: the integral drifts
    assert plain.speed_bias == 0.0 and plain.samples == 0
    assert abs(xs_plain[-1] - travelled[-1]) == pytest.approx(abs(speed_bias) * 0.005 * (len(states) - 1), abs=0.01)


def test_a_rolling_foot_is_not_a_speed_bias(mpc_bounding_trajectory):
    """A round foot larger than the model's point rolls: its centre moves at ``rho w`` (``w`` its shank's rate) while
    its contact point rests. Measurements whose single stance foot moves at ``b + rho w`` give back ``b`` and ``rho``;
    a mean of the feet's velocity would read the rolling (``rho`` times 4.4 rad/s, 9 cm/s here) as a bias."""
    from hsddp_gym.core.conventions import FOOT_JOINTS
    from hsddp_gym.planners.policies.estimation import Odometry

    states, modes = mpc_bounding_trajectory
    b, rho = 0.03, 0.02
    odo = Odometry(CheetahModel(), 0.005)
    rolled = []
    for x, m in zip(states, modes):
        y = x.copy()
        y[IVX] += b
        if m in (Mode.FRONT_STANCE, Mode.BACK_STANCE):
            hip, knee = FOOT_JOINTS[0 if m == Mode.FRONT_STANCE else 1]
            y[IVX] += rho * (y[NQ + IPITCH] + y[NQ + hip] + y[NQ + knee])
            rolled.append(rho * (y[NQ + IPITCH] + y[NQ + hip] + y[NQ + knee]))
        odo.update(y, m)
    assert np.mean(rolled) > 0.05
    assert odo.speed_bias == pytest.approx(b, abs=0.01) and odo.rolling == pytest.approx(rho, abs=3e-3)


def test_odometry_averages_noise_ignores_slipping_feet_and_validates(mpc_bounding_trajectory):
    from hsddp_gym.planners.policies.estimation import Odometry

    states, modes = mpc_bounding_trajectory
    noisy, _ = _odometry(states, modes, 0.05, noise=0.1, seed=2)
    assert noisy.speed_bias == pytest.approx(0.05, abs=0.02)
    flight, xs = _odometry(states, [Mode.FLIGHT] * len(states), 0.05)  # no foot on the ground: nothing to learn
    assert flight.samples == 0 and flight.speed_bias == 0.0
    slipping, _ = _odometry(states, modes, 0.8)  # every sample beyond the 0.2 m/s gate from the zero start
    assert slipping.samples == 0 and slipping.speed_bias == 0.0
    bounded, _ = _odometry(states, modes, 0.8, gate=2.0)
    assert bounded.speed_bias == pytest.approx(0.3)  # the limit
    robot = CheetahModel()
    for kwargs, name in (({"memory": 0.0}, "memory"), ({"settle_steps": 0}, "settle_steps"), ({"gate": 0.0}, "gate"),
                         ({"limit": -1.0}, "limit"), ({"min_samples": 0}, "min_samples")):
        with pytest.raises(ValueError, match=name):
            Odometry(robot, 0.005, **kwargs)
    with pytest.raises(TypeError, match="robot"):
        Odometry(None, 0.005)
    with pytest.raises(ValueError, match="y"):
        Odometry(robot, 0.005).update(np.zeros(3), Mode.FLIGHT)


def test_the_motion_mpc_plans_from_the_state_less_the_speed_bias_the_bound_does_not(
        mpc_bounding_trajectory):
    """``MotionOptions.bias_correction``: the state the motion MPC's estimator gives its plans is the measurement
    less the estimated forward-speed bias (the height bias stays the model's ground, the pitch bias is left); the
    bounding MPC's
    estimator leaves the measurement alone."""
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.planners.policies.mpc.state import StateEstimator

    states, modes = mpc_bounding_trajectory
    bias = np.zeros(NX)
    bias[[IZ, IPITCH, IVX]] = [-0.02, 0.03, 0.05]
    estimators = {}
    for correct in (True, False):
        est = StateEstimator(EnvInterface(), MPCOptions().estimator, CheetahModel(), correct_bias=correct)
        est.reset()
        for x, m in zip(states, modes):
            y = x + bias
            est.trunk_x(y, m)
            est.bias.update(y, m)
        estimators[correct] = est
    y = states[-1] + bias
    corrected = estimators[True].corrected(y)
    np.testing.assert_allclose(corrected - states[-1], [0, -0.02, 0.03, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], atol=0.015)
    assert estimators[True].model_ground() == pytest.approx(-0.02, abs=2e-3)
    assert estimators[False].odometry.speed_bias == 0.0  # not estimated without the correction
    bound = MPCPolicy(EnvInterface(), MPCOptions())
    assert bound.estimator.correct_bias is False and bound.estimator.mass is None
    with pytest.raises(TypeError, match="correct_bias"):
        StateEstimator(EnvInterface(), MPCOptions().estimator, CheetahModel(), correct_bias=1)
    env = gym.make("hsddp_gym/GapJump-v0")
    from hsddp_gym.workflows import make_policy

    motion = make_policy("mpc", env)
    assert motion.estimator.correct_bias is True and motion.gait.estimator is motion.estimator
    from hsddp_gym.rollout.policies import PolicySpec

    spec = PolicySpec("mpc", env_id="hsddp_gym/GapJump-v0", options={"bias_correction": False})
    assert make_policy(spec, env).estimator.correct_bias is False
    env.close()
