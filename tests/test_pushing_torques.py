"""The contact-consistent torques of the MPC (hsddp_gym.planners.policies.contact_consistency.PushingTorques): a
stance foot is never asked to pull on the ground or to leave the friction cone, and the torques sent are the nearest
ones that satisfy that."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.planners.policies.contact_consistency import PushingTorques

LIMIT = 18.0
MU = 0.45


def stance_state(feet=(BACK,)) -> np.ndarray:
    """The paper's initial state lowered so that the lower of ``feet`` is on the ground, at rest."""
    x = paper_initial_state().copy()
    x[7:] = 0.0
    dyn = HybridDynamics()
    heights = dyn.robot.foot_heights(x[:7])
    x[1] -= min(heights[f] for f in feet)
    return x


def conditions(p: PushingTorques, x, u, mode):
    """Normal forces minus min_force and the two friction margins of every stance foot (all >= 0 when satisfied)."""
    grf, _ = p.forces(x, u, mode)
    out = []
    for f in Mode(mode).feet:
        t, n = grf[2 * f], grf[2 * f + 1]
        out += [n - p.min_force, MU * n - t, MU * n + t]
    return np.array(out)


def test_forces_are_affine_in_the_torques_and_G_is_their_derivative():
    p = PushingTorques(LIMIT, friction=MU)
    x = stance_state()
    rng = np.random.default_rng(0)
    u = rng.uniform(-LIMIT, LIMIT, 4)
    grf, G = p.forces(x, u, Mode.BACK_STANCE)
    for _ in range(5):
        d = rng.uniform(-5.0, 5.0, 4)
        grf_d, _ = p.forces(x, u + d, Mode.BACK_STANCE)
        np.testing.assert_allclose(grf_d, grf + G @ d, atol=1e-6 * (1 + np.abs(grf).max()))
    # central finite differences of the constrained dynamics' forces
    dyn = HybridDynamics()
    for i in range(4):
        e = np.zeros(4)
        e[i] = 1e-4
        plus, minus = dyn.accelerations(x, u + e, Mode.BACK_STANCE)[1], dyn.accelerations(x, u - e, Mode.BACK_STANCE)[1]
        fd = (plus - minus) / 2e-4
        np.testing.assert_allclose(G[:, i], fd, rtol=1e-5, atol=1e-6)
    assert np.all(grf[[0, 1]] == 0.0)  # the front foot is in the air: no force


def test_a_flight_and_torques_the_contact_can_transmit_are_left_alone():
    p = PushingTorques(LIMIT, friction=MU)
    x = stance_state()
    u = PushingTorques(LIMIT, min_force=30.0, friction=MU)(x, np.zeros(4), Mode.BACK_STANCE)  # a firm stance
    assert np.all(conditions(p, x, u, Mode.BACK_STANCE) >= 0) and p.forces(x, u, Mode.BACK_STANCE)[0][3] > 29.0
    np.testing.assert_array_equal(p(x, u, Mode.BACK_STANCE), u)
    np.testing.assert_array_equal(p(x, np.array([40.0, -40.0, 3.0, 0.0]), Mode.FLIGHT), [LIMIT, -LIMIT, 3.0, 0.0])
    assert p.projections == 0


@pytest.mark.parametrize("mode,feet", [(Mode.BACK_STANCE, (BACK,)), (Mode.FRONT_STANCE, (FRONT,)),
                                       (Mode.DOUBLE_STANCE, (FRONT, BACK))])
def test_torques_that_pull_or_slide_are_projected_to_the_nearest_that_push_inside_the_cone(mode, feet):
    p = PushingTorques(LIMIT, min_force=2.0, friction=MU)
    x = stance_state(feet)
    rng = np.random.default_rng(1)
    projected = 0
    for _ in range(40):
        u0 = rng.uniform(-LIMIT, LIMIT, 4)
        u = p(x, u0, mode)
        assert np.all(np.abs(u) <= LIMIT + 1e-12)
        if np.all(conditions(p, x, u0, mode) >= 0):
            np.testing.assert_array_equal(u, u0)
            continue
        projected += 1
        assert np.all(conditions(p, x, u, mode) >= -1e-6)
        # the nearest: no feasible torque is closer (the projection's variational inequality on random samples)
        for v in rng.uniform(-LIMIT, LIMIT, (400, 4)):
            if np.all(conditions(p, x, v, mode) >= 0):
                assert (u0 - u) @ (v - u) <= 1e-6 * (1 + np.linalg.norm(u0 - u) * np.linalg.norm(v - u))
    assert projected >= 5 and p.projections == projected


def test_arguments_are_validated():
    with pytest.raises(ValueError, match="torque_limit"):
        PushingTorques(0.0)
    with pytest.raises(ValueError, match="min_force"):
        PushingTorques(LIMIT, min_force=-1.0)
    with pytest.raises(ValueError, match="friction"):
        PushingTorques(LIMIT, friction=-0.1)
    with pytest.raises(ValueError, match="iterations"):
        PushingTorques(LIMIT, iterations=0)
    with pytest.raises(TypeError, match="dynamics"):
        PushingTorques(LIMIT, dynamics="pinocchio")
    p = PushingTorques(LIMIT)
    with pytest.raises(ValueError, match="x"):
        p(np.zeros(13), np.zeros(4), Mode.BACK_STANCE)
    with pytest.raises(ValueError, match="u"):
        p(np.zeros(14), np.zeros(3), Mode.BACK_STANCE)
    with pytest.raises(ValueError, match="mode"):
        p(np.zeros(14), np.zeros(4), 7)
    with pytest.raises(ValueError, match="x"):
        p(np.full(14, np.nan), np.zeros(4), Mode.BACK_STANCE)


def test_on_a_slope_the_cone_is_the_surface_normals():
    """With the surface's normals under the feet the forces are split along them: a projection keeps the force inside
    the tilted cone, and a flat-ground normal gives the flat-ground result exactly."""
    x = stance_state()
    slope = 0.3
    n = np.array([-slope, 1.0]) / np.hypot(slope, 1.0)
    normals = np.array([n, n])
    p = PushingTorques(LIMIT, min_force=2.0, friction=MU)
    rng = np.random.default_rng(3)
    tilted = 0
    for _ in range(30):
        u0 = rng.uniform(-LIMIT, LIMIT, 4)
        u = p(x, u0, Mode.BACK_STANCE, normals)
        fx, fz = p.forces(x, u, Mode.BACK_STANCE)[0][2:]
        f_n, f_t = n[0] * fx + n[1] * fz, n[1] * fx - n[0] * fz
        assert f_n >= 2.0 - 1e-6 and abs(f_t) <= MU * f_n + 1e-6
        flat = p(x, u0, Mode.BACK_STANCE)
        np.testing.assert_array_equal(p(x, u0, Mode.BACK_STANCE, np.array([[0.0, 1.0], [0.0, 1.0]])), flat)
        tilted += not np.allclose(u, flat)
    assert tilted > 0
    with pytest.raises(ValueError, match="normals"):
        p(x, np.zeros(4), Mode.BACK_STANCE, np.array([[0.0, 2.0], [0.0, 1.0]]))
