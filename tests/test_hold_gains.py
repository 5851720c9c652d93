"""The feedback law of a control held over several knots (``planners/optimizer/hold.py``).

A stiff one-joint system (a light leg, semi-implicit Euler at the MPC's 2.5 ms) tracked by an LQR: the
per-knot gains, held for two knots as the env's 5 ms control period does, make the closed loop unstable (the
velocity flips sign from one control step to the next, the chatter seen after pushes); the held-input gains
keep it stable, and each is the minimizer of the held pair's quadratic model.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.hold import held_input_gains
from hsddp_gym.planners.optimizer.riccati import backward_pass

H = 0.0025        # planner step [s]
INERTIA = 0.004   # a shank about its knee [kg m^2]


def _joint(n_knots: int, phase_start, q_pos=4e3, q_vel=40.0, r=1e-4, rng=None):
    """LQR of a joint ``(angle, rate)`` driven by a torque: returns (solver, problem) stand-ins for
    :func:`held_input_gains` after the backward pass. ``rng``: random cross terms and time variation."""
    nx, nu = 2, 1
    A = np.array([[1.0, H], [0.0, 1.0]])
    B = np.array([[H * H / INERTIA], [H / INERTIA]])  # semi-implicit Euler: the rate first, the angle with it
    f_x = np.repeat(A[None], n_knots, 0)
    f_u = np.repeat(B[None], n_knots, 0)
    l_xx = np.repeat(np.diag([q_pos, q_vel])[None], n_knots, 0)
    l_uu = np.full((n_knots, nu, nu), r)
    l_ux = np.zeros((n_knots, nu, nx))
    if rng is not None:
        f_x = f_x + 0.01 * rng.standard_normal(f_x.shape)
        f_u = f_u * (1 + 0.1 * rng.standard_normal(f_u.shape))
        l_ux = 0.01 * rng.standard_normal(l_ux.shape)
        l_xx = l_xx * (1 + 0.2 * rng.random((n_knots, 1, 1)))
    n_phases = len(phase_start) - 1
    Phi_x = np.zeros((n_phases, nx))
    Phi_xx = np.repeat((10 * np.diag([q_pos, q_vel]))[None], n_phases, 0)
    P_x = np.repeat(np.eye(nx)[None], n_phases, 0)
    if rng is not None:
        P_x = P_x + 0.1 * rng.standard_normal(P_x.shape)
    phase_start = np.asarray(phase_start, dtype=np.int64)
    k_ff, K = np.zeros((n_knots, nu)), np.zeros((n_knots, nu, nx))
    V_x, V_xx = np.zeros((n_knots + 1, nx)), np.zeros((n_knots + 1, nx, nx))
    ok, *_ = backward_pass(f_x, f_u, np.zeros((n_knots, nx)), np.zeros((n_knots, nu)), l_xx, l_uu, l_ux, Phi_x,
                           Phi_xx, P_x, phase_start, 0.0, k_ff, K, V_x, V_xx)
    assert ok
    problem = SimpleNamespace(n_knots=n_knots, n_phases=n_phases, phase_start=phase_start)
    ws = SimpleNamespace(K=K, lin=SimpleNamespace(f_x=f_x, f_u=f_u), l_xx=l_xx, l_uu=l_uu, l_ux=l_ux, V_xx=V_xx,
                         Phi_xx=Phi_xx, P_x=P_x)
    return SimpleNamespace(_ws=ws, last_problem=problem), problem


def _held_pair_map(solver, k, gain):
    """``x_{k+2} = M x_k`` with the control ``gain x_k`` held over knots k, k+1."""
    A, B = solver._ws.lin.f_x, solver._ws.lin.f_u
    return A[k + 1] @ (A[k] + B[k] @ gain) + B[k + 1] @ gain


def test_per_knot_gains_held_for_two_knots_oscillate_held_gains_do_not():
    solver, problem = _joint(200, [0, 200])
    k = 100  # mid horizon: the stationary gain
    K = solver._ws.K
    rho_knot = max(abs(np.linalg.eigvals(_held_pair_map(solver, k, K[k]))))
    rho_one = max(abs(np.linalg.eigvals(solver._ws.lin.f_x[k] + solver._ws.lin.f_u[k] @ K[k])))
    K_hold = held_input_gains(solver, problem, 2)
    eig_hold = np.linalg.eigvals(_held_pair_map(solver, k, K_hold[k]))
    assert rho_one < 1.0               # the per-knot law is stable at the rate it was designed for
    assert rho_knot > 1.0              # ... and unstable held for two knots: the 5 ms chatter
    assert max(abs(eig_hold)) < 1.0    # the held-input law is stable at 5 ms
    assert abs(K_hold[k][0, 1]) < abs(K[k][0, 1])  # it asks less of the rate feedback


def test_held_gain_minimizes_the_quadratic_model_of_the_held_knots():
    rng = np.random.default_rng(3)
    solver, problem = _joint(40, [0, 17, 40], rng=rng)
    ws = solver._ws
    for m in (2, 3):
        K_hold = held_input_gains(solver, problem, m)
        for k in (0, 5, 17 - m, 23, 40 - m):
            i = 0 if k < 17 else 1
            end = 17 if i == 0 else 40
            V = ws.V_xx[k + m] if k + m < end else (
                ws.Phi_xx[i] + ws.P_x[i].T @ ws.V_xx[end] @ ws.P_x[i] if i == 0 else ws.Phi_xx[i])

            def cost(dx, du, k=k, m=m, V=V):  # the model, rolled out knot by knot
                c = 0.0
                for j in range(m):
                    kj = k + j
                    z = np.concatenate([dx, du])
                    H_j = np.block([[ws.l_xx[kj], ws.l_ux[kj].T], [ws.l_ux[kj], ws.l_uu[kj]]])
                    c += 0.5 * z @ H_j @ z
                    dx = ws.lin.f_x[kj] @ dx + ws.lin.f_u[kj] @ du
                return c + 0.5 * dx @ V @ dx

            dx = rng.standard_normal(2)
            du_star = K_hold[k] @ dx
            # a 1-D quadratic: the minimizer from three evaluations
            s = 1e-3 * (1 + abs(du_star[0]))
            c0, cp, cm = (cost(dx, du_star + d) for d in (0.0, s, -s))
            slope, curvature = (cp - cm) / (2 * s), (cp + cm - 2 * c0) / s ** 2  # exact for a quadratic
            assert curvature > 0
            assert abs(slope) <= 1e-6 * curvature * (1 + abs(du_star[0]))  # the model's minimum


def test_hold_of_one_knot_and_holds_across_a_switch_keep_the_per_knot_gains():
    solver, problem = _joint(30, [0, 11, 30])
    K = solver._ws.K
    np.testing.assert_array_equal(held_input_gains(solver, problem, 1), K)
    K2 = held_input_gains(solver, problem, 2)
    np.testing.assert_array_equal(K2[10], K[10])      # knot 10's hold would run into phase 1
    np.testing.assert_array_equal(K2[29], K[29])      # the last knot
    assert not np.allclose(K2[9], K[9]) and not np.allclose(K2[28], K[28])  # holds ending at a phase's end


def test_knots_with_non_finite_or_indefinite_models_keep_the_per_knot_gains():
    # a warm start far off can overflow the barrier terms (non-finite derivatives); a knot's model can be indefinite
    solver, problem = _joint(30, [0, 30])
    ws = solver._ws
    K = ws.K.copy()
    ws.l_uu[7] = np.nan
    ws.l_uu[12] = -1e9
    ws.l_xx[20] = np.inf
    K2 = held_input_gains(solver, problem, 2)
    for k in (6, 7, 11, 12, 19, 20):  # the holds that contain one of those knots
        np.testing.assert_array_equal(K2[k], K[k])
    assert np.all(np.isfinite(K2)) and not np.allclose(K2[3], K[3])


def test_bad_input_is_refused():
    solver, problem = _joint(10, [0, 10])
    with pytest.raises(ValueError, match="hold"):
        held_input_gains(solver, problem, 0)
    with pytest.raises(ValueError, match="solve it first"):
        held_input_gains(solver, SimpleNamespace(n_knots=10, n_phases=1, phase_start=np.array([0, 10])), 2)


def test_held_feedforward_is_the_mean_over_the_held_knots_and_follows_the_plan_closer():
    from hsddp_gym.planners.optimizer.hold import held_feedforward

    rng = np.random.default_rng(0)
    U = rng.standard_normal((12, 4))
    starts = np.array([0, 5, 12])
    F = held_feedforward(U, starts, 2)
    np.testing.assert_allclose(F[0], (U[0] + U[1]) / 2)
    np.testing.assert_allclose(F[3], (U[3] + U[4]) / 2)
    np.testing.assert_array_equal(F[4], U[4])        # the hold would cross the switch at knot 5
    np.testing.assert_allclose(F[10], (U[10] + U[11]) / 2)
    np.testing.assert_array_equal(F[11], U[11])
    np.testing.assert_array_equal(held_feedforward(U, starts, 1), U)
    with pytest.raises(ValueError, match="hold"):
        held_feedforward(U, starts, 0)
    with pytest.raises(ValueError, match="phase_start"):
        held_feedforward(U, np.array([0, 5, 11]), 2)
    with pytest.raises(ValueError, match="U must be"):
        held_feedforward(U[0], starts, 2)
    # the joint of the LQR tests driven by a ramp of torques: holding the mean over two knots lands nearer the plan's
    # state two knots on than holding the first knot's torque (the lag of half a control period)
    solver, _ = _joint(2, [0, 2])
    A, B = solver._ws.lin.f_x, solver._ws.lin.f_u
    u = np.array([[1.0], [3.0]])
    plan = A[1] @ (B[0] @ u[0]) + B[1] @ u[1]
    F = held_feedforward(u, np.array([0, 2]), 2)
    err_mean = np.linalg.norm(A[1] @ (B[0] @ F[0]) + B[1] @ F[0] - plan)
    err_first = np.linalg.norm(A[1] @ (B[0] @ u[0]) + B[1] @ u[0] - plan)
    assert err_mean < 0.25 * err_first
