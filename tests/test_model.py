"""The planar Mini Cheetah model: mass properties, sign conventions, kinematics and foot-height derivatives."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from hsddp_gym.core.conventions import BACK, FEET, FOOT_JOINTS, FOOT_SIGN, FRONT, IPITCH, IX, IZ, NQ, NX, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import DEFAULT_PARAMS, RobotParams
from hsddp_gym.core.references import end_of_mode_reference, paper_initial_state

MM = 1e-3

# (mode, touchdown foot, foot that must be on the ground) -- original_code_facts §3.4
REFERENCES = [
    (Mode.BACK_STANCE, None, BACK),
    (Mode.FLIGHT, FRONT, FRONT),
    (Mode.FRONT_STANCE, None, FRONT),
    (Mode.FLIGHT, BACK, BACK),
]


def standing_q(z_offset: float = 0.0, **joints) -> np.ndarray:
    """Body level, legs straight down, trunk at ``leg_length + z_offset`` (feet on the ground when 0)."""
    q = np.zeros(NQ)
    q[IZ] = DEFAULT_PARAMS.leg_length + z_offset
    names = {"pitch": IPITCH, "hip_front": 3, "knee_front": 4, "hip_back": 5, "knee_back": 6}
    for name, value in joints.items():
        q[names[name]] = value
    return q


def closed_form_points(q: np.ndarray, foot: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hip, knee and foot (x, z) from the authors' planar kinematics (original_code_facts §1.1)."""
    x, z, th = q[IX], q[IZ], q[IPITCH]
    s = FOOT_SIGN[foot]
    th_h, th_k = q[FOOT_JOINTS[foot][0]], q[FOOT_JOINTS[foot][1]]
    hip = np.array([x + s * 0.19 * math.cos(th), z - s * 0.19 * math.sin(th)])
    knee = hip + 0.209 * np.array([-math.sin(th + th_h), -math.cos(th + th_h)])
    foot_pt = knee + 0.195 * np.array([-math.sin(th + th_h + th_k), -math.cos(th + th_h + th_k)])
    return hip, knee, foot_pt


# ----------------------------------------------------------------------------------------- mass properties
def test_total_mass_is_8_252_kg(robot):
    assert robot.total_mass == pytest.approx(8.252, abs=1e-12)
    assert robot.params.total_mass == pytest.approx(8.252, abs=1e-12)
    assert robot.model.nq == NQ and robot.model.nv == NQ


def test_mass_matrix_and_com_match_the_parameter_table(robot):
    """At the zero configuration the pitch inertia about the trunk origin and the CoM height follow from
    the per-link numbers of original_code_facts §1.2 (mass, CoM offset, I_yy, link lengths)."""
    p = robot.params
    q = np.zeros(NQ)
    data = robot.new_data()
    M = pin.crba(robot.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    thigh_com = (p.hip_offset, p.thigh.com_z)
    shank_com = (p.hip_offset, -p.thigh.length + p.shank.com_z)
    i_pitch = (p.trunk.inertia_yy
               + 2 * (p.thigh.inertia_yy + p.thigh.mass * (thigh_com[0] ** 2 + thigh_com[1] ** 2))
               + 2 * (p.shank.inertia_yy + p.shank.mass * (shank_com[0] ** 2 + shank_com[1] ** 2)))
    assert M[IPITCH, IPITCH] == pytest.approx(i_pitch, rel=1e-12)
    assert M[IX, IX] == pytest.approx(8.252, rel=1e-12)
    assert M[IZ, IZ] == pytest.approx(8.252, rel=1e-12)
    com = pin.centerOfMass(robot.model, data, q)
    expected_z = 2 * (p.thigh.mass * thigh_com[1] + p.shank.mass * shank_com[1]) / p.total_mass
    assert com[0] == pytest.approx(0.0, abs=1e-14)
    assert com[2] == pytest.approx(expected_z, rel=1e-12)
    assert robot.model.gravity.linear[2] == pytest.approx(-9.81)


# ----------------------------------------------------------------------------------------- paper states
def test_paper_initial_state_back_foot_on_ground(robot):
    x0 = paper_initial_state()
    heights = robot.foot_heights(x0[:NQ])
    assert abs(heights[BACK]) < MM
    assert heights[FRONT] == pytest.approx(0.142, abs=MM)  # original_code_facts §3.3
    # a consistent mid-stance state: the back foot barely moves (facts: (-0.0014, +0.0017) m/s)
    assert np.all(np.abs(robot.foot_velocities(x0)[BACK]) < 5e-3)


@pytest.mark.parametrize(("mode", "touchdown", "foot"), REFERENCES,
                         ids=["BS-end", "FL-before-front-TD", "FS-end", "FL-before-back-TD"])
def test_reference_posture_puts_its_foot_on_the_ground(robot, mode, touchdown, foot):
    x_ref = end_of_mode_reference(mode, touchdown)
    heights = robot.foot_heights(x_ref[:NQ])
    assert abs(heights[foot]) < MM
    assert heights[1 - foot] > 0.05  # the other foot is clearly up (facts: 0.07-0.10 m)


# ----------------------------------------------------------------------------------------- signs
def test_zero_configuration_legs_straight_down(robot):
    q = standing_q()
    feet = robot.foot_positions(q)
    np.testing.assert_allclose(feet, [[0.19, 0.0], [-0.19, 0.0]], atol=1e-14)
    np.testing.assert_allclose(robot.hip_positions(q), [[0.19, 0.404], [-0.19, 0.404]], atol=1e-14)


def test_positive_pitch_lowers_the_front_hip(robot):
    level = robot.hip_positions(standing_q())
    nose_down = robot.hip_positions(standing_q(pitch=0.1))
    assert nose_down[FRONT, 1] < level[FRONT, 1]
    assert nose_down[BACK, 1] > level[BACK, 1]
    assert robot.foot_heights(standing_q(pitch=0.1))[FRONT] < robot.foot_heights(standing_q(pitch=0.1))[BACK]


@pytest.mark.parametrize("foot", FEET, ids=["front", "back"])
@pytest.mark.parametrize("joint", ["hip", "knee"])
def test_positive_joint_angle_moves_the_foot_toward_minus_x(robot, foot, joint):
    name = f"{joint}_{'front' if foot == FRONT else 'back'}"
    x_rest = robot.foot_positions(standing_q())[foot, 0]
    x_moved = robot.foot_positions(standing_q(**{name: 0.2}))[foot, 0]
    assert x_moved < x_rest - 0.01
    # the other foot does not move
    other = 1 - foot
    np.testing.assert_allclose(robot.foot_positions(standing_q(**{name: 0.2}))[other],
                               robot.foot_positions(standing_q())[other], atol=1e-15)


def test_forward_kinematics_matches_the_authors_closed_form(robot, rng):
    for _ in range(20):
        q = rng.uniform(-1.5, 1.5, NQ)
        points = robot.link_points(q)
        feet = robot.foot_positions(q)
        hips = robot.hip_positions(q)
        for foot in FEET:
            hip, knee, foot_pt = closed_form_points(q, foot)
            np.testing.assert_allclose(points[foot, 0], hip, atol=1e-14)
            np.testing.assert_allclose(points[foot, 1], knee, atol=1e-14)
            np.testing.assert_allclose(points[foot, 2], foot_pt, atol=1e-14)
            np.testing.assert_allclose(points[foot, 3], q[[IX, IZ]], atol=1e-14)
            np.testing.assert_allclose(feet[foot], foot_pt, atol=1e-14)
            np.testing.assert_allclose(hips[foot], hip, atol=1e-14)
        np.testing.assert_array_equal(robot.foot_heights(q), feet[:, 1])


# ----------------------------------------------------------------------------------------- derivatives
@pytest.mark.parametrize("foot", FEET, ids=["front", "back"])
def test_foot_jacobian_and_velocity(robot, rng, tools, foot):
    for _ in range(5):
        x = tools.random_state(rng)
        q, v = x[:NQ], x[NQ:]
        J = robot.foot_jacobian(q, foot)
        assert J.shape == (2, NQ)
        J_fd = tools.fd_jacobian(lambda qq: robot.foot_positions(qq)[foot], q)
        assert tools.max_rel_err(J, J_fd) <= tools.FD_TOL
        np.testing.assert_allclose(robot.foot_velocities(x)[foot], J @ v, atol=1e-12)


@pytest.mark.parametrize("foot", FEET, ids=["front", "back"])
def test_foot_height_derivatives_match_finite_differences(robot, rng, tools, foot):
    for _ in range(8):
        x = tools.random_state(rng, q_scale=0.3)
        g, g_x, g_xx = robot.foot_height_derivatives(x, foot)
        assert g_x.shape == (NX,) and g_xx.shape == (NX, NX)
        assert g == pytest.approx(robot.foot_heights(x[:NQ])[foot], abs=1e-15)
        grad_fd = tools.fd_jacobian(lambda xx: robot.foot_heights(xx[:NQ])[foot], x)[0]
        hess_fd = tools.fd_jacobian(lambda xx: robot.foot_height_derivatives(xx, foot)[1], x)
        assert tools.max_rel_err(g_x, grad_fd) <= tools.FD_TOL
        assert tools.max_rel_err(g_xx, hess_fd) <= tools.FD_TOL
        np.testing.assert_array_equal(g_xx, g_xx.T)
        assert not np.any(g_x[NQ:]) and not np.any(g_xx[NQ:]) and not np.any(g_xx[:, NQ:])
        # the configuration alone gives the same answer as the full state
        g_q, g_x_q, g_xx_q = robot.foot_height_derivatives(x[:NQ], foot)
        assert g_q == g and np.array_equal(g_x_q, g_x) and np.array_equal(g_xx_q, g_xx)


def test_models_with_other_parameters_are_independent():
    heavy = CheetahModel(RobotParams(gravity=3.7))
    assert heavy.model.gravity.linear[2] == pytest.approx(-3.7)
    assert CheetahModel().model.gravity.linear[2] == pytest.approx(-9.81)
