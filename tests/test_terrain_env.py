"""Terrain in Bounding-v0's physics (hsddp_gym.core.terrain, the compiled contact kernel, envs/bounding.py), its
rendering, the MuJoCo twin built from the same profile and the registered hsddp_gym/Terrain-v0: argument checks, the
simulated surface, a flat terrain equal to no terrain, no penetration on steps, slopes and gaps under bang-bang
torques (with the energy balance), the friction cone in the slope's frame, seeded random profiles, the fall rule
measured from the terrain, and the env checkers."""

from __future__ import annotations

import zlib

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym
from hsddp_gym.core.compiled_contact import CompiledContactSimulator
from hsddp_gym.core.contact_lcp import SLIDE_NEG, SLIDE_POS, STICK
from hsddp_gym.core.conventions import BACK, FEET, FRONT, IX, IZ, NQ, grf_slice
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.terrain import RISER_WIDTH, Terrain
from hsddp_gym.envs.bounding import BoundingEnv

TOL_J = 1e-9  # the energy balance per 1 ms step [J] (as tests/test_env_physics.py)
TERRAINS = {
    "step_up": Terrain.step(0.05, 0.04),
    "step_down": Terrain.step(0.05, -0.04),
    "slope_up": Terrain.ramp(-0.4, 3.0, 0.3),
    "slope_down": Terrain.ramp(-0.4, 3.0, -0.3),
    "gap": Terrain.gap(0.15, 0.35, depth=0.2),
    "random": Terrain.sample(np.random.default_rng(5), "mixed", start=-0.3, max_step=0.04, max_slope=0.3,
                             segment_length=(0.1, 0.3)),
}


@pytest.fixture(scope="module")
def robot():
    return CheetahModel()


def on_terrain(robot, terrain, x, clearance=0.001) -> np.ndarray:
    """``x`` (14,) moved vertically so that its lowest foot is ``clearance`` [m] above ``terrain``'s surface."""
    x = np.array(x, dtype=np.float64)
    feet = robot.foot_positions(x[:NQ])
    x[IZ] += clearance - float(np.min(feet[:, 1] - terrain.surface_heights(feet[:, 0])))
    return x


def bound_state(robot, rng) -> np.ndarray:
    """A random leg posture and velocity (joint rates up to 30 rad/s, trunk up to 2 m/s) near x = 0."""
    q = np.array([rng.uniform(-0.1, 0.1), 0.0, rng.uniform(-0.3, 0.3), rng.uniform(-1, 1), rng.uniform(-2, -0.5),
                  rng.uniform(-1, 1), rng.uniform(-2, -0.5)])
    v = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-5, 5), rng.uniform(-30, 30, 4)]
    return np.r_[q, v]


# ----------------------------------------------------------------------------------------------- the profile
@pytest.mark.parametrize("make, name", [
    (lambda: Terrain((0.5,), (0.0, 0.1), (False, False), (0.0,)), "slopes"),
    (lambda: Terrain((0.5, 0.8), (0.0, -1.0, 0.0), (False, True, False), (0.0, 0.2, 0.0)), "slopes"),
    (lambda: Terrain((0.5,), (0.0, 0.1), (False, False), (0.0, float("nan"))), "slopes"),
    (lambda: Terrain.ramp(1.0, 0.5, 0.1), "x1"),
    (lambda: Terrain.ramp(0.0, 1.0, "steep"), "slope"),
    (lambda: Terrain((0.5, 0.5005), (0.0, 0.1, 0.0), (False,) * 3).surface_vertices(), "edges"),
    (lambda: Terrain.sample(np.random.default_rng(0), "stairs"), "kind"),
    (lambda: Terrain.sample(0, "steps"), "rng"),
    (lambda: Terrain.sample(np.random.default_rng(0), segment_length=(0.5, 0.2)), "segment_length"),
    (lambda: Terrain.from_dict({"edges": [0.5]}), "terrain"),
    (lambda: BoundingEnv(terrain="bumpy"), "terrain"),
    (lambda: BoundingEnv(terrain=3), "terrain"),
    (lambda: BoundingEnv(terrain=Terrain.step(0.5, 0.1), energy_consistent=False), "terrain"),
])
def test_bad_terrain_arguments_are_refused_by_name(make, name):
    with pytest.raises((ValueError, TypeError), match=name):
        make()


def test_the_simulated_surface_follows_the_profile_with_steep_risers():
    t = Terrain((0.5, 1.0, 2.0), (0.0, 0.05, 0.05, 0.0), (False,) * 4, (0.0, 0.0, 0.1, 0.0))
    xs = np.array([-3.0, 0.2, 0.7, 1.5, 1.99, 2.5, 40.0])
    np.testing.assert_allclose(t.surface_heights(xs), t.heights(xs), atol=1e-15)
    np.testing.assert_allclose(t.heights([1.5]), [0.05 + 0.1 * 0.5])
    vx, vz = t.surface_vertices()
    assert np.all(np.diff(vx) > 0)
    # a jump of h is a riser over [edge - RISER_WIDTH, edge]; the slope's start at x = 1 is continuous (no riser)
    assert 0.5 - RISER_WIDTH in vx and 2.0 - RISER_WIDTH in vx and 1.0 - RISER_WIDTH not in vx
    assert t.surface_heights(0.5 - RISER_WIDTH / 2) == pytest.approx(0.025)
    n = t.surface_normals([0.2, 1.5, 0.5 - RISER_WIDTH / 2])
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)
    np.testing.assert_allclose(n[0], [0.0, 1.0])
    np.testing.assert_allclose(n[1], np.array([-0.1, 1.0]) / np.hypot(0.1, 1.0))
    assert n[2, 0] < -0.99  # the riser's normal points back, against a foot that runs into the step
    assert Terrain.from_dict(t.to_dict()) == t
    assert Terrain.flat().is_flat and not Terrain.ramp(0.0, 1.0, 0.1).is_flat


def test_a_gap_is_a_deep_drop_bridged_for_the_trunk():
    g = Terrain.gap(0.4, 0.7, depth=0.5)
    assert g.surface_heights(0.55) == -0.5 and g.surface_heights(0.3) == 0.0
    assert g.support_heights(0.55) == 0.0  # the trunk over the gap is measured from its near edge's level
    s = Terrain((0.0, 0.4, 0.7), (0.0, 0.1, -1.0, 0.1), (False, False, True, False))
    assert s.support_heights(0.55) == pytest.approx(0.1)


@pytest.mark.parametrize("kind", ["steps", "slopes", "mixed"])
def test_the_scalar_ground_queries_equal_the_vectorized_ones(kind):
    rng = np.random.default_rng(11)
    terrains = [Terrain.sample(rng, kind) for _ in range(5)]
    terrains += [Terrain.gap(0.4, 0.7), Terrain((-0.2, 0.3, 0.9), (0.0, -0.4, 0.1, 0.2), (True, True, False, False),
                                               (0.0, 0.0, 0.3, -0.1))]
    for t in terrains:
        xs = np.concatenate([rng.uniform(-1.0, 4.0, 200), np.array(t.edges)])  # the edges themselves included
        np.testing.assert_array_equal([t.support_height(float(x)) for x in xs], t.support_heights(xs))
        np.testing.assert_array_equal([t.gap_at(float(x)) for x in xs], t.over_gap(xs))
    with pytest.raises(ValueError, match="x must be finite"):
        Terrain.gap(0.4, 0.7).support_height(float("nan"))
    with pytest.raises(ValueError, match="x must be finite"):
        Terrain.gap(0.4, 0.7).gap_at(float("inf"))


# ----------------------------------------------------------------------------------------------- seeded profiles
@pytest.mark.parametrize("kind", ["steps", "slopes", "mixed"])
def test_random_terrain_is_deterministic_per_seed_and_inside_its_distribution(kind):
    a = Terrain.sample(np.random.default_rng(7), kind)
    assert a == Terrain.sample(np.random.default_rng(7), kind)
    assert a != Terrain.sample(np.random.default_rng(8), kind)
    assert a.heights(0.59) == 0.0 and a.edges[0] == 0.6 and a.edges[-1] >= 8.6
    lengths = np.diff(a.edges)
    assert np.all((lengths >= 0.3) & (lengths <= 0.8))
    assert max(map(abs, a.slopes)) <= 0.1 and max(map(abs, a.levels)) <= 0.15
    # segment i (1..k-1) ends at edges[i]; the last one (x >= edges[-1]) is level, continuous with the one before
    ends = np.array([a.levels[i] + a.slopes[i] * (a.edges[i] - a.edges[i - 1]) for i in range(1, len(a.edges))])
    assert a.levels[-1] == pytest.approx(ends[-1], abs=1e-12) and a.slopes[-1] == 0.0
    jumps = np.r_[a.levels[1], np.array(a.levels[2:-1]) - ends[:-1]]
    assert np.all(np.abs(jumps) <= 0.03 + 1e-12)
    if kind == "steps":
        assert not any(a.slopes) and np.count_nonzero(jumps) == len(jumps)
    if kind == "slopes":
        assert np.allclose(jumps, 0.0, atol=1e-12) and any(a.slopes)


def test_terrain_v0_draws_a_profile_per_episode_from_the_reset_seed():
    env = gym.make("hsddp_gym/Terrain-v0")
    obs1, _ = env.reset(seed=9800)
    t1 = env.unwrapped.terrain
    traj1 = [env.step(np.full(4, 0.3 * (-1) ** k))[0] for k in range(30)]
    obs2, _ = env.reset(seed=9800)
    assert env.unwrapped.terrain == t1 and not t1.is_flat
    traj2 = [env.step(np.full(4, 0.3 * (-1) ** k))[0] for k in range(30)]
    assert np.array_equal(obs1, obs2) and np.array_equal(np.array(traj1), np.array(traj2))
    env.reset()  # no seed: the next profile of the same generator
    assert env.unwrapped.terrain != t1
    env.reset(seed=9801)
    assert env.unwrapped.terrain != t1


# ----------------------------------------------------------------------------------------------- flat = no terrain
def test_a_flat_terrain_is_the_flat_ground_bit_for_bit():
    runs = []
    for terrain in (None, Terrain.flat(), {"edges": [], "levels": [0.0], "gaps": [False]}):
        env = BoundingEnv(terrain=terrain)
        rng = np.random.default_rng(3)
        obs, info = env.reset(seed=3)
        out = [obs]
        for _ in range(150):
            obs, r, term, _, info = env.step(rng.choice([-1.0, 1.0], 4))
            out.append(np.r_[obs, r, info["qpos"], info["qvel"], info["grf"], info["foot_heights"]])
            if term:
                break
        runs.append(np.array(out, dtype=object))
    assert all(np.array_equal(np.vstack(runs[0][1:]), np.vstack(r[1:])) for r in runs[1:])


def test_a_raised_terrain_is_the_same_profile_shifted_everywhere():
    base = Terrain((0.5, 1.0, 1.5), (0.0, 0.05, -0.02, 0.1), (False, False, True, False), (0.0, 0.1, 0.0, -0.05))
    xs = np.linspace(-1.0, 3.0, 401)
    for dz in (-0.03, 0.0, 0.02):
        raised = base.raised(dz)
        assert raised.edges == base.edges and raised.gaps == base.gaps and raised.slopes == base.slopes
        assert np.allclose(raised.heights(xs), base.heights(xs) + dz, atol=1e-15)
    assert not Terrain.flat().raised(-0.01).is_flat and Terrain.flat().raised(0.0).is_flat
    assert Terrain.flat().uniform_height == 0.0 and Terrain.flat().raised(-0.01).uniform_height == -0.01
    assert Terrain((1.0,), (0.02, 0.02), (False, False)).uniform_height == 0.02  # an edge between two equal levels
    for uneven in (base, Terrain.step(1.0, 0.02), Terrain.gap(1.0, 1.2), Terrain((), (0.0,), (False,), (0.1,))):
        assert uneven.uniform_height is None, uneven
    with pytest.raises(ValueError, match="dz"):
        base.raised(float("nan"))


def test_a_terrain_far_away_changes_nothing_near_the_robot(robot):
    """The kernel's terrain code path (closest points, rotated Jacobian rows, projection rows along a direction) on a
    level piece gives the flat ground's steps to float precision: the same contact states, states within 1e-7
    relative."""
    rng = np.random.default_rng(11)
    for _ in range(4):
        x0 = on_terrain(robot, Terrain.flat(), bound_state(robot, rng))
        flat = CompiledContactSimulator(robot)
        far = CompiledContactSimulator(robot, terrain=Terrain.step(50.0, 0.1))
        for sim in (flat, far):
            sim.set_state(x0)
        for t in range(200):
            u = np.full(4, 20.0 if (t // 5) % 2 == 0 else -20.0)
            flat.run(u, 1)
            far.run(u, 1)
            assert list(flat.states) == list(far.states)
            scale = 1.0 + np.abs(flat.x).max()  # float error, grown over 200 steps (6e-9 relative at most, seen)
            assert np.abs(far.x - flat.x).max() <= 1e-7 * scale
            assert np.abs(far.impulse - flat.impulse).max() <= 1e-7 * (1.0 + np.abs(flat.impulse).max())


# ----------------------------------------------------------------------------------------------- no penetration
@pytest.mark.parametrize("name", sorted(TERRAINS))
def test_no_penetration_under_bang_bang_torques_in_every_physics_step(robot, name):
    """Every 1 ms step, 12 random start states dropped onto the terrain, 0.4 s of bang-bang joint torques (the torque
    limit, sign flipped every 5 ms): no foot ends a step more than 1 um below the surface under it (also checked
    along the surface's normal), the energy balance holds in every step, and the feet do touch the terrain."""
    deepest, worst_excess, contacts = _bang_bang(robot, TERRAINS[name], zlib.crc32(name.encode()))
    assert deepest <= 1e-6
    assert worst_excess <= TOL_J
    assert contacts > 100


def test_no_penetration_where_a_foot_slides_into_a_small_step(robot):
    """Random terrain, the rng seed whose fifth start state slides its front foot past the 4.4 mm step up at
    x = 1.056 m within one step (it used to end that step 4.4 mm inside the step)."""
    deepest, worst_excess, _ = _bang_bang(robot, TERRAINS["random"], 110, episodes=5)
    assert deepest <= 1e-6
    assert worst_excess <= TOL_J


@pytest.mark.parametrize("speed, passes", [(3.0, False), (8.0, True)])
def test_a_foot_sliding_into_a_low_riser_ends_on_the_surface(robot, speed, passes):
    """A back foot in contact (the paper's initial posture) 2 mm before a 3 mm step up, the robot moving forward at
    ``speed`` [m/s]. At 3 m/s the step's travel ends at the riser, which stops the foot. At 8 m/s one 1 ms step
    carries it 6 mm past the edge: its closest point is on the upper level, parallel to the lower level's contact
    row, and the projection puts it on the upper level (it used to stay on the lower one, 3 mm inside the step)."""
    x = paper_initial_state(robot.params)
    x[NQ:] = 0.0
    x[NQ + IX] = speed
    x = on_terrain(robot, Terrain.flat(), x, clearance=0.0)
    terrain = Terrain.step(float(robot.foot_positions(x[:NQ])[BACK, 0]) + 0.002, 0.003)
    sim = CompiledContactSimulator(robot, terrain=terrain, friction=0.0)
    sim.set_state(x)
    for _ in range(3):
        sim.run(np.zeros(4), 1)
        p = sim.foot_positions()[BACK]
        assert p[1] - terrain.surface_heights(p[0]) >= -1e-6
        assert (p[0] > terrain.edges[0]) == passes
        assert sim.foot_heights()[BACK] == pytest.approx(0.0, abs=1e-6)  # on the surface, not above it


def _bang_bang(robot, terrain, seed: int, episodes: int = 12):
    """``(deepest penetration [m], worst energy excess per step [J], contact steps)`` of ``episodes`` random start
    states dropped onto ``terrain``, each 0.4 s of bang-bang torques (1 ms steps; random states and signs from
    ``seed``)."""
    rng = np.random.default_rng(seed)
    limit = BoundingEnv().torque_limit
    deepest, worst_excess, contacts = 0.0, -np.inf, 0
    for _ in range(episodes):
        sim = CompiledContactSimulator(robot, motor_speed_limits=(36.0, 50.0), terrain=terrain)
        sim.set_state(on_terrain(robot, terrain, bound_state(robot, rng)))
        e = sim.energy()
        for t in range(400):
            q0 = sim.q.copy()
            sim.run(np.full(4, limit if (t // 5) % 2 == 0 else -limit) * rng.choice([-1, 1], 4), 1)
            e1 = sim.energy()
            worst_excess = max(worst_excess, e1 - e - float(sim._tau[3:] @ (sim.q[3:] - q0[3:])))
            e = e1
            feet = sim.foot_positions()
            vertical = feet[:, 1] - terrain.surface_heights(feet[:, 0])
            normal = vertical * terrain.surface_normals(feet[:, 0])[:, 1]
            np.testing.assert_allclose(sim.foot_heights(), vertical, atol=1e-12)
            deepest = max(deepest, -float(vertical.min()), -float(normal.min()))
            contacts += int(sim.contact.sum())
        assert np.all(np.isfinite(sim.x))
    return deepest, worst_excess, contacts


@pytest.mark.parametrize("name", ["step_up", "slope_up", "random"])
def test_the_env_keeps_its_feet_out_of_the_terrain(name):
    """Through the env (info['foot_heights'] measured from the terrain): bang-bang actions from noisy resets."""
    env = BoundingEnv(terrain=TERRAINS[name], terminate_when_unhealthy=False)
    deepest = 0.0
    for seed in range(5):
        _, info = env.reset(seed=seed)
        assert info["foot_heights"].min() >= -1e-12
        for t in range(150):
            _, _, _, _, info = env.step(np.full(4, 1.0 if t % 2 == 0 else -1.0))
            deepest = max(deepest, -float(np.min(info["foot_heights"])))
    assert deepest <= 1e-6


def test_a_foot_running_into_a_step_is_stopped_by_its_riser(robot):
    """A robot moving forward at 1.5 m/s with its front foot 2 cm below the top of a step 5 mm ahead: the riser
    stops the foot (it never ends up inside the step), pushing it back."""
    x = paper_initial_state(robot.params)
    x[NQ:] = 0.0
    x[NQ + IX] = 1.5
    feet = robot.foot_positions(x[:NQ])
    terrain = Terrain.step(float(feet[FRONT, 0]) + 0.005, float(feet[FRONT, 1]) + 0.02)
    sim = CompiledContactSimulator(robot, terrain=terrain)
    sim.set_state(x)
    hit = False
    for _ in range(40):
        sim.run(np.zeros(4), 1)
        p = sim.foot_positions()[FRONT]
        inside = p[0] > terrain.edges[0] - RISER_WIDTH and p[1] < terrain.levels[1] - 1e-6
        assert not inside or p[1] - terrain.surface_heights(p[0]) >= -1e-6
        hit = hit or (sim.contact[FRONT] and sim.impulse[grf_slice(FRONT)][0] < 0.0)
    assert hit  # the riser pushed the front foot back (-x)


# ----------------------------------------------------------------------------------------------- the friction cone
@pytest.mark.parametrize("slope", [0.3, -0.5])
def test_the_friction_cone_is_in_the_slope_frame(robot, slope):
    """On a slope, every contact force (the ground's on the foot) lies in the cone around the surface normal
    ``n``: ``|f . t| <= mu f . n``; without friction it is along ``n`` exactly. Both would fail in the world frame
    (``|f_x| <= mu f_z`` / ``f_x = 0``)."""
    terrain = Terrain.ramp(-3.0, 3.0, slope)
    n = np.array([-slope, 1.0]) / np.hypot(slope, 1.0)
    t = np.array([n[1], -n[0]])
    rng = np.random.default_rng(21)
    for mu in (0.0, 0.6):
        along, across, states = [], [], set()
        for _ in range(6):
            sim = CompiledContactSimulator(robot, friction=mu, terrain=terrain)
            sim.set_state(on_terrain(robot, terrain, bound_state(robot, rng), clearance=0.0))
            for _ in range(200):
                sim.run(rng.uniform(-10, 10, 4), 1)
                for foot in FEET:
                    if sim.contact[foot]:
                        f = sim.impulse[grf_slice(foot)] / sim.dt
                        along.append(f @ n)
                        across.append(f @ t)
                        states.add(int(sim.states[foot]))
        along, across = np.array(along), np.array(across)
        assert len(along) > 50 and np.all(along > 0.0)
        assert np.all(np.abs(across) <= mu * along + 1e-9 * (1.0 + along))
        if mu == 0.0:
            assert states <= {SLIDE_POS, SLIDE_NEG, STICK}
            assert np.max(np.abs(across)) <= 1e-9 * np.max(along)
            # the same forces in the world frame push along x, which a world-frame cone without friction forbids
            assert np.max(np.abs(along * n[0])) > 1.0
        else:
            assert np.max(np.abs(across)) > 1.0  # friction acts along the slope


# ----------------------------------------------------------------------------------------------- the fall rule
def test_the_healthy_height_is_measured_from_the_terrain_under_the_trunk():
    raised = BoundingEnv(terrain=Terrain.step(-5.0, 0.3))
    _, info = raised.reset(seed=0)
    assert info["qpos"][IZ] > 0.5  # above the flat ground's healthy range ...
    assert raised.unwrapped.is_healthy and info["ground_height"] == pytest.approx(0.3)  # ... but not the terrain's
    assert min(info["foot_heights"]) == pytest.approx(0.0, abs=1e-3)
    # over a gap: nothing to stand on; the trunk falls into it and the episode ends (measured from the near edge)
    gap = BoundingEnv(terrain=Terrain.gap(-2.0, 3.0, depth=1.0))
    _, info = gap.reset(seed=0)
    assert min(info["foot_heights"]) > 0.9 and info["ground_height"] == 0.0
    for _ in range(200):
        _, _, terminated, _, info = gap.step(np.zeros(4))
        if terminated:
            break
    assert terminated and info["qpos"][IZ] < 0.12 and not info["contact"].any()


# ----------------------------------------------------------------------------------------------- rendering
def test_rendering_draws_the_terrain():
    pytest.importorskip("PIL")
    env = BoundingEnv(render_mode="rgb_array", terrain=Terrain.step(0.3, 0.08))
    env.reset(seed=0)
    frame = env.render()
    flat = BoundingEnv(render_mode="rgb_array")
    flat.reset(seed=0)
    base = flat.render()
    assert frame.shape == base.shape
    h, w, _ = frame.shape
    # right of the step, between the flat ground line and the step's top: the ground's fill colour, not the sky
    col = int(w * 0.95)
    region_t, region_f = frame[int(0.8 * h) - 20:int(0.8 * h) - 5, col], base[int(0.8 * h) - 20:int(0.8 * h) - 5, col]
    assert np.any(region_t != region_f)
    assert np.all(region_t == np.array([225, 220, 205], dtype=np.uint8))


# ----------------------------------------------------------------------------------------------- the MuJoCo twin
def test_the_mujoco_twin_is_built_from_the_same_profile():
    mujoco = pytest.importorskip("mujoco")
    from hsddp_gym.envs.mujoco_twin import FOOT_RADIUS, TERRAIN_BOX_THICKNESS, MuJoCoBoundingEnv

    terrain = Terrain((0.3, 1.0), (0.0, 0.05, 0.05), (False,) * 3, (0.0, 0.0, 0.1))
    env = MuJoCoBoundingEnv(terrain=terrain)
    sim = env.unwrapped.sim
    xs, zs = terrain.surface_vertices()
    assert sim.xml.count('name="terrain_') == len(xs) - 1 and 'name="floor"' not in sim.xml
    mujoco.mj_forward(sim.model, sim.data)
    for i in range(len(xs) - 1):
        gid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, f"terrain_{i}")
        rot = sim.data.geom_xmat[gid].reshape(3, 3)
        top = sim.data.geom_xpos[gid] + rot[:, 2] * (0.5 * TERRAIN_BOX_THICKNESS + FOOT_RADIUS)
        mid = 0.5 * (np.array([xs[i], zs[i]]) + np.array([xs[i + 1], zs[i + 1]]))
        np.testing.assert_allclose(top[[0, 2]], mid, atol=1e-9)  # the top face (+ the foot radius) on the piece
        np.testing.assert_allclose(rot[[0, 2], 2], terrain.surface_normals(mid[0] + 1e-9), atol=1e-9)
    # a robot dropped onto the step lands on it (the twin's soft contacts sink millimetres), not at z = 0
    x = paper_initial_state()
    x[0] = 0.6
    x = on_terrain(env.unwrapped.robot, terrain, x, clearance=0.02)
    x[NQ:] = 0.0
    env.reset(seed=0, options={"state": x})
    touching = []
    for _ in range(40):
        _, _, _, _, info = env.step(np.zeros(4))
        for foot in FEET:
            if info["contact"][foot]:
                touching.append((info["foot_heights"][foot], env.unwrapped.sim.foot_positions()[foot, 1]))
    touching = np.array(touching)
    assert len(touching) >= 3
    assert np.all(np.abs(touching[:, 0]) <= 5e-3) and np.all(touching[:, 1] > 0.045)  # on the step, 5 cm up


# ----------------------------------------------------------------------------------------------- registration
def test_terrain_v0_passes_the_env_checkers_and_sync_vectorization():
    assert hsddp_gym.TERRAIN_ENV_ID in gym.registry
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make("hsddp_gym/Terrain-v0").unwrapped, skip_render_check=True)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(gym.make("hsddp_gym/Terrain-v0").unwrapped)
    envs = gym.make_vec("hsddp_gym/Terrain-v0", num_envs=2, vectorization_mode="sync")
    obs, info = envs.reset(seed=[1, 2])
    assert obs.shape == (2, 17) and "ground_height" in info
    terrains = [e.unwrapped.terrain for e in envs.envs]
    assert terrains[0] != terrains[1]
    for _ in range(10):
        obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    assert np.all(np.isfinite(obs)) and reward.shape == (2,)
    envs.close()


def test_the_compiled_vector_env_refuses_a_terrain():
    with pytest.raises(ValueError, match="terrain"):
        gym.make_vec("hsddp_gym/Bounding-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     terrain=Terrain.step(0.5, 0.03))
