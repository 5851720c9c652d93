"""hsddp_gym/Pronking-v0: registration, both env checkers, seeding, the reward terms, the start state and constants
against the pronk planner's, the pronking expert, and a small Minari dataset recorded in it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.envs.pronking import (
    PronkingEnv,
    contact_match_fraction,
    pronk_start_state,
    pronking_success,
)

ENV_ID = "hsddp_gym/Pronking-v0"


def test_registered_with_a_time_limit_and_the_task_vector_env():
    spec = gym.spec(ENV_ID)
    assert spec.entry_point == "hsddp_gym.envs.pronking:PronkingEnv"
    assert spec.max_episode_steps == hsddp_gym.PRONKING_MAX_EPISODE_STEPS == 1000
    assert spec.vector_entry_point == "hsddp_gym.envs.task_vector:PronkingVectorEnv"
    env = gym.make(ENV_ID)
    assert isinstance(env.unwrapped, PronkingEnv)
    assert env.unwrapped.gait_period == pytest.approx(0.18)


def test_gymnasium_env_checker_passes(tools):
    tools.assert_gymnasium_checker_passes(gym.make(ENV_ID))


def test_sb3_env_checker_passes(tools):
    tools.assert_sb3_checker_passes(gym.make(ENV_ID))


def test_sync_vector_env_runs():
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync")
    obs, info = envs.reset(seed=3)
    assert obs.shape == (2, 17)
    obs, reward, terminated, truncated, info = envs.step(np.zeros((2, 4), dtype=np.float32))
    assert reward.shape == (2,) and "reward_contact_match" in info
    envs.close()


def test_same_seed_same_trajectory_and_different_seed_differs(tools):
    a, b, c = (tools.random_rollout(gym.make(ENV_ID), seed) for seed in (5, 5, 6))
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


def test_start_state_is_the_pronk_planners():
    from hsddp_gym.planners import motions

    robot = PronkingEnv().robot
    for speed in (0.5, 1.0, 1.5):
        x0 = motions.pronk_problem(1, speed)[0].x0
        np.testing.assert_allclose(pronk_start_state(robot, speed), x0, atol=1e-12)
    env = PronkingEnv(target_speed=1.25, reset_noise_scale=0.0)
    env.reset(seed=0)
    np.testing.assert_allclose(env.state, motions.pronk_problem(1, 1.25)[0].x0, atol=1e-12)
    assert env.contact.all()  # both feet on the ground at the start


def test_reward_terms_follow_the_documented_formula():
    env = PronkingEnv()
    obs, info = env.reset(seed=1)
    assert info["reward_contact_match"] == 0.0 and "contact_match" in info
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(80):
        a = rng.uniform(-0.5, 0.5, 4).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(a)
        a64 = np.clip(a.astype(np.float64), -1, 1)
        fwd = math.exp(-((info["x_velocity"] - 1.0) / 0.5) ** 2)
        match = bool(info["contact"][0] == info["contact"][1])
        healthy = info["reward_healthy"] > 0
        assert info["contact_match"] == match
        assert info["reward_contact_match"] == (0.5 if match and healthy else 0.0)
        assert reward == pytest.approx(fwd - 0.1 * float(a64 @ a64) + 0.5 * healthy + 0.5 * (match and healthy))
        seen.add(match)
        if terminated:
            break
    assert seen == {True, False}  # both cases met
    quiet = PronkingEnv(contact_match_reward=0.0)
    quiet.reset(seed=1)
    _, r, *_, info = quiet.step(np.zeros(4, dtype=np.float32))
    assert info["reward_contact_match"] == 0.0
    assert r == pytest.approx(info["reward_forward"] + info["reward_ctrl"] + info["reward_healthy"])


@pytest.mark.parametrize("kwargs, message", [({"target_speed": 2.0}, "target_speed"),
                                             ({"target_speed": True}, "target_speed"),
                                             ({"contact_match_reward": -1.0}, "contact_match_reward"),
                                             ({"start_at_pronk": 1}, "start_at_pronk")])
def test_bad_arguments_raise_naming_them(kwargs, message):
    with pytest.raises((ValueError, TypeError), match=message):
        PronkingEnv(**kwargs)


def test_success_criterion():
    assert contact_match_fraction([[1, 1], [0, 0], [1, 0], [0, 0]]) == 0.75
    assert pronking_success(False, 0.9, 0.85, 1.0)
    assert not pronking_success(True, 1.0, 1.0, 1.0)
    assert not pronking_success(False, 0.75, 1.0, 1.0)
    assert not pronking_success(False, 1.0, 0.75, 1.0)


def test_the_expert_pronks_for_a_second():
    from hsddp_gym.rollout.policies import make_policy

    env = gym.make(ENV_ID, max_episode_steps=200)  # 1 s, about 5.5 pronk cycles
    policy = make_policy("expert", env)
    assert policy.reset_options is None
    obs, _ = env.reset(seed=9999)
    contacts, speeds, both_air = [], [], 0
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        assert not terminated
        contacts.append(info["contact"])
        speeds.append(info["x_velocity"])
        both_air += not info["contact"].any()
    assert truncated
    assert contact_match_fraction(contacts) >= 0.95
    assert both_air >= 60  # flights: about 80 ms of each 180 ms cycle
    assert abs(np.mean(speeds) - 1.0) <= 0.2
    assert policy.tracker.loops >= 1  # the plan's cycles were repeated


def test_a_small_expert_dataset_writes_and_loads_with_minari(tmp_path):
    pytest.importorskip("minari")
    from hsddp_gym import cli
    from hsddp_gym.datasets.storage import load_npz, minari_root, read_metadata

    out = tmp_path / "pronk"
    assert cli.main(["dataset", "--env", ENV_ID, "--policy", "expert", "--episodes", "2", "--max-episode-steps", "40",
                     "--out", str(out), "--quiet"]) == 0
    import minari

    meta = read_metadata(out)
    assert meta["dataset_id"] == "hsddp_gym/pronking/expert-v0" and meta["env_id"] == ENV_ID
    assert meta["policy"]["class"].endswith("experts.pronking_expert")
    with minari_root(out / "minari"):
        ds = minari.load_dataset("hsddp_gym/pronking/expert-v0")
        assert ds.total_episodes == 2 and ds.total_steps == 80
        ep = next(ds.iterate_episodes())
        assert ep.observations.shape == (41, 17) and "reward_contact_match" in ep.infos
        assert ds.recover_environment().unwrapped.__class__.__name__ == "PronkingEnv"
    assert load_npz(out).n_episodes == 2


def test_dagger_runs_a_tiny_iteration_labelled_by_the_pronking_expert(tmp_path):
    pytest.importorskip("torch")
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig, load_dagger_data, run_dagger

    config = DAggerConfig(rounds=1, episodes_per_round=1, max_episode_steps=30, bc=BCConfig(epochs=2))
    summary = run_dagger("expert", tmp_path / "dagger", config=config, eval_episodes=1, progress=False,
                         env_id=ENV_ID)
    assert summary["env_id"] == ENV_ID and summary["config"]["env_id"] == ENV_ID
    assert summary["expert"]["class"].endswith("experts.pronking_expert")
    assert summary["expert_labels"] == len(load_dagger_data(tmp_path / "dagger")) <= 60
    assert [h["round"] for h in summary["history"]] == [0, 1] and summary["eval"]["episodes"] == 1
    with pytest.raises(ValueError, match="expert 'heuristic'.*or 'mpc'"):  # the heuristic is a bounding controller
        run_dagger("heuristic", tmp_path / "h", config=config, eval_episodes=0, progress=False, env_id=ENV_ID)
    assert DAggerConfig(env_id=ENV_ID, conditions=("push",)).conditions == ("push",)  # built for the pronk
    with pytest.raises(ValueError, match="conditions: condition 'speed_2.0' does not apply"):
        DAggerConfig(env_id=ENV_ID, conditions=("speed_2.0",))  # beyond the pronk's speeds


def test_the_cli_trains_sac_in_the_pronking_env_and_refuses_what_it_does_not_take(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from hsddp_gym import cli
    from hsddp_gym.workflows import load_policy

    out = tmp_path / "sac"
    assert cli.main(["train", "--algo", "sac", "--env", ENV_ID, "--steps", "64", "--learning-starts", "32",
                     "--eval-freq", "0", "--eval-episodes", "1", "--max-episode-steps", "32", "--hidden", "16,16",
                     "--quiet", "--out", str(out)]) == 0
    import json

    summary = json.loads((out / "summary.json").read_text())
    assert summary["env_id"] == ENV_ID and summary["steps"] == 64 and summary["eval"]["episodes"] == 1
    env = gym.make(ENV_ID, max_episode_steps=5)
    obs, _ = env.reset(seed=0)
    assert load_policy(f"sb3:{out}", env)(obs).shape == (4,)
    assert cli.main(["train", "--algo", "sac", "--env", ENV_ID, "--steps", "40", "--learning-starts", "20",
                     "--eval-freq", "0", "--eval-episodes", "1", "--max-episode-steps", "16", "--hidden", "16,16",
                     "--quiet", "--vector-env", "--out", str(tmp_path / "vec")]) == 0  # the task vector env
    assert json.loads((tmp_path / "vec" / "summary.json").read_text())["vector_env"] is True
    assert cli.main(["train", "--algo", "sac", "--env", ENV_ID, "--steps", "10", "--out", str(tmp_path / "x"),
                     "--condition", "push", "--vector-env"]) == 2  # a task's pushes come in single envs
    assert f"given with --env {ENV_ID}" in capsys.readouterr().err
    for argv, option in ((["--algo", "dagger", "--expert", "heuristic"], "--expert"), (["--algo", "bc"], "--env")):
        assert cli.main(["train", "--env", ENV_ID, *argv, "--out", str(tmp_path / "x")]) == 2
        assert capsys.readouterr().err.startswith(f"error: {option}")
