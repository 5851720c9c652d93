"""The contact-model family of the MuJoCo twin (envs/mujoco_twin.py: ContactModel, CONTACT_CORNERS) and its
perturbation conditions (envs/perturbations/conditions.py: contact_family, contact_<corner>); skipped without mujoco."""

from __future__ import annotations

import dataclasses
import hashlib
import math

import gymnasium as gym
import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import hsddp_gym  # noqa: E402
from hsddp_gym.core.model import CheetahModel  # noqa: E402
from hsddp_gym.envs.mujoco_twin import (  # noqa: E402
    CONTACT_CORNERS,
    FAMILY_RANGES,
    ContactModel,
    MuJoCoBoundingEnv,
    MuJoCoSimulator,
    build_mjcf,
)
from hsddp_gym.envs.perturbations import (  # noqa: E402
    CONDITIONS,
    CONTACT_CONDITIONS,
    SUITE,
    RandomContactModel,
    get_condition,
    make_env,
    wrapper_info_keys,
)

TWIN = hsddp_gym.BOUNDING_MUJOCO_ENV_ID
DEFAULT_MJCF_SHA256 = "4a2b750f6895b780474bc1861255b2befc6cd793729e8752ba4a715fdb680c91"
"""sha256 of ``build_mjcf()`` as the twin wrote it before contact models were configurable."""
DEFAULT_TRAJECTORY_END = np.array([0.18097058, 0.11517264, -0.17840019, 0.64342485, 1.27828902, 5.5767753,
                                   -0.91193559, 0.91858729, -1.74441052, -0.15089596, 2.70656704, 3.64320078,
                                   3.57868297, -21.41462042])
"""The state after the 45 steps of :func:`_random_rollout` (it falls then) in that twin (MuJoCo 4.0.1)."""


def _random_rollout(env, seed: int = 11, steps: int = 100) -> np.ndarray:
    """States (T, 14) after each step of seeded random actions in [-0.3, 0.3] from ``reset(seed)``."""
    env.reset(seed=seed)
    rng = np.random.default_rng(0)
    states = []
    for _ in range(steps):
        _, _, terminated, _, info = env.step(rng.uniform(-0.3, 0.3, 4).astype(np.float32))
        states.append(np.r_[info["qpos"], info["qvel"]])
        if terminated:
            break
    return np.array(states)


def test_the_default_model_is_the_twin_bit_for_bit():
    xml = build_mjcf()
    assert hashlib.sha256(xml.encode()).hexdigest() == DEFAULT_MJCF_SHA256
    assert build_mjcf(contact_model=ContactModel.DEFAULT) == xml == build_mjcf(contact_model={})
    assert MuJoCoSimulator(contact_model=ContactModel()).xml == xml
    reference = _random_rollout(gym.make(TWIN))
    assert len(reference) == 45
    if mujoco.__version__ == "4.0.1":  # the version the reference was recorded with
        np.testing.assert_allclose(reference[-1], DEFAULT_TRAJECTORY_END, rtol=0, atol=1e-7)
    for kwargs in ({"contact_model": ContactModel.DEFAULT}, {"contact_model": ContactModel.DEFAULT.as_dict()},
                   {"solref": (0.005, 1.0), "cone": "elliptic", "foot_radius": 0.005, "sim_timestep": 1e-3,
                    "friction": 0.6, "impratio": 1.0, "solimp": (0.9, 0.95, 0.001, 0.5, 2.0)}):
        env = gym.make(TWIN, **kwargs)
        assert env.unwrapped.sim.xml == xml and env.unwrapped.frame_skip == 5 and env.unwrapped.dt == 0.005
        np.testing.assert_array_equal(_random_rollout(env), reference)


@pytest.mark.parametrize("kwargs, argument", [
    ({"cone": "conic"}, "cone"),
    ({"solref": (0.0001, 1.0)}, "solref"),
    ({"solref": (0.005, 20.0)}, "solref"),
    ({"solref": (0.005,)}, "solref"),
    ({"solimp": (0.9, 0.95, 0.001)}, "solimp"),
    ({"solimp": (0.9, 0.95, 0.001, 1.5, 2.0)}, "solimp"),
    ({"solimp": (0.99, 0.95, 0.001, 0.5, 2.0)}, "solimp"),
    ({"foot_radius": 0.0001}, "foot_radius"),
    ({"foot_radius": 0.1}, "foot_radius"),
    ({"impratio": 0.5}, "impratio"),
    ({"timestep": 0.003}, "timestep"),
    ({"timestep": 0.0009}, "timestep"),  # in range, but 5 ms is not a whole number of it
    ({"friction": 3.0}, "friction"),
    ({"friction": float("nan")}, "friction"),
])
def test_validation_names_the_argument(kwargs, argument):
    """Out of the accepted ranges (wider than the family's): ValueError naming the argument, from the model, the
    MJCF builder and the env alike."""
    with pytest.raises(ValueError, match=argument):
        ContactModel(**kwargs)
    with pytest.raises(ValueError, match=argument):
        build_mjcf(**kwargs)
    env_kwargs = {("sim_timestep" if k == "timestep" else k): v for k, v in kwargs.items()}
    with pytest.raises(ValueError, match=argument):
        MuJoCoBoundingEnv(**env_kwargs)


def test_parse_and_replace_validate():
    assert ContactModel.parse("stiffest") is CONTACT_CORNERS["stiffest"]
    assert ContactModel.parse({"friction": 0.8}) == ContactModel(friction=0.8)
    with pytest.raises(ValueError, match="contact_model"):
        ContactModel.parse("hardest")
    with pytest.raises(ValueError, match="unknown field"):
        ContactModel.parse({"stiffness": 1.0})
    with pytest.raises(TypeError, match="contact_model"):
        MuJoCoBoundingEnv(contact_model=3)
    with pytest.raises(TypeError, match="rng"):
        ContactModel.sample(0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ContactModel.DEFAULT.friction = 0.5
    # the keywords replace the model's fields; the control period stays 5 ms
    env = MuJoCoBoundingEnv(contact_model="pyramidal", sim_timestep=0.0005, friction=0.9)
    assert env.contact_model == ContactModel(cone="pyramidal", timestep=0.0005, friction=0.9)
    assert env.frame_skip == 10 and env.dt == 0.005 and env.sim.mu == 0.9 and 'cone="pyramidal"' in env.sim.xml
    assert MuJoCoBoundingEnv(sim_timestep=0.005 / 3, frame_skip=2).dt == pytest.approx(0.005 * 2 / 3)


def _stand_action(env, robot: CheetahModel, z_ref: float, q_ref: np.ndarray) -> np.ndarray:
    """A standing law (4,) normalized: in the air the joints hold ``q_ref`` (4,) (PD); on the ground the feet push
    the trunk's weight plus a height, forward-speed and pitch PD (``u = -J^T f`` with the least-norm foot forces)."""
    x = env.state
    q, v = x[:7], x[7:]
    if robot.foot_heights(q).min() > 0.002:
        return np.clip((8.0 * (q_ref - q[3:]) - 0.2 * v[3:]) / env.torque_limit, -1, 1).astype(np.float32)
    wrench = np.array([-30.0 * v[0], robot.total_mass * 9.81 + 300.0 * (z_ref - q[1]) - 60.0 * v[1],
                       0.3 * (-30.0 * q[2] - 3.0 * v[2])])
    r = robot.foot_positions(q) - q[[0, 1]]
    A = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [r[0, 1], -r[0, 0], r[1, 1], -r[1, 0]]])
    f = np.linalg.pinv(A) @ wrench  # [fx, fz] of the front foot, then of the back foot
    u = np.zeros(4)
    for foot, joints in ((0, [3, 4]), (1, [5, 6])):
        J = robot.foot_jacobian(q, foot)[:, joints]
        u[2 * foot:2 * foot + 2] = -(J.T @ f[2 * foot:2 * foot + 2])
    return np.clip(u / env.torque_limit, -1, 1).astype(np.float32)


@pytest.mark.parametrize("corner", list(CONTACT_CORNERS))
def test_each_corner_lands_and_stands(corner):
    """Dropped from 3 cm above the standing posture, in each corner model, for 0.5 s:

    * with zero torques (the legs have no joint stiffness, so they fold and the trunk, which does not collide,
      sinks through the floor): the feet land, nothing blows up (finite states, no invalid state, no energy gained:
      the passive robot on a soft contact only loses energy), the feet sink less than 5 cm into the floor;
    * with a standing law (:func:`_stand_action`): both feet stay on the ground, the trunk stays above 0.2 m and
      level, and it has settled (every velocity below 3 m/s or rad/s)."""
    robot = CheetahModel()
    env = MuJoCoBoundingEnv(contact_model=corner, terminate_when_unhealthy=False)
    assert env.sim.model.opt.timestep == CONTACT_CORNERS[corner].timestep and env.dt == 0.005
    state = env.init_state.copy()
    state[7:] = 0.0
    z_ref, q_ref = state[1], state[3:7].copy()
    state[1] += 0.03
    # zero torques
    env.reset(options={"state": state})
    energy0 = env.sim.energy()
    touched, deepest = np.zeros(2, dtype=bool), 0.0
    for _ in range(100):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
        assert not info["invalid_state"] and np.all(np.isfinite(env.state))
        assert env.sim.energy() <= energy0 + 1e-6
        touched |= env.sim.contact
        deepest = min(deepest, float(env.sim.foot_heights().min()))
    assert touched.all() and deepest > -0.05
    # standing
    env.reset(options={"state": state})
    heights, both = [], []
    for _ in range(100):
        _, _, terminated, _, info = env.step(_stand_action(env, robot, z_ref, q_ref))
        assert not info["invalid_state"] and not terminated
        heights.append(info["qpos"][1])
        both.append(bool(env.sim.contact.all()))
    assert min(heights) > 0.2 and all(both[-20:]) and abs(env.state[2]) < 0.15
    assert np.abs(env.state[7:]).max() < 3.0


def test_sample_respects_the_ranges_and_covers_them():
    rng = np.random.default_rng(0)
    models = [ContactModel.sample(rng) for _ in range(400)]
    r = FAMILY_RANGES

    def inside(values, key):
        lo, hi = r[key]
        return min(values) >= lo and max(values) <= hi and min(values) < lo + 0.2 * (hi - lo) \
            and max(values) > hi - 0.2 * (hi - lo)

    assert {m.cone for m in models} == {"pyramidal", "elliptic"}
    assert inside([m.solref[0] for m in models], "solref_time_constant")
    assert inside([m.solref[1] for m in models], "solref_damping_ratio")
    assert inside([m.solimp[0] for m in models], "solimp_d_min")
    assert inside([m.solimp[1] for m in models], "solimp_d_max")
    assert inside([m.solimp[2] for m in models], "solimp_width")
    assert inside([m.foot_radius for m in models], "foot_radius")
    assert inside([m.impratio for m in models], "impratio")
    assert inside([m.friction for m in models], "friction")
    assert {m.frame_skip for m in models} == set(range(3, 11))
    assert all(m.timestep * m.frame_skip == 0.005 for m in models)
    # log-uniform: the median time constant is near the geometric mean of its range
    assert np.median([m.solref[0] for m in models]) == pytest.approx(math.sqrt(0.002 * 0.02), rel=0.2)
    assert ContactModel.sample(np.random.default_rng(5)) == ContactModel.sample(np.random.default_rng(5))


def test_contact_conditions_are_extra_and_run_in_the_twin():
    assert len(SUITE) == 13 and not set(SUITE) & set(CONTACT_CONDITIONS)
    assert set(CONTACT_CONDITIONS) == {"contact_family"} | {f"contact_{c}" for c in CONTACT_CORNERS}
    assert all(c in CONDITIONS for c in CONTACT_CONDITIONS)
    for name in CONTACT_CONDITIONS:
        cond = get_condition(name)
        assert cond.simulator_for("bounding") == "mujoco" and not cond.acts_through_env_arguments
    env = make_env("contact_stiffest")
    assert env.spec.id == TWIN and env.unwrapped.contact_model == CONTACT_CORNERS["stiffest"]
    with pytest.raises(ValueError, match="simulator"):
        make_env("contact_stiffest", simulator="bounding")
    assert get_condition("contact_family").as_dict()["family"] is True
    assert get_condition("contact_large_feet").as_dict()["env_kwargs"]["contact_model"]["foot_radius"] == 0.02
    with pytest.raises(TypeError, match="MuJoCo"):
        RandomContactModel(gym.make("hsddp_gym/Bounding-v0"))


def test_the_family_condition_draws_one_model_per_seed():
    env = make_env("contact_family", max_episode_steps=20)
    assert isinstance(env, RandomContactModel) and wrapper_info_keys(env) == {"contact_model"}
    drawn = {}
    for seed in (3, 4, 5, 3):
        obs, info = env.reset(seed=seed)
        model = env.unwrapped.contact_model
        assert info["contact_model"] == model.as_dict() and env.last_contact_model == model
        assert env.unwrapped.sim.contact_model == model and env.unwrapped.sim.model.opt.timestep == model.timestep
        assert env.unwrapped.dt == 0.005 and env.unwrapped.frame_skip == model.frame_skip
        if seed in drawn:
            assert drawn[seed] == model  # same seed, same model
        drawn[seed] = model
        for _ in range(3):
            obs, _, terminated, _, info = env.step(np.zeros(4, dtype=np.float32))
            assert not info["invalid_state"]
    assert len({drawn[3], drawn[4], drawn[5]}) == 3
    # independent of the env's own reset noise and of the episode history: a fresh env draws the same
    other = make_env("contact_family")
    other.reset(seed=4)
    assert other.unwrapped.contact_model == drawn[4]
    # an unseeded reset continues the generator: another model
    env.reset(seed=3)
    env.reset()
    assert env.unwrapped.contact_model != drawn[3]


def test_robustness_script_reports_the_contact_conditions(tmp_path, experiment):
    import json

    experiment("robustness").main(["--out", str(tmp_path), "--policies", "heuristic", "--seed-list", "9000", "9001",
                                   "--conditions", "default", "contact_family", "contact_stiffest",
                                   "--max-steps", "5", "--quiet"])
    data = json.loads((tmp_path / "robustness.json").read_text())
    cells = data["results"]["heuristic"]
    assert "contact_model" not in cells["default"]["runs"][0]  # the suite's rows are unchanged
    runs = cells["contact_family"]["runs"]
    assert all(r["simulator"] == "mujoco" for r in runs) and runs[0]["contact_model"] != runs[1]["contact_model"]
    assert cells["contact_stiffest"]["runs"][0]["contact_model"]["solref"] == [0.002, 1.0]
    table = (tmp_path / "robustness.md").read_text()
    assert "| contact_family | **0/2** |" in table and "| contact falls | 0/4 |" in table


def test_models_outside_the_family_are_accepted():
    """The accepted ranges are wider than the family's: a user can build ``friction=0.3`` or a 30 ms contact."""
    model = ContactModel(friction=0.3, solref=(0.03, 0.3), foot_radius=0.03, timestep=0.0025)
    assert model.friction == 0.3 and model.frame_skip == 2
    env = gym.make(TWIN, contact_model=model)
    env.reset(seed=0)
    assert np.isfinite(env.step(np.zeros(4))[0]).all()
