"""hsddp_gym/StandToBound-v0, hsddp_gym/BoundPronkBound-v0 and hsddp_gym/BoundToStop-v0: registration, both env
checkers, seeding, the schedules and starts against the transition planner's, and the success criterion (met by the
HS-DDP transition expert, never by zero torque)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.envs.transitions import SCHEDULES, TASKS, TransitionEnv, contact_schedule, plan_duration

ENV_IDS = hsddp_gym.TRANSITION_ENV_IDS


@pytest.mark.parametrize("task", TASKS)
def test_registered_with_a_time_limit_and_the_task(task):
    spec = gym.spec(ENV_IDS[task])
    assert spec.entry_point == "hsddp_gym.envs.transitions:TransitionEnv" and spec.kwargs == {"task": task}
    assert spec.max_episode_steps == hsddp_gym.TRANSITION_MAX_EPISODE_STEPS[task]
    assert spec.max_episode_steps * 0.005 >= plan_duration(task) + 0.4
    assert spec.vector_entry_point == "hsddp_gym.envs.task_vector:TransitionVectorEnv"
    env = gym.make(ENV_IDS[task])
    assert isinstance(env.unwrapped, TransitionEnv) and env.unwrapped.task == task
    twin = gym.spec(hsddp_gym.TRANSITION_MUJOCO_ENV_IDS[task])
    assert twin.entry_point == "hsddp_gym.envs.transitions:MuJoCoTransitionEnv" and twin.kwargs == {"task": task}


@pytest.mark.parametrize("task", TASKS)
def test_schedule_and_start_are_the_planners(task):
    from hsddp_gym.planners import motions

    problem, _ = motions.transition_problem(task, 1.0, 2)
    modes = problem.schedule.modes
    assert len(modes) == len(SCHEDULES[task])
    for mode, (contacts, _) in zip(modes, SCHEDULES[task]):
        assert (mode.in_contact(0), mode.in_contact(1)) == contacts
    assert np.allclose(problem.schedule.durations, [d for _, d in SCHEDULES[task]])
    env = gym.make(ENV_IDS[task], reset_noise_scale=0.0)
    env.reset(seed=0)
    assert np.allclose(env.unwrapped.sim.x, problem.x0, atol=1e-9)


def test_contact_schedule_repeats_the_bound_or_stays_standing():
    assert contact_schedule("stand_to_bound", 0.1) == (True, True)
    t = plan_duration("stand_to_bound")
    assert contact_schedule("stand_to_bound", t + 0.01) == (False, True)  # back stance of the repeated cycle
    assert contact_schedule("bound_to_stop", 5.0) == (True, True)


@pytest.mark.parametrize("task", TASKS)
def test_gymnasium_env_checker_passes(task, tools):
    tools.assert_gymnasium_checker_passes(gym.make(ENV_IDS[task]))


@pytest.mark.parametrize("task", TASKS)
def test_sb3_env_checker_passes(task, tools):
    tools.assert_sb3_checker_passes(gym.make(ENV_IDS[task]))


def test_sync_vector_env_runs():
    envs = gym.make_vec(ENV_IDS["bound_pronk_bound"], num_envs=2, vectorization_mode="sync")
    obs, info = envs.reset(seed=3)
    assert obs.shape == (2, 17)
    obs, reward, terminated, truncated, info = envs.step(np.zeros((2, 4), dtype=np.float32))
    assert reward.shape == (2,) and "success" in info and "reward_gait" in info
    envs.close()


@pytest.mark.parametrize("task", TASKS)
def test_same_seed_same_trajectory_and_different_seed_differs(task, tools):
    a, b, c = (tools.random_rollout(gym.make(ENV_IDS[task]), seed) for seed in (5, 5, 6))
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("kwargs, message", [({"task": "gallop"}, "task"), ({"speed_reward": -1.0}, "speed_reward"),
                                             ({"gait_reward": float("nan")}, "gait_reward"),
                                             ({"task": "stand_to_bound", "reset_noise_scale": 0.2},
                                              "reset_noise_scale")])
def test_bad_arguments_raise_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TransitionEnv(**kwargs)


def _episode(env, policy, seed):
    obs, info = env.reset(seed=seed)
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            return info, terminated


@pytest.mark.parametrize("task", TASKS)
def test_expert_succeeds_and_zero_torque_never_does(task):
    from hsddp_gym.rollout.plans import make_expert

    env = gym.make(ENV_IDS[task])
    expert = make_expert(env)
    expert.reset()
    info, fell = _episode(env, expert, 9700)
    assert not fell and info["success"]
    if task == "bound_pronk_bound":
        assert info["pronk_stances"] >= 2
    zero = np.zeros(4, dtype=np.float32)
    info, _ = _episode(env, lambda obs: zero, 9700)
    assert not info["success"]


def test_a_small_expert_dataset_writes_and_loads_with_minari(tmp_path):
    pytest.importorskip("minari")
    from hsddp_gym import cli
    from hsddp_gym.datasets.storage import load_npz, minari_root, read_metadata

    task = "bound_to_stop"
    out = tmp_path / task
    assert cli.main(["dataset", "--env", ENV_IDS[task], "--policy", "expert", "--episodes", "2",
                     "--max-episode-steps", "30", "--action-noise", "0.01", "--out", str(out), "--quiet"]) == 0
    import minari

    meta = read_metadata(out)
    dataset_id = f"hsddp_gym/{task}/expert-v0"
    assert meta["dataset_id"] == dataset_id and meta["env_id"] == ENV_IDS[task]
    assert meta["policy"]["class"].endswith("experts.transition_expert")
    assert meta["policy"]["options"]["plan"]["motion"] == task
    with minari_root(out / "minari"):
        ds = minari.load_dataset(dataset_id)
        assert ds.total_episodes == 2 and ds.total_steps == 60
        ep = next(ds.iterate_episodes())
        assert ep.observations.shape == (31, 17) and "success" in ep.infos and "expert_action" in ep.infos
        env = ds.recover_environment().unwrapped
        assert isinstance(env, TransitionEnv) and env.task == task
    assert load_npz(out).n_episodes == 2
