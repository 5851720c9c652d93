"""hsddp_gym/GapJump-v0 and hsddp_gym/BoxJump-v0: registration, both env checkers, seeding, the terrain against the
jump planner's, the success criterion (met by the HS-DDP jump expert, never by zero torque), and a small Minari
dataset recorded in each."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.core.task_constants import jump_terrain
from hsddp_gym.envs.jumps import JumpEnv

ENV_IDS = {"gap_jump": "hsddp_gym/GapJump-v0", "box_jump": "hsddp_gym/BoxJump-v0"}


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_registered_with_a_time_limit_and_the_task(task):
    spec = gym.spec(ENV_IDS[task])
    assert spec.entry_point == "hsddp_gym.envs.jumps:JumpEnv" and spec.kwargs == {"task": task}
    assert spec.max_episode_steps == hsddp_gym.JUMP_MAX_EPISODE_STEPS == 400
    assert spec.vector_entry_point == "hsddp_gym.envs.task_vector:JumpVectorEnv"
    env = gym.make(ENV_IDS[task])
    assert isinstance(env.unwrapped, JumpEnv) and env.unwrapped.task == task
    assert env.unwrapped.terrain == jump_terrain(task)
    assert gym.spec(ENV_IDS[task].replace("-v0", "MuJoCo-v0")).entry_point == "hsddp_gym.envs.jumps:MuJoCoJumpEnv"


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_gymnasium_env_checker_passes(task, tools):
    tools.assert_gymnasium_checker_passes(gym.make(ENV_IDS[task]))


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_sb3_env_checker_passes(task, tools):
    tools.assert_sb3_checker_passes(gym.make(ENV_IDS[task]))


def test_sync_vector_env_runs():
    envs = gym.make_vec(ENV_IDS["gap_jump"], num_envs=2, vectorization_mode="sync")
    obs, info = envs.reset(seed=3)
    assert obs.shape == (2, 17)
    obs, reward, terminated, truncated, info = envs.step(np.zeros((2, 4), dtype=np.float32))
    assert reward.shape == (2,) and "success" in info and "reward_crossing" in info
    envs.close()


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_same_seed_same_trajectory_and_different_seed_differs(task, tools):
    a, b, c = (tools.random_rollout(gym.make(ENV_IDS[task]), seed) for seed in (5, 5, 6))
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("kwargs, message", [({"task": "pit"}, "task"),
                                             ({"crossing_reward": -1.0}, "crossing_reward"),
                                             ({"upright_reward": float("nan")}, "upright_reward"),
                                             ({"terrain": "random_steps"}, "terrain")])
def test_bad_arguments_raise_naming_them(kwargs, message):
    with pytest.raises((ValueError, TypeError), match=message):
        JumpEnv(**kwargs)


def test_dropping_into_the_gap_is_a_fall():
    env = JumpEnv(task="gap_jump", reset_noise_scale=0.0)
    env.reset(seed=0)
    x = env.state.copy()
    near, far = env.terrain.edges
    x[0] = 0.5 * (near + far)  # the trunk over the middle of the gap, both feet over it
    env.reset(options={"state": x})
    for _ in range(100):
        _, _, terminated, _, info = env.step(np.zeros(4, dtype=np.float32))
        if terminated:
            break
    assert terminated and not info["success"] and info["reward_crossing"] <= 0.0


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_zero_torque_never_succeeds(task):
    env = gym.make(ENV_IDS[task])
    env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
        assert not info["success"]
        if terminated or truncated:
            break
    assert terminated


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_the_expert_jumps_lands_and_bounds_on(task):
    from hsddp_gym.rollout.policies import make_policy

    env = gym.make(ENV_IDS[task])
    policy = make_policy("expert", env)
    assert policy.reset_options is None
    obs, info = env.reset(seed=9999)
    ret = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        assert not terminated
        if truncated:
            break
    assert info["success"] and info["crossing_progress"] == 1.0
    assert info["x_position"] > env.unwrapped.far_edge + 0.3
    assert policy.tracker.loops >= 1 and max(policy.errors) < 2.0
    assert ret > 50.0


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_a_small_expert_dataset_writes_and_loads_with_minari(task, tmp_path):
    pytest.importorskip("minari")
    from hsddp_gym import cli
    from hsddp_gym.datasets.storage import load_npz, minari_root, read_metadata

    out = tmp_path / task
    assert cli.main(["dataset", "--env", ENV_IDS[task], "--policy", "expert", "--episodes", "2",
                     "--max-episode-steps", "30", "--out", str(out), "--quiet"]) == 0
    import minari

    meta = read_metadata(out)
    dataset_id = f"hsddp_gym/{task}/expert-v0"
    assert meta["dataset_id"] == dataset_id and meta["env_id"] == ENV_IDS[task]
    assert meta["policy"]["class"].endswith("experts.jump_expert")
    with minari_root(out / "minari"):
        ds = minari.load_dataset(dataset_id)
        assert ds.total_episodes == 2 and ds.total_steps == 60
        ep = next(ds.iterate_episodes())
        assert ep.observations.shape == (31, 17) and "success" in ep.infos and "reward_crossing" in ep.infos
        env = ds.recover_environment().unwrapped
        assert env.__class__.__name__ == "JumpEnv" and env.task == task
    assert load_npz(out).n_episodes == 2


def test_the_loop_arguments_are_checked_and_the_expert_loops_the_cycle_after_the_jump():
    from hsddp_gym.planners.policies.experts import JUMP_LOOP
    from hsddp_gym.planners.policies.touchdown import FootClearance
    from hsddp_gym.planners.policies.tracking import PlanTracker
    from hsddp_gym.registry import TASKS
    from hsddp_gym.rollout.plans import task_plan

    LOOP_PHASE, LOOP_END = JUMP_LOOP
    sol = task_plan(TASKS["gap_jump"], hold=5)
    rule = FootClearance()
    with pytest.raises(ValueError, match="loop_end"):
        PlanTracker.from_solution(sol, touchdown=rule, loop_phase=LOOP_PHASE, loop_end=LOOP_PHASE - 4)
    with pytest.raises(ValueError, match="loop_phase"):
        PlanTracker.from_solution(sol, touchdown=rule, loop_phase=LOOP_PHASE + 1, loop_end=LOOP_END)
    tracker = PlanTracker.from_solution(sol, touchdown=rule, loop_phase=LOOP_PHASE, loop_end=LOOP_END)
    tracker.phase, tracker.local_time = LOOP_END - 1, 0.0
    tracker.advance(1.0)  # waits for the touchdown that ends the cycle
    assert tracker.phase == LOOP_END - 1 and tracker.loops == 0
    tracker.sync(tracker.modes[LOOP_END], None)  # no foot seen clear: not a touchdown
    assert tracker.phase == LOOP_END - 1
    x = sol.X[(sol.phase_start[LOOP_END - 1] + sol.phase_start[LOOP_END]) // 2].copy()  # mid-flight, feet clear
    assert rule.robot.foot_heights(x[:7]).min() >= 0.02
    tracker.sync(tracker.modes[LOOP_END - 1], x)
    tracker.sync(tracker.modes[LOOP_END], x)
    assert tracker.phase == LOOP_PHASE and tracker.loops == 1 and not tracker.finished


@pytest.mark.parametrize("task", sorted(ENV_IDS))
def test_info_has_the_same_keys_at_reset_and_every_step_and_the_reward_is_its_terms(task):
    env = gym.make(ENV_IDS[task])
    _, info0 = env.reset(seed=2)
    assert info0["success"] is False and info0["crossing_progress"] == 0.0
    rng = np.random.default_rng(2)
    for _ in range(20):
        a = rng.uniform(-0.3, 0.3, 4).astype(np.float32)
        _, reward, terminated, _, info = env.step(a)
        assert set(info) == set(info0)
        a64 = a.astype(np.float64)
        assert reward == pytest.approx(info["reward_crossing"] + info["reward_upright"] - 0.1 * float(a64 @ a64))
        assert info["reward_upright"] == 0.0  # not across yet
        if terminated:
            break
