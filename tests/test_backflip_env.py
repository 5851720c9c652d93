"""hsddp_gym/Backflip-v0: registration, both env checkers, seeding, the start state against the backflip planner's, the
reward terms, the success criterion (met by the HS-DDP expert, never by zero torque), and a small Minari dataset
recorded in it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.envs.backflip import (
    FULL_TURN,
    BackflipEnv,
    backflip_start_state,
    backflip_success,
    trunk_clearance,
)

ENV_ID = "hsddp_gym/Backflip-v0"


def test_registered_with_a_time_limit_and_the_task_vector_env():
    spec = gym.spec(ENV_ID)
    assert spec.entry_point == "hsddp_gym.envs.backflip:BackflipEnv"
    assert spec.max_episode_steps == hsddp_gym.BACKFLIP_MAX_EPISODE_STEPS == 400
    assert spec.vector_entry_point == "hsddp_gym.envs.task_vector:BackflipVectorEnv"
    env = gym.make(ENV_ID)
    assert isinstance(env.unwrapped, BackflipEnv)
    assert env.unwrapped.gait_period == pytest.approx(2.0)
    assert gym.spec("hsddp_gym/BackflipMuJoCo-v0").entry_point == "hsddp_gym.envs.backflip:MuJoCoBackflipEnv"


def test_gymnasium_env_checker_passes(tools):
    tools.assert_gymnasium_checker_passes(gym.make(ENV_ID))


def test_sb3_env_checker_passes(tools):
    tools.assert_sb3_checker_passes(gym.make(ENV_ID))


def test_sync_vector_env_runs():
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync")
    obs, info = envs.reset(seed=3)
    assert obs.shape == (2, 17)
    obs, reward, terminated, truncated, info = envs.step(np.zeros((2, 4), dtype=np.float32))
    assert reward.shape == (2,) and "success" in info and "reward_rotation" in info
    envs.close()


def test_same_seed_same_trajectory_and_different_seed_differs(tools):
    a, b, c = (tools.random_rollout(gym.make(ENV_ID), seed) for seed in (5, 5, 6))
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


def test_start_state_is_the_backflip_plans_and_the_noisy_start_stands_on_both_feet():
    from hsddp_gym.planners import motions

    robot = BackflipEnv().robot
    x0 = motions.backflip_problem()[0].x0
    np.testing.assert_allclose(backflip_start_state(robot), x0, atol=1e-12)
    env = BackflipEnv(reset_noise_scale=0.0)
    env.reset(seed=0)
    np.testing.assert_allclose(env.state, x0, atol=1e-12)
    noisy = BackflipEnv()
    for seed in range(5):
        noisy.reset(seed=seed)
        x = noisy.state
        assert not np.allclose(x, x0)
        np.testing.assert_allclose(robot.foot_heights(x[:7]), 0.0, atol=1e-9)  # both feet on the ground
        for f in (0, 1):  # and at rest
            np.testing.assert_allclose(robot.foot_jacobian(x[:7], f) @ x[7:], 0.0, atol=1e-9)
        assert noisy.contact.all()


def test_trunk_clearance_is_the_lower_hip():
    robot = BackflipEnv().robot
    for pitch in (0.3, -1.0, -3.0, FULL_TURN - 0.4):
        x = backflip_start_state(robot)
        x[2] = pitch
        hips = robot.hip_positions(x[:7])
        assert trunk_clearance(x, robot.params.hip_offset) == pytest.approx(min(hips[:, 1]), abs=1e-9)


def test_reward_terms_follow_the_documented_formula():
    env = BackflipEnv()
    obs, info = env.reset(seed=1)
    assert info["reward_rotation"] == 0.0 and info["reward_landing"] == 0.0 and info["success"] is False
    rng = np.random.default_rng(1)
    paid, progress = 0.0, info["pitch_progress"]
    assert progress == pytest.approx(min(max(-info["qpos"][2] / (2 * math.pi), 0.0), 1.0))
    for _ in range(60):
        a = rng.uniform(-0.5, 0.5, 4).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(a)
        a64 = np.clip(a.astype(np.float64), -1, 1)
        pitch = info["qpos"][2]
        progress_now = max(progress, min(max(-pitch / (2 * math.pi), 0.0), 1.0))
        assert info["pitch_progress"] == pytest.approx(progress_now)
        expected_rotation = -paid if terminated else 20.0 * (progress_now - progress)
        assert info["reward_rotation"] == pytest.approx(expected_rotation)
        assert info["reward_landing"] <= 1e-6  # far from -2 pi
        assert reward == pytest.approx(info["reward_rotation"] + info["reward_landing"] - 0.1 * float(a64 @ a64))
        paid += info["reward_rotation"]
        progress = progress_now
        if terminated:
            assert paid == pytest.approx(0.0, abs=1e-9)  # a fall takes the rotation reward back
            break


@pytest.mark.parametrize("kwargs, message", [({"rotation_reward": -1.0}, "rotation_reward"),
                                             ({"landing_reward": float("nan")}, "landing_reward"),
                                             ({"trunk_contact_height": 0.5}, "trunk_contact_height"),
                                             ({"reset_noise_scale": 0.2}, "reset_noise_scale")])
def test_bad_arguments_raise_naming_them(kwargs, message):
    with pytest.raises((ValueError, TypeError), match=message):
        BackflipEnv(**kwargs)


def test_success_criterion():
    upright = np.zeros(14)
    upright[1], upright[2] = 0.22, FULL_TURN + 0.05
    assert backflip_success(False, FULL_TURN - 0.3, upright, True)
    assert not backflip_success(True, FULL_TURN - 0.3, upright, True)  # a fall
    assert not backflip_success(False, FULL_TURN - 0.3, upright, False)  # not on both feet
    assert not backflip_success(False, -1.0, upright, True)  # no full turn
    moving = upright.copy()
    moving[7] = 0.5
    assert not backflip_success(False, FULL_TURN, moving, True)
    standing = upright.copy()
    standing[2] = 0.0
    assert not backflip_success(False, FULL_TURN, standing, True)  # not upright at -2 pi


def test_zero_torque_never_succeeds():
    env = gym.make(ENV_ID)
    for seed in (0, 1):
        env.reset(seed=seed)
        while True:
            _, _, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
            assert not info["success"]
            if terminated or truncated:
                break
        assert terminated  # the legs fold, the trunk drops: a fall


def test_the_expert_flips_lands_and_stands():
    from hsddp_gym.rollout.policies import make_policy

    env = gym.make(ENV_ID)
    policy = make_policy("expert", env)
    assert policy.reset_options is None
    obs, info = env.reset(seed=9999)
    min_pitch, ret = 0.0, 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        min_pitch = min(min_pitch, info["qpos"][2])
        assert not terminated
        if truncated:
            break
    assert info["success"] and policy.plan_over
    assert min_pitch < FULL_TURN and abs(info["qpos"][2] - FULL_TURN) < 0.1
    assert ret > 150.0  # the whole turn (20) and most of the hold's landing reward


def test_a_small_expert_dataset_writes_and_loads_with_minari(tmp_path):
    pytest.importorskip("minari")
    from hsddp_gym import cli
    from hsddp_gym.datasets.storage import load_npz, minari_root, read_metadata

    out = tmp_path / "flip"
    assert cli.main(["dataset", "--env", ENV_ID, "--policy", "expert", "--episodes", "2", "--max-episode-steps", "40",
                     "--out", str(out), "--quiet"]) == 0
    import minari

    meta = read_metadata(out)
    assert meta["dataset_id"] == "hsddp_gym/backflip/expert-v0" and meta["env_id"] == ENV_ID
    assert meta["policy"]["class"].endswith("experts.backflip_expert")
    with minari_root(out / "minari"):
        ds = minari.load_dataset("hsddp_gym/backflip/expert-v0")
        assert ds.total_episodes == 2 and ds.total_steps == 80
        ep = next(ds.iterate_episodes())
        assert ep.observations.shape == (41, 17) and "success" in ep.infos and "reward_rotation" in ep.infos
        assert ds.recover_environment().unwrapped.__class__.__name__ == "BackflipEnv"
    assert load_npz(out).n_episodes == 2
