"""A target-speed-conditioned learner: the target speed of each demonstration from its dataset, as one more input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hsddp_gym.core.observation import build_observation
from hsddp_gym.learning.demonstrations import Demonstrations, load_demonstrations
from hsddp_gym.planners.policies.base import EnvInterface

pytest.importorskip("torch")


@pytest.fixture(scope="module")
def two_speeds(tmp_path_factory):
    from hsddp_gym.datasets.generation import generate_dataset

    root = tmp_path_factory.mktemp("speeds")
    for v in (0.7, 1.3):
        generate_dataset("heuristic", 2, root / f"v{v}", seed=3, max_episode_steps=40, progress=False,
                         env_kwargs={"target_speed": v})
    return [root / "v0.7", root / "v1.3"]


def test_demonstrations_carry_their_target_speed(two_speeds):
    one = load_demonstrations(two_speeds[0], fmt="npz")
    assert np.all(one.target_speed == 0.7)
    both = load_demonstrations(two_speeds, fmt="npz")
    assert both.n_episodes == 4 and len(both) == 2 * len(one)
    np.testing.assert_array_equal(np.unique(both.target_speed), [0.7, 1.3])
    assert np.all(both.target_speed[both.episode >= 2] == 1.3)
    assert np.all(both.first_episodes(2).target_speed == 0.7)
    with pytest.raises(ValueError, match="empty list"):
        load_demonstrations([])


def test_a_speed_conditioned_learner_follows_the_target_speed():
    """Labels that depend on the target speed only: with the speed as input BC reproduces them at both speeds;
    the observation alone cannot tell them apart."""
    from hsddp_gym.learning.bc import BCConfig, MLPPolicy, train_bc

    rng = np.random.default_rng(0)
    n = 400
    x = np.zeros((n, 14))
    x[:, 1] = 0.3 + 0.01 * rng.standard_normal(n)
    obs = np.stack([build_observation(xi, [1, 0], 0.0, 0.296) for xi in x]).astype(np.float32)
    speed = np.where(np.arange(n) < n // 2, 0.7, 1.3)
    actions = np.tile((0.5 * (speed - 1.0))[:, None], (1, 4)).astype(np.float32)
    demos = Demonstrations(obs, actions, (np.arange(n) >= n // 2).astype(np.int64), target_speed=speed)
    cfg = BCConfig(hidden=(32, 32), epochs=60, batch_size=64, lr=3e-3, speed_input=True)
    policy, _ = train_bc(demos, cfg)
    assert policy.obs_mean.shape == (18,)
    for v in (0.7, 1.3):
        p = MLPPolicy(EnvInterface(target_speed=v), weights=policy.weights, obs_mean=policy.obs_mean,
                      obs_std=policy.obs_std, config=cfg)
        np.testing.assert_allclose(p(obs[0]), 0.5 * (v - 1.0), atol=0.03)
    plain, _ = train_bc(demos, BCConfig(hidden=(32, 32), epochs=60, batch_size=64, lr=3e-3))
    assert abs(float(plain(obs[0])[0]) - 0.5 * (0.7 - 1.0)) > 0.08  # it can only average the two speeds
    with pytest.raises(ValueError, match="speed_input needs the target speed"):
        train_bc(Demonstrations(obs, actions, demos.episode), cfg)
    with pytest.raises(TypeError, match="speed_input must be a bool"):
        BCConfig(speed_input="yes")


def test_cli_trains_on_several_datasets_with_the_speed_input(two_speeds, tmp_path):
    from hsddp_gym import cli
    from hsddp_gym.learning.bc import MLPPolicy

    out = tmp_path / "bc"
    assert cli.main(["train", "--algo", "bc", "--dataset", *map(str, two_speeds), "--format", "npz",
                     "--speed-input", "--epochs", "2", "--hidden", "16", "--eval-episodes", "1",
                     "--max-episode-steps", "10", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["demonstrations"] == 4 and summary["config"]["speed_input"] is True
    assert summary["dataset"] == [str(d) for d in two_speeds]
    policy = MLPPolicy.load(out / "policy.npz", EnvInterface(target_speed=1.3))
    assert policy.config.speed_input and policy.obs_mean.shape == (18,)
    a13 = policy(np.zeros(17, np.float32))
    a07 = MLPPolicy.load(out / "policy.npz", EnvInterface(target_speed=0.7))(np.zeros(17, np.float32))
    assert not np.array_equal(a07, a13)
    # DAgger from several datasets, speed as an input, behind the estimator, rollouts under a delay
    assert cli.main(["train", "--algo", "dagger", "--expert", "heuristic", "--dataset", *map(str, two_speeds),
                     "--speed-input", "--estimator", "--condition", "delay_5ms", "--rounds", "1",
                     "--episodes-per-round", "1", "--max-episode-steps", "20", "--epochs", "1", "--hidden", "8",
                     "--eval-episodes", "0", "--out", str(tmp_path / "d"), "--quiet"]) == 0
    dagger = MLPPolicy.load(tmp_path / "d" / "policy.npz")
    assert dagger.config.speed_input and dagger.info["estimator"] is True
    summary = json.loads((tmp_path / "d" / "summary.json").read_text())
    assert summary["config"]["estimator"] is True and summary["conditions"] == ["delay_5ms"]
    # the aggregate labels keep each pair's target speed and delay: another learner can be trained on them
    from hsddp_gym.learning.dagger import load_dagger_data

    data = load_dagger_data(tmp_path / "d")
    assert data.n_episodes == 5 and len(data) == summary["transitions"]
    assert [set(data.target_speed[data.episode == e]) for e in range(5)] == [{0.7}, {0.7}, {1.3}, {1.3}, {1.0}]
    assert set(data.action_delay[data.episode == 4]) == {1} and data.sent_actions.shape == (len(data), 4)
    with pytest.raises(ValueError, match="path"):
        load_dagger_data(two_speeds[0] / "episodes.npz")


@pytest.mark.parametrize("argv, option", [
    (["--algo", "ppo", "--steps", "10", "--gain-copies", "2"], "--gain-copies"),
    (["--algo", "ppo", "--steps", "10", "--speed-input"], "--speed-input"),
    (["--algo", "bc", "--estimator"], "--estimator"),
    (["--algo", "dagger", "--estimator", "--action-queue", "2"], "--action-queue"),
    (["--algo", "bc", "--gain-noise", "0.01", "0.1"], "--gain-noise"),
    (["--algo", "bc", "--n-envs", "4"], "--n-envs"),
])
def test_learner_options_are_refused_where_they_do_not_apply(argv, option, tmp_path, capsys, two_speeds):
    from hsddp_gym import cli

    extra = ["--dataset", str(two_speeds[0])] if "bc" in argv else []
    assert cli.main(["train", *argv, *extra, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {option}:") and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()
