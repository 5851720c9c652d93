"""Residual RL on the plan tracker (``hsddp_gym/learning/residual.py``): a zero residual is the expert, the env and the
policy compose the same actions, the run's summary rebuilds the policy, and bad settings raise naming the argument."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.learning.residual import (
    ResidualEnv,
    ResidualPolicy,
    check_residual_scale,
    residual_action,
    residual_observation,
)
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.rollout.episodes import run_episode
from hsddp_gym.rollout.policies import make_policy

ENV_ID = "hsddp_gym/Backflip-v0"


class _Learner(Policy):
    """A deterministic stand-in for a trained learner: a fixed smooth function of its input."""

    def __init__(self) -> None:
        super().__init__(EnvInterface())
        self.w = np.random.default_rng(0).normal(0.0, 0.3, (4, 21))

    def act(self, obs):
        return np.tanh(self.w @ np.asarray(obs, dtype=np.float64)).astype(np.float32)


def test_the_composition_and_its_checks():
    np.testing.assert_array_equal(residual_action([0.5, -0.5, 0.9, 0.0], [1.0, 1.0, 1.0, 5.0], 0.3),
                                  np.float32([0.8, -0.2, 1.0, 0.3]))  # the residual clipped to [-1, 1], then the sum
    assert residual_observation(np.zeros(17), np.ones(4)).shape == (21,)
    for bad in (0.0, -0.1, 2.5, float("nan"), True, "0.3"):
        with pytest.raises(ValueError, match="residual_scale"):
            check_residual_scale(bad)
    assert check_residual_scale(2) == 2.0
    for bad, message in ((0.5, r"shape \(4,\)"), ([0.1, 0.2], r"shape \(4,\)"), ([0.0, np.nan, 0.0, 0.0], "finite"),
                         (["a"] * 4, "residual")):
        with pytest.raises((ValueError, TypeError), match=message):
            residual_action(np.zeros(4), bad, 0.3)


def test_a_zero_residual_is_the_expert_step_for_step():
    env = gym.make(ENV_ID, max_episode_steps=150)
    expert = make_policy("expert", env)
    result = run_episode(env, expert, seed=4)
    wrapped = ResidualEnv(gym.make(ENV_ID, max_episode_steps=150), 0.3)
    assert wrapped.observation_space.shape == (21,)
    obs, _ = wrapped.reset(seed=4)
    for k, action in enumerate(result.actions):
        np.testing.assert_array_equal(obs[17:], action)  # the learner sees the expert's action of this step
        obs, _, terminated, truncated, info = wrapped.step(np.zeros(4))
        np.testing.assert_array_equal(info["base_action"], action)
        np.testing.assert_array_equal(np.concatenate([info["qpos"], info["qvel"]]), result.states[k + 1])
    assert terminated or truncated


def test_the_policy_acts_as_the_learner_in_the_residual_env():
    learner = _Learner()
    wrapped = ResidualEnv(gym.make(ENV_ID, max_episode_steps=100, reset_noise_scale=0.03), 0.5)
    obs, _ = wrapped.reset(seed=9)
    applied, bases = [], []
    done = False
    while not done:
        r = learner(obs)
        bases.append(obs[17:].copy())
        applied.append(residual_action(obs[17:], r, 0.5))
        obs, _, terminated, truncated, _ = wrapped.step(r)
        done = terminated or truncated
    env = gym.make(ENV_ID, max_episode_steps=100, reset_noise_scale=0.03)
    policy = ResidualPolicy(make_policy("expert", env), learner, 0.5)
    result = run_episode(env, policy, seed=9)
    np.testing.assert_array_equal(np.array(result.actions), np.array(applied))
    assert np.abs(np.array(applied) - np.array(bases)).max() > 0.1  # the residual changed the expert's actions


def test_a_residual_run_trains_saves_and_loads_as_one_policy(tmp_path):
    pytest.importorskip("stable_baselines3")
    from hsddp_gym.learning.sb3 import load_trained_policy, train_sb3

    res = train_sb3("ppo", 128, 0, tmp_path / "ppo", env_id=ENV_ID, max_episode_steps=40, eval_freq=0,
                    final_eval_episodes=1, overrides={"n_envs": 2, "n_steps": 32, "n_epochs": 1},
                    residual_scale=0.2, train_condition="reset_noise_x4")
    summary = json.loads((tmp_path / "ppo" / "summary.json").read_text())
    assert summary["residual"] == {"base": "expert", "scale": 0.2} and res.summary["eval"]["episodes"] == 1
    assert summary["train_condition"]["name"] == "reset_noise_x4"
    env = gym.make(ENV_ID, max_episode_steps=40)
    policy = load_trained_policy(tmp_path / "ppo", env=env)
    assert isinstance(policy, ResidualPolicy) and policy.scale == 0.2
    result = run_episode(env, policy, seed=0)
    assert len(result.actions) >= 1
    with pytest.raises(ValueError, match="residual_scale is not offered with vector_env"):
        train_sb3("ppo", 10, 0, tmp_path / "bad", env_id=ENV_ID, residual_scale=0.2, vector_env=True)
    with pytest.raises(ValueError, match="residual_scale"):
        train_sb3("ppo", 10, 0, tmp_path / "bad", env_id=ENV_ID, residual_scale=3.0)


def test_the_cli_takes_a_residual_for_rl_only(tmp_path, capsys):
    from hsddp_gym import cli

    out = str(tmp_path / "x")
    ppo = ["--algo", "ppo", "--env", ENV_ID, "--steps", "10"]
    for argv, message in (([*ppo, "--residual", "3"], "--residual: 3.0"),
                          ([*ppo, "--residual", "0.3", "--vector-env"], "--residual: given with --vector-env"),
                          (["--algo", "bc", "--residual", "0.3"], "--residual: given with --algo bc")):
        assert cli.main(["train", *argv, "--out", out]) == 2
        assert capsys.readouterr().err.startswith(f"error: {message}")


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_a_residual_learner_starts_as_the_expert(algo):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO, SAC

    from hsddp_gym.learning.residual import zero_mean_action

    env = ResidualEnv(gym.make(ENV_ID, max_episode_steps=20), 0.3)
    model = (PPO if algo == "ppo" else SAC)("MlpPolicy", env, seed=0, device="cpu")
    obs = np.stack([env.observation_space.sample() for _ in range(8)])
    assert np.abs(model.predict(obs, deterministic=True)[0]).max() > 1e-3  # a fresh network's mean is not zero
    zero_mean_action(model)
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], np.zeros((8, 4)))
