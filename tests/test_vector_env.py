"""The compiled vector env: its kernel against Pinocchio and ContactSimulator, its transitions against N single
envs, autoreset, seeding, arguments, and SB3 training through it (smoke)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pinocchio as pin
import pytest

import hsddp_gym  # noqa: F401  (registers the env)
from hsddp_gym.core import batch_model as bm
from hsddp_gym.core.batch_contact import kernel_scratch, run_one
from hsddp_gym.core.compiled_contact import CompiledContactSimulator
from hsddp_gym.core.contact import ContactSimulator
from hsddp_gym.core.contact_lcp import SEPARATE, SLIDE_NEG, SLIDE_POS, STICK
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import DEFAULT_PARAMS
from hsddp_gym.envs import vector
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.vector import INFO_KEYS, BoundingVectorEnv

ENV_ID = "hsddp_gym/Bounding-v0"
TOL = 1e-12
"""Model quantities (M, b, Jacobians, momentum map, energy) against Pinocchio."""
STEP_TOL = 1e-11
"""Whole steps against ContactSimulator, relative to ``1 + max |x|``. Not 1e-12: the contact impulse goes through
``M^-1``, whose entries reach ~2e3 at cond(M) ~ 2e4, and Pinocchio's own two routes to it
(``computeMinverse`` and ``inv(crba)``) differ by ~8e-12 there; the median step differs by ~1e-15 and most by
< 1e-12 (asserted)."""


def _close(a, b, scale_of=None) -> float:
    """Largest ``|a - b|`` relative to ``1 + max |b|`` (the round-off scale of a state whose joint rates reach
    tens of rad/s)."""
    b = np.asarray(b, dtype=np.float64)
    return float(np.max(np.abs(np.asarray(a) - b)) / (1.0 + np.max(np.abs(b if scale_of is None else scale_of))))


def _sims():
    """The default simulator and one with every parameter changed (the kernel reads them all)."""
    params = dataclasses.replace(DEFAULT_PARAMS, trunk=dataclasses.replace(DEFAULT_PARAMS.trunk, mass=6.5,
                                                                           com_z=-0.01, inertia_yy=0.13),
                                 thigh=dataclasses.replace(DEFAULT_PARAMS.thigh, length=0.22, com_z=-0.03),
                                 shank=dataclasses.replace(DEFAULT_PARAMS.shank, mass=0.2, length=0.18),
                                 hip_offset=0.2)
    return [ContactSimulator(motor_speed_limits=(36.0, 50.0)),
            ContactSimulator(CheetahModel(params), friction=0.3, gravity=7.0, torque_limit=25.0)]


@pytest.mark.parametrize("which", [0, 1])
def test_kernel_model_matches_pinocchio_at_random_states(which):
    sim = _sims()[which]
    p = bm.kernel_params(sim)
    sc = kernel_scratch()
    model, data = sim.model, sim.data
    rng = np.random.default_rng(which)
    for _ in range(40):
        q = rng.uniform(-2.0, 2.0, 7)
        v = rng.uniform(-20.0, 20.0, 7)
        bm.kinematics(p, q, sc.pts)
        bm.mass_matrix(p, sc.pts, sc.M)
        assert np.max(np.abs(sc.M - pin.crba(model, data, q))) < TOL
        bm.bias(p, sc.pts, v, sc.bvec)
        assert np.max(np.abs(sc.bvec - pin.nonLinearEffects(model, data, q, v))) < TOL * 10  # |b| ~ 1e3
        pin.computeJointJacobians(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        for foot, fid in enumerate(sim.robot.foot_frame_ids):
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            bm.point_jacobian(sc.pts, 5 + foot, sc.jx, sc.jz)
            assert np.max(np.abs(J[0] - sc.jx)) < TOL and np.max(np.abs(J[2] - sc.jz)) < TOL
            pos = data.oMf[fid].translation
            assert abs(pos[0] - sc.pts[bm.FOOT_POINT[foot], 0]) < TOL
            assert abs(pos[2] - sc.pts[bm.FOOT_POINT[foot], 1]) < TOL
        bm.centroidal_rows(sc.M, sc.P)
        assert np.max(np.abs(sc.P - pin.computeCentroidalMap(model, data, q)[[0, 2, 4]])) < TOL
        pin.computeMechanicalEnergy(model, data, q, v)
        energy = bm.mechanical_energy(p, np.concatenate([q, v]), sc)
        assert abs(energy - data.kinetic_energy - data.potential_energy) < TOL * (1.0 + abs(energy))


def _contact_states(sim, rng, n):
    """States near the ground: standing on both feet, then tilted, lifted, pushed down, sliding, spinning."""
    out = []
    for _ in range(n):
        q = np.zeros(7)
        q[2] = rng.uniform(-0.15, 0.15)
        q[3:] = rng.uniform(-0.4, 0.4, 4)
        x = np.concatenate([q, np.zeros(7)])
        x[1] -= sim.robot.foot_heights(q).min()
        x[7:] += rng.choice([0.02, 1.0]) * rng.normal(0.0, [1.5, 0.5, 2.0, 5.0, 5.0, 5.0, 5.0])  # quiet or not
        x[1] += rng.choice([0.0, 0.0, 5e-4, -3e-4, 0.02, 0.3])
        u = rng.uniform(-1.0, 1.0, 4) * sim.torque_limit * rng.choice([0.05, 1.0])
        out.append((x, u, [int(s) for s in rng.integers(0, 4, 2)]))
    for _ in range(10):  # standing still on straight legs: double stick at any friction
        q = np.zeros(7)
        q[3:] = rng.uniform(-0.02, 0.02, 4)
        x = np.concatenate([q, rng.normal(0.0, 0.01, 7)])
        x[1] -= sim.robot.foot_heights(q).min()
        out.append((x, rng.uniform(-0.5, 0.5, 4), [STICK, STICK]))
    return out


def _category(states) -> str:
    front, back = states
    if front == SEPARATE and back == SEPARATE:
        return "flight"
    kind = {STICK: "stick", SLIDE_POS: "slide", SLIDE_NEG: "slide"}
    if back == SEPARATE:
        return f"front {kind[front]}"
    if front == SEPARATE:
        return f"back {kind[back]}"
    return "double stick" if front == back == STICK else "double slide"


@pytest.mark.parametrize("which", [0, 1])
def test_kernel_step_matches_contact_simulator_in_every_contact_combination(which):
    """From the same state and previous foot states: one 1 ms step and a 5-step control step, in flight, front,
    back and double stance, sticking and sliding: same foot states and contact flags, same state and impulses
    to 1e-11 relative to the state's size (see STEP_TOL), 97 % to 1e-12. The env's CompiledContactSimulator (the
    same kernel, one robot) equals the kernel bit for bit."""
    sim = _sims()[which]
    p = bm.kernel_params(sim)
    sc = kernel_scratch()
    compiled = CompiledContactSimulator(sim.robot, friction=sim.mu, gravity=sim.gravity,
                                           motor_speed_limits=sim.motor_speed_limits, torque_limit=sim.torque_limit)
    assert np.array_equal(bm.kernel_params(compiled), p)
    seen = {}
    errors = []
    for x, u, prev in _contact_states(sim, np.random.default_rng(10 + which), 250):
        for n in (1, 5):
            sim.set_state(x)
            sim.states[:] = prev
            impulse = np.array(sim.run(u, n))
            xs = x.copy()
            states = np.array(prev, dtype=np.int64)
            contact = np.zeros(2, dtype=np.bool_)
            total = np.zeros(4)
            counters = np.zeros(4, dtype=np.int64)
            run_one(p, xs, u, n, states, contact, total, sc, counters)
            compiled.set_state(x)
            compiled.states[:] = prev
            assert np.array_equal(compiled.run(u, n), total) and np.array_equal(compiled.x, xs)
            assert compiled.states.tolist() == states.tolist() and compiled.contact.tolist() == contact.tolist()
            assert compiled.time == sim.time and np.array_equal(compiled._tau, sc.tau)
            assert np.max(np.abs(np.subtract(compiled.foot_heights_fast(), sim.robot.foot_heights(xs[:7])))) < TOL
            assert states.tolist() == list(sim.states) and contact.tolist() == sim.contact.tolist()
            errors.append(_close(xs, sim.x))
            assert errors[-1] < STEP_TOL
            assert np.max(np.abs(total - impulse)) < STEP_TOL * (1.0 + np.max(np.abs(impulse)))
            cat = _category(sim.states)
            seen[cat] = seen.get(cat, 0) + 1
    # every free step ends with the momentum-and-energy projection, whose M^-1 the two compute differently
    # (Pinocchio's computeMinverse, the kernel's tree factorization): a few more steps differ by 1e-13-1e-12
    assert np.median(errors) < 1e-14 and np.mean(np.array(errors) < TOL) > 0.97
    expected = {"flight", "front stick", "front slide", "back stick", "back slide", "double stick", "double slide"}
    assert expected <= set(seen), f"contact combinations not reached: {expected - set(seen)} (seen {seen})"


def test_kernel_energy_projection_paths_match():
    """Energy projections in flight (momentum-keeping) and in contact (scaling) are exercised and equal."""
    sim = ContactSimulator(motor_speed_limits=(36.0, 50.0))
    p = bm.kernel_params(sim)
    sc = kernel_scratch()
    rng = np.random.default_rng(3)
    projected = np.zeros(4, dtype=np.int64)
    for x, u, prev in _contact_states(sim, rng, 120):
        x = x.copy()
        x[10:] = rng.uniform(-80.0, 80.0, 4)  # fast legs: the semi-implicit step gains energy
        sim.set_state(x)
        sim.states[:] = prev
        sim.run(u, 5)
        xs, states = x.copy(), np.array(prev, dtype=np.int64)
        run_one(p, xs, u, 5, states, np.zeros(2, dtype=np.bool_), np.zeros(4), sc, projected)
        assert _close(xs, sim.x) < STEP_TOL
    assert projected[1] == sim.energy_projections > 0
    assert projected[2] == sim.momentum_fallbacks and projected[3] == sim.energy_deficits
    compiled = CompiledContactSimulator(motor_speed_limits=(36.0, 50.0))  # counts with the kernel's counters
    for x, u, prev in _contact_states(sim, np.random.default_rng(3), 120):
        compiled.set_state(x)
        compiled.states[:] = prev
        compiled.run(u, 5)
    assert compiled.energy_projections > 0 and compiled.lcp_fallbacks == 0


# ------------------------------------------------------------------------------ the vector env
def _pair(n, seed, **kwargs):
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    envs = [gym.make(ENV_ID, **kwargs) for _ in range(n)]
    obs_v, info_v = venv.reset(seed=seed)
    singles = [env.reset(seed=seed + i) for i, env in enumerate(envs)]
    assert np.array_equal(obs_v, np.stack([o for o, _ in singles]))  # the reset noise: bit-identical
    for key in INFO_KEYS:
        assert np.array_equal(info_v[key], np.stack([np.asarray(i[key]) for _, i in singles]))
        assert info_v["_" + key].all()
    return venv, envs


def _step_singles(envs, actions, pending):
    """Step the single envs with SyncVectorEnv's NEXT_STEP autoreset."""
    rows = []
    for i, env in enumerate(envs):
        if pending[i]:
            obs, info = env.reset()
            rows.append((obs, 0.0, False, False, info))
        else:
            rows.append(env.step(actions[i]))
        pending[i] = rows[-1][2] or rows[-1][3]
    return rows


def _compare(out_v, rows):
    """The vector env's step equals the single envs' bit for bit: observations, rewards, flags, every info entry."""
    obs, reward, terminated, truncated, info = out_v
    assert terminated.tolist() == [r[2] for r in rows] and truncated.tolist() == [r[3] for r in rows]
    assert np.array_equal(obs, np.stack([r[0] for r in rows]))
    assert reward.tolist() == [r[1] for r in rows]
    for key in INFO_KEYS:
        assert np.array_equal(info[key], np.stack([np.asarray(r[4][key]) for r in rows]), equal_nan=True), key


def test_single_env_steps_through_the_compiled_kernel():
    """The default scheme runs the vector env's compiled code (one robot); the legacy scheme stays Python."""
    assert isinstance(gym.make(ENV_ID).unwrapped.sim, CompiledContactSimulator)
    legacy = gym.make(ENV_ID, energy_consistent=False).unwrapped.sim
    assert type(legacy) is ContactSimulator and not legacy.energy_consistent


def test_a_copied_single_env_steps_as_the_original():
    """The compiled simulator's state lives in its kernel arrays; a deep copy re-links its views to the copies."""
    import copy

    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=4)
    env.step(np.ones(4, dtype=np.float32))
    twin = copy.deepcopy(env)
    assert twin.sim.x.base is twin.sim._xb and twin.sim.x is not env.sim.x
    for a in np.random.default_rng(1).uniform(-1.0, 1.0, (20, 4)).astype(np.float32):
        mine, theirs = env.step(a), twin.step(a)
        assert np.array_equal(mine[0], theirs[0]) and mine[1] == theirs[1]


def test_whole_episodes_equal_single_envs_with_zero_actions():
    """3 robots over 1100 steps (dozens of falls and autoresets) equal 3 single envs bit for bit in every
    observation, reward, flag and info entry."""
    venv, envs = _pair(3, seed=3)
    pending = [False] * 3
    actions = np.zeros((3, 4), dtype=np.float32)
    resets = 0
    for _ in range(1100):
        rows = _step_singles(envs, actions, pending)
        _compare(venv.step(actions), rows)
        resets += sum(pending)
    assert resets > 20


@pytest.mark.parametrize("kwargs", [{}, {"target_speed": 2.0, "friction": 0.4, "reset_noise_scale": 0.05,
                                         "frame_skip": 3, "trunk_mass_scale": 1.2, "max_episode_steps": 80,
                                         "exclude_current_positions_from_observation": False,
                                         "motor_speed_limits": (30.0, 45.0)}])
def test_whole_episodes_equal_single_envs_with_random_actions(kwargs):
    """Random actions (chaotic motion: any round-off difference would grow) over whole episodes, with falls,
    time limits and NEXT_STEP autoresets, default and changed keywords: the vector env and the single envs,
    both stepping through the same compiled kernel, agree bit for bit at every step."""
    venv, envs = _pair(4, seed=11, **kwargs)
    pending = [False] * 4
    rng = np.random.default_rng(0)
    falls = limits = 0
    for _ in range(500):
        actions = rng.uniform(-1.2, 1.2, (4, 4)).astype(np.float32)  # beyond the box: clipped alike
        rows = _step_singles(envs, actions, pending)
        _compare(venv.step(actions), rows)
        falls += sum(r[2] for r in rows)
        limits += sum(r[3] for r in rows)
    assert falls >= 4
    if "max_episode_steps" in kwargs:
        assert limits >= 4


@pytest.mark.parametrize("push", [{"count": 3, "time_range": (0.02, 0.6)},
                                  {"count": 2, "time_range": (0.101, 0.1035), "max_delta_v": (1.5, 1.0, 8.0)}])
def test_random_pushes_equal_single_envs_with_random_push(push):
    """``push=...``: every robot is pushed as ``RandomPush`` pushes a single env reset with the same seed, at the
    same simulation step, over whole episodes with falls and autoresets (the push generators continue after
    an unseeded reset alike), bit for bit; the second set puts both pushes of an episode in one control step."""
    from hsddp_gym.envs.perturbations import RandomPush

    n = 4
    venv = BoundingVectorEnv(num_envs=n, push=push)
    envs = [RandomPush(gym.make(ENV_ID), **push) for _ in range(n)]
    obs_v, _ = venv.reset(seed=21)
    firsts = [env.reset(seed=21 + i) for i, env in enumerate(envs)]
    assert np.array_equal(obs_v, np.stack([o for o, _ in firsts]))
    for i, (_, info) in enumerate(firsts):
        drawn = venv.scheduled_pushes(i)
        assert [t for t, _ in drawn] == [p["time"] for p in info["push"]]
        assert [dv.tolist() for _, dv in drawn] == [p["delta_v"] for p in info["push"]]
    pending = [False] * n
    rng = np.random.default_rng(2)
    falls = pushed = 0
    for _ in range(400):
        pushed += sum(bool(venv.scheduled_pushes(i)) for i in range(n))
        actions = rng.uniform(-1.0, 1.0, (n, 4)).astype(np.float32)
        rows = _step_singles(envs, actions, pending)
        _compare(venv.step(actions), rows)
        falls += sum(r[2] for r in rows)
    assert falls >= 4 and pushed > 0
    assert BoundingVectorEnv(num_envs=1).scheduled_pushes(0) == []
    with pytest.raises(ValueError, match="count"):
        BoundingVectorEnv(num_envs=1, push={"count": 0})
    with pytest.raises(ValueError, match="unknown field"):
        BoundingVectorEnv(num_envs=1, push={"times": (1.0, 2.0)})
    with pytest.raises(TypeError, match="push must be"):
        BoundingVectorEnv(num_envs=1, push=3)


def test_invalid_states_are_reported_alike():
    """A non-finite state (set by hand in robot 1 and its single env): the same invalid_state transition
    (terminated, NaN foot heights, finite observation), then an autoreset in both."""
    venv, envs = _pair(2, seed=21)
    actions = np.zeros((2, 4), dtype=np.float32)
    pending = [False] * 2
    for _ in range(3):
        _compare(venv.step(actions), _step_singles(envs, actions, pending))
    venv.unwrapped._x[1, 10] = np.nan
    envs[1].unwrapped.sim.v[3] = np.nan
    rows = _step_singles(envs, actions, pending)
    out = venv.step(actions)
    _compare(out, rows)
    assert out[4]["invalid_state"].tolist() == [False, True] and out[2].tolist() == [False, True]
    assert np.isnan(out[4]["foot_heights"][1]).all() and np.isfinite(out[0]).all()
    with pytest.raises(RuntimeError, match="invalid"):
        envs[1].step(actions[1])
    _compare(venv.step(actions), _step_singles(envs, actions, pending))  # robot 1 autoresets in both


def test_reset_seeding_and_autoreset_noise_follow_single_envs():
    venv, envs = _pair(3, seed=5)
    obs, _ = venv.reset(seed=[7, None, 9])
    assert np.array_equal(obs[0], envs[0].reset(seed=7)[0]) and np.array_equal(obs[2], envs[2].reset(seed=9)[0])
    assert np.array_equal(obs[1], envs[1].reset()[0])  # None: the generator goes on
    obs, _ = venv.reset()
    assert np.array_equal(obs, np.stack([env.reset()[0] for env in envs]))
    with pytest.raises(ValueError, match="num_envs=3"):
        venv.reset(seed=[1, 2])


def test_same_step_autoreset_reports_the_final_observation():
    venv = BoundingVectorEnv(num_envs=2, max_episode_steps=3, autoreset_mode="same_step")
    env = gym.make(ENV_ID, max_episode_steps=3)
    venv.reset(seed=0)
    env.reset(seed=0)
    actions = np.zeros((2, 4), dtype=np.float32)
    for _ in range(2):
        _, _, _, truncated, info = venv.step(actions)
        env.step(actions[0])
        assert not truncated.any() and "final_obs" not in info
    obs, _, _, truncated, info = venv.step(actions)
    last, _, _, last_truncated, last_info = env.step(actions[0])
    assert truncated.all() and last_truncated and info["_final_obs"].all()
    assert np.array_equal(info["final_obs"][0], last)
    assert info["final_info"]["x_position"][0] == last_info["x_position"]
    assert np.array_equal(obs[0], env.reset()[0])  # already reset, with the generator's next noise


def test_the_env_parameter_vector_holds_each_setting_at_its_slot():
    env = BoundingEnv(frame_skip=4, target_speed=1.7, tracking_sigma=0.3, forward_reward_weight=2.5,
                      ctrl_cost_weight=0.07, healthy_reward=0.9, terminate_when_unhealthy=False,
                      healthy_z_range=(0.11, 0.45), healthy_pitch_range=(-0.6, 0.7), gait_period=0.25)
    p = vector.env_params(env)
    assert p.shape == (vector.N_ENV_PARAMS,)
    expected = {vector.EP_DT: 0.004, vector.EP_TARGET_SPEED: 1.7, vector.EP_TRACKING_SIGMA: 0.3,
                vector.EP_FORWARD_WEIGHT: 2.5, vector.EP_CTRL_WEIGHT: 0.07, vector.EP_HEALTHY_WEIGHT: 0.9,
                vector.EP_TERMINATE_UNHEALTHY: 0.0, vector.EP_Z_LOW: 0.11, vector.EP_Z_HIGH: 0.45,
                vector.EP_PITCH_LOW: -0.6, vector.EP_PITCH_HIGH: 0.7, vector.EP_GAIT_PERIOD: 0.25}
    assert sorted(expected) == list(range(vector.N_ENV_PARAMS))
    for slot, value in expected.items():
        assert p[slot] == pytest.approx(value, rel=1e-15), slot
    with pytest.raises(TypeError, match="env must be a BoundingEnv, got dict"):
        vector.env_params({})


def test_arguments_and_inputs_are_checked():
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", target_speed=1.5)
    assert isinstance(venv, BoundingVectorEnv) and venv.template.target_speed == 1.5
    assert venv.max_episode_steps == 1000 and venv.observation_space.shape == (2, 17)
    with pytest.raises(TypeError, match="render_mode"):
        BoundingVectorEnv(num_envs=2, render_mode="rgb_array")
    with pytest.raises(TypeError, match="no_such_argument"):
        BoundingVectorEnv(num_envs=2, no_such_argument=1)
    with pytest.raises(ValueError, match="energy_consistent"):
        BoundingVectorEnv(num_envs=2, energy_consistent=False)
    with pytest.raises(ValueError, match="friction"):
        BoundingVectorEnv(num_envs=2, friction=-1.0)
    with pytest.raises(ValueError, match="num_envs"):
        BoundingVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        BoundingVectorEnv(num_envs=2, autoreset_mode="disabled")
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 4)))
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros(4))
    with pytest.raises(ValueError, match=r"robot\(s\) \[1\]"):
        venv.step(np.array([[0.0] * 4, [0.0, np.nan, 0.0, 0.0]]))
    with pytest.raises(ValueError, match="push"):
        venv.reset(options={"push": [1.0, 0.0, 0.0]})
    state = np.tile(venv.template.init_state, (2, 1))
    state[1, 10] = 500.0
    with pytest.raises(ValueError, match=r"robot 1: options\['state'\]\[10\]"):
        venv.reset(options={"state": state})
    state[1, 10] = 0.0
    obs, info = venv.reset(options={"state": state, "time": 0.1, "reset_mask": np.array([False, True])})
    assert np.array_equal(info["qpos"][1], state[1, :7]) and info["time"][1] == 0.1


def test_sb3_ppo_trains_through_the_vector_env():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from hsddp_gym.learning.vector_sb3 import make_sb3_vec_env

    env = make_sb3_vec_env(4, seed=0, max_episode_steps=40)
    obs = env.reset()
    assert obs.shape == (4, 17)
    saw_end = False
    for _ in range(45):
        obs, reward, done, infos = env.step(np.zeros((4, 4), dtype=np.float32))
        for i in np.nonzero(done)[0]:
            saw_end = True
            assert infos[i]["terminal_observation"].shape == (17,)
            assert "TimeLimit.truncated" in infos[i]
            assert not np.array_equal(infos[i]["terminal_observation"], obs[i])  # obs is the reset one
    assert saw_end
    model = PPO("MlpPolicy", VecMonitor(env), n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=512)
    assert model.num_timesteps == 512 and len(model.ep_info_buffer) > 0


def test_train_sb3_with_the_vector_env_writes_one_monitor_for_all_robots(tmp_path):
    pytest.importorskip("stable_baselines3")
    from hsddp_gym.learning.sb3 import train_sb3

    # evaluations during training with VecNormalize (the preset's): the evaluation env is wrapped as the training
    # env, and eval_freq counts env steps of all robots (SB3's EvalCallback counts calls of n_envs steps)
    res = train_sb3("ppo", 256, 0, tmp_path / "ppo", max_episode_steps=30, eval_freq=64, eval_episodes=1,
                    final_eval_episodes=0, overrides={"n_envs": 4, "n_steps": 32, "n_epochs": 1}, vector_env=True)
    assert res.summary["vector_env"] is True and res.summary["steps"] == 256
    assert res.summary["training_episodes"] >= 4  # 30-step episodes of 4 robots, one train.monitor.csv
    np.testing.assert_array_equal(np.load(tmp_path / "ppo" / "evaluations.npz")["timesteps"], [64, 128, 192, 256])
    with pytest.raises(TypeError, match="vector_env"):
        train_sb3("ppo", 10, 0, tmp_path / "bad", vector_env="yes")


def test_cli_refuses_vector_env_for_other_learners(tmp_path, capsys):
    from hsddp_gym import cli

    assert cli.main(["train", "--algo", "dagger", "--expert", "heuristic", "--vector-env",
                     "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --vector-env:"), err


def test_train_condition_perturbs_the_training_robots_only(tmp_path):
    """``train_condition``: the training robots run under the condition (the vector env's pushes, or the
    condition's wrappers around single envs), the evaluation env does not; bad conditions are refused by name
    before anything is written."""
    pytest.importorskip("stable_baselines3")
    from hsddp_gym.envs.perturbations import ObservationNoise, RandomPush
    from hsddp_gym.learning.sb3 import check_train_condition, train_sb3
    from hsddp_gym.learning.sb3.training import _make_venv

    push_x3 = check_train_condition("push_x3", vector_env=True)
    venv = _make_venv(3, 0, {}, None, None, vector_env=True, condition=push_x3)
    assert venv.venv.venv.push.count == 3  # VecMonitor -> SB3 adapter -> BoundingVectorEnv
    venv.reset()
    assert all(len(venv.venv.venv.scheduled_pushes(i)) == 3 for i in range(3))
    assert _make_venv(1, 0, {}, None, None, vector_env=True).venv.venv.push is None
    noisy = _make_venv(2, 0, {}, None, None, condition=check_train_condition("obs_noise"))
    assert all(isinstance(e.env, ObservationNoise) for e in noisy.envs)  # Monitor around the condition's env
    heavy = _make_venv(1, 0, {}, 50, None, condition=check_train_condition("mass_+15"))
    assert heavy.envs[0].unwrapped.trunk_mass_scale == 1.15
    single_push = _make_venv(1, 0, {}, None, None, condition=check_train_condition("push"))
    assert isinstance(single_push.envs[0].env, RandomPush)

    res = train_sb3("ppo", 64, 0, tmp_path / "ppo", max_episode_steps=30, eval_freq=0, final_eval_episodes=0,
                    overrides={"n_envs": 2, "n_steps": 32, "n_epochs": 1}, vector_env=True, train_condition="push")
    assert res.summary["train_condition"]["name"] == "push" and res.summary["train_condition"]["push"] == {}
    for kwargs, message in [({"train_condition": "nope"}, "train_condition must be one of"),
                            ({"train_condition": "obs_noise", "vector_env": True}, "vector env does not offer"),
                            ({"train_condition": "speed_2.0", "env_kwargs": {"target_speed": 1.0}},
                             r"sets \['target_speed'\] itself")]:
        with pytest.raises(ValueError, match=message):
            train_sb3("ppo", 64, 0, tmp_path / "bad", **kwargs)
    assert not (tmp_path / "bad").exists()
