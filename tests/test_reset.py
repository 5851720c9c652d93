"""Reset maps (paper eqs. 12-13): impact physics, lift-off, restitution and the Jacobian P_x."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hsddp_gym.core.conventions import NQ, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.references import paper_initial_state

MODES = tuple(Mode)
CONTACT_MODES = (Mode.FRONT_STANCE, Mode.BACK_STANCE, Mode.DOUBLE_STANCE)
SINGLE_CONTACT = (Mode.FRONT_STANCE, Mode.BACK_STANCE)
RESTITUTIONS = (0.0, 0.5)

_ROBOT = CheetahModel()
_DYN = HybridDynamics(_ROBOT)  # for hypothesis tests (reset_map itself keeps no state between calls)

# Regression note: Pinocchio 4.1.0's computeImpulseDynamicsDerivatives writes only the contact chain's columns
# of data.dvc_dq and then subtracts from all of them, so P_x once drifted from call to call on one Data;
# HybridDynamics._reset_jacobian zeroes dvc_dq first (the *_repeated_calls / *_call_history tests below).

# impulseDynamics runs with a 1e-12 proximal regularization (dynamics._proximal): the post-impact contact
# velocity is ~1e-11 off zero (max 8.7e-12 over 3000 random states and the three contact modes), so the impact
# physics is checked to 1e-9.
IMPACT_TOL = 1e-9


def block_rel_err(value: np.ndarray, reference: np.ndarray) -> float:
    """``max |value - reference| / max |reference|`` (0-scale references must match exactly)."""
    scale = float(np.max(np.abs(reference)))
    err = float(np.max(np.abs(np.asarray(value) - np.asarray(reference))))
    return err if scale == 0.0 else err / scale


def _sample(seed: int, q_scale: float = 0.05, v_scale: float = 0.5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = paper_initial_state()
    x[:NQ] += rng.normal(0.0, q_scale, NQ)
    x[NQ:] += rng.normal(0.0, v_scale, NX - NQ)
    return x


def _kinetic_energy(robot: CheetahModel, x: np.ndarray) -> float:
    M = pin.crba(robot.model, robot.new_data(), x[:NQ])
    M = np.triu(M) + np.triu(M, 1).T
    v = x[NQ:]
    return 0.5 * float(v @ M @ v)


# ----------------------------------------------------------------------------------------- lift-off
@pytest.mark.parametrize("e", RESTITUTIONS)
def test_lift_off_is_the_identity(dynamics, rng, tools, e):
    for _ in range(3):
        x = tools.random_state(rng)
        x_plus, impulse = dynamics.reset_map(x, Mode.FLIGHT, e)
        np.testing.assert_array_equal(x_plus, x)
        np.testing.assert_array_equal(impulse, 0.0)
        x_plus_j, P, impulse_j = dynamics.reset_map_jacobian(x, Mode.FLIGHT, e)
        np.testing.assert_array_equal(x_plus_j, x)
        np.testing.assert_array_equal(P, np.eye(NX))
        np.testing.assert_array_equal(impulse_j, 0.0)
        assert x_plus is not x  # a copy, not an alias of the input


# ----------------------------------------------------------------------------------------- impact physics
@pytest.mark.parametrize("mode", CONTACT_MODES, ids=[m.name for m in CONTACT_MODES])
def test_touching_feet_stop_and_positions_do_not_jump(robot, dynamics, rng, tools, mode):
    for _ in range(10):
        x = tools.random_state(rng, v_scale=0.5)
        x_plus, _ = dynamics.reset_map(x, mode)
        np.testing.assert_array_equal(x_plus[:NQ], x[:NQ])
        v_feet = robot.foot_velocities(x_plus)
        for foot in mode.feet:
            assert np.max(np.abs(v_feet[foot])) <= IMPACT_TOL, (foot, v_feet[foot])


@pytest.mark.parametrize("mode", CONTACT_MODES, ids=[m.name for m in CONTACT_MODES])
def test_plastic_impact_is_idempotent(dynamics, rng, tools, mode):
    for _ in range(10):
        x = tools.random_state(rng, v_scale=0.5)
        once, _ = dynamics.reset_map(x, mode)
        twice, impulse = dynamics.reset_map(once, mode)
        np.testing.assert_allclose(twice, once, rtol=0, atol=IMPACT_TOL)
        np.testing.assert_allclose(impulse, 0.0, atol=IMPACT_TOL)


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from(CONTACT_MODES))
def test_plastic_impact_never_increases_kinetic_energy(seed, mode):
    x = _sample(seed, q_scale=0.1, v_scale=1.0)
    x_plus, _ = _DYN.reset_map(x, mode, 0.0)
    before, after = _kinetic_energy(_ROBOT, x), _kinetic_energy(_ROBOT, x_plus)
    assert after <= before * (1.0 + 1e-12) + 1e-12


@settings(max_examples=100, deadline=None, derandomize=True, database=None)
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from(CONTACT_MODES), e=st.floats(0.0, 1.0))
def test_impact_with_restitution_never_increases_kinetic_energy(seed, mode, e):
    x = _sample(seed, q_scale=0.1, v_scale=1.0)
    x_plus, _ = _DYN.reset_map(x, mode, e)
    before, after = _kinetic_energy(_ROBOT, x), _kinetic_energy(_ROBOT, x_plus)
    assert after <= before * (1.0 + 1e-10) + 1e-12
    if e == 1.0:  # perfectly elastic: energy is conserved
        assert after == pytest.approx(before, rel=1e-9, abs=1e-12)


def _falling_onto(robot: CheetahModel, mode: Mode, rng: np.random.Generator, tools) -> np.ndarray:
    """A random state whose contact feet all move down (a touchdown)."""
    for _ in range(1000):
        x = tools.random_state(rng, v_scale=0.5)
        x[NQ + 1] -= 1.0  # falling at about 1 m/s, like the code's -1 m/s touchdown reference
        if all(robot.foot_velocities(x)[f, 1] < -0.1 for f in mode.feet):
            return x
    raise AssertionError("no falling state found")


@pytest.mark.parametrize("e", (0.0, 0.25, 0.5, 1.0))
@pytest.mark.parametrize("mode", SINGLE_CONTACT, ids=[m.name for m in SINGLE_CONTACT])
def test_restitution_reverses_the_normal_velocity(robot, dynamics, rng, tools, mode, e):
    (foot,) = mode.feet
    for _ in range(5):
        x = _falling_onto(robot, mode, rng, tools)
        v_before = robot.foot_velocities(x)[foot]
        x_plus, impulse = dynamics.reset_map(x, mode, e)
        v_after = robot.foot_velocities(x_plus)[foot]
        assert v_after[1] == pytest.approx(-e * v_before[1], abs=IMPACT_TOL)
        # Pinocchio's 3D contact applies e to the whole contact velocity, tangential part included (documented
        # by HybridDynamics.reset_map: "post-impact velocity -e times its pre-impact velocity")
        assert v_after[0] == pytest.approx(-e * v_before[0], abs=IMPACT_TOL)
        assert impulse[2 * foot + 1] > 0.0  # the ground pushes the falling foot up


@pytest.mark.parametrize("e", RESTITUTIONS)
@pytest.mark.parametrize("mode", CONTACT_MODES, ids=[m.name for m in CONTACT_MODES])
def test_impulse_changes_the_momentum(robot, dynamics, rng, tools, mode, e):
    """m (v_com+ - v_com-) = sum of ground impulses; airborne feet get no impulse."""
    m = robot.total_mass
    for _ in range(5):
        x = tools.random_state(rng, v_scale=0.5)
        x_plus, impulse = dynamics.reset_map(x, mode, e)
        vcom = []
        for state in (x, x_plus):
            data = robot.new_data()
            pin.centerOfMass(robot.model, data, state[:NQ], state[NQ:])
            vcom.append(data.vcom[0].copy())
        assert m * (vcom[1][0] - vcom[0][0]) == pytest.approx(impulse[0] + impulse[2], abs=1e-9)
        assert m * (vcom[1][2] - vcom[0][2]) == pytest.approx(impulse[1] + impulse[3], abs=1e-9)
        for foot in (0, 1):
            if not mode.in_contact(foot):
                np.testing.assert_array_equal(impulse[2 * foot:2 * foot + 2], 0.0)


@pytest.mark.parametrize("mode", CONTACT_MODES, ids=[m.name for m in CONTACT_MODES])
def test_reset_map_equals_the_exact_impact_solution(robot, dynamics, rng, tools, mode):
    """Against Pinocchio's unregularized impulse KKT with the explicit (2k, 7) planar contact Jacobian."""
    for _ in range(10):
        x = tools.random_state(rng, v_scale=1.0)
        J = np.vstack([robot.foot_jacobian(x[:NQ], foot) for foot in mode.feet])
        v_exact = pin.impulseDynamics(robot.model, robot.new_data(), x[:NQ], x[NQ:], J, 0.5, 0.0)
        np.testing.assert_allclose(dynamics.reset_map(x, mode, 0.5)[0][NQ:], v_exact, rtol=0, atol=1e-10)


# ----------------------------------------------------------------------------------------- Jacobian
@pytest.mark.parametrize("e", RESTITUTIONS)
@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_reset_map_jacobian_matches_finite_differences(robot, rng, tools, mode, e):
    """P_x against central differences of the reset map; each P_x is the first call on its dynamics
    (see the repeated-call tests below)."""
    for _ in range(4):
        x = tools.random_state(rng, v_scale=0.5)
        dyn = HybridDynamics(robot)
        x_plus, P, impulse = dyn.reset_map_jacobian(x, mode, e)
        ref_x, ref_impulse = dyn.reset_map(x, mode, e)
        np.testing.assert_array_equal(x_plus, ref_x)
        np.testing.assert_array_equal(impulse, ref_impulse)
        P_fd = tools.fd_jacobian(lambda xx, dyn=dyn: dyn.reset_map(xx, mode, e)[0], x)
        assert tools.max_rel_err(P, P_fd) <= tools.FD_TOL
        for block in (np.s_[NQ:, :NQ], np.s_[NQ:, NQ:]):  # dv+/dq and dv+/dv-, each relative to its own scale
            assert block_rel_err(P[block], P_fd[block]) <= tools.FD_TOL
        np.testing.assert_array_equal(P[:NQ], np.hstack([np.eye(NQ), np.zeros((NQ, NQ))]))


@pytest.mark.parametrize("e", RESTITUTIONS)
@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_reset_map_jacobian_far_from_the_nominal_state(robot, rng, tools, mode, e):
    """As above at broader random states (joint angles +-0.3 rad, rates ~2 rad/s) on one dynamics object."""
    dyn = HybridDynamics(robot)
    for _ in range(4):
        x = tools.random_state(rng, q_scale=0.3, v_scale=2.0)
        P = dyn.reset_map_jacobian(x, mode, e)[1]
        P_fd = tools.fd_jacobian(lambda xx: dyn.reset_map(xx, mode, e)[0], x)
        assert tools.max_rel_err(P, P_fd) <= tools.FD_TOL
        for block in (np.s_[NQ:, :NQ], np.s_[NQ:, NQ:]):
            assert block_rel_err(P[block], P_fd[block]) <= tools.FD_TOL


@pytest.mark.parametrize("e", RESTITUTIONS)
@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_reset_map_jacobian_matches_finite_differences_on_repeated_calls(robot, rng, tools, mode, e):
    """As a solver uses it: one dynamics object, P_x at one touchdown after another."""
    dyn = HybridDynamics(robot)
    for _ in range(4):
        x = tools.random_state(rng, v_scale=0.5)
        P = dyn.reset_map_jacobian(x, mode, e)[1]
        P_fd = tools.fd_jacobian(lambda xx: dyn.reset_map(xx, mode, e)[0], x)
        assert tools.max_rel_err(P, P_fd) <= tools.FD_TOL


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_reset_map_jacobian_does_not_depend_on_call_history(robot, rng, tools, mode):
    x = tools.random_state(rng, v_scale=0.5)
    P_fresh = HybridDynamics(robot).reset_map_jacobian(x, mode)[1]
    dyn = HybridDynamics(robot)
    for _ in range(3):
        dyn.reset_map_jacobian(tools.random_state(rng, v_scale=0.5), mode)
    P_used = dyn.reset_map_jacobian(x, mode)[1]
    np.testing.assert_allclose(P_used, P_fresh, rtol=0, atol=1e-12)


def test_reset_map_does_not_depend_on_call_history(robot, rng, tools):
    for mode in MODES:
        x = tools.random_state(rng, v_scale=0.5)
        fresh = HybridDynamics(robot).reset_map(x, mode, 0.3)
        dyn = HybridDynamics(robot)
        for _ in range(3):
            dyn.reset_map_jacobian(tools.random_state(rng), mode, 0.3)
            dyn.step_derivatives(tools.random_state(rng), tools.random_control(rng), mode)
        used = dyn.reset_map(x, mode, 0.3)
        np.testing.assert_array_equal(used[0], fresh[0])
        np.testing.assert_array_equal(used[1], fresh[1])
