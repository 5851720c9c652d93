"""The planner's model as an env (envs/kkt_twin.py, hsddp_gym/BoundingKKT-v0): API, seeding, pinned stance feet,
touchdown reset maps, lift-off on a negative KKT normal force, landing without penetration, invalid states."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.core.conventions import BACK, FRONT, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.kkt_twin import KKTBoundingEnv, KKTSimulator

Q_STAND = np.array([0.0, 0.0, 0.0, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])


def posture(robot, lift: float = 0.0, q: np.ndarray = Q_STAND) -> np.ndarray:
    """``q`` with its lowest foot ``lift`` above the ground, at rest (14,)."""
    q = q.copy()
    q[1] = lift - robot.foot_heights(q).min()
    return np.concatenate([q, np.zeros(7)])


def pd(sim, q_ref=Q_STAND, kp=100.0, kd=1.0):
    """Joint PD toward ``q_ref`` (stable at 1 kHz for the light legs)."""
    return kp * (q_ref[3:] - sim.q[3:]) - kd * sim.v[3:]


def test_registered_env_has_the_task_of_bounding_v0():
    import gymnasium.utils.env_checker as checker

    lcp = gym.make(hsddp_gym.BOUNDING_ENV_ID)
    kkt = gym.make(hsddp_gym.BOUNDING_KKT_ENV_ID)
    assert isinstance(kkt.unwrapped, KKTBoundingEnv) and isinstance(kkt.unwrapped, BoundingEnv)
    assert kkt.spec.max_episode_steps == lcp.spec.max_episode_steps == 1000
    assert kkt.observation_space == lcp.observation_space and kkt.action_space == lcp.action_space
    checker.check_env(kkt.unwrapped, skip_render_check=True)
    obs_a, info_a = lcp.reset(seed=3)
    obs_b, info_b = kkt.reset(seed=3)
    np.testing.assert_array_equal(obs_a, obs_b)  # same reset distribution and seeding
    assert set(info_b) == set(info_a) | {"friction_ratio"} and info_b["friction_ratio"] == 0.0
    _, reward, terminated, truncated, info = kkt.step(np.zeros(4, dtype=np.float32))
    assert isinstance(reward, float) and not truncated and info.keys() == info_b.keys()
    with pytest.raises(TypeError, match="action"):
        kkt.step(np.array([1j, 0, 0, 0]))
    with pytest.raises(ValueError, match="friction"):
        KKTBoundingEnv(friction=-1.0)


def test_same_seed_same_trajectory_different_seed_differs():
    def rollout(seed):
        env = KKTBoundingEnv()
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(60):
            obs, *_ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            out.append(obs)
        return np.array(out)

    a, b, c = rollout(5), rollout(5), rollout(6)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 1e-3


@pytest.mark.parametrize("stabilize", [True, False])
def test_stance_feet_stay_pinned_and_the_model_reports_its_friction_demand(stabilize):
    """Double stance under a joint PD that swings the trunk: the feet do not slip (the planner's model has no
    friction cone) and the tangential force they need is reported, not limited. With the stabilization they stay
    at their anchors to round-off; the bare discrete model lets them creep (O(h^2) per step)."""
    sim = KKTSimulator(motor_speed_limits=(36.0, 50.0), stabilize=stabilize)
    sim.set_state(posture(sim.robot, -1e-7))  # both feet just below the ground: pinned by the first step
    sim.step(pd(sim))
    assert sim.mode == Mode.DOUBLE_STANCE
    start = sim.foot_positions().copy()
    ratios, violations = [], sim.cone_violations
    for k in range(300):
        wave = 0.1 * math.sin(0.02 * k)
        sim.run(pd(sim, q_ref=Q_STAND + np.array([0, 0, 0, wave, 0, -wave, 0])), 1)
        assert sim.mode == Mode.DOUBLE_STANCE
        ratios.append(sim.friction_ratio)
    drift = np.abs(sim.foot_positions() - start).max()
    if stabilize:
        assert drift < 1e-12 and np.abs(sim.foot_velocities()).max() < 1e-12, drift
        assert 1e-9 < sim.pin_correction < 1e-5
    else:
        assert 1e-7 < drift < 1e-3, drift
    # the sway needs more than the friction cone allows (mu = 0.6): counted, not prevented
    assert max(ratios) > sim.mu and sim.cone_violations - violations == sum(r > sim.mu for r in ratios) > 0


def test_touchdown_applies_the_reset_map():
    """A foot falling onto the ground stops in the step it crosses z = 0: post-impact foot velocity 0 (to the
    O(h) of the remaining part of the step), a positive normal impulse, no bounce."""
    sim = KKTSimulator()
    x = posture(sim.robot, 0.002)
    x[8] = -0.5  # falling at 0.5 m/s: crosses the ground within 4-5 steps
    sim.set_state(x)
    for _ in range(20):
        before = sim.foot_velocities()[:, 1].copy()
        sim.step(np.zeros(4))
        if sim.touchdowns:
            break
    assert sim.touchdowns >= 1 and sim.mode == Mode.DOUBLE_STANCE
    assert np.all(before < -0.4)
    after = sim.foot_velocities()
    assert np.abs(after).max() < 0.02 * 0.5, after  # the reset map zeroed the feet's velocities
    assert sim.impulse[1] > 0.0 and sim.impulse[3] > 0.0
    assert np.all(sim.foot_heights() > -1e-5)
    # the landing state is the reset map of the crossing state: its foot velocity is exactly 0 there
    dyn = HybridDynamics(sim.robot, integrator="semi_implicit")
    x_plus, impulse = dyn.reset_map(sim.x, Mode.DOUBLE_STANCE)
    assert np.abs(sim.robot.foot_velocities(x_plus)).max() < 1e-9


def test_lift_off_exactly_when_the_kkt_normal_force_turns_negative():
    """In back stance, random torques: the foot is released in a step exactly when the planner's KKT dynamics of
    that mode give it a negative normal force; otherwise it stays pinned. Both cases occur."""
    rng = np.random.default_rng(0)
    dyn = HybridDynamics(integrator="semi_implicit")
    q = Q_STAND.copy()
    q[2] = -0.15  # nose up: the back foot is the lowest
    outcomes = set()
    for _ in range(40):
        sim = KKTSimulator()
        sim.set_state(posture(sim.robot, 0.0, q))
        sim.step(np.zeros(4))
        assert sim.mode == Mode.BACK_STANCE
        u = rng.uniform(-33.0, 33.0, 4)
        _, grf = dyn.accelerations(sim.x, u, Mode.BACK_STANCE)
        sim.step(u)
        released = sim.liftoffs == 1  # it may be caught again in the same step if its free motion points down
        assert released == (grf[3] < 0.0), (grf, sim.mode)
        assert sim.liftoffs <= 1 and (sim.mode.in_contact(BACK) or released)
        outcomes.add(released)
    assert outcomes == {True, False}


def test_a_dropped_robot_lands_and_stands_without_penetration():
    sim = KKTSimulator(motor_speed_limits=(36.0, 50.0))
    sim.set_state(posture(sim.robot, 0.05))
    lowest = np.inf
    for _ in range(800):
        sim.run(pd(sim), 1)
        lowest = min(lowest, float(sim.foot_heights().min()))
    assert sim.mode == Mode.DOUBLE_STANCE and sim.touchdowns >= 2
    assert lowest > -1e-5, lowest  # the touchdown is located within the step; pinned feet do not sink
    assert 0.2 < sim.q[1] < 0.35  # standing (the pinned closed chain under a light joint PD still sways)


def test_invalid_state_is_reported_as_in_the_base_env():
    env = KKTBoundingEnv(terminate_when_unhealthy=False)
    env.reset(seed=0)
    env.sim.v[3] = np.nan
    obs, reward, terminated, _, info = env.step(np.zeros(4))
    assert terminated and info["invalid_state"] is True and math.isfinite(reward)
    assert np.isnan(info["qvel"]).any() and np.all(np.isfinite(obs))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4))
    env.reset(seed=0)
    env.apply_push([1e3, 0.0, 0.0])  # beyond the 100 m/s of a valid state
    _, _, terminated, _, info = env.step(np.zeros(4))
    assert terminated and info["invalid_state"] is True
    _, info = env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.zeros(4))
    assert not terminated and info["invalid_state"] is False


def test_simulator_arguments_are_checked():
    with pytest.raises(TypeError, match="robot"):
        KKTSimulator(robot="cheetah")
    with pytest.raises(ValueError, match="timestep"):
        KKTSimulator(timestep=0.0)
    with pytest.raises(ValueError, match="x"):
        KKTSimulator().set_state(np.zeros(3))
    sim = KKTSimulator(gravity=0.0)
    sim.set_state(posture(sim.robot, 0.1))
    e0 = sim.energy()
    sim.run(np.zeros(4), 50)  # flight without gravity or torque: the robot drifts at constant energy
    assert sim.mode == Mode.FLIGHT and abs(sim.energy() - e0) < 1e-9
    assert FRONT == 0
