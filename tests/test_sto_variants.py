"""HS-DDP Algorithm 2 on the task-2 variants: the cost and reference variants (references, GRF term, terminal 1/2) and
the paper-closest one against the paper's reductions, the max |g| stop of Algorithm 1, and the periodic task (one
cycle that ends where it started). Most of its time goes to the 30-iteration STO runs of both methods, with the
authors' references and periodic."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.hsddp import HSDDP, _Traj, rollout_policy
from hsddp_gym.planners.optimizer.objective import Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import heuristic_warm_start


def test_cost_variants_build_the_paper_form():
    """terminal_half=False is the paper's eq. 33 (no 1/2): the same objective as doubled weights; grf_tracking
    False removes the force term; z_velocity='code' puts the authors' +-1 m/s in the phase-end references."""
    base = HybridProblem.bounding(1)
    paper = HybridProblem.bounding(1, grf_tracking=False, terminal_half=False, z_velocity="code")
    np.testing.assert_array_equal(paper.QF, 2.0 * base.QF)
    np.testing.assert_array_equal(paper.Sd, 0.0)
    assert np.all(base.Sd.max(axis=1)[base.stance_any] > 0)
    np.testing.assert_array_equal(paper.XF[:, 8], [1.0, -1.0, 1.0, -1.0])
    np.testing.assert_array_equal(base.XF[:, 8], 0.0)
    from hsddp_gym.planners.optimizer.metrics import task_cost

    tr = heuristic_warm_start(base)
    half_off = HybridProblem.bounding(1, terminal_half=False)
    run = Objective(base).evaluate(tr.X, tr.X_pre, tr.U, tr.GRF, _no_constraints(base))
    off = Objective(half_off).evaluate(tr.X, tr.X_pre, tr.U, tr.GRF, _no_constraints(base))
    assert off.running == run.running and off.terminal == pytest.approx(2.0 * run.terminal, rel=1e-14)
    assert task_cost(half_off, tr.X, tr.X_pre, tr.U, tr.GRF) == pytest.approx(run.running + 2 * run.terminal)
    for kwargs, name in (({"grf_tracking": 1}, "grf_tracking"), ({"terminal_half": "no"}, "terminal_half")):
        with pytest.raises(TypeError, match=name):
            HybridProblem.bounding(1, **kwargs)


def _no_constraints(problem):
    from hsddp_gym.planners.optimizer.objective import ConstraintState

    return ConstraintState(sigma=0.0, lam=np.zeros(problem.n_phases), use_al=False, use_reb=False, delta_torque=1.0,
                           delta_grf=1.0, eps_torque=0.0, eps_grf=0.0)


@pytest.fixture(scope="module")
def code_reference_runs() -> dict:
    """Both methods, 30 iterations, with the authors' vertical-velocity references (the paper-closest
    variant), ~10 s."""
    from hsddp_gym.planners.tasks import run_sto

    return {m: run_sto(m, iterations=30, z_velocity="code")[1] for m in ("hsddp", "open-loop")}


def test_paper_closest_variant_matches_the_paper(code_reference_runs):
    """With z_velocity='code' the same solver and weights come close to the paper (21.1 % vs 6.3 %): measured
    23.3 % vs 4.8 % (README). The issue's bar: HS-DDP >= 15 % and >= 2x the open-loop reduction."""
    hs, ol = code_reference_runs["hsddp"], code_reference_runs["open-loop"]
    print(f"\nz_velocity=code: HS-DDP {100 * hs['reduction']:.1f} %, open loop {100 * ol['reduction']:.1f} %")
    for s in (hs, ol):
        assert s["z_velocity"] == "code" and s["grf_tracking"] and s["terminal_half"] and not s["periodic"]
        assert s["switching_violation"] <= 1e-4
        assert s["max_touchdown_error"] == pytest.approx(max(abs(g) for g in s["touchdown_heights"]), rel=1e-15)
        assert s["switching_violation"] == pytest.approx(sum(g * g for g in s["touchdown_heights"]), rel=1e-9)
    assert hs["reduction"] >= 0.15 and hs["reduction"] >= 2.0 * ol["reduction"], (hs["reduction"], ol["reduction"])
    assert hs["reduction"] <= 0.30  # not the 52 % of the zero-velocity references


def test_max_touchdown_error_stop():
    """al_max_abs_tolerance: Algorithm 1 stops only once every landing foot is within it of the ground. On the
    paper-closest task-2 start (one cycle, z_velocity='code'), sum g^2 <= 1e-4 alone stops with a foot several
    mm off the ground; with 1 mm the solve needs another AL iteration and meets it."""
    problem = HybridProblem.bounding(1, z_velocity="code")
    U = heuristic_warm_start(problem).U
    loose = HSDDP(SolverOptions()).solve(problem, U)
    tight = HSDDP(SolverOptions(al_max_abs_tolerance=1e-3)).solve(problem, U)
    print(f"\nmax |g|: sum g^2 stop {1e3 * np.max(np.abs(loose.switching)):.2f} mm in {loose.al_iterations} AL "
          f"iterations, max |g| <= 1 mm stop {1e3 * np.max(np.abs(tight.switching)):.2f} mm in "
          f"{tight.al_iterations}")
    assert loose.converged and tight.converged
    assert np.max(np.abs(loose.switching)) > 1e-3  # the gap the option closes
    assert np.max(np.abs(tight.switching)) <= 1e-3 and tight.al_iterations > loose.al_iterations
    for bad in (0.0, -1e-3, float("nan")):
        with pytest.raises(ValueError, match="al_max_abs_tolerance"):
            SolverOptions(al_max_abs_tolerance=bad)


@pytest.fixture(scope="module")
def periodic_runs() -> dict:
    from hsddp_gym.planners.tasks import run_sto

    return {m: run_sto(m, iterations=30, periodic=True) for m in ("hsddp", "open-loop")}


def test_periodic_problem_structure():
    p = HybridProblem.bounding_periodic()
    assert p.n_phases == 5 and [int(m) for m in p.schedule.modes] == [int(m) for m in p.schedule.modes[:4]] + [
        int(p.schedule.modes[0])]
    np.testing.assert_array_equal(p.touchdown >= 0, [False, True, False, True, False])
    np.testing.assert_array_equal(p.XF[-1, 1:], p.x0[1:])
    assert p.QF[-1, 0] == 0.0 and np.all(p.QF[-1, 1:] > 0)
    with pytest.raises(ValueError, match="durations"):
        HybridProblem.bounding_periodic(durations=(0.08, 0.07, 0.07, 0.07))
    with pytest.raises(ValueError, match="periodic_weight"):
        HybridProblem.bounding_periodic(periodic_weight=-1.0)


def test_periodic_task_ends_where_it_started_and_repeats(periodic_runs):
    """The periodic STO result ends within a few mm / cm/s of its start state (up to x), and applying its
    controls again from its end state repeats the cycle: the second cycle's states stay close to the first's."""
    for method, (res, s) in periodic_runs.items():
        assert s["periodic"] and len(s["mode_durations"]) == 5 and s["switching_violation"] <= 1e-4
        assert s["total_time"] < s["initial_total_time"], method
        assert s["max_periodicity_error_position"] <= 0.01 and s["max_periodicity_error_velocity"] <= 0.05, s
        # a sustainable gait: the vertical velocity returns and the mean normal force is near the weight
        assert abs(s["final_vertical_velocity"] - s["initial_vertical_velocity"]) <= 0.05
        assert abs(s["mean_normal_grf"] - s["weight"]) <= 0.1 * s["weight"]
        sol = res.solution
        problem = HybridProblem.bounding_periodic().with_durations(res.durations[-1])
        x1 = sol.X[-1].copy()
        x1[0] = problem.x0[0]
        again = _Traj(problem.n_knots, problem.n_phases)
        assert rollout_policy(problem.with_x0(x1), again, sol.U, sol.X, sol.K)
        dev = np.max(np.abs(again.X[:, 1:] - sol.X[:, 1:]), axis=0)
        print(f"\n{method}: second cycle's largest deviation, positions {dev[:6].max():.2e}, velocities "
              f"{dev[6:].max():.2e}")
        assert dev[:6].max() <= 0.02, dev
    hs, ol = periodic_runs["hsddp"][1], periodic_runs["open-loop"][1]
    assert hs["reduction"] > ol["reduction"]


def test_task_2_variant_arguments_are_validated():
    from hsddp_gym.planners.optimizer.metrics import trajectory_summary
    from hsddp_gym.planners.tasks import sto_problem

    with pytest.raises(ValueError, match="z_velocity"):
        sto_problem(z_velocity="zero")
    with pytest.raises(ValueError, match="cycles"):
        sto_problem(cycles=2, periodic=True)
    for name in ("grf_tracking", "terminal_half", "periodic"):
        with pytest.raises(TypeError, match=name):
            sto_problem(**{name: "on"})
    # the plan summaries carry max |g| too
    problem = HybridProblem.bounding(1)
    warm = heuristic_warm_start(problem)
    s = trajectory_summary(problem, warm.X, warm.X_pre, warm.U, warm.GRF)
    assert s["max_touchdown_error"] == max(abs(g) for g in s["touchdown_foot_heights"]) > 0
