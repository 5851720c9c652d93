"""The trunk-mass estimate from the stances' vertical impulse (``MassEstimate``) and the motion MPC's plans on a model
of the estimated mass (``MotionOptions.mass_estimate``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.core.conventions import Mode, mode_from_contacts
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import DEFAULT_PARAMS
from hsddp_gym.planners.policies import MPCPolicy
from hsddp_gym.planners.policies.estimation import MassEstimate

STEPS = 300
"""1.5 s of bounding: six stances or more."""


def _bounding(trunk_mass_scale: float):
    """Exact states (n, 14), contact modes and executed torques (n, 4) [N m] (None first) of the bounding MPC in
    Bounding-v0 with the trunk's mass scaled (no latency: the torque executed up to an observation is the last
    action's)."""
    env = gym.make("hsddp_gym/Bounding-v0", trunk_mass_scale=trunk_mass_scale)
    policy = MPCPolicy.from_env(env)
    limit = float(env.unwrapped.torque_limit)
    obs, info = env.reset(seed=5)
    policy.reset()
    states, modes, torques, last = [], [], [], None
    for _ in range(STEPS):
        action = policy.act(obs)
        obs, _, terminated, truncated, info = env.step(action)
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        modes.append(mode_from_contacts(*info["contact"]))
        torques.append(last)
        last = np.clip(action, -1.0, 1.0).astype(np.float64) * limit
        assert not (terminated or truncated)
    env.close()
    return np.array(states), modes, torques


@pytest.mark.parametrize("scale", [0.85, 1.0, 1.15])
def test_the_trunk_mass_is_found_from_the_stances_whatever_it_is(scale):
    states, modes, torques = _bounding(scale)
    est = MassEstimate(CheetahModel(), 0.005)
    for y, m, u in zip(states, modes, torques):
        est.update(y, u, m)
    assert est.stances >= 5
    assert est.scale == pytest.approx(scale, abs=0.03)


def test_noise_averages_out_and_without_stances_or_torques_nothing_is_learnt():
    states, modes, torques = _bounding(1.15)
    rng = np.random.default_rng(0)
    noisy = MassEstimate(CheetahModel(), 0.005)
    for y, m, u in zip(states, modes, torques):
        noisy.update(y + np.r_[np.full(7, 0.01), np.full(7, 0.1)] * rng.standard_normal(14), u, m)
    assert noisy.scale == pytest.approx(1.15, abs=0.06)
    flight = MassEstimate(CheetahModel(), 0.005)
    blind = MassEstimate(CheetahModel(), 0.005)
    for y, m, u in zip(states, modes, torques):
        flight.update(y, u, Mode.FLIGHT)
        blind.update(y, None, m)
    assert flight.stances == blind.stances == 0 and flight.scale == blind.scale == 1.0


def test_the_estimate_is_bounded_and_validates_its_arguments():
    states, modes, torques = _bounding(1.0)
    est = MassEstimate(CheetahModel(), 0.005, limits=(0.9, 1.05))
    for y, m, u in zip(states, modes, torques):
        est.update(y, None if u is None else 1.4 * u, m)  # more torque than moved the robot: a heavier one
    assert est.scale == pytest.approx(1.05)
    light = MassEstimate(CheetahModel(), 0.005, limits=(0.9, 1.05))
    for y, m, u in zip(states, modes, torques):
        light.update(y, None if u is None else 0.7 * u, m)
    assert light.scale == pytest.approx(0.9)
    robot = CheetahModel()
    for kwargs, name in (({"memory": 0.0}, "memory"), ({"settle_steps": 0}, "settle_steps"),
                         ({"min_steps": 0}, "min_steps"), ({"prior": 0.0}, "prior"), ({"limits": (1.1, 1.2)}, "limits"),
                         ({"limits": (0.0, 1.2)}, "limits")):
        with pytest.raises(ValueError, match=name):
            MassEstimate(robot, 0.005, **kwargs)
    with pytest.raises(TypeError, match="robot"):
        MassEstimate(None, 0.005)
    est = MassEstimate(robot, 0.005)
    with pytest.raises(ValueError, match="y"):
        est.update(np.zeros(7), None, Mode.FLIGHT)
    with pytest.raises(ValueError, match="torque"):
        est.update(states[0], np.array([np.nan, 0.0, 0.0, 0.0]), modes[0])
    with pytest.raises(ValueError, match="scale"):
        DEFAULT_PARAMS.with_trunk_mass_scale(0.0)


def test_the_motion_mpc_plans_on_a_model_of_the_estimated_trunk_mass():
    """``MotionMPCPolicy.plan_dynamics``: the reference's model while the estimate rounds to 1; a model whose trunk has
    the estimated mass (rounded to ``mass_step``) otherwise, built once; the re-plans are on it; the nominal model
    with ``mass_estimate=False``."""
    from hsddp_gym.rollout.policies import PolicySpec
    from hsddp_gym.workflows import make_policy

    env = gym.make("hsddp_gym/GapJump-v0")
    mpc = make_policy("mpc", env)
    nominal = mpc.reference.problem.dynamics
    mpc.estimator.mass.scale = 1.004
    assert mpc.plan_dynamics() is nominal
    mpc.estimator.mass.scale = 1.127
    heavy = mpc.plan_dynamics()
    assert heavy.robot.params.trunk.mass == pytest.approx(1.13 * DEFAULT_PARAMS.trunk.mass)
    assert heavy.robot.params.trunk.inertia_yy == pytest.approx(1.13 * DEFAULT_PARAMS.trunk.inertia_yy)
    assert heavy.robot.params.thigh == DEFAULT_PARAMS.thigh and heavy.dt == nominal.dt
    assert mpc.plan_dynamics() is heavy
    x = mpc.reference.solution.X[0]
    assert mpc._remaining(x).dynamics is heavy
    off = make_policy(PolicySpec("mpc", env_id="hsddp_gym/GapJump-v0", options={"mass_estimate": False}), env)
    assert off.estimator.mass is None and off.plan_dynamics() is off.reference.problem.dynamics
    with pytest.raises(ValueError, match="mass_step"):
        from hsddp_gym.planners.policies.mpc.options import MotionOptions

        MotionOptions(mass_step=0.0)
    env.close()
