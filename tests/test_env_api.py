"""Gymnasium / SB3 API compliance, registration, seeding, vector envs and input validation of Bounding-v0."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import hsddp_gym
from hsddp_gym.core.conventions import NX, Mode
from hsddp_gym.core.observation import ObservationLayout, state_from_observation
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.vector import BoundingVectorEnv

ENV_ID = "hsddp_gym/Bounding-v0"
INFO_KEYS = {"x_position", "x_velocity", "reward_forward", "reward_ctrl", "reward_healthy", "contact", "foot_heights",
             "grf", "qpos", "qvel", "time", "invalid_state"}


def make_env():
    return gym.make("hsddp_gym:" + ENV_ID)


# ------------------------------------------------------------------------------------------ checkers
HEADLESS_HUMAN_RENDER_WARNING = "render_mode='human' needs an interactive matplotlib backend"


def test_gymnasium_env_checker_passes():
    """check_env raises on errors and reports the rest as warnings: the only one allowed is the human-mode
    render check on a machine without a display (BoundingEnv's own headless notice)."""
    env = make_env()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped)
    unexpected = [str(w.message) for w in caught if HEADLESS_HUMAN_RENDER_WARNING not in str(w.message)]
    assert not unexpected, unexpected
    env.close()


def test_sb3_env_checker_passes():
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3 reports problems as warnings: there must be none
        sb3_check_env(BoundingEnv(), warn=True)


def test_registration_spec_and_time_limit():
    assert ENV_ID in gym.registry
    spec = gym.spec(ENV_ID)
    assert spec.entry_point == "hsddp_gym.envs.bounding:BoundingEnv"
    assert spec.max_episode_steps == hsddp_gym.BOUNDING_MAX_EPISODE_STEPS
    from pathlib import Path

    import tomllib

    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert hsddp_gym.__version__ == pyproject["project"]["version"]
    env = gym.make(ENV_ID, max_episode_steps=3, reset_noise_scale=0.0)
    env.reset(seed=0)
    flags = [env.step(np.zeros(4, dtype=np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]  # truncation only from the TimeLimit wrapper
    env.close()


def test_make_without_prior_import_in_a_fresh_interpreter():
    code = ("import sys, gymnasium as gym; env = gym.make('hsddp_gym:hsddp_gym/Bounding-v0'); "
            "obs, info = env.reset(seed=0); env.step(env.action_space.sample()); "
            "assert 'hsddp_gym' in sys.modules and 'hsddp_gym.envs.bounding' in sys.modules; print(obs.shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(17,)"


def test_kwargs_are_json_serializable_and_recreate_the_env():
    env = gym.make(ENV_ID, frame_skip=2, healthy_z_range=[0.1, 0.6], target_speed=0.5)
    spec_json = env.spec.to_json()
    spec = gym.envs.registration.EnvSpec.from_json(spec_json)
    env2 = spec.make()
    assert env2.unwrapped.frame_skip == 2 and env2.unwrapped.healthy_z_range == (0.1, 0.6)
    assert env2.unwrapped.target_speed == 0.5
    json.dumps(env.spec.kwargs)
    env.close()
    env2.close()


def test_spaces_dtypes_and_metadata():
    env = BoundingEnv()
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    assert env.observation_space.dtype == np.float32 and env.observation_space.shape == (17,)
    assert np.all(np.isfinite(env.observation_space.low)) and np.all(np.isfinite(env.observation_space.high))
    assert env.metadata["render_fps"] == round(1.0 / env.dt)
    assert BoundingEnv(frame_skip=10).metadata["render_fps"] == 100
    assert env.dt == pytest.approx(env.frame_skip * 1e-3)
    assert env.observation_structure == {"skipped_qpos": 1, "qpos": 6, "qvel": 7, "contact": 2, "phase": 2}
    full = BoundingEnv(exclude_current_positions_from_observation=False)
    assert full.observation_space.shape == (18,)
    assert full.observation_structure["skipped_qpos"] == 0
    obs, info = env.reset(seed=0)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert type(reward) is float and type(terminated) is bool and truncated is False
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)


# ------------------------------------------------------------------------------------------ info, reward
def test_info_has_the_same_keys_and_shapes_at_reset_and_every_step():
    env = BoundingEnv()
    _, info0 = env.reset(seed=1)
    assert set(info0) == INFO_KEYS
    shapes = {k: np.shape(v) for k, v in info0.items()}
    assert shapes["contact"] == (2,) and shapes["foot_heights"] == (2,) and shapes["grf"] == (4,)
    assert shapes["qpos"] == (7,) and shapes["qvel"] == (7,)
    assert info0["reward_forward"] == info0["reward_ctrl"] == info0["reward_healthy"] == 0.0
    for _ in range(20):
        _, reward, _, _, info = env.step(env.action_space.sample())
        assert set(info) == INFO_KEYS
        assert {k: np.shape(v) for k, v in info.items()} == shapes
        total = info["reward_forward"] + info["reward_ctrl"] + info["reward_healthy"]
        assert reward == pytest.approx(total, abs=1e-12)
        np.testing.assert_allclose(info["qpos"][[0, 1, 2]], env.state[:3])


def test_reward_terms_follow_the_documented_formula():
    env = BoundingEnv(target_speed=0.8, tracking_sigma=0.4, forward_reward_weight=2.0, ctrl_cost_weight=0.3,
                      healthy_reward=0.7, reset_noise_scale=0.0)
    env.reset(seed=0)
    x_before = env.state[0]
    action = np.array([0.5, -0.2, 2.0, 0.1])  # the 2.0 is clipped to 1.0
    _, reward, _, _, info = env.step(action)
    v = (env.state[0] - x_before) / env.dt
    assert info["x_velocity"] == pytest.approx(v)
    assert info["reward_forward"] == pytest.approx(2.0 * math.exp(-((v - 0.8) / 0.4) ** 2))
    assert info["reward_ctrl"] == pytest.approx(-0.3 * (0.25 + 0.04 + 1.0 + 0.01))
    assert info["reward_healthy"] == 0.7
    assert reward == pytest.approx(info["reward_forward"] + info["reward_ctrl"] + 0.7)


def test_unhealthy_terminates_without_healthy_reward_hopper_v5_semantics():
    env = BoundingEnv(healthy_z_range=(0.12, 0.5), reset_noise_scale=0.0)
    x = paper_initial_state()
    env.reset(seed=0, options={"state": x})
    terminated, steps = False, 0
    while not terminated:  # no torque: the legs fold and the trunk drops below 0.12 m
        _, _, terminated, truncated, info = env.step(np.zeros(4))
        steps += 1
        assert steps < 500 and not truncated
    assert info["reward_healthy"] == 0.0 and not env.is_healthy
    assert info["qpos"][1] <= 0.12 or abs(info["qpos"][2]) >= 0.8
    # the same fall without termination keeps going and pays no healthy reward while unhealthy
    env2 = BoundingEnv(terminate_when_unhealthy=False, reset_noise_scale=0.0)
    env2.reset(seed=0, options={"state": x})
    for _ in range(steps + 10):
        _, _, terminated, _, info = env2.step(np.zeros(4))
        assert not terminated
    assert info["reward_healthy"] == 0.0


def test_pitch_out_of_range_is_unhealthy():
    env = BoundingEnv(reset_noise_scale=0.0)
    x = paper_initial_state()
    x[2] = 0.9
    env.reset(options={"state": x})
    assert not env.is_healthy
    _, _, terminated, _, _ = env.step(np.zeros(4))
    assert terminated


# ------------------------------------------------------------------------------------------ seeding
def test_same_seed_same_trajectory_and_different_seed_differs(tools):
    rollout = tools.random_rollout
    env = BoundingEnv()
    a = rollout(env, seed=5, n=30)
    b = rollout(env, seed=5, n=30)  # the same instance after an episode: nothing carries over
    fresh = rollout(BoundingEnv(), seed=5, n=30)  # a new instance
    made = rollout(make_env(), seed=5, n=30)  # through gym.make's wrappers
    c = rollout(BoundingEnv(), seed=6, n=30)
    for other in (b, fresh, made):
        assert len(a) == len(other) == 31
        for u, v in zip(a, other):
            np.testing.assert_array_equal(u, v)
    assert not np.array_equal(a[0], c[0])


def test_vector_envs_are_deterministic_per_seed():
    def run(cls):
        venv = cls([make_env, make_env])
        obs, _ = venv.reset(seed=[3, 4])
        out = [obs]
        actions = np.random.default_rng(0).uniform(-0.3, 0.3, (5, 2, 4)).astype(np.float32)
        for a in actions:
            out.append(venv.step(a)[0])
        venv.close()
        return np.array(out)

    sync = run(gym.vector.SyncVectorEnv)
    np.testing.assert_array_equal(sync, run(gym.vector.SyncVectorEnv))
    np.testing.assert_array_equal(sync, run(gym.vector.AsyncVectorEnv))  # subprocesses give the same numbers
    assert not np.array_equal(sync[:, 0], sync[:, 1])  # the two seeds differ


def test_reset_noise_keeps_the_feet_above_ground():
    env = BoundingEnv(reset_noise_scale=0.05)
    for seed in range(20):
        _, info = env.reset(seed=seed)
        assert info["foot_heights"].min() >= -1e-12
    _, info = BoundingEnv(reset_noise_scale=0.0).reset(seed=0)
    np.testing.assert_array_equal(np.concatenate([info["qpos"], info["qvel"]]), paper_initial_state())


# ------------------------------------------------------------------------------------------ vector envs
def test_sync_and_async_vector_envs_run():
    for cls in (gym.vector.SyncVectorEnv, gym.vector.AsyncVectorEnv):
        venv = cls([make_env, make_env])
        obs, info = venv.reset(seed=[0, 1])
        assert obs.shape == (2, 17) and info["contact"].shape == (2, 2)
        for _ in range(3):
            obs, reward, terminated, truncated, info = venv.step(venv.action_space.sample())
        assert obs.shape == (2, 17) and reward.shape == (2,)
        venv.close()


def test_sb3_subproc_vec_env_runs():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = make_vec_env("hsddp_gym:" + ENV_ID, n_envs=2, seed=0, vec_env_cls=SubprocVecEnv)
    obs = venv.reset()
    assert obs.shape == (2, 17)
    for _ in range(3):
        obs, rewards, dones, infos = venv.step(np.zeros((2, 4), dtype=np.float32))
    assert rewards.shape == (2,) and len(infos) == 2 and "x_velocity" in infos[0]
    venv.close()


# ------------------------------------------------------------------------------------------ observation
def test_observation_maps_back_to_state_mode_and_phase():
    for exclude in (True, False):
        env = BoundingEnv(exclude_current_positions_from_observation=exclude, gait_period=0.3)
        obs, info = env.reset(seed=3, options={"time": 0.075})
        for _ in range(7):
            obs, _, _, _, info = env.step(np.zeros(4))
        x, mode, phase = state_from_observation(obs, env.observation_layout, x_position=info["x_position"])
        true = np.concatenate([info["qpos"], info["qvel"]])
        np.testing.assert_allclose(x, true, rtol=1e-6, atol=1e-6)
        assert mode == Mode(int(info["contact"][0]) | 2 * int(info["contact"][1]))
        assert info["time"] == pytest.approx(0.075 + 7 * env.dt)
        assert phase == pytest.approx((info["time"] / 0.3) % 1.0, abs=1e-6)


def test_contact_flags_and_mode_at_reset():
    obs, info = BoundingEnv(reset_noise_scale=0.0).reset(seed=0)
    _, mode, phase = state_from_observation(obs)
    assert mode == Mode.BACK_STANCE  # the paper's state: back foot 0.2 mm above the ground
    assert info["contact"].tolist() == [False, True] and phase == 0.0


def test_state_from_observation_validates():
    layout = ObservationLayout()
    with pytest.raises(ValueError, match="shape"):
        state_from_observation(np.zeros(18), layout)
    with pytest.raises(ValueError, match="finite"):
        state_from_observation(np.full(17, np.nan), layout)
    with pytest.raises(TypeError, match="layout"):
        state_from_observation(np.zeros(17), "layout")


# ------------------------------------------------------------------------------------------ options
def test_reset_to_a_given_state_and_validation():
    env = BoundingEnv()
    x = paper_initial_state()
    x[7] = 0.3
    obs, info = env.reset(options={"state": x})
    np.testing.assert_array_equal(env.state, x)
    with pytest.raises(ValueError, match="shape"):
        env.reset(options={"state": np.zeros(NX - 1)})
    with pytest.raises(ValueError, match="finite"):
        env.reset(options={"state": np.full(NX, np.nan)})
    bad = x.copy()
    bad[1] -= 0.05
    with pytest.raises(ValueError, match="below the ground"):
        env.reset(options={"state": bad})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"stat": x})
    with pytest.raises(ValueError, match="finite"):
        env.reset(options={"state": np.where(np.arange(NX) == 9, np.inf, x)})
    with pytest.raises(ValueError, match="time"):
        env.reset(options={"time": -1.0})


@pytest.mark.parametrize("index, value, name", [
    (7, 10.5, "vx"), (8, -11.0, "vz"), (9, 50.5, "pitch_rate"), (10, 101.0, "hip_front_rate"),
    (13, -1000.0, "knee_back_rate"), (2, 150.0, "pitch"), (1, 20.0, "z"),
])
def test_reset_state_outside_the_documented_bounds_is_refused_naming_the_entry(index, value, name):
    from hsddp_gym.envs.bounding import RESET_VELOCITY_BOUNDS

    assert RESET_VELOCITY_BOUNDS == (10.0, 10.0, 50.0, 100.0, 100.0, 100.0, 100.0)
    env = BoundingEnv()
    x = paper_initial_state()
    x[index] = value
    with pytest.raises(ValueError, match=rf"options\['state'\]\[{index}\] \({name}\)"):
        env.reset(options={"state": x})
    x[index] = 0.0 if index < 7 else np.sign(value) * RESET_VELOCITY_BOUNDS[index - 7]  # on the bound: accepted
    if index >= 7:
        env.reset(options={"state": x})
        np.testing.assert_array_equal(env.state, x)


def test_pushes_change_the_trunk_velocity():
    env = BoundingEnv(reset_noise_scale=0.0)
    env.reset(seed=0)
    v = env.state[7:10].copy()
    env.unwrapped.apply_push([0.5, -0.2, 1.0])
    np.testing.assert_allclose(env.state[7:10], v + [0.5, -0.2, 1.0])
    _, info = env.reset(seed=0, options={"push": [1.0, 0.0, 0.0]})
    assert info["qvel"][0] == pytest.approx(paper_initial_state()[7] + 1.0)
    # a scheduled push acts at the first simulation step at or after its time
    quiet, pushed = BoundingEnv(reset_noise_scale=0.0), BoundingEnv(reset_noise_scale=0.0)
    quiet.reset(seed=0)
    pushed.reset(seed=0, options={"push": {"delta_v": [0.0, 0.0, 3.0], "time": 0.012}})
    for k in range(4):
        _, _, _, _, info_q = quiet.step(np.zeros(4))
        _, _, _, _, info_p = pushed.step(np.zeros(4))
        if (k + 1) * quiet.dt < 0.012 - 1e-9:
            np.testing.assert_array_equal(info_q["qvel"], info_p["qvel"])
    assert not np.allclose(info_q["qvel"], info_p["qvel"])
    with pytest.raises(ValueError, match="delta_v"):
        env.unwrapped.apply_push([1.0, 2.0])
    with pytest.raises(ValueError, match="push"):
        env.reset(options={"push": {"delta_v": [0, 0, 1]}})


def test_two_pushes_in_one_control_step_act_at_their_own_simulation_steps():
    """Pushes are placed from the control step's start time, also the second one in the same step (not from the
    time after the first piece has run, which would be two simulation steps early here): a 5 ms control step
    with pushes at 1.1 ms and 3.2 ms equals five 1 ms steps with the pushes after the 2nd and the 4th."""
    from hsddp_gym.envs.bounding import pop_due_pushes

    a, b, c = np.array([0.0, 0.0, 4.0]), np.array([0.6, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    schedule = [(0.0061, a), (0.0082, b), (0.0101, c)]
    due = pop_due_pushes(schedule, 0.005, 5, 0.001)
    assert [k for k, _ in due] == [2, 4] and due[0][1] is a and due[1][1] is b and schedule == [(0.0101, c)]
    assert pop_due_pushes([(0.0, a)], 0.0, 5, 0.001) == [(0, a)]  # at the start: before the first step
    assert pop_due_pushes([(0.0049, a), (0.0049, b)], 0.0, 5, 0.001)[1][0] == 5  # in the last step: after it
    coarse = BoundingEnv(reset_noise_scale=0.0, frame_skip=5)
    fine = BoundingEnv(reset_noise_scale=0.0, frame_skip=1)
    coarse.reset(options={"push": [{"delta_v": a.tolist(), "time": 0.0011}, {"delta_v": b.tolist(), "time": 0.0032}]})
    fine.reset()
    for k in range(5):
        fine.step(np.zeros(4))
        if k in (1, 3):
            fine.unwrapped.apply_push(a if k == 1 else b)
    coarse.step(np.zeros(4))
    np.testing.assert_allclose(coarse.state, fine.state, atol=1e-9)


# ------------------------------------------------------------------------------------------ bad inputs
@pytest.mark.parametrize("action, message", [
    (np.array([np.nan, 0, 0, 0]), "finite"),
    (np.array([np.inf, 0, 0, 0]), "finite"),
    (np.zeros(3), "shape"),
    (np.zeros((1, 4)), "shape"),
    ([10**400, 0, 0, 0], "action"),
    (np.array([10**400, 0, 0, 0], dtype=object), "action"),
    ([0.1, 0.2, 0.3], "shape"),
])
def test_bad_actions_raise(action, message):
    env = BoundingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


@pytest.mark.parametrize("action", [
    np.array([0.1 + 0.5j, 0, 0, 0]),
    [0.1 + 0j, 0, 0, 0],
    np.array([True, False, True, False]),
    "left",
    np.array(["a", "b", "c", "d"]),
    np.array([None, 0, 0, 0], dtype=object),
])
def test_non_real_actions_raise_type_error_without_warnings(action):
    env = BoundingEnv()
    env.reset(seed=0)
    x = env.state
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning on the way
        with pytest.raises(TypeError, match="action"):
            env.step(action)
    np.testing.assert_array_equal(env.state, x)  # nothing was simulated


@pytest.mark.parametrize("action", [
    [10**400, 0, 0, 0], np.array([10**400, 0, 0, 0], dtype=object), np.array([np.nan, 0, 0, 0]),
    np.array([-np.inf, 0, 0, 0]), np.zeros(3), np.array([0.1 + 0.5j, 0, 0, 0]), np.array([True, False, True, False]),
    np.array(["a", "b", "c", "d"]), np.array([None, 0, 0, 0], dtype=object), [1.0, "2", 0, 0],
])
def test_single_and_vector_env_raise_the_same_error_type(action):
    """One rule for bad actions: the vector env raises what the single env raises for the same action (given to
    each of its robots), ``ValueError`` for values (shape, NaN, too large for a float), ``TypeError`` for types."""
    env = BoundingEnv()
    env.reset(seed=0)
    with pytest.raises((TypeError, ValueError)) as single:
        env.step(action)
    vec = BoundingVectorEnv(2)
    vec.reset(seed=0)
    batch = np.array([action, action], dtype=object) if not isinstance(action, np.ndarray) or action.dtype == object \
        else np.stack([action, action])
    with pytest.raises((TypeError, ValueError)) as vector:
        vec.step(batch)
    assert vector.type is single.type, (single.value, vector.value)
    assert "action" in str(vector.value)


def test_real_action_types_are_accepted():
    env = BoundingEnv(reset_noise_scale=0.0)
    ref = BoundingEnv(reset_noise_scale=0.0)
    env.reset(seed=0)
    ref.reset(seed=0)
    expected = ref.step(np.array([0.5, -0.25, 0.0, 1.0], dtype=np.float32))[0]
    for action in ([0.5, -0.25, 0, 1], (0.5, -0.25, 0.0, 1.0), np.array([0.5, -0.25, 0.0, 1.0]),
                   np.array([0.5, -0.25, 0, 1], dtype=object)):
        env.reset(seed=0)
        np.testing.assert_array_equal(env.step(action)[0], expected)
    env.reset(seed=0)
    env.step(np.array([2, -3, 0, 1], dtype=np.int64))  # integers are real: clipped to the box


# ------------------------------------------------------------------------------------------ invalid states
def test_invalid_state_is_reported_terminates_and_blocks_further_steps():
    env = BoundingEnv(terminate_when_unhealthy=False)
    obs, info = env.reset(seed=0)
    assert info["invalid_state"] is False
    env.apply_push([1e3, 0.0, 0.0])  # 1 km/s: far beyond the 100 m/s of a valid state
    obs, reward, terminated, truncated, info = env.step(np.zeros(4))
    assert terminated and not truncated
    assert info["invalid_state"] is True
    assert not env.valid_state() and not env.is_healthy
    assert env.observation_space.contains(obs)  # the observation stays in its box ...
    assert abs(info["qvel"][0]) > 100.0  # ... while info carries the raw state
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4))
    obs, info = env.reset(seed=0)
    assert info["invalid_state"] is False
    _, _, terminated, _, info = env.step(np.zeros(4))
    assert not terminated and info["invalid_state"] is False


def test_non_finite_state_is_reported_not_masked():
    env = BoundingEnv()
    env.reset(seed=0)
    env.sim.v[3] = np.nan
    obs, reward, terminated, _, info = env.step(np.zeros(4))
    assert terminated and info["invalid_state"] is True and math.isfinite(reward)
    assert np.isnan(info["qvel"]).any() and np.isnan(info["foot_heights"]).all()
    assert np.all(np.isfinite(obs))
    with pytest.raises(RuntimeError, match="invalid"):
        env.step(np.zeros(4))


def test_out_of_box_actions_are_clipped():
    a, b = BoundingEnv(reset_noise_scale=0.0), BoundingEnv(reset_noise_scale=0.0)
    a.reset(seed=0)
    b.reset(seed=0)
    obs_a, r_a, *_ = a.step(np.array([5.0, -7.0, 1.0, 0.0]))
    obs_b, r_b, *_ = b.step(np.array([1.0, -1.0, 1.0, 0.0]))
    np.testing.assert_array_equal(obs_a, obs_b)
    assert r_a == r_b


@pytest.mark.parametrize("kwargs, error, message", [
    ({"frame_skip": -1}, ValueError, "frame_skip"),
    ({"frame_skip": 0}, ValueError, "frame_skip"),
    ({"frame_skip": 2.5}, TypeError, "frame_skip"),
    ({"sim_timestep": 0.0}, ValueError, "sim_timestep"),
    ({"sim_timestep": 0.05}, ValueError, "sim_timestep"),
    ({"target_speed": float("nan")}, ValueError, "target_speed"),
    ({"tracking_sigma": 0.0}, ValueError, "tracking_sigma"),
    ({"ctrl_cost_weight": -0.1}, ValueError, "ctrl_cost_weight"),
    ({"healthy_reward": "1"}, TypeError, "healthy_reward"),
    ({"terminate_when_unhealthy": 1}, TypeError, "terminate_when_unhealthy"),
    ({"healthy_z_range": (0.5, 0.1)}, ValueError, "healthy_z_range"),
    ({"healthy_pitch_range": 0.8}, TypeError, "healthy_pitch_range"),
    ({"reset_noise_scale": -0.01}, ValueError, "reset_noise_scale"),
    ({"gait_period": 0.0}, ValueError, "gait_period"),
    ({"torque_limit": 0.0}, ValueError, "torque_limit"),
    ({"friction": -0.6}, ValueError, "friction"),
    ({"gravity": -9.81}, ValueError, "gravity"),
    ({"contact_erp": 1.5}, ValueError, "contact_erp"),
    ({"motor_speed_limits": (50.0, 36.0)}, ValueError, "motor_speed_limits"),
    ({"energy_consistent": 1}, TypeError, "energy_consistent"),
    ({"render_mode": "rgb"}, ValueError, "render_mode"),
    ({"width": 4}, ValueError, "width"),
    ({"exclude_current_positions_from_observation": "yes"}, TypeError, "exclude_current_positions"),
])
def test_bad_kwargs_raise_naming_the_argument(kwargs, error, message):
    with pytest.raises(error, match=message):
        BoundingEnv(**kwargs)


def test_physics_options_reach_the_simulator():
    env = BoundingEnv(gravity=0.0, friction=0.3, motor_speed_limits=None, frame_skip=3, sim_timestep=5e-4)
    assert env.sim.gravity == 0.0 and env.sim.mu == 0.3 and env.sim.motor_speed_limits is None
    assert env.sim.energy_consistent and not BoundingEnv(energy_consistent=False).sim.energy_consistent
    assert env.dt == pytest.approx(1.5e-3)
    env.reset(seed=0)
    t0 = env.time
    env.step(np.zeros(4))
    assert env.time - t0 == pytest.approx(1.5e-3)
