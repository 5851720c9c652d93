"""Objective derivatives (:meth:`Objective.derivatives`) against finite differences of
:meth:`Objective.evaluate`:

* running cost without ground-force terms (S = 0, barrier weight on the forces 0) and relaxed barriers on
  the torques (interior, relaxed and violated torques): l_x, l_u from central differences of the value,
  l_xx, l_uu, l_ux from second differences of the value and from differences of the analytic gradient;
* the full running cost with ground-force tracking and force barriers, the force a function of (x, u)
  through the contact dynamics: l_x, l_u (first order; the Hessian is Gauss-Newton by design);
* terminal cost + augmented-Lagrangian term (eq. 23) as a function of the pre-switch state: Phi_x, Phi_xx.
"""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import NU, NX
from hsddp_gym.core.dynamics import Linearization
from hsddp_gym.core.rollout import rollout
from hsddp_gym.planners.optimizer.hsddp import _Traj, rollout_policy
from hsddp_gym.planners.optimizer.objective import ConstraintState, Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController


def _trajectory(problem: HybridProblem):
    ctrl = HeuristicBoundingController(problem.dynamics.robot).as_schedule_controller(problem.schedule)
    U0 = rollout(problem.dynamics, problem.schedule, problem.x0, controller=ctrl).U
    tr = _Traj(problem.n_knots, problem.n_phases)
    assert rollout_policy(problem, tr, U0)
    lin = Linearization(problem.n_knots)
    problem.dynamics.linearize(tr.X, tr.U, problem.modes, lin, problem.h)
    return tr, lin


def _derivatives(obj: Objective, tr, lin, cs):
    N, n = obj.problem.n_knots, obj.problem.n_phases
    out = dict(l_x=np.zeros((N, NX)), l_u=np.zeros((N, NU)), l_xx=np.zeros((N, NX, NX)), l_uu=np.zeros((N, NU, NU)),
               l_ux=np.zeros((N, NU, NX)), Phi_x=np.zeros((n, NX)), Phi_xx=np.zeros((n, NX, NX)))
    obj.derivatives(tr.X, tr.X_pre, tr.U, tr.GRF, lin.grf_x, lin.grf_u, cs, out["l_x"], out["l_u"], out["l_xx"],
                    out["l_uu"], out["l_ux"], out["Phi_x"], out["Phi_xx"])
    return out


def assert_scaled(actual, expected, rtol, what=""):
    """``max|actual - expected| <= rtol * max|expected|`` -- relative to the block's scale, not to 1 (the running
    cost's Hessian entries are ~1e-4)."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    scale = float(np.max(np.abs(expected)))
    assert scale > 0, f"{what}: reference is identically zero"
    err = float(np.max(np.abs(actual - expected)))
    assert err <= rtol * scale, f"{what}: error {err:.3e} > {rtol:.1e} * {scale:.3e}"


def _grad(f, z, h):
    E = h * np.eye(z.size)
    return np.array([(f(z + e) - f(z - e)) / (2.0 * h) for e in E])


def _hess(f, z, h):
    n = z.size
    E = h * np.eye(n)
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            H[i, j] = H[j, i] = (f(z + E[i] + E[j]) - f(z + E[i] - E[j]) - f(z - E[i] + E[j])
                                 + f(z - E[i] - E[j])) / (4.0 * h * h)
    return H


SHORT = (0.003, 0.003, 0.003, 0.003)
"""A one-cycle bounding schedule of 12 knots (back stance, flight, front stance, flight; 3 knots each): the
value finite differences sum few terms, so their round-off stays far below the tested derivatives."""


def short_problem(**kwargs) -> HybridProblem:
    problem = HybridProblem.bounding(cycles=1, durations=SHORT, **kwargs)
    assert problem.n_knots == 12 and list(problem.phase_start) == [0, 3, 6, 9, 12]
    return problem


@pytest.fixture(scope="module", params=["uniform", "time_scaled"])
def no_grf_setup(request):
    problem = short_problem(grf_tracking=False)
    if request.param == "time_scaled":
        # per-phase steps h_i = T_i / N_i (the switching-time optimization's problems): the running cost is h_k l_k
        problem = problem.with_durations([0.0036, 0.0027, 0.003, 0.0024])
        assert len(set(np.round(problem.h, 12))) == 4
    assert np.all(problem.Sd == 0)
    tr, lin = _trajectory(problem)
    umax = problem.constraints.torque_limit
    # torques in every regime of the barrier (delta = 0.2): interior, relaxed (c <= delta), violated
    tr.U[1] = (umax - 0.05, -umax + 0.12, 4.0, -7.5)
    tr.U[3] = (umax + 1.5, 0.3, -(umax + 0.4), umax - 0.19)
    tr.U[7] = (-20.0, 25.0, umax - 0.25, -umax + 0.21)
    return problem, tr, lin


KNOTS = (1, 3, 7, 10)  # back stance, first flight knot (post-reset state), front stance, flight
TORQUE_ONLY = dict(sigma=5.0, use_al=False, use_reb=True, delta_torque=0.2, delta_grf=0.4, eps_torque=0.05,
                   eps_grf=0.0)


def test_running_cost_derivatives_without_force_terms(no_grf_setup):
    problem, tr, lin = no_grf_setup
    obj = Objective(problem)
    cs = ConstraintState(lam=np.zeros(problem.n_phases), **TORQUE_ONLY)
    d = _derivatives(obj, tr, lin, cs)
    base = obj.evaluate(tr.X, tr.X_pre, tr.U, tr.GRF, cs)
    assert base.barrier != 0.0 and base.al == 0.0

    for k in KNOTS:
        def total(z, k=k):
            X, U = tr.X.copy(), tr.U.copy()
            X[k], U[k] = z[:NX], z[NX:]
            c = obj.evaluate(X, tr.X_pre, U, tr.GRF, cs)
            return c.running + c.barrier

        z0 = np.concatenate([tr.X[k], tr.U[k]])
        # the value is quadratic in x (any step is exact) and piecewise -log / quadratic in u
        xk, uk = tr.X[k].copy(), tr.U[k].copy()

        def of_x(x, f=total, uk=uk):
            return f(np.concatenate([x, uk]))

        def of_u(u, f=total, xk=xk):
            return f(np.concatenate([xk, u]))

        g_x = _grad(of_x, xk, 1e-2)
        g_u = _grad(of_u, uk, 1e-4)
        assert_scaled(d["l_x"][k], g_x, 1e-8, f"l_x[{k}]")
        assert_scaled(d["l_u"][k], g_u, 3e-7, f"l_u[{k}]")
        # second differences of the value: the cost is quadratic in x (any step is exact) and in u up to the
        # log branch of the barrier (small 4th derivative)
        Hx = _hess(of_x, xk, 0.1)
        Hu = _hess(of_u, uk, 3e-4)
        diag_x = np.diag(Hx)
        assert_scaled(d["l_xx"][k], Hx, 1e-5, f"l_xx[{k}]")
        assert_scaled(d["l_uu"][k], Hu, 1e-4, f"l_uu[{k}]")
        assert np.max(np.abs(Hx - np.diag(diag_x))) <= 1e-6 * np.max(np.abs(diag_x))
        # no cross term without force terms
        np.testing.assert_array_equal(d["l_ux"][k], 0.0)

        # differences of the analytic gradient (tight)
        def grad_at(z, k=k):
            t = _Traj(problem.n_knots, problem.n_phases)
            t.X[:], t.X_pre[:], t.U[:], t.GRF[:] = tr.X, tr.X_pre, tr.U, tr.GRF
            t.X[k], t.U[k] = z[:NX], z[NX:]
            dd = _derivatives(obj, t, lin, cs)
            return np.concatenate([dd["l_x"][k], dd["l_u"][k]])

        J = np.array([(grad_at(z0 + e) - grad_at(z0 - e)) / 2e-6 for e in 1e-6 * np.eye(NX + NU)]).T
        assert_scaled(d["l_xx"][k], J[:NX, :NX], 1e-6, f"l_xx[{k}] vs grad FD")
        assert_scaled(d["l_uu"][k], J[NX:, NX:], 1e-6, f"l_uu[{k}] vs grad FD")
        np.testing.assert_allclose(J[NX:, :NX], 0.0, atol=1e-9)


def test_barrier_curvature_is_used_in_the_relaxed_branch(no_grf_setup):
    """At a relaxed torque the barrier adds eps / delta^2 (not eps) to l_uu (the authors' code used 1)."""
    problem, tr, lin = no_grf_setup
    obj = Objective(problem)
    cs = ConstraintState(lam=np.zeros(problem.n_phases), **TORQUE_ONLY)
    d = _derivatives(obj, tr, lin, cs)
    cs_off = ConstraintState(lam=np.zeros(problem.n_phases), **dict(TORQUE_ONLY, use_reb=False))
    d_off = _derivatives(obj, tr, lin, cs_off)
    extra = np.diag(d["l_uu"][1] - d_off["l_uu"][1])
    # U[1, 0] = umax - 0.05: relaxed upper row (1/delta^2) + log lower row 1/(2 umax - 0.05)^2
    umax = problem.constraints.torque_limit
    assert extra[0] == pytest.approx(cs.eps_torque * (1.0 / 0.2 ** 2 + 1.0 / (2 * umax - 0.05) ** 2), rel=1e-12)


def test_running_cost_gradient_with_force_terms_through_the_dynamics():
    """l_x, l_u of the full running cost (force tracking + force barriers), the ground force being the
    contact-dynamics force of (x, u): the force Jacobians of the linearization map the force-space gradient."""
    problem = short_problem()
    tr, lin = _trajectory(problem)
    obj = Objective(problem)
    cs = ConstraintState(sigma=5.0, lam=np.zeros(problem.n_phases), use_al=False, use_reb=True, delta_torque=0.2,
                         delta_grf=5.0, eps_torque=1e-3, eps_grf=0.05)
    d = _derivatives(obj, tr, lin, cs)
    dyn = problem.dynamics
    x_next, grf = np.empty(NX), np.empty(4)
    for k in range(problem.n_knots):
        mode = int(problem.modes[k])

        def total(z, k=k, mode=mode):
            X, U, G = tr.X.copy(), tr.U.copy(), tr.GRF.copy()
            X[k], U[k] = z[:NX], z[NX:]
            dyn.simulate_step(X[k], U[k], mode, x_next, grf)
            G[k] = grf
            c = obj.evaluate(X, tr.X_pre, U, G, cs)
            return c.running + c.barrier

        g = _grad(total, np.concatenate([tr.X[k], tr.U[k]]), 1e-5)
        assert_scaled(d["l_x"][k], g[:NX], 2e-6, f"l_x[{k}] (mode {mode})")
        assert_scaled(d["l_u"][k], g[NX:], 2e-6, f"l_u[{k}] (mode {mode})")


@pytest.mark.parametrize("use_al", [True, False])
def test_terminal_and_al_derivatives(use_al):
    problem = HybridProblem.bounding(cycles=1)
    tr, lin = _trajectory(problem)
    # move the landing feet away from the ground so that the AL term has a real slope
    tr.X_pre[1, 1] += 0.02
    tr.X_pre[3, 1] -= 0.015
    obj = Objective(problem)
    lam = np.array([0.9, 0.7, -0.3, -0.4])  # entries of lift-off phases are unused
    cs = ConstraintState(sigma=40.0, lam=lam, use_al=use_al, use_reb=False, delta_torque=0.2, delta_grf=0.4,
                         eps_torque=1e-5, eps_grf=1e-5)
    d = _derivatives(obj, tr, lin, cs)
    g = obj.switching_values(tr.X_pre)
    assert g[0] == g[2] == 0.0 and abs(g[1]) > 1e-3 and abs(g[3]) > 1e-3
    for i in range(problem.n_phases):
        def value(x, i=i):
            X_pre = tr.X_pre.copy()
            X_pre[i] = x
            c = obj.evaluate(tr.X, X_pre, tr.U, tr.GRF, cs)
            return c.terminal + c.al

        def phi_x_at(x, i=i):
            t = _Traj(problem.n_knots, problem.n_phases)
            t.X[:], t.X_pre[:], t.U[:], t.GRF[:] = tr.X, tr.X_pre, tr.U, tr.GRF
            t.X_pre[i] = x
            return _derivatives(obj, t, lin, cs)["Phi_x"][i]

        x = tr.X_pre[i]
        assert_scaled(d["Phi_x"][i], _grad(value, x, 1e-6), 1e-7, f"Phi_x[{i}]")
        assert_scaled(d["Phi_xx"][i], _hess(value, x, 1e-3), 1e-5, f"Phi_xx[{i}] (second differences)")
        J = np.array([(phi_x_at(x + e) - phi_x_at(x - e)) / 2e-6 for e in 1e-6 * np.eye(NX)]).T
        assert_scaled(d["Phi_xx"][i], J, 1e-7, f"Phi_xx[{i}] (differences of Phi_x)")
        np.testing.assert_array_equal(d["Phi_xx"][i], d["Phi_xx"][i].T)
    if use_al:
        # the AL term contributes only at touchdowns, with slope (sigma^2 / 2) g + lambda along g_x
        d_off = _derivatives(obj, tr, lin, ConstraintState(**dict(cs.__dict__, use_al=False)))
        np.testing.assert_array_equal(d["Phi_x"][[0, 2]], d_off["Phi_x"][[0, 2]])
        for i in (1, 3):
            foot = int(problem.touchdown[i])
            _, g_x, _ = problem.dynamics.robot.foot_height_derivatives(tr.X_pre[i, :7], foot)
            slope = 2.0 * (cs.sigma / 2.0) ** 2 * g[i] + lam[i]
            np.testing.assert_allclose(d["Phi_x"][i] - d_off["Phi_x"][i], slope * g_x, rtol=1e-12, atol=1e-12)


def test_bounding_weights_are_the_authors():
    """original_code_facts §3.5: the weights closest to the paper (default) and the later ones (MH HEAD / HM)."""
    from hsddp_gym.core.conventions import Mode
    from hsddp_gym.planners.optimizer.problem import bounding_phase_cost

    bs = bounding_phase_cost(Mode.BACK_STANCE, None)
    np.testing.assert_allclose(bs.q, 0.01 * np.array([0, 10, 5, 2, 2, 2, 2, 8, 1, 0.01, 5, 5, 5, 5]))
    np.testing.assert_allclose(bs.qf, 100 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 2, 0.01, 5, 5, 0.01, 0.01]))
    np.testing.assert_allclose(bs.r, [5, 5, 1, 1])
    fl = bounding_phase_cost(Mode.FLIGHT, 0)
    np.testing.assert_allclose(fl.qf[10:], 100 * np.array([5, 5, 5, 5]))
    later = bounding_phase_cost(Mode.FRONT_STANCE, None, weights="later")
    np.testing.assert_allclose(later.q, 0.01 * np.array([0, 10, 5, 4, 4, 4, 4, 2, 1, 0.01, 6, 6, 6, 6]))
    np.testing.assert_allclose(later.qf, 100 * np.array([0, 20, 8, 3, 3, 3, 3, 3, 2, 0.01, 0.01, 0.01, 5, 5]))
    np.testing.assert_allclose(later.r, 0.5 * np.array([1, 1, 5, 5]))
    np.testing.assert_allclose(later.s, bounding_phase_cost(Mode.FRONT_STANCE, None).s)
    with pytest.raises(ValueError, match="weights"):
        bounding_phase_cost(Mode.FLIGHT, 0, weights="mine")
    problem = HybridProblem.bounding(1, weights="later")
    np.testing.assert_allclose(problem.Qd[0], later.q)  # Q is the same in every mode


def test_double_stance_cost_and_reference():
    """Double stance (the MPC's with ``MPCOptions.double_stance``, not the authors' gait): the touchdown posture of
    the foot that stays with zero vertical velocity, stance weights on both legs, the weight shared by the two
    feet."""
    from hsddp_gym.core.conventions import BACK, FRONT, NQ, Mode, grf_slice
    from hsddp_gym.core.references import end_of_mode_reference
    from hsddp_gym.core.schedule import ModeSchedule
    from hsddp_gym.planners.optimizer.problem import bounding_phase_cost

    for foot in (FRONT, BACK):
        for z_velocity in ("code", "paper"):
            ds = end_of_mode_reference(Mode.DOUBLE_STANCE, foot, 0.8, z_velocity=z_velocity)
            fl = end_of_mode_reference(Mode.FLIGHT, foot, 0.8, z_velocity=z_velocity)
            np.testing.assert_array_equal(ds[:NQ], fl[:NQ])
            assert ds[NQ] == 0.8 and ds[NQ + 1] == 0.0
    with pytest.raises(ValueError, match="touchdown_foot"):
        end_of_mode_reference(Mode.DOUBLE_STANCE, None)
    c = bounding_phase_cost(Mode.DOUBLE_STANCE, FRONT)
    weight = c.grf_ref[grf_slice(FRONT)][1]
    assert weight == pytest.approx(0.5 * bounding_phase_cost(Mode.FRONT_STANCE, None).grf_ref[grf_slice(FRONT)][1])
    np.testing.assert_allclose(c.grf_ref[grf_slice(BACK)], [0.0, weight])
    assert np.all(c.s > 0) and np.all(c.r == 1.0)
    np.testing.assert_allclose(c.qf[10:], [1, 1, 1, 1])
    # in a schedule the cost's foot is the one that stays on the ground after the double stance
    sched = ModeSchedule([Mode.BACK_STANCE, Mode.DOUBLE_STANCE, Mode.FRONT_STANCE, Mode.FLIGHT],
                         [0.02, 0.04, 0.07, 0.07], final_mode=Mode.BACK_STANCE)
    problem = HybridProblem.bounding(schedule=sched)
    np.testing.assert_array_equal(problem.XF[1], end_of_mode_reference(Mode.DOUBLE_STANCE, FRONT))
    assert list(problem.touchdown) == [FRONT, -1, -1, BACK]  # the front foot lands into the double stance
    with pytest.raises(ValueError, match="double stance must be followed by a single stance"):
        HybridProblem.bounding(schedule=ModeSchedule([Mode.DOUBLE_STANCE, Mode.FLIGHT], [0.04, 0.07],
                                                     final_mode=Mode.BACK_STANCE))
