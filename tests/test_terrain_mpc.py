"""The terrain-aware MPC: ``MPCPolicy(..., terrain=...)`` given the ground as privileged information (its switching
constraints, reference heights, late-landing rule, state filter and bias estimate on the terrain), the planner's
switching constraint on a slope, the argument's checks, and a Terrain-v0 dataset recorded with it
(``hsddp-gym dataset --env hsddp_gym/Terrain-v0 --policy mpc``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IZ, NQ, NX, Mode, mode_from_contacts
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.core.terrain import Terrain
from hsddp_gym.planners.optimizer.objective import ConstraintState, Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.policies import MPCOptions, MPCPolicy
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.estimation import MeasurementBias, project_onto_contacts, terrain_clearance
from hsddp_gym.planners.policies.mpc import GaitClock, ScheduleOptions, env_terrain, late_landing
from hsddp_gym.rollout.episodes import run_episode

TERRAIN_ENV = "hsddp_gym/Terrain-v0"
DRIFT_SEED = 9812
"""A Terrain-v0 seed whose ground drifts 11-14 cm below the start within the first 3.5 s (a terrain, not an
outcome: the bias test needs a ground far from ``z = 0``)."""


@pytest.fixture(scope="module")
def terrain_env():
    env = gym.make(TERRAIN_ENV)
    yield env
    env.close()


def test_the_terrain_aware_mpc_plans_on_the_episode_s_terrain_and_integrates_its_trunk_x(terrain_env):
    """Given the terrain, the MPC reads it at its reset, plans with it (the switching constraints' ground, the
    reference heights raised by the ground under the trunk at each phase's end) and, without the trunk x in the
    observation, integrates the measured forward speed for it."""
    env = terrain_env
    mpc = MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=env_terrain(env))
    result = run_episode(env, mpc, 3, max_steps=300)
    assert mpc.terrain is env.unwrapped.terrain and not mpc.terrain.is_flat
    assert mpc.stats["planner_failures"] == 0
    x = mpc.last_prediction
    height = mpc.schedule.plan_height(mpc.estimator.bias)  # where the feet put the ground above the terrain
    assert abs(height) < 0.01
    schedule, speed = mpc.schedule.schedule(x), mpc.speed.plan_speed(x)
    problem = mpc.planner.problem(x, schedule, speed, height)
    assert problem.terrain == mpc.terrain.raised(height)
    flat = MPCPolicy(EnvInterface(), MPCOptions()).planner.problem(x, schedule, speed, 0.0)
    raised = np.array([c.x_ref[IZ] for c in problem.costs]) - np.array([c.x_ref[IZ] for c in flat.costs])
    ends = x[0] + speed * np.cumsum(schedule.durations)
    np.testing.assert_allclose(raised, mpc.ground.under_trunk(ends) + height, atol=1e-12)
    assert np.ptp(raised) > 0.005  # the ground under the trunk changes over the horizon
    assert abs(mpc.last_estimate[0] - result.states[-2, 0]) < 0.02


def test_a_terrain_object_acts_as_the_env_terrain_function(terrain_env):
    env = terrain_env
    profile = Terrain.sample(np.random.default_rng(11), "mixed")  # the env's draw at reset(seed=11)
    actions = []
    for terrain in (profile, env_terrain(env)):
        mpc = MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=terrain)
        result = run_episode(env, mpc, 11, max_steps=120)
        assert env.unwrapped.terrain == profile and mpc.terrain == profile
        actions.append(result.actions)
    np.testing.assert_array_equal(actions[0], actions[1])


def test_no_terrain_or_a_flat_one_is_the_flat_ground_mpc_bit_for_bit():
    env = gym.make("hsddp_gym/Bounding-v0")
    reference = run_episode(env, MPCPolicy.from_env(env), 5, max_steps=80).actions
    for terrain in (None, Terrain.flat(), env_terrain(env), lambda: None):
        mpc = MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=terrain)
        np.testing.assert_array_equal(run_episode(env, mpc, 5, max_steps=80).actions, reference)
        assert mpc.terrain is None
    env.close()


@pytest.mark.parametrize("terrain", ["random_mixed", 0.03, {"edges": [], "levels": [0.0], "gaps": [False]}])
def test_the_terrain_argument_is_checked(terrain):
    with pytest.raises(TypeError, match="terrain must be None, a Terrain or a function"):
        MPCPolicy(EnvInterface(), MPCOptions(), terrain=terrain)


def test_what_the_terrain_function_returns_is_checked():
    with pytest.raises(TypeError, match=r"terrain\(\) must be a Terrain or None, got str"):
        MPCPolicy(EnvInterface(), MPCOptions(), terrain=lambda: "random_mixed")


def _standing(level: float) -> np.ndarray:
    """A state (14,) with both feet on level ground at height ``level`` [m]."""
    from hsddp_gym.core.references import paper_initial_state

    robot = CheetahModel()
    x = paper_initial_state(robot.params).copy()
    for _ in range(5):  # Gauss-Newton steps
        x = project_onto_contacts(robot, x, Mode.DOUBLE_STANCE)
    x[IZ] += level
    return x


def test_the_late_landing_rule_measures_the_landing_foot_from_the_terrain():
    robot = CheetahModel()
    ground = Terrain.step(-10.0, 0.05)  # 5 cm up everywhere the robot is
    x = _standing(0.05)
    x[IZ] += 0.005  # both feet 5 mm above the terrain, 5.5 cm above z = 0
    assert abs(terrain_clearance(robot, x[:NQ], FRONT, ground) - 0.005) < 1e-4
    clock = GaitClock((0.08, 0.072, 0.072, 0.072), 0.005, ScheduleOptions(restep=False))
    clock.update(Mode.FLIGHT, 1.0)  # a flight that lands the front foot
    clock.tau = 0.08  # past its nominal end
    assert late_landing(clock, Mode.FLIGHT, x, robot, 0.01, ground) == Mode.FRONT_STANCE
    assert late_landing(clock, Mode.FLIGHT, x, robot, 0.01) == Mode.FLIGHT  # 5.5 cm above z = 0
    x[IZ] += 0.02
    assert late_landing(clock, Mode.FLIGHT, x, robot, 0.01, ground) == Mode.FLIGHT


def test_the_state_filter_projection_puts_the_stance_feet_on_a_slope():
    robot = CheetahModel()
    ramp = Terrain.ramp(-1.0, 2.0, 0.1)
    x = _standing(ramp.height(0.0))  # level, feet on the ramp's height under the trunk
    x[IZ] += 0.02
    y = project_onto_contacts(robot, x, Mode.DOUBLE_STANCE, ramp)  # one Gauss-Newton step

    def off(state):
        return max(abs(terrain_clearance(robot, state[:NQ], f, ramp)) for f in (FRONT, BACK))

    assert off(x) > 0.02 and off(y) < 0.05 * off(x)
    assert off(project_onto_contacts(robot, y, Mode.DOUBLE_STANCE, ramp)) < 1e-4
    assert y[IPITCH] < x[IPITCH] - 0.05  # nose up along the rising ground


def test_the_bias_estimate_on_a_known_terrain_finds_the_sensor_bias_alone(terrain_env):
    env = terrain_env
    mpc = MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=env_terrain(env))
    obs, info = env.reset(seed=DRIFT_SEED)
    mpc.reset()
    states, modes = [], []
    for _ in range(700):  # 3.5 s: the ground drifts 11 cm below the start
        obs, _, terminated, truncated, info = env.step(mpc(obs))
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        modes.append(mode_from_contacts(*info["contact"]))
        assert not terminated
    bias = np.zeros(NX)
    bias[[IZ, IPITCH]] = [0.02, -0.03]
    estimates = []
    for terrain in (env.unwrapped.terrain, None):
        est = MeasurementBias(CheetahModel(), 0.005)
        est.terrain = terrain
        for x, m in zip(states, modes):
            est.update(x + bias, m)
        estimates.append(est.bias.copy())
    assert abs(estimates[0][IZ] - 0.02) < 2e-3 and abs(estimates[0][IPITCH] + 0.03) < 5e-3
    assert abs(estimates[1][IZ] - 0.02) > 0.02  # the flat-ground estimate takes the terrain for a bias


def _switching_gradient(terrain, X_pre_state):
    """``(g, dg/dx)`` of the front foot's switching constraint at ``X_pre_state`` (14,) on ``terrain``: the value
    from :meth:`Objective.switching_values`, the gradient from :meth:`Objective.derivatives` (the AL term's
    ``Phi_x`` with multiplier 1 less that with multiplier 0)."""
    from hsddp_gym.core.conventions import NGRF, NU
    from hsddp_gym.core.dynamics import HybridDynamics
    from hsddp_gym.planners.optimizer.problem import bounding_phase_cost

    schedule = ModeSchedule([Mode.FLIGHT, Mode.FRONT_STANCE], [0.01, 0.01], final_mode=Mode.FLIGHT)
    costs = [bounding_phase_cost(Mode.FLIGHT, FRONT), bounding_phase_cost(Mode.FRONT_STANCE, None)]
    problem = HybridProblem(HybridDynamics(dt=0.0025), schedule, costs, X_pre_state, terrain=terrain)
    objective = Objective(problem)
    N, n = problem.n_knots, problem.n_phases
    row = next(r for r, (i, f) in enumerate(zip(problem.switch_phase, problem.switch_foot)) if f == FRONT)
    X, X_pre = np.tile(X_pre_state, (N + 1, 1)), np.tile(X_pre_state, (n, 1))
    U, GRF = np.zeros((N, NU)), np.zeros((N, NGRF))
    grf_x, grf_u = np.zeros((N, NGRF, NX)), np.zeros((N, NGRF, NU))
    phis = []
    for lam in (0.0, 1.0):
        multipliers = np.zeros(problem.n_switching)
        multipliers[row] = lam
        cs = ConstraintState(sigma=0.0, lam=multipliers, use_al=True, use_reb=False, delta_torque=0.1,
                             delta_grf=0.1, eps_torque=0.0, eps_grf=0.0)
        out = [np.zeros((N, NX)), np.zeros((N, NU)), np.zeros((N, NX, NX)), np.zeros((N, NU, NU)),
               np.zeros((N, NU, NX)), np.zeros((n, NX)), np.zeros((n, NX, NX))]
        objective.derivatives(X, X_pre, U, GRF, grf_x, grf_u, cs, *out)
        phis.append(out[5][problem.switch_phase[row]])
    return objective.switching_values(X_pre)[row], phis[1] - phis[0]


@pytest.mark.parametrize("terrain", [Terrain.ramp(-1.0, 2.0, 0.1), Terrain.ramp(-1.0, 2.0, -0.07),
                                     Terrain.step(-1.0, 0.03)])
def test_the_switching_constraint_gradient_on_a_terrain_matches_finite_differences(terrain):
    x = _standing(0.0)
    x[IZ] += 0.05
    g, grad = _switching_gradient(terrain, x)
    robot = CheetahModel()
    foot = robot.foot_positions(x[:NQ])[FRONT]
    assert g == foot[1] - terrain.height(float(foot[0]))
    for k in (IZ, IPITCH, 3, 4, 5, 6):
        eps = 1e-6
        xp, xm = x.copy(), x.copy()
        xp[k] += eps
        xm[k] -= eps
        fd = (_switching_gradient(terrain, xp)[0] - _switching_gradient(terrain, xm)[0]) / (2 * eps)
        assert abs(grad[k] - fd) < 1e-6, k


def test_a_small_terrain_dataset_is_recorded_by_the_terrain_aware_mpc(terrain_env, tmp_path, capsys):
    """``hsddp-gym dataset --env hsddp_gym/Terrain-v0 --policy mpc``: the expert is given each episode's terrain
    (its actions are the terrain-aware MPC's, not the flat-ground MPC's, past the flat start), Minari loads the
    dataset and rebuilds Terrain-v0; ``--policy expert`` (a flat-ground plan tracker) is refused."""
    pytest.importorskip("minari")
    import minari

    from hsddp_gym import cli
    from hsddp_gym.datasets.storage import load_npz, minari_root, read_metadata

    out, steps, seed = tmp_path / "terrain", 150, 11
    assert cli.main(["dataset", "--env", TERRAIN_ENV, "--policy", "mpc", "--episodes", "2", "--seed", str(seed),
                     "--max-episode-steps", str(steps), "--out", str(out), "--quiet"]) == 0
    meta = read_metadata(out)
    dataset_id = "hsddp_gym/terrain/mpc-v0"
    assert meta["dataset_id"] == dataset_id and meta["env_id"] == TERRAIN_ENV
    assert meta["policy"]["class"].endswith(".MPCPolicy") and "env_terrain" in meta["policy"]["terrain"]
    with minari_root(out / "minari"):
        ds = minari.load_dataset(dataset_id)
        assert ds.total_episodes == 2 and ds.total_steps == 2 * steps
        env = ds.recover_environment()
        assert env.spec.id == TERRAIN_ENV and env.unwrapped.terrain_option == "random_mixed"
        env.close()
    data = load_npz(out)
    assert data.n_episodes == 2
    recorded = data.actions[:steps]
    env = terrain_env
    aware = run_episode(env, MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=env_terrain(env)), seed,
                        max_steps=steps).actions
    flat = run_episode(env, MPCPolicy(EnvInterface.from_env(env), MPCOptions()), seed, max_steps=steps).actions
    np.testing.assert_array_equal(recorded, aware)
    assert not np.array_equal(recorded, flat)
    assert cli.main(["dataset", "--env", TERRAIN_ENV, "--policy", "expert", "--episodes", "1",
                     "--out", str(tmp_path / "expert")]) == 2
    assert "terrain-aware MPC" in capsys.readouterr().err and not (tmp_path / "expert").exists()


def test_make_policy_mpc_in_terrain_v0_is_the_terrain_aware_mpc(terrain_env):
    from hsddp_gym.rollout.policies import make_policy

    policy = make_policy("mpc", terrain_env)
    assert getattr(policy, "reset_options", None) is None
    terrain_env.reset(seed=11)
    policy.reset()
    assert policy.terrain is terrain_env.unwrapped.terrain and not policy.terrain.is_flat
    flat_env = gym.make("hsddp_gym/Bounding-v0")
    policy = make_policy("mpc", flat_env)
    flat_env.reset(seed=0)
    policy.reset()
    assert policy.terrain is None
    flat_env.close()


def test_dagger_in_terrain_v0_is_labelled_by_the_terrain_aware_mpc(tmp_path, capsys):
    pytest.importorskip("torch")
    from hsddp_gym import cli
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig, run_dagger

    config = DAggerConfig(rounds=1, episodes_per_round=1, max_episode_steps=20, bc=BCConfig(epochs=1))
    summary = run_dagger("mpc", tmp_path / "dagger", config=config, eval_episodes=0, progress=False,
                         env_id=TERRAIN_ENV)
    assert summary["env_id"] == TERRAIN_ENV and "env_terrain" in summary["expert"]["terrain"]
    with pytest.raises(ValueError, match="terrain-aware MPC"):
        run_dagger("expert", tmp_path / "expert", config=config, eval_episodes=0, progress=False, env_id=TERRAIN_ENV)
    assert cli.main(["train", "--algo", "dagger", "--env", TERRAIN_ENV, "--expert", "expert",
                     "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err.startswith("error: --expert")
