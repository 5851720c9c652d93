"""Long bounding horizons: the warm start of more than five cycles stays finite and the plan meets the limits; a
diverging initial guess is reported with the cycle, knot and time where it diverged; the five-cycle warm start and
plan (the paper reproduction's) are unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.metrics import trajectory_summary
from hsddp_gym.planners.optimizer.problem import HybridProblem, first_non_finite_knot
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import (
    HEURISTIC_WARM_START_CYCLES,
    REPEATED_CYCLE,
    WarmStartDivergedError,
    bounding_warm_start,
    check_warm_start,
    heuristic_warm_start,
    plan_bounding,
)

ROOT = Path(__file__).resolve().parents[1]
KNOTS_PER_CYCLE = 296


# ----------------------------------------------------------------------------------------- the 10-cycle plan

@pytest.fixture(scope="module")
def ten_cycles():
    return plan_bounding(cycles=10)


def test_the_ten_cycle_warm_start_is_finite_and_bounds_at_about_the_desired_speed(ten_cycles):
    warm = ten_cycles.warm_start
    problem = ten_cycles.problem
    assert problem.n_knots == 10 * KNOTS_PER_CYCLE
    assert ten_cycles.summary["warm_start"] == "repeated plan"
    assert warm.is_finite and first_non_finite_knot(warm.X, warm.U) is None
    ps = problem.phase_start
    for c in range(10):  # every cycle a bound: trunk up, near 1 m/s, pitch small (the heuristic alone reaches 4 m/s)
        X = warm.X[ps[4 * c]:ps[4 * c + 4]]
        assert 0.8 <= X[:, 7].mean() <= 1.2, (c + 1, X[:, 7].mean())
        assert X[:, 1].min() >= 0.2 and np.abs(X[:, 2]).max() <= 0.4, c + 1


def test_the_ten_cycle_plan_meets_the_limits(ten_cycles):
    sol, problem = ten_cycles.solution, ten_cycles.problem
    assert sol.status == "converged" and np.all(np.isfinite(sol.X)) and sol.X.shape == (problem.n_knots + 1, 14)
    s = trajectory_summary(problem, sol.X, sol.X_pre, sol.U, sol.GRF)
    assert s["max_abs_torque"] <= problem.constraints.torque_limit + 1e-3 * problem.constraints.torque_limit
    assert s["min_normal_grf"] >= 0.0
    assert s["max_friction_violation"] <= 1e-6
    assert s["max_touchdown_error"] <= 1e-3 and s["switching_violation"] <= 1e-4
    assert abs(s["avg_forward_speed"] - 1.0) <= 0.1
    assert ten_cycles.summary["max_abs_torque"] == s["max_abs_torque"]


def test_the_long_warm_start_is_the_solved_five_cycle_plan_with_its_fourth_cycle_repeated():
    problem = HybridProblem.bounding(6)
    warm = bounding_warm_start(problem)
    N = problem.n_knots
    assert warm.source == "repeated plan" and warm.K.shape == (N, 4, 14)
    args = warm.solve_arguments()
    assert set(args) == {"U_init", "X_init", "K_init"} and args["X_init"].shape == (N + 1, 14)
    seed = warm.seed
    assert seed.X.shape[0] == HEURISTIC_WARM_START_CYCLES * KNOTS_PER_CYCLE + 1
    # the seed is the five-cycle task solved from the heuristic
    five = HybridProblem.bounding(HEURISTIC_WARM_START_CYCLES)
    ref = HSDDP(SolverOptions()).solve(five, heuristic_warm_start(five).U)
    assert np.array_equal(seed.U, ref.U) and np.array_equal(seed.X, ref.X)
    # cycles 1 .. REPEATED_CYCLE - 1 follow the seed, the later cycles repeat its gains
    r0 = (REPEATED_CYCLE - 1) * KNOTS_PER_CYCLE
    assert np.max(np.abs(warm.trajectory.X[:r0] - seed.X[:r0])) <= 1e-6
    assert np.array_equal(warm.K[r0 + KNOTS_PER_CYCLE + 7], seed.K[r0 + 7])
    assert not np.array_equal(warm.K[r0 + 7], warm.K[7])


# ----------------------------------------------------------------------------------------- up to five cycles

@pytest.mark.parametrize("cycles", [1, 2, HEURISTIC_WARM_START_CYCLES])
def test_up_to_five_cycles_the_warm_start_is_the_heuristic_unchanged(cycles):
    problem = HybridProblem.bounding(cycles)
    warm = bounding_warm_start(problem)
    assert warm.source == "heuristic" and warm.K is None and warm.seed is None
    assert set(warm.solve_arguments()) == {"U_init"}
    assert np.array_equal(warm.U, heuristic_warm_start(problem).U)


def test_the_five_cycle_plan_is_the_published_one_to_round_off():
    """The paper reproduction's al-reb row (results/paper/task1.json) comes from this call: the same iterations and
    the same objective and cost to the record's 8 significant digits (``SIGNIFICANT_DIGITS``; another CPU rounds the
    compiled kernels' arithmetic differently only in the last bits)."""
    published = json.loads((ROOT / "results/paper/task1.json").read_text())["data"]["methods"]["al-reb"]
    result = plan_bounding(cycles=5)
    assert result.summary["warm_start"] == "heuristic"
    assert result.summary["objective"] == pytest.approx(published["objective"], rel=1e-7, abs=0.0)
    assert result.summary["cost"] == pytest.approx(published["cost"], rel=1e-7, abs=0.0)
    assert result.summary["ddp_iterations"] == published["ddp_iterations"]


# ----------------------------------------------------------------------------------------- diverging guesses

def test_the_heuristic_alone_diverges_in_cycle_ten_and_says_so():
    problem = HybridProblem.bounding(10)
    with pytest.raises(WarmStartDivergedError, match=r"diverged in cycle 10: X\[\d+\] of 2961 states") as exc:
        heuristic_warm_start(problem)
    e = exc.value
    assert isinstance(e, RuntimeError) and e.cycle == 10
    assert 9 * KNOTS_PER_CYCLE <= e.knot < 10 * KNOTS_PER_CYCLE
    assert e.phase == problem.phase_of_knot[e.knot] and e.time == pytest.approx(e.knot * 1e-3)
    assert f"t = {e.time:.3f} s" in str(e) and "cycle 10 of 10" in str(e)
    traj = heuristic_warm_start(problem, check=False)  # the trajectory itself, NaN from that knot on
    assert first_non_finite_knot(traj.X, traj.U) == e.knot
    with pytest.raises(WarmStartDivergedError, match="cycle 10"):
        plan_bounding("heuristic", cycles=10)


def test_a_deliberately_diverging_guess_names_its_cycle_knot_and_time():
    problem = HybridProblem.bounding(3)
    traj = heuristic_warm_start(problem)
    k = 2 * KNOTS_PER_CYCLE - 5  # the last flight of cycle 2
    traj.X[k:] = np.nan
    with pytest.raises(WarmStartDivergedError, match=r"my guess diverged in cycle 2: X\[587\]") as exc:
        check_warm_start(problem, traj, "my guess")
    e = exc.value
    assert (e.cycle, e.knot, e.phase) == (2, k, 7) and e.time == pytest.approx(0.587)
    assert "phase 8 of 12 (flight)" in str(e)
    traj = heuristic_warm_start(problem)
    traj.U[10, 2] = np.inf  # a control, in cycle 1
    with pytest.raises(WarmStartDivergedError, match=r"cycle 1: X\[10\]"):
        check_warm_start(problem, traj)


def test_the_solver_names_where_a_diverged_guess_is_not_finite():
    problem = HybridProblem.bounding(2)
    U = heuristic_warm_start(problem).U.copy()
    U[300:] = np.nan
    solver = HSDDP(SolverOptions())
    with pytest.raises(ValueError, match=r"U_init\[300\] is not \(t = 0\.300 s, cycle 2 of 2, phase 5 of 8 "
                                         r"\(back stance\)\)"):
        solver.solve(problem, U)
    U[300:] = 1e8  # finite controls whose rollout blows up
    with pytest.raises(ValueError, match=r"diverging rollout: X\[3\d\d\] is not finite \(t = 0\.3\d\d s, "
                                         r"cycle 2 of 2, phase 5 of 8"):
        solver.solve(problem, U)


def test_the_plan_cli_reports_a_diverged_heuristic_in_one_line(tmp_path, capsys):
    from hsddp_gym.cli import main

    code = main(["plan", "--method", "heuristic", "--cycles", "10", "--out", str(tmp_path / "p"), "--no-plots",
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and err.startswith("error: the heuristic warm start diverged in cycle 10")
    assert "Traceback" not in err


# ----------------------------------------------------------------------------------------- the problem's helpers

def test_knot_descriptions_count_cycles_and_phases_from_one():
    problem = HybridProblem.bounding(2)
    N = problem.n_knots
    assert problem.cycle_length == 4
    assert problem.describe_knot(0) == "t = 0.000 s, cycle 1 of 2, phase 1 of 8 (back stance)"
    assert problem.describe_knot(80) == "t = 0.080 s, cycle 1 of 2, phase 2 of 8 (flight)"
    assert problem.describe_knot(N) == "t = 0.592 s, cycle 2 of 2, phase 8 of 8 (flight)"
    assert problem.knot_time(N) == pytest.approx(problem.schedule.total_time)
    assert problem.cycle_of_knot(KNOTS_PER_CYCLE) == 2
    with pytest.raises(ValueError, match="k must be at most"):
        problem.knot_time(N + 1)
    with pytest.raises(TypeError, match="k must be an integer"):
        problem.describe_knot(1.5)
    periodic = HybridProblem.bounding_periodic()
    assert periodic.cycle_length == 4 and "cycle 2 of 2" in periodic.describe_knot(periodic.n_knots)


def test_sub_problem_keeps_phases_costs_and_the_closing_switch():
    problem = HybridProblem.bounding(3)
    sub = problem.sub_problem(0, 8)
    assert sub.n_knots == 2 * KNOTS_PER_CYCLE and np.array_equal(sub.x0, problem.x0)
    assert sub.schedule.final_mode == problem.schedule.modes[8] and sub.touchdown[-1] == problem.touchdown[7]
    assert np.array_equal(sub.Qd, problem.Qd[:sub.n_knots]) and np.array_equal(sub.XF, problem.XF[:8])
    two = HybridProblem.bounding(2)
    assert np.array_equal(sub.XR, two.XR) and np.array_equal(sub.QF, two.QF) and sub.schedule == two.schedule
    x0 = problem.x0 + 0.01
    later = problem.sub_problem(4, 12, x0)
    assert np.array_equal(later.x0, x0) and later.n_phases == 8
    with pytest.raises(ValueError, match="x0 is required"):
        problem.sub_problem(4, 12)
    with pytest.raises(ValueError, match="start and stop"):
        problem.sub_problem(5, 5)
    with pytest.raises(ValueError, match="start and stop"):
        problem.sub_problem(0, 13)
    with pytest.raises(TypeError, match="start must be an integer"):
        problem.sub_problem(0.0, 4)


def test_bounding_warm_start_refuses_bad_arguments():
    with pytest.raises(TypeError, match="problem must be a HybridProblem"):
        bounding_warm_start("bounding")
    with pytest.raises(TypeError, match="options must be a SolverOptions"):
        bounding_warm_start(HybridProblem.bounding(1), {"method": "al"})


def test_the_demo_plans_a_long_horizon_beside_its_warm_start(tmp_path):
    """``hsddp-gym demo --cycles 10``: the demo draws the plan's own warm start (the repeated plan beyond five
    cycles), so it runs at any horizon the planner plans."""
    pytest.importorskip("matplotlib")
    from hsddp_gym.workflows import run_demo

    summary = run_demo(tmp_path / "demo", cycles=10, episodes=1, video=False, quiet=True, max_episode_steps=10)
    assert summary["warm_start"]["source"] == "repeated plan"
    assert summary["hsddp_plan"]["status"] == "converged" and summary["hsddp_plan"]["max_abs_torque"] <= 33.0
    assert summary["mpc_in_env"]["falls"] == 0
    assert all((tmp_path / "demo" / f).is_file() for f in summary["files"])
    assert json.loads((tmp_path / "demo" / "summary.json").read_text())["warm_start"]["source"] == "repeated plan"
