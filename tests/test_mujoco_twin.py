"""The MuJoCo twin (envs/mujoco_twin.py) against the Pinocchio model and Bounding-v0 (skipped without mujoco)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pinocchio as pin
import pytest

mujoco = pytest.importorskip("mujoco")

import hsddp_gym  # noqa: E402
from hsddp_gym.core.model import CheetahModel  # noqa: E402
from hsddp_gym.core.params import LinkParams, RobotParams  # noqa: E402
from hsddp_gym.envs.bounding import BoundingEnv  # noqa: E402
from hsddp_gym.envs.contact import ContactSimulator  # noqa: E402
from hsddp_gym.envs.mujoco_twin import FOOT_RADIUS, MuJoCoBoundingEnv, MuJoCoSimulator, build_mjcf  # noqa: E402


@pytest.fixture(scope="module")
def robot():
    return CheetahModel()


def random_states(rng, n):
    for _ in range(n):
        q = rng.uniform(-1.5, 1.5, 7)
        q[1] += 1.0
        yield q, rng.normal(0.0, 5.0, 7)


@pytest.mark.parametrize("params", [RobotParams(), RobotParams(thigh=LinkParams(2.0, -0.05, 8e-3, 0.25),
                                                               hip_offset=0.21)])
def test_mass_matrix_bias_and_feet_equal_the_pinocchio_model(params):
    robot = CheetahModel(params)
    sim = MuJoCoSimulator(robot)
    m, d = sim.model, sim.data
    pdata = robot.model.createData()
    M = np.zeros((7, 7))
    worst = np.zeros(3)
    for q, v in random_states(np.random.default_rng(0), 100):
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        M_pin = pin.crba(robot.model, pdata, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        bias = pin.nonLinearEffects(robot.model, pdata, q, v)
        feet = np.array([d.site_xpos[s][[0, 2]] for s in sim._foot_sites])
        worst = np.maximum(worst, [np.abs(M - M_pin).max(), np.abs(d.qfrc_bias - bias).max(),
                                   np.abs(feet - robot.foot_positions(q)).max()])
    assert np.all(worst <= 1e-9), worst
    assert float(np.sum(m.body_mass)) == pytest.approx(params.total_mass, abs=1e-12)


def test_free_flight_step_equals_the_bounding_env_step(robot):
    """Far above the ground, with torques: MuJoCo's semi-implicit Euler step equals Bounding-v0's legacy scheme
    to 1e-9. The default scheme takes the same positions ``q + h v+`` and then projects ``v+`` onto the momentum
    and energy the step must have (gravity's impulse, the torques' work): its velocities differ from semi-implicit
    Euler's by a higher-order term: over the 20 states its largest value falls at least 8x when the step is
    quartered (measured: 0.86 rad/s at 1 ms, 0.011 rad/s at 0.25 ms, from torques of up to 33 N m on the legs)."""
    rng = np.random.default_rng(1)
    gaps = {1e-3: 0.0, 2.5e-4: 0.0}
    for q, v in random_states(rng, 20):
        q[1] = 3.0  # feet at least 2.5 m above the ground
        x = np.r_[q, v]
        u = rng.uniform(-33.0, 33.0, 4)
        ours = ContactSimulator(robot, energy_consistent=False)
        ours.set_state(x)
        ours.run(u, 1)
        twin = MuJoCoSimulator(robot)
        twin.set_state(x)
        twin.run(u, 1)
        np.testing.assert_allclose(twin.x, ours.x, rtol=0, atol=1e-9)
        default = ContactSimulator(robot)
        default.set_state(x)
        default.run(u, 1)
        np.testing.assert_allclose(twin.x[:7], default.x[:7], rtol=0, atol=1e-9)
        for h in gaps:
            legacy, projected = (ContactSimulator(robot, timestep=h, energy_consistent=flag) for flag in (False, True))
            for sim in (legacy, projected):
                sim.set_state(x)
                sim.run(u, 1)
            gaps[h] = max(gaps[h], float(np.abs(projected.v - legacy.v).max()))
    assert gaps[2.5e-4] <= gaps[1e-3] / 8.0


def test_floor_and_feet_make_contact_at_the_foot_point(robot):
    """The foot sphere is centred on the foot point and the floor lies FOOT_RADIUS below z = 0: feet placed at
    z = 0 touch the ground (the ground pushes them within two 1 ms steps, they sink micrometres), 1 cm up
    they do not."""
    sim = MuJoCoSimulator(robot)
    q = np.array([0.0, 0.0, 0.0, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    q[1] = -robot.foot_heights(q).min()
    sim.set_state(np.r_[q, np.zeros(7)])
    impulse = sim.run(np.zeros(4), 2)
    assert sim.contact.all()
    assert impulse[1] > 0.0 and impulse[3] > 0.0
    assert -5e-3 < sim.foot_heights().min() < 0.0
    assert "floor" in sim.xml and f'pos="0 0 {-FOOT_RADIUS!r}"' in sim.xml
    lifted = MuJoCoSimulator(robot)
    lifted.set_state(np.r_[q + np.array([0, 0.01, 0, 0, 0, 0, 0]), np.zeros(7)])
    assert lifted.run(np.zeros(4), 10) == [0.0, 0.0, 0.0, 0.0]  # 1 cm up: 10 ms of free fall, no contact
    assert not lifted.contact.any()


def test_registered_twin_has_the_same_spaces_reset_and_api():
    import gymnasium.utils.env_checker as checker

    lcp = gym.make("hsddp_gym/Bounding-v0")
    twin = gym.make(hsddp_gym.BOUNDING_MUJOCO_ENV_ID)
    assert isinstance(twin.unwrapped, MuJoCoBoundingEnv) and isinstance(twin.unwrapped, BoundingEnv)
    assert twin.spec.max_episode_steps == lcp.spec.max_episode_steps == 1000
    assert twin.observation_space == lcp.observation_space and twin.action_space == lcp.action_space
    checker.check_env(twin.unwrapped, skip_render_check=True)
    obs_a, info_a = lcp.reset(seed=3)
    obs_b, info_b = twin.reset(seed=3)
    np.testing.assert_array_equal(obs_a, obs_b)  # same reset distribution and seeding
    assert info_a.keys() == info_b.keys()
    _, reward, terminated, truncated, info = twin.step(np.zeros(4, dtype=np.float32))
    assert isinstance(reward, float) and not truncated and info.keys() == info_a.keys()
    with pytest.raises(TypeError, match="action"):
        twin.step(np.array([1j, 0, 0, 0]))


def test_build_mjcf_validates():
    with pytest.raises(TypeError, match="params"):
        build_mjcf("robot")
    with pytest.raises(ValueError, match="solref"):
        build_mjcf(solref=(0.0, 1.0))
    with pytest.raises(ValueError, match="timestep"):
        build_mjcf(timestep=-1.0)


def test_two_simulator_table_experiment(tmp_path, experiment):
    """``experiments/two_simulators.py``: one row per policy with the three simulators, missing models noted."""
    import json

    experiment("two_simulators").main(["--out", str(tmp_path), "--policies", "heuristic", "sac", "--episodes", "2",
                                       "--max-episode-steps", "10"])
    table = (tmp_path / "two_simulators.md").read_text()
    assert "| heuristic |" in table and "sac: skipped" in table
    data = json.loads((tmp_path / "two_simulators.json").read_text())
    runs = data["results"]["heuristic"]
    assert set(runs) == {"planner's model (BoundingKKT-v0)", "exact LCP (Bounding-v0)", "MuJoCo (BoundingMuJoCo-v0)"}
    assert all(r["episodes"] == 2 for r in runs.values())


def test_a_mujoco_divergence_is_reported_as_an_invalid_state(tmp_path, monkeypatch):
    """MuJoCo resets a diverging simulation to qpos0 with only a warning; the twin reports an invalid state."""
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory
    env = MuJoCoBoundingEnv(terminate_when_unhealthy=False)
    env.reset(seed=0)
    env.sim.v[3] = np.nan
    _, _, terminated, _, info = env.step(np.zeros(4))
    assert terminated and info["invalid_state"] is True
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4))
    _, info = env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.zeros(4))
    assert not info["invalid_state"]
