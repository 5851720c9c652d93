"""The vector env of the task envs (``envs/task_vector.py``): every task env's ``gym.make_vec`` builds it, and its
transitions are bit-identical to N single envs in a ``SyncVectorEnv`` (observations, rewards, terminations,
truncations, the batched info with its masks), with either autoreset mode and with random pushes; the batched
simulators step each robot as its own ``run`` does; bad inputs raise naming the argument, before any robot moves."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import VectorEnv

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.core.compiled_contact import CompiledContactSimulator, SimulatorBatch
from hsddp_gym.core.task_constants import jump_terrain
from hsddp_gym.envs import task_vector
from hsddp_gym.envs.perturbations import RandomPush
from hsddp_gym.envs.task_vector import BackflipVectorEnv, TaskVectorEnv, batch_infos

TASK_VECTOR_ENVS = {
    "hsddp_gym/Backflip-v0": task_vector.BackflipVectorEnv,
    "hsddp_gym/GapJump-v0": task_vector.JumpVectorEnv,
    "hsddp_gym/BoxJump-v0": task_vector.JumpVectorEnv,
    "hsddp_gym/StandToBound-v0": task_vector.TransitionVectorEnv,
    "hsddp_gym/BoundPronkBound-v0": task_vector.TransitionVectorEnv,
    "hsddp_gym/BoundToStop-v0": task_vector.TransitionVectorEnv,
    "hsddp_gym/Pronking-v0": task_vector.PronkingVectorEnv,
    "hsddp_gym/Terrain-v0": TaskVectorEnv,
}
N = 3
MODE_NAMES = {"next_step": "NextStep", "same_step": "SameStep"}


def assert_infos_equal(a: dict, b: dict, path: str = "") -> None:
    """Same keys in the same order, same dtypes and equal values (NaN equal to NaN), recursively."""
    assert list(a) == list(b), (path, list(a), list(b))
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, dict):
            assert isinstance(y, dict), path + key
            assert_infos_equal(x, y, f"{path}{key}/")
            continue
        assert x.dtype == y.dtype and x.shape == y.shape, (path + key, x.dtype, y.dtype, x.shape, y.shape)
        if x.dtype != object:
            np.testing.assert_array_equal(x, y, err_msg=path + key)
            continue
        for u, v in zip(x, y):
            if isinstance(u, dict):
                assert_infos_equal(u, v, f"{path}{key}/")
            else:
                np.testing.assert_array_equal(np.asarray(u), np.asarray(v), err_msg=path + key)


def _pair(env_id: str, mode: str = "next_step", push: dict | None = None, **kwargs):
    """The task vector env and a SyncVectorEnv of single envs, built alike."""
    wrappers = None if push is None else [lambda e: RandomPush(e, **push)]
    sync = gym.make_vec(env_id, num_envs=N, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": MODE_NAMES[mode]}, wrappers=wrappers, **kwargs)
    vec = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", autoreset_mode=mode, push=push,
                       **kwargs)
    return vec, sync


def _without_push(info: dict) -> dict:
    return {k: v for k, v in info.items() if k not in ("push", "_push")}


def _play(vec, sync, steps: int, seed: int = 3) -> int:
    """Reset both with ``seed`` and play ``steps`` random actions, comparing every output; the number of episode
    ends seen."""
    o1, i1 = sync.reset(seed=seed)
    o2, i2 = vec.reset(seed=seed)
    np.testing.assert_array_equal(o1, o2)
    assert_infos_equal(_without_push(i1), i2)
    rng = np.random.default_rng(seed)
    ends = 0
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, (N, 4))
        out1, out2 = sync.step(a), vec.step(a)
        for x, y in zip(out1[:4], out2[:4]):
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x, y)
        assert_infos_equal(_without_push(out1[4]), out2[4])
        ends += int(np.sum(out2[2] | out2[3]))
    return ends


@pytest.mark.parametrize("env_id", sorted(TASK_VECTOR_ENVS))
def test_every_task_env_vectorizes_bit_identically_to_single_envs(env_id):
    vec, sync = _pair(env_id, max_episode_steps=40, reset_noise_scale=0.04)
    assert type(vec) is TASK_VECTOR_ENVS[env_id]
    assert vec.single_observation_space == sync.single_observation_space
    assert vec.observation_space == sync.observation_space and vec.action_space == sync.action_space
    assert _play(vec, sync, 90) >= N  # every robot's episode ended at least once (truncation at 40 steps)


@pytest.mark.parametrize("env_id", ["hsddp_gym/Backflip-v0", "hsddp_gym/Terrain-v0"])
def test_same_step_autoreset_matches_sync_vector_env(env_id):
    vec, sync = _pair(env_id, "same_step", max_episode_steps=25, reset_noise_scale=0.04)
    assert _play(vec, sync, 60) >= N


@pytest.mark.parametrize("env_id", ["hsddp_gym/Backflip-v0", "hsddp_gym/GapJump-v0"])
def test_random_pushes_match_random_push_on_single_envs(env_id):
    push = {"time_range": (0.0, 0.15), "max_delta_v": (0.5, 0.5, 4.0)}
    vec, sync = _pair(env_id, push=push, max_episode_steps=40)
    _play(vec, sync, 90)
    # the pushes really came: without them the robots move otherwise
    plain = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", max_episode_steps=40)
    plain.reset(seed=3)
    vec.reset(seed=3)
    zeros = np.zeros((N, 4))
    for _ in range(30):
        obs_pushed = vec.step(zeros)[0]
        obs_plain = plain.step(zeros)[0]
    assert np.all(np.any(obs_pushed != obs_plain, axis=1))


def test_reset_options_state_time_and_mask():
    vec = BackflipVectorEnv(num_envs=N)
    single = gym.make("hsddp_gym/Backflip-v0").unwrapped
    obs, _ = vec.reset(seed=5)
    start, _ = single.reset(seed=5)
    np.testing.assert_array_equal(obs[0], start)
    states = np.stack([env.sim.x.copy() for env in vec.envs])
    states[:, 1] += 0.02  # 2 cm higher: in the air
    obs, info = vec.reset(options={"state": states, "time": 0.3})
    for i, env in enumerate(vec.envs):
        np.testing.assert_array_equal(env.sim.x, states[i])
        assert env.time == pytest.approx(0.3)
    o, _ = single.reset(options={"state": states[1], "time": 0.3})
    np.testing.assert_array_equal(obs[1], o)
    # a masked reset leaves the other robots as they are
    for _ in range(3):
        before, *_ = vec.step(np.full((N, 4), 0.2))
    mask = np.array([False, True, False])
    after, info = vec.reset(seed=9, options={"reset_mask": mask})
    np.testing.assert_array_equal(after[[0, 2]], before[[0, 2]])
    o, _ = single.reset(seed=9 + 1)
    np.testing.assert_array_equal(after[1], o)
    np.testing.assert_array_equal(info["_time"], mask)


def test_bad_inputs_raise_naming_the_argument_before_any_robot_moves():
    vec = BackflipVectorEnv(num_envs=N)
    with pytest.raises(RuntimeError, match="before reset"):
        vec.step(np.zeros((N, 4)))
    vec.reset(seed=0)
    states = np.stack([env.sim.x.copy() for env in vec.envs])
    with pytest.raises(ValueError, match=r"actions must have shape \(3, 4\)"):
        vec.step(np.zeros((N, 3)))
    bad = np.zeros((N, 4))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"actions must be finite: the rows of robots \[2\]"):
        vec.step(bad)
    with pytest.raises(TypeError, match="actions"):
        vec.step([["a"] * 4] * N)
    np.testing.assert_array_equal(np.stack([env.sim.x for env in vec.envs]), states)  # nobody moved
    vec._autoreset[2] = True  # a robot that resets at this step: its action is ignored, as in SyncVectorEnv
    vec.step(bad)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="reset_mask"):
        vec.reset(options={"reset_mask": np.ones(N + 1, dtype=bool)})
    with pytest.raises(ValueError, match="reset_mask"):
        vec.reset(options={"reset_mask": np.zeros(N, dtype=bool)})
    with pytest.raises(ValueError, match=r"options\['state'\] must have shape"):
        vec.reset(options={"state": np.zeros((N, 14, 1))})
    with pytest.raises(ValueError, match=r"options\['time'\]"):
        vec.reset(options={"time": -1.0})
    with pytest.raises(ValueError, match="unknown reset option"):
        vec.reset(options={"push": {"delta_v": [0, 0, 0]}})
    with pytest.raises(ValueError, match="num_envs"):
        BackflipVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="max_episode_steps"):
        BackflipVectorEnv(num_envs=1, max_episode_steps=0)
    with pytest.raises(TypeError, match="does not render"):
        BackflipVectorEnv(num_envs=1, render_mode="rgb_array")
    with pytest.raises(ValueError, match="energy_consistent must be True"):
        BackflipVectorEnv(num_envs=1, energy_consistent=False)
    with pytest.raises(TypeError, match="BackflipVectorEnv.*no_such_argument"):
        BackflipVectorEnv(num_envs=1, no_such_argument=1)
    with pytest.raises(ValueError, match="autoreset_mode"):
        BackflipVectorEnv(num_envs=1, autoreset_mode="sometimes")


def test_batch_infos_builds_what_add_info_builds():
    n = 4
    obs = np.arange(3.0)
    entries = [
        (0, {"a": 1, "b": 0.5, "c": True, "d": np.float32(2.0), "e": np.bool_(True), "f": np.ones(2, np.int8),
             "g": {"h": 1.5, "i": np.zeros(3)}, "s": "text"}),
        (2, {"a": 2.9, "b": 1, "f": np.zeros(2, np.int8), "g": {"h": 2}, "final_obs": obs, "final_info": {"b": 3.0}}),
        (2, {"a": 7, "s": None}),
        (1, {"c": 0.0, "j": [1, 2]}),
        (3, {"a": -1, "b": 2.5, "c": False, "d": np.float32(1.0), "e": np.bool_(False), "f": np.ones(2, np.int8),
             "g": {"h": 3.5, "i": np.ones(3)}}),
    ]
    expected: dict = {}
    reference = VectorEnv()
    reference.num_envs = n
    for i, info in entries:
        expected = reference._add_info(expected, info, i)
    got = batch_infos(n, entries)
    assert_infos_equal(expected, got)
    assert got["a"].dtype == np.int64 and got["a"][2] == 7  # the first entry's type; a later entry overwrites
    assert got["e"].dtype == object  # a NumPy bool is not a number: an object array, as _add_info makes
    assert got["final_obs"][2] is obs and list(got["_final_obs"]) == [False, False, True, False]
    every = [(i, {"x": float(i), "v": np.full(2, i)}) for i in range(n)]  # the one-assignment path
    for i, info in every:
        expected = reference._add_info({} if i == 0 else expected, info, i)
    assert_infos_equal(expected, batch_infos(n, every))


def _sims():
    """Four simulators: two on the flat ground (one with another friction), two on the gap jump's terrain, from
    states perturbed alike."""
    sims = [CompiledContactSimulator(), CompiledContactSimulator(friction=0.4),
            CompiledContactSimulator(terrain=jump_terrain("gap_jump")),
            CompiledContactSimulator(terrain=jump_terrain("gap_jump"))]
    env = gym.make("hsddp_gym/Bounding-v0").unwrapped
    rng = np.random.default_rng(0)
    for sim in sims:
        x = env.init_state.copy()
        x[7:10] += rng.normal(0.0, 0.3, 3)
        sim.set_state(x)
    return sims


def test_simulator_batch_steps_each_robot_as_its_own_run():
    alone, batched = _sims(), _sims()
    start = batched[2].x.copy()
    batch = SimulatorBatch(batched)
    rng = np.random.default_rng(1)
    active = np.array([True, True, False, True])
    for _ in range(40):
        u = rng.uniform(-15.0, 15.0, (4, 4))
        for i, sim in enumerate(alone):
            if active[i]:
                sim.run(u[i], 5)
        batch.arrays["_ub"][:] = u
        batch.run(active, 5)
        for i in range(4):
            np.testing.assert_array_equal(batched[i].x, alone[i].x)
            np.testing.assert_array_equal(batched[i].states, alone[i].states)
            np.testing.assert_array_equal(batched[i].contact, alone[i].contact)
            assert batched[i].time == alone[i].time
            if active[i]:
                np.testing.assert_array_equal(batched[i].impulse, alone[i].impulse)
                assert batched[i].foot_heights_fast() == alone[i].foot_heights_fast()
    assert len(batch._groups(np.ones(4, dtype=bool))) == 3  # flat, flat at friction 0.4, the terrain
    assert batched[2].time == 0.0
    np.testing.assert_array_equal(batched[2].x, start)  # the inactive robot stayed put
    # a simulator in a batch still steps alone, on its own row
    u = np.full(4, 3.0)
    alone[0].run(u, 7)
    batched[0].run(u, 7)
    np.testing.assert_array_equal(batched[0].x, alone[0].x)
    np.testing.assert_array_equal(batch.arrays["_xb"][0], alone[0].x)
    # a new terrain regroups the robot
    batched[1].set_terrain(jump_terrain("gap_jump"))
    groups = batch._groups(np.ones(4, dtype=bool))
    assert [(on_terrain, list(np.flatnonzero(mask))) for _, on_terrain, mask in groups] == [
        (False, [0]), (True, [1]), (True, [2, 3])]


def test_simulator_batch_checks_its_simulators():
    with pytest.raises(ValueError, match="sims"):
        SimulatorBatch([])
    with pytest.raises(TypeError, match=r"sims\[0\]"):
        SimulatorBatch([object()])
    sim = CompiledContactSimulator()
    with pytest.raises(ValueError, match="distinct"):
        SimulatorBatch([sim, sim])



def test_sb3_trains_in_a_task_env_through_its_vector_env(tmp_path):
    pytest.importorskip("stable_baselines3")
    from hsddp_gym.learning.sb3 import train_sb3
    from hsddp_gym.learning.vector_sb3 import make_sb3_vec_env

    env = make_sb3_vec_env(3, seed=0, max_episode_steps=20, env_id="hsddp_gym/Backflip-v0", reset_noise_scale=0.04)
    assert type(env.venv) is BackflipVectorEnv
    env.reset()
    ends = 0
    for _ in range(25):
        obs, _, done, infos = env.step(np.zeros((3, 4), dtype=np.float32))
        for i in np.flatnonzero(done):
            ends += 1
            assert infos[i]["is_success"] is False and "terminal_observation" in infos[i]
    assert ends >= 3
    assert env.get_attr("reset_noise_scale") == [0.04] * 3
    with pytest.raises(ValueError, match="no compiled vector env"):
        make_sb3_vec_env(2, env_id="hsddp_gym/BackflipMuJoCo-v0")
    res = train_sb3("ppo", 192, 0, tmp_path / "ppo", env_id="hsddp_gym/GapJump-v0", max_episode_steps=30,
                    eval_freq=0, final_eval_episodes=0, overrides={"n_envs": 3, "n_steps": 32, "n_epochs": 1},
                    vector_env=True)
    assert res.summary["vector_env"] is True and res.summary["steps"] == 192
