"""Mode dynamics: analytical derivatives against finite differences, the horizon linearization, contact
kinematics, ground-force signs and momentum balance."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, NGRF, NQ, NU, NV, NX, Mode, grf_slice
from hsddp_gym.core.dynamics import HybridDynamics, Linearization
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.rollout import rollout
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController

MODES = tuple(Mode)
CONTACT_MODES = (Mode.FRONT_STANCE, Mode.BACK_STANCE, Mode.DOUBLE_STANCE)
INTEGRATORS = ("euler", "semi_implicit")
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
N_STATES = 4  # random states per (mode, integrator)


def _zero_v_block() -> np.ndarray:
    """d(v + h a)/dx minus the h * da/dx part: [0, I]."""
    return np.hstack([np.zeros((NV, NQ)), np.eye(NV)])


def block_rel_err(value: np.ndarray, reference: np.ndarray) -> float:
    """``max |value - reference| / max |reference|``: the error relative to the block's own scale.

    Complements ``tools.max_rel_err`` (elementwise, relative to ``max(1, |reference|)``), which compares
    entries below 1 in absolute terms: a block whose entries are all ~1e-2 would pass it with 1e-3 relative
    error. A reference that is identically zero must be matched exactly."""
    value, reference = np.asarray(value, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    assert value.shape == reference.shape, (value.shape, reference.shape)
    scale = float(np.max(np.abs(reference)))
    err = float(np.max(np.abs(value - reference)))
    return err if scale == 0.0 else err / scale


def assert_derivatives_match(dyn, x, u, mode, tools):
    """Every Jacobian of ``step_derivatives`` (f_x, f_u, grf_x, grf_u, and the continuous da/dx, da/du hidden
    in f = x + h (...)) against central differences: max relative error <= tools.FD_TOL in both measures,
    elementwise and per block."""
    h = dyn.dt
    _, _, f_x, f_u, grf_x, grf_u = dyn.step_derivatives(x, u, mode)
    pairs = {
        "f_x": (f_x, tools.fd_jacobian(lambda xx: dyn.step(xx, u, mode)[0], x)),
        "f_u": (f_u, tools.fd_jacobian(lambda uu: dyn.step(x, uu, mode)[0], u)),
        "grf_x": (grf_x, tools.fd_jacobian(lambda xx: dyn.step(xx, u, mode)[1], x)),
        "grf_u": (grf_u, tools.fd_jacobian(lambda uu: dyn.step(x, uu, mode)[1], u)),
        "a_x": ((f_x[NQ:] - _zero_v_block()) / h, tools.fd_jacobian(lambda xx: dyn.accelerations(xx, u, mode)[0], x)),
        "a_u": (f_u[NQ:] / h, tools.fd_jacobian(lambda uu: dyn.accelerations(x, uu, mode)[0], u)),
    }
    for name, (analytic, fd) in pairs.items():
        assert tools.max_rel_err(analytic, fd) <= tools.FD_TOL, (name, tools.max_rel_err(analytic, fd))
        assert block_rel_err(analytic, fd) <= tools.FD_TOL, (name, block_rel_err(analytic, fd))


# ----------------------------------------------------------------------------------------- step derivatives
@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_step_derivatives_match_finite_differences(robot, rng, tools, mode, integrator):
    dyn = HybridDynamics(robot, integrator=integrator)
    h = dyn.dt
    for _ in range(N_STATES):
        x = tools.random_state(rng)
        u = tools.random_control(rng)
        x_next, grf, f_x, f_u, grf_x, grf_u = dyn.step_derivatives(x, u, mode)
        assert f_x.shape == (NX, NX) and f_u.shape == (NX, NU)
        assert grf_x.shape == (NGRF, NX) and grf_u.shape == (NGRF, NU)
        x_step, grf_step = dyn.step(x, u, mode)
        # flight: computeABADerivatives' ddq and aba's differ in the last bits
        np.testing.assert_allclose(x_next, x_step, rtol=0, atol=1e-12)
        np.testing.assert_allclose(grf, grf_step, rtol=0, atol=1e-10)

        def step_x(xx, u=u):
            return dyn.step(xx, u, mode)[0]

        def step_u(uu, x=x):
            return dyn.step(x, uu, mode)[0]

        def grf_of_x(xx, u=u):
            return dyn.step(xx, u, mode)[1]

        def grf_of_u(uu, x=x):
            return dyn.step(x, uu, mode)[1]

        assert tools.max_rel_err(f_x, tools.fd_jacobian(step_x, x)) <= tools.FD_TOL
        assert tools.max_rel_err(f_u, tools.fd_jacobian(step_u, u)) <= tools.FD_TOL
        assert tools.max_rel_err(grf_x, tools.fd_jacobian(grf_of_x, x)) <= tools.FD_TOL
        assert tools.max_rel_err(grf_u, tools.fd_jacobian(grf_of_u, u)) <= tools.FD_TOL

        # f_x = I + O(h) hides derivative errors by a factor h: also check the continuous da/dx, da/du
        a_x = (f_x[NQ:] - _zero_v_block()) / h
        a_u = f_u[NQ:] / h
        a_x_fd = tools.fd_jacobian(lambda xx, u=u: dyn.accelerations(xx, u, mode)[0], x)
        a_u_fd = tools.fd_jacobian(lambda uu, x=x: dyn.accelerations(x, uu, mode)[0], u)
        assert tools.max_rel_err(a_x, a_x_fd) <= tools.FD_TOL
        assert tools.max_rel_err(a_u, a_u_fd) <= tools.FD_TOL
        assert_derivatives_match(dyn, x, u, mode, tools)  # the same, per block as well


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_step_derivatives_match_finite_differences_far_from_the_nominal_state(robot, rng, tools, mode, integrator):
    """Broader random states (joint angles +-0.3 rad, rates ~2 rad/s, torques up to the 33 N m limit) than the
    near-nominal ones above, and the per-block relative error as well as the elementwise one."""
    dyn = HybridDynamics(robot, integrator=integrator)
    for _ in range(N_STATES):
        x = tools.random_state(rng, q_scale=0.3, v_scale=2.0)
        u = tools.random_control(rng, scale=33.0)
        assert_derivatives_match(dyn, x, u, mode, tools)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_step_jacobian_structure_follows_the_integrator(robot, rng, tools, integrator):
    dyn = HybridDynamics(robot, integrator=integrator)
    h = dyn.dt
    x, u = tools.random_state(rng), tools.random_control(rng)
    for mode in MODES:
        x_next, _, f_x, f_u, _, _ = dyn.step_derivatives(x, u, mode)
        a, _ = dyn.accelerations(x, u, mode)
        np.testing.assert_allclose(x_next[NQ:], x[NQ:] + h * a, rtol=0, atol=1e-12)
        if integrator == "euler":
            np.testing.assert_allclose(x_next[:NQ], x[:NQ] + h * x[NQ:], rtol=0, atol=1e-15)
            np.testing.assert_array_equal(f_x[:NQ], np.hstack([np.eye(NQ), h * np.eye(NV)]))
            np.testing.assert_array_equal(f_u[:NQ], 0.0)
        else:
            np.testing.assert_allclose(x_next[:NQ], x[:NQ] + h * x_next[NQ:], rtol=0, atol=1e-15)
            np.testing.assert_allclose(f_x[:NQ], np.hstack([np.eye(NQ), h * np.eye(NV)]) + h * (f_x[NQ:] -
                                       _zero_v_block()), rtol=0, atol=1e-15)
            np.testing.assert_allclose(f_u[:NQ], h * f_u[NQ:], rtol=0, atol=1e-15)


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_ground_force_rows_of_airborne_feet_are_zero(dynamics, rng, tools, mode):
    x, u = tools.random_state(rng), tools.random_control(rng)
    _, grf, _, _, grf_x, grf_u = dynamics.step_derivatives(x, u, mode)
    for foot in (FRONT, BACK):
        rows = grf_slice(foot)
        if mode.in_contact(foot):
            assert np.any(grf[rows] != 0.0) and np.any(grf_x[rows] != 0.0)
        else:
            assert not np.any(grf[rows]) and not np.any(grf_x[rows]) and not np.any(grf_u[rows])


# ----------------------------------------------------------------------------------------- linearize
def _check_linearization_against_step_derivatives(dyn, X, U, modes, lin):
    # equal to rounding: linearize runs the compiled dynamics (hsddp_gym.core.planar_dynamics), the single-step
    # methods Pinocchio's (about 1e-12 relative apart, tests/test_planar_dynamics.py)
    for k in range(U.shape[0]):
        _, grf, f_x, f_u, grf_x, grf_u = dyn.step_derivatives(X[k], U[k], modes[k])
        for name, ref in (("f_x", f_x), ("f_u", f_u), ("grf", grf), ("grf_x", grf_x), ("grf_u", grf_u)):
            np.testing.assert_allclose(getattr(lin, name)[k], ref, rtol=1e-10, atol=1e-10,
                                       err_msg=f"{name} knot {k}")
        a, _ = dyn.accelerations(X[k], U[k], modes[k])
        np.testing.assert_allclose(lin.acc[k], a, rtol=1e-10, atol=1e-10, err_msg=f"acc knot {k}")


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_linearize_equals_step_derivatives_at_random_knots(robot, rng, tools, integrator):
    dyn = HybridDynamics(robot, integrator=integrator)
    n = 48
    X = np.array([tools.random_state(rng) for _ in range(n + 1)])
    U = np.array([tools.random_control(rng) for _ in range(n)])
    modes = np.tile(np.array([int(m) for m in MODES]), n // len(MODES))
    rng.shuffle(modes)
    lin = Linearization(n + 10)  # capacity above N: only the first N knots are filled
    dyn.linearize(X, U, modes, lin)
    _check_linearization_against_step_derivatives(dyn, X, U, modes, lin)
    assert not np.any(lin.f_x[n:]) and not np.any(lin.grf[n:])

    # reusing the buffer with a different mode per knot leaves nothing stale behind
    modes2 = np.roll(modes, 1)
    dyn.linearize(X, U, modes2, lin)
    _check_linearization_against_step_derivatives(dyn, X, U, modes2, lin)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_linearize_equals_step_derivatives_on_a_bounding_trajectory(robot, integrator):
    dyn = HybridDynamics(robot, integrator=integrator)
    schedule = ModeSchedule.bounding(1)
    traj = rollout(dyn, schedule, paper_initial_state(),
                   controller=HeuristicBoundingController(robot).as_schedule_controller(schedule))
    lin = Linearization(traj.U.shape[0])
    dyn.linearize(traj.X, traj.U, traj.modes, lin)
    _check_linearization_against_step_derivatives(dyn, traj.X, traj.U, traj.modes, lin)
    np.testing.assert_allclose(lin.grf, traj.GRF, rtol=0, atol=1e-10)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_linearize_with_per_knot_steps(robot, rng, tools, integrator):
    """Time-scaled problems pass one step per knot; each knot matches a dynamics built with that dt."""
    n = 12
    X = np.array([tools.random_state(rng) for _ in range(n + 1)])
    U = np.array([tools.random_control(rng) for _ in range(n)])
    modes = np.array([int(MODES[k % len(MODES)]) for k in range(n)])
    h = np.where(np.arange(n) < n // 2, 0.8e-3, 1.3e-3)
    lin = Linearization(n)
    HybridDynamics(robot, integrator=integrator).linearize(X, U, modes, lin, h)
    for k in range(n):
        dyn_k = HybridDynamics(robot, dt=float(h[k]), integrator=integrator)
        _, _, f_x, f_u, grf_x, _ = dyn_k.step_derivatives(X[k], U[k], modes[k])
        np.testing.assert_allclose(lin.f_x[k], f_x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(lin.f_u[k], f_u, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(lin.grf_x[k], grf_x, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("per_knot_h", [False, True])
def test_compiled_finish_is_bit_identical_to_the_numpy_assembly(robot, rng, integrator, per_knot_h):
    """:meth:`Linearization.finish` (compiled) gives the numbers of :func:`assemble_step_jacobians` and
    :func:`grf_from_lambda` with the ground-force rows copied per mode, bit for bit, over stale rows of other modes."""
    from hsddp_gym.core.dynamics import assemble_step_jacobians, grf_from_lambda

    dyn = HybridDynamics(robot, integrator=integrator)
    n = 40
    lin = Linearization(n + 5)
    for name in ("a_q", "a_v", "a_tau", "lam6_q", "lam6_v", "lam6_tau", "lam6"):
        getattr(lin, name)[:] = rng.normal(size=getattr(lin, name).shape)
    lin.a_v[0, 2, 2] = -0.0
    modes = rng.integers(0, 4, n)
    h = rng.uniform(1e-3, 5e-3, n) if per_knot_h else 2.5e-3
    lin.finish(n, modes, h, integrator, dyn._contact)
    f_x, f_u, grf = np.empty((n, NX, NX)), np.empty((n, NX, NU)), np.empty((n, NGRF))
    assemble_step_jacobians(lin.a_q[:n], lin.a_v[:n], lin.a_tau[:n, :, 3:], h, integrator, f_x, f_u)
    grf_from_lambda(lin.lam6[:n], modes, dyn._contact, grf)
    grf_x, grf_u = np.zeros((n, NGRF, NX)), np.zeros((n, NGRF, NU))
    for mode, cs in dyn._contact.items():
        idx = np.flatnonzero(modes == int(mode))
        for g, r in zip(cs.grf_rows, cs.lam_rows):
            grf_x[idx, g] = np.concatenate([lin.lam6_q[idx, r], lin.lam6_v[idx, r]], axis=1)
            grf_u[idx, g] = lin.lam6_tau[idx, r, 3:]
    for got, want in ((lin.f_x, f_x), (lin.f_u, f_u), (lin.grf, grf), (lin.grf_x, grf_x), (lin.grf_u, grf_u)):
        np.testing.assert_array_equal(got[:n].view(np.uint64), want.view(np.uint64))


# ----------------------------------------------------------------------------------------- contact physics
@pytest.mark.parametrize("mode", CONTACT_MODES, ids=[m.name for m in CONTACT_MODES])
def test_stance_feet_do_not_accelerate(robot, dynamics, rng, tools, mode):
    """|J a + dJ v| <= 1e-9 for every stance foot, near the nominal state and far from it."""
    for i in range(12):
        if i < 6:
            x, u = tools.random_state(rng), tools.random_control(rng)
        else:
            x, u = tools.random_state(rng, q_scale=0.3, v_scale=2.0), tools.random_control(rng, scale=33.0)
        a, _ = dynamics.accelerations(x, u, mode)
        data = robot.new_data()
        pin.forwardKinematics(robot.model, data, x[:NQ], x[NQ:], a)
        for foot in mode.feet:
            acc = pin.getFrameClassicalAcceleration(robot.model, data, robot.foot_frame_ids[foot], LWA).linear
            assert np.max(np.abs(acc[[0, 2]])) <= 1e-9, (foot, acc)


def test_flight_acceleration_is_aba(robot, dynamics, rng, tools):
    for _ in range(6):
        x, u = tools.random_state(rng), tools.random_control(rng)
        a, grf = dynamics.accelerations(x, u, Mode.FLIGHT)
        tau = np.concatenate([np.zeros(3), u])
        np.testing.assert_allclose(a, pin.aba(robot.model, robot.new_data(), x[:NQ], x[NQ:], tau), rtol=0,
                                   atol=1e-12)
        np.testing.assert_array_equal(grf, 0.0)


def test_positive_torque_accelerates_its_joint_positively(dynamics, rng, tools):
    x = tools.random_state(rng)
    a0, _ = dynamics.accelerations(x, np.zeros(NU), Mode.FLIGHT)
    for j in range(NU):
        a1, _ = dynamics.accelerations(x, np.eye(NU)[j], Mode.FLIGHT)
        assert a1[3 + j] > a0[3 + j]


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_ground_forces_balance_the_momentum(robot, dynamics, rng, tools, mode):
    """Newton for the whole robot: sum of ground forces = m (a_com - g)."""
    m, g = robot.total_mass, robot.params.gravity
    for _ in range(6):
        x, u = tools.random_state(rng), tools.random_control(rng)
        a, grf = dynamics.accelerations(x, u, mode)
        data = robot.new_data()
        pin.centerOfMass(robot.model, data, x[:NQ], x[NQ:], a)
        acom = data.acom[0]
        fx = grf[0] + grf[2]
        fz = grf[1] + grf[3]
        assert fx == pytest.approx(m * acom[0], abs=1e-8)
        assert fz == pytest.approx(m * (acom[2] + g), abs=1e-8)


def test_standing_still_each_foot_carries_half_the_weight(dynamics):
    """Straight legs on the ground, zero torque, at rest: a static equilibrium."""
    weight = dynamics.robot.total_mass * dynamics.robot.params.gravity
    x = np.zeros(NX)
    x[1] = dynamics.robot.params.leg_length
    a, grf = dynamics.accelerations(x, np.zeros(NU), Mode.DOUBLE_STANCE)
    np.testing.assert_allclose(a, 0.0, atol=1e-10)
    assert grf[1] > 0.0 and grf[3] > 0.0
    assert grf[1] + grf[3] == pytest.approx(weight, rel=1e-10)
    assert grf[1] == pytest.approx(weight / 2, rel=1e-10)
    assert abs(grf[0]) < 1e-10 and abs(grf[2]) < 1e-10


def test_stance_force_at_the_paper_initial_state_pushes_up(dynamics):
    """Back stance at the paper's initial state with gravity-supporting knee torque: f_z > 0."""
    x0 = paper_initial_state()
    _, grf = dynamics.accelerations(x0, np.array([0.0, 0.0, -5.0, 10.0]), Mode.BACK_STANCE)
    assert grf[3] > 0.0
    np.testing.assert_array_equal(grf[:2], 0.0)


def test_step_uses_dt(robot, rng, tools):
    x, u = tools.random_state(rng), tools.random_control(rng)
    a, _ = HybridDynamics(robot).accelerations(x, u, Mode.BACK_STANCE)
    x_next, _ = HybridDynamics(robot, dt=5e-3).step(x, u, Mode.BACK_STANCE)
    np.testing.assert_allclose(x_next[NQ:], x[NQ:] + 5e-3 * a, rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_simulate_step_equals_step(robot, rng, tools, mode):
    for integrator in INTEGRATORS:
        dyn = HybridDynamics(robot, integrator=integrator)
        x, u = tools.random_state(rng), tools.random_control(rng)
        x_next, grf = np.empty(NX), np.empty(NGRF)
        dyn.simulate_step(x, u, int(mode), x_next, grf)
        ref_x, ref_grf = dyn.step(x, u, mode)
        np.testing.assert_array_equal(x_next, ref_x)
        np.testing.assert_array_equal(grf, ref_grf)
