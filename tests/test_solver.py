"""HS-DDP Algorithm 1 on a one-cycle bounding problem (296 knots, ~0.1-0.5 s per solve): the line search
never accepts an increase, callbacks see every record (and the verbose printer prints them), the AL update
follows eq. 24, warm starts with states, gains and multipliers are used, the stop statuses, solves are
bit-for-bit deterministic, solutions round-trip through ``.npz`` without pickle, ``hsddp-gym plan`` writes
its summary keys, and options are validated."""

from __future__ import annotations

import dataclasses
import json
import math
import os

import numpy as np
import pytest

from hsddp_gym.core.rollout import rollout
from hsddp_gym.planners.optimizer.callbacks import VerbosePrinter
from hsddp_gym.planners.optimizer.hsddp import HSDDP, _Traj, rollout_policy, solve
from hsddp_gym.planners.optimizer.objective import ConstraintState, Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import LOG_FIELDS, IterationRecord, Solution, SolverOptions
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController

METHODS = ("ddp", "al", "al-reb")


def fresh_problem(**kwargs) -> HybridProblem:
    """A new problem (and so new Pinocchio ``Data``) for every solve that is compared bit for bit."""
    return HybridProblem.bounding(cycles=1, **kwargs)


@pytest.fixture(scope="module")
def warm_start() -> np.ndarray:
    problem = fresh_problem()
    ctrl = HeuristicBoundingController(problem.dynamics.robot).as_schedule_controller(problem.schedule)
    U = rollout(problem.dynamics, problem.schedule, problem.x0, controller=ctrl).U
    assert U.shape == (problem.n_knots, 4) and np.all(np.isfinite(U))
    U.setflags(write=False)
    return U


def _records_without_time(log):
    return [dataclasses.replace(r, wall_time=0.0) for r in log]


def _records_equal(a: list, b: list) -> bool:
    """Equal field by field (NaN == NaN), ignoring wall_time."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(_records_without_time(a), _records_without_time(b)):
        for f in LOG_FIELDS:
            x, y = getattr(ra, f), getattr(rb, f)
            if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
                continue
            if x != y:
                return False
    return True


def check_log(sol: Solution, opt: SolverOptions) -> int:
    """The invariants of the log; returns the number of accepted DDP steps."""
    log = sol.log
    assert log and log[0].event == "init" and log[0].al_iteration == 0 and log[0].ddp_iteration == 0
    n_ddp = 0
    for prev, r in zip(log, log[1:]):
        assert r.event in ("ddp", "al_update"), r.event
        if r.event == "ddp":
            n_ddp += 1
            assert r.al_iteration == prev.al_iteration
            assert r.ddp_iteration == prev.ddp_iteration + 1
            # the line search never accepts an increase: Armijo on the recorded (positive) expected decrease
            assert r.objective <= prev.objective, (prev, r)
            assert r.expected > 0.0
            assert prev.objective - r.objective >= opt.armijo * r.expected
            # an accepted step is one of 1, f, f^2, ... >= min_step
            assert opt.min_step <= r.step <= 1.0
            j = round(math.log(r.step) / math.log(opt.step_factor))
            assert r.step == pytest.approx(opt.step_factor ** j, rel=1e-12)
        else:
            # a new AL iteration: the objective changes (new multipliers / penalty / barrier parameters)
            assert r.al_iteration == prev.al_iteration + 1
            assert r.ddp_iteration == prev.ddp_iteration
            assert r.step == 0.0
    assert sol.ddp_iterations == n_ddp
    assert sol.al_iterations == 1 + sum(r.event == "al_update" for r in log)
    return n_ddp


# ----------------------------------------------------------------------------------------- line search


@pytest.mark.parametrize("method", METHODS)
def test_line_search_never_accepts_an_increase(method, warm_start):
    opt = SolverOptions(method=method, max_ddp_iterations=10, max_al_iterations=3)
    sol = HSDDP(opt).solve(fresh_problem(), warm_start)
    assert check_log(sol, opt) >= 3
    assert sol.status in ("converged", "al_iteration_limit")
    assert sol.log[-1].objective < sol.log[0].objective
    assert np.all(np.isfinite(sol.X)) and np.all(np.isfinite(sol.K))
    if method == "ddp":
        assert "al_update" not in {r.event for r in sol.log} and np.all(sol.multipliers == 0.0)
    else:
        assert any(r.event == "al_update" for r in sol.log)


def test_line_search_backtracks_and_still_never_accepts_an_increase(warm_start):
    """A demanding Armijo constant and a fast gait force step rejections: rejected trials leave no trace."""
    opt = SolverOptions(method="al-reb", armijo=0.5, max_ddp_iterations=15, max_al_iterations=3)
    sol = HSDDP(opt).solve(fresh_problem(speed=3.0), warm_start)
    check_log(sol, opt)
    steps = [r.step for r in sol.log if r.event == "ddp"]
    assert min(steps) < 1.0, "this problem was chosen to make the line search backtrack"
    assert sol.timings["line_search_trials"] > len(steps)


@pytest.mark.parametrize("failure", ["rollout", "cost"])
def test_non_finite_trials_are_failed_trials(failure, warm_start, monkeypatch):
    """Every full-step (eps = 1) line-search trial is made non-finite -- the rollout reports a non-finite
    state, or it "succeeds" with a NaN force (so the cost is NaN): the line search rejects them all and
    backtracks, and still never accepts an increase."""
    import hsddp_gym.planners.optimizer.hsddp as hsddp_module

    original = hsddp_module.rollout_policy
    spoiled = []

    def spoil_full_steps(problem, out, U_ref, X_ref=None, K=None, k_ff=None, eps=0.0, lam6=None, lin=None):
        ok = original(problem, out, U_ref, X_ref, K, k_ff, eps, lam6, lin)
        if K is None or eps != 1.0:
            return ok
        spoiled.append(eps)
        if failure == "rollout":
            out.X[problem.phase_start[1]:] = np.nan
            return False
        out.GRF[3, 1] = np.nan
        return ok

    monkeypatch.setattr(hsddp_module, "rollout_policy", spoil_full_steps)
    opt = SolverOptions(method="al-reb", max_al_iterations=2, max_ddp_iterations=5)
    sol = HSDDP(opt).solve(fresh_problem(), warm_start)
    assert check_log(sol, opt) >= 3 and spoiled
    assert max(r.step for r in sol.log if r.event == "ddp") <= opt.step_factor
    assert np.all(np.isfinite(sol.X)) and np.all(np.isfinite(sol.GRF)) and np.isfinite(sol.objective)


def test_a_warm_start_with_a_non_finite_objective_is_refused(warm_start, monkeypatch):
    """A warm start whose rollout is finite but whose barrier terms overflow (the back foot pulling the ground
    with 1e200 N in the back stance) is refused with a ValueError naming the warm start, not optimized from an
    infinite objective."""
    import warnings

    import hsddp_gym.planners.optimizer.hsddp as hsddp_module

    original = hsddp_module.rollout_policy

    def huge_force(problem, out, U_ref, X_ref=None, K=None, k_ff=None, eps=0.0, lam6=None, lin=None):
        ok = original(problem, out, U_ref, X_ref, K, k_ff, eps, lam6, lin)
        out.GRF[3, 3] = -1e200
        return ok

    monkeypatch.setattr(hsddp_module, "rollout_policy", huge_force)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the overflow on the way is expected, not printed
        with pytest.raises(ValueError, match="warm start .* non-finite objective"):
            HSDDP(SolverOptions(method="al-reb", max_ddp_iterations=2)).solve(fresh_problem(), warm_start)


def test_callbacks_see_every_record(warm_start):
    seen: list[IterationRecord] = []
    calls = []
    opt = SolverOptions(method="al", max_al_iterations=2, max_ddp_iterations=5)
    sol = HSDDP(opt, callbacks=[seen.append, lambda r: calls.append(r.event)]).solve(fresh_problem(), warm_start)
    assert len(sol.log) > 3
    assert len(seen) == len(sol.log) == len(calls)
    assert all(a is b for a, b in zip(seen, sol.log))
    assert calls == [r.event for r in sol.log]
    assert {"init", "ddp", "al_update"} <= set(calls)
    # the module-level solve passes callbacks too, and the in-memory log is filled without any
    seen2: list[IterationRecord] = []
    sol2 = solve(fresh_problem(), warm_start, opt, callbacks=[seen2.append])
    assert _records_equal(seen2, sol.log) and _records_equal(sol2.log, sol.log)
    assert _records_equal(HSDDP(opt).solve(fresh_problem(), warm_start).log, sol.log)


def test_verbose_printer_prints_every_record_and_the_default_is_silent(warm_start, capsys):
    opt = SolverOptions(method="al", max_al_iterations=2, max_ddp_iterations=4)
    quiet = HSDDP(opt).solve(fresh_problem(), warm_start)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert len(quiet.log) > 3  # the in-memory log runs without being asked
    sol = HSDDP(opt, verbose=True).solve(fresh_problem(), warm_start)
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == VerbosePrinter.HEADER
    assert len(lines) == 1 + len(sol.log)
    assert [line.split()[-1] for line in lines[1:]] == [r.event for r in sol.log]
    assert _records_equal(sol.log, quiet.log)  # printing changes nothing


# ----------------------------------------------------------------------------------------- warm starts


def test_warm_start_with_states_gains_and_multipliers(warm_start):
    """A re-solve from a converged solution (U, X, K, multipliers, sigma) starts on it; the multipliers and
    penalty given are the ones used; from a perturbed initial state the gains of the warm start reject the
    perturbation (the first rollout is ``u = U + K (x - X)``, eq. 8 with eps = 0)."""
    opt = SolverOptions(method="al", max_al_iterations=6)
    sol = HSDDP(opt).solve(fresh_problem(), warm_start)
    assert sol.converged and sol.sigma > opt.sigma0 and np.any(sol.multipliers != 0.0)
    again = HSDDP(opt).solve(fresh_problem(), sol.U, X_init=sol.X, K_init=sol.K, multipliers=sol.multipliers,
                             sigma=sol.sigma)
    assert again.log[0].objective == pytest.approx(sol.objective, rel=1e-9)
    assert again.converged and again.al_iterations == 1 and again.ddp_iterations <= 2
    np.testing.assert_array_equal(again.multipliers, sol.multipliers)
    assert again.sigma == sol.sigma
    # the initial objective is eq. 23 with the multipliers and penalty passed in
    problem = fresh_problem()
    tr = _Traj(problem.n_knots, problem.n_phases)
    assert rollout_policy(problem, tr, sol.U, sol.X, sol.K)
    for lam, sigma in ((sol.multipliers, sol.sigma), (np.zeros(problem.n_phases), opt.sigma0)):
        one = SolverOptions(method="al", max_al_iterations=1, max_ddp_iterations=1)
        r = HSDDP(one).solve(fresh_problem(), sol.U, X_init=sol.X, K_init=sol.K, multipliers=lam, sigma=sigma)
        cs = ConstraintState(sigma=sigma, lam=lam, use_al=True, use_reb=False, delta_torque=one.delta_torque0,
                             delta_grf=one.delta_grf0, eps_torque=one.eps_torque, eps_grf=one.eps_grf)
        assert r.log[0].objective == pytest.approx(Objective(problem).evaluate(tr.X, tr.X_pre, tr.U, tr.GRF,
                                                                               cs).total, rel=1e-12)
    # perturbed initial state (+0.2 m/s forward, +0.2 rad/s pitch rate): feedback warm start vs open loop
    x0 = sol.X[0].copy()
    x0[7] += 0.2
    x0[9] += 0.2
    one = SolverOptions(method="al", max_al_iterations=1, max_ddp_iterations=1)
    fb = HSDDP(one).solve(fresh_problem().with_x0(x0), sol.U, X_init=sol.X, K_init=sol.K,
                          multipliers=sol.multipliers, sigma=sol.sigma)
    ol = HSDDP(one).solve(fresh_problem().with_x0(x0), sol.U, multipliers=sol.multipliers, sigma=sol.sigma)
    assert fb.log[0].objective < 0.9 * ol.log[0].objective  # measured 437 vs 539


# ----------------------------------------------------------------------------------------- stop status


def test_stop_status_at_iteration_and_time_limits(warm_start):
    sol = HSDDP(SolverOptions(method="al", max_total_ddp_iterations=2)).solve(fresh_problem(), warm_start)
    assert (sol.status, sol.converged, sol.ddp_iterations) == ("iteration_limit", False, 2)
    sol = HSDDP(SolverOptions(method="al", time_limit=1e-9)).solve(fresh_problem(), warm_start)
    assert (sol.status, sol.converged, sol.ddp_iterations) == ("time_limit", False, 0)
    # the solution is the warm start's rollout, with gains from a backward pass along it
    np.testing.assert_array_equal(sol.U, warm_start)
    assert np.all(np.isfinite(sol.K)) and np.max(np.abs(sol.K)) > 0
    assert [r.event for r in sol.log] == ["init"]


# ----------------------------------------------------------------------------------------- AL update (eq. 24)


def test_al_update_follows_eq24(warm_start):
    """lam <- lam + sigma g (with the penalty before its growth), then sigma <- beta sigma, between AL
    iterations that end with sum g^2 > al_tolerance; only touchdown phases carry multipliers."""
    base = dict(method="al", max_ddp_iterations=10)
    opt1 = SolverOptions(max_al_iterations=1, **base)
    opt2 = SolverOptions(max_al_iterations=2, **base)
    s1 = HSDDP(opt1).solve(fresh_problem(), warm_start)
    s2 = HSDDP(opt2).solve(fresh_problem(), warm_start)
    problem = fresh_problem()
    touchdown = problem.touchdown >= 0
    assert touchdown.any() and (~touchdown).any()

    g0 = s1.switching  # g after the first AL iteration (same deterministic path in both solves)
    assert s1.switching_violation > opt1.al_tolerance and s1.status == "al_iteration_limit"
    np.testing.assert_array_equal(g0[~touchdown], 0.0)
    n0 = sum(r.al_iteration == 0 for r in s2.log)
    assert _records_equal(s2.log[:n0], s1.log)

    lam0 = np.full(problem.n_phases, opt1.lambda0)
    lam1 = lam0 + opt1.sigma0 * g0
    sigma1 = opt1.sigma0 * opt1.beta
    # the objective of the second AL iteration, at its start, is eq. 23 with (lam1, sigma1) on the first
    # iteration's trajectory
    (upd,) = [r for r in s2.log if r.event == "al_update"]
    assert upd.switching_violation == pytest.approx(float(np.sum(g0 ** 2)), rel=1e-14)
    obj = Objective(problem)

    def al_objective(lam, sigma):
        cs = ConstraintState(sigma=sigma, lam=lam, use_al=True, use_reb=False, delta_torque=opt1.delta_torque0,
                             delta_grf=opt1.delta_grf0, eps_torque=opt1.eps_torque, eps_grf=opt1.eps_grf)
        return obj.evaluate(s1.X, s1.X_pre, s1.U, s1.GRF, cs).total

    assert upd.objective == pytest.approx(al_objective(lam1, sigma1), rel=1e-13)
    # ... and not with the grown penalty in the multiplier update (Algorithm 1, line 9 read literally)
    alt = al_objective(lam0 + sigma1 * g0, sigma1)
    assert abs(alt - upd.objective) > 1e3 * 1e-13 * abs(upd.objective)

    # the returned multipliers / penalty are those of the last subproblem actually solved: no update is
    # applied after the last (unconverged) AL iteration
    np.testing.assert_array_equal(s1.multipliers, lam0)
    assert s1.sigma == opt1.sigma0
    np.testing.assert_allclose(s2.multipliers, lam1, rtol=1e-15, atol=0)
    assert s2.sigma == sigma1
    for s in (s1, s2):
        np.testing.assert_array_equal(s.multipliers[~touchdown], 0.0)
    assert np.all(s2.multipliers[touchdown] != 0.0)


def test_converged_solution_objective_matches_the_last_record(warm_start):
    sol = HSDDP(SolverOptions(method="al", max_al_iterations=6)).solve(fresh_problem(), warm_start)
    assert sol.converged and sol.status == "converged"
    assert sol.switching_violation <= sol.options.al_tolerance
    assert sol.objective == sol.log[-1].objective
    # after convergence the last backward pass leaves a small feed-forward
    assert np.max(np.abs(sol.k_ff)) < 0.1


def test_iteration_limited_solution_objective_and_gains_belong_to_the_solved_subproblem(warm_start):
    sol = HSDDP(SolverOptions(method="al", max_al_iterations=2)).solve(fresh_problem(), warm_start)
    assert sol.status == "al_iteration_limit"
    assert sol.objective == pytest.approx(sol.log[-1].objective, rel=1e-12)
    assert np.max(np.abs(sol.k_ff)) < 1.0


def _count_passes(solver: HSDDP, monkeypatch) -> dict:
    """Count ``solver``'s backward passes and the rollouts that linearize (``rollout_policy(..., lin=...)``)."""
    from hsddp_gym.planners.optimizer import hsddp as hsddp_module

    counts = {"backward": 0, "linearized_rollouts": 0}
    backward = solver._backward

    def counted_backward(*args, **kwargs):
        counts["backward"] += 1
        return backward(*args, **kwargs)

    rollout = hsddp_module.rollout_policy

    def counted_rollout(*args, **kwargs):
        counts["linearized_rollouts"] += int(kwargs.get("lin", args[8] if len(args) > 8 else None) is not None)
        return rollout(*args, **kwargs)

    monkeypatch.setattr(solver, "_backward", counted_backward)
    monkeypatch.setattr(hsddp_module, "rollout_policy", counted_rollout)
    return counts


@pytest.mark.parametrize("method", ["ddp", "al-reb"])
def test_step_gains_are_the_forward_pass_law_and_save_a_linearization_and_a_backward_pass(method, warm_start,
                                                                                          monkeypatch):
    """``refresh_gains=False`` (one DDP iteration, the MPC's re-plan): the same trajectory (to round-off: the
    step is rolled out without its linearization, and Pinocchio's ABA and its derivatives' accelerations differ in
    the last bits), one linearization and one backward pass instead of two each, and along the returned trajectory
    the law ``u = U + K (x - X)`` is the forward pass's ``U_0 + eps k_ff + K (x - X_0)`` around the warm start's
    rollout."""
    one = dict(method=method, max_al_iterations=2, max_ddp_iterations=1, max_total_ddp_iterations=1)
    results, counts = {}, {}
    for refresh in (True, False):
        solver = HSDDP(SolverOptions(**one, refresh_gains=refresh))
        c = _count_passes(solver, monkeypatch)
        results[refresh] = solver.solve(fresh_problem(), warm_start)
        counts[refresh] = dict(c)
        monkeypatch.undo()
    fresh, step = results[True], results[False]
    assert fresh.ddp_iterations == step.ddp_iterations == 1
    for name in ("X", "X_pre", "U", "GRF", "switching", "multipliers"):
        a, b = getattr(fresh, name), getattr(step, name)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * (1 + np.max(np.abs(a))), err_msg=name)
    assert fresh.objective == pytest.approx(step.objective, rel=1e-9) and fresh.status == step.status
    assert counts[True] == {"backward": 2, "linearized_rollouts": 2}
    assert counts[False] == {"backward": 1, "linearized_rollouts": 1}
    assert np.max(np.abs(fresh.K - step.K)) > 1e-6  # the gains differ: they belong to other trajectories
    # the forward pass's law, around the warm start's open-loop rollout X_0
    problem = fresh_problem()
    tr = _Traj(problem.n_knots, problem.n_phases)
    assert rollout_policy(problem, tr, warm_start)
    eps = step.log[-1].step
    N = problem.n_knots
    law = warm_start + eps * step.k_ff + np.einsum("nux,nx->nu", step.K, step.X[:N] - tr.X[:N])
    np.testing.assert_allclose(step.U, law, rtol=0, atol=1e-9 * (1 + np.max(np.abs(step.U))))
    # ... and so off the trajectory too: the MPC's tracker applies U + K (x - X) at a perturbed state
    dx = np.random.default_rng(0).normal(scale=1e-2, size=(N, 14))
    np.testing.assert_allclose(step.U + np.einsum("nux,nx->nu", step.K, dx),
                               law + np.einsum("nux,nx->nu", step.K, dx), rtol=0, atol=1e-9 * (1 + np.abs(law).max()))


def test_step_gains_leave_a_multi_iteration_solve_unchanged_but_for_its_gains(warm_start):
    """With several iterations the trajectory, log and statuses are those of the refreshed solve; the gains are
    the last step's backward pass (its ``k_ff`` was applied: with refreshing, the final ``k_ff`` is the next
    step's, small near convergence)."""
    opt = dict(method="al", max_al_iterations=3)
    fresh = HSDDP(SolverOptions(**opt)).solve(fresh_problem(), warm_start)
    step = HSDDP(SolverOptions(**opt, refresh_gains=False)).solve(fresh_problem(), warm_start)
    for name in ("X", "U", "multipliers"):
        np.testing.assert_array_equal(getattr(fresh, name), getattr(step, name), err_msg=name, strict=True)
    assert _records_equal(fresh.log, step.log)
    assert fresh.status == step.status and fresh.objective == step.objective
    assert np.max(np.abs(fresh.K - step.K)) > 0.0


def test_refresh_gains_must_be_a_bool():
    for bad in (1, "yes", None):
        with pytest.raises(TypeError, match="refresh_gains"):
            SolverOptions(refresh_gains=bad)


# ----------------------------------------------------------------------------------------- determinism


ARRAYS = ("X", "X_pre", "U", "GRF", "K", "k_ff", "modes", "phase_start", "switching", "multipliers", "V_x0",
          "V_xx0")


def assert_identical(a: Solution, b: Solution):
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name, strict=True)
    for name in ("sigma", "cost", "objective", "status", "converged", "al_iterations", "ddp_iterations", "dt"):
        assert getattr(a, name) == getattr(b, name), name
    assert _records_equal(a.log, b.log)
    assert a.timings["line_search_trials"] == b.timings["line_search_trials"]


@pytest.mark.parametrize("method", ["al", "al-reb"])
def test_identical_solves_are_bit_identical(method, warm_start):
    opt = SolverOptions(method=method, max_al_iterations=3, max_ddp_iterations=8)
    # fresh solver objects on fresh problems
    a = HSDDP(opt).solve(fresh_problem(), warm_start)
    b = HSDDP(opt).solve(fresh_problem(), warm_start)
    assert_identical(a, b)
    # fresh solver objects on one problem (its Pinocchio Data keeps the history of earlier solves)
    problem = fresh_problem()
    assert_identical(HSDDP(opt).solve(problem, warm_start), a)
    assert_identical(HSDDP(opt).solve(problem, warm_start), a)
    # one solver reused (its workspace keeps the previous solve's arrays)
    solver = HSDDP(opt)
    assert_identical(solver.solve(problem, warm_start), a)
    assert_identical(solver.solve(fresh_problem(), warm_start), a)


def test_a_reused_workspace_of_another_size_changes_nothing(warm_start):
    """One solver through problems of several sizes (its workspace grows once, then serves smaller problems with
    the stale arrays of larger ones behind its views) gives, bit for bit, a fresh solver's solutions."""
    opt = SolverOptions(max_al_iterations=2, max_ddp_iterations=4)

    def problem(scale):
        return HybridProblem.bounding(cycles=1, durations=scale * np.array([0.080, 0.072, 0.072, 0.072]))

    def controls(p):
        ctrl = HeuristicBoundingController(p.dynamics.robot).as_schedule_controller(p.schedule)
        return rollout(p.dynamics, p.schedule, p.x0, controller=ctrl).U

    solver = HSDDP(opt)
    capacities = []
    for scale in (0.75, 1.0, 1.2, 0.9, 0.75):  # 222, 296, 354, 267, 222 knots
        p = problem(scale)
        got = solver.solve(p, controls(p))
        capacities.append(solver._ws.knot_capacity)
        assert_identical(got, HSDDP(opt).solve(problem(scale), controls(p)))
    assert capacities[1] > capacities[0] and capacities[2:] == capacities[1:2] * 3  # grew once, then reused


# ----------------------------------------------------------------------------------------- persistence


@pytest.fixture(scope="module")
def al_solution(warm_start) -> Solution:
    return HSDDP(SolverOptions(method="al-reb", max_al_iterations=2, max_ddp_iterations=5)).solve(
        fresh_problem(), warm_start)


def test_save_load_round_trip_is_exact(al_solution, tmp_path):
    sol = al_solution
    path = tmp_path / "solution.npz"
    sol.save(path)
    loaded = Solution.load(path)
    for name in ARRAYS:
        x, y = getattr(sol, name), getattr(loaded, name)
        np.testing.assert_array_equal(y, x, err_msg=name, strict=True)
    for name in ("dt", "sigma", "cost", "objective", "status", "converged", "al_iterations", "ddp_iterations",
                 "solve_time", "timings", "options"):
        assert getattr(loaded, name) == getattr(sol, name), name
    assert loaded.schedule == sol.schedule
    assert _records_equal(loaded.log, sol.log)
    assert [r.wall_time for r in loaded.log] == [r.wall_time for r in sol.log]
    assert all(type(r.al_iteration) is int and type(r.ddp_iteration) is int for r in loaded.log)
    # the policy and log accessors of the loaded solution agree
    x = sol.X[7] + 1e-3
    np.testing.assert_array_equal(loaded.control(7, x), sol.control(7, x))
    np.testing.assert_array_equal(loaded.log_array("objective"), sol.log_array("objective"))


def test_load_of_a_foreign_or_garbage_file_says_what_it_is(al_solution, tmp_path):
    """A new user's mistakes: an npz of something else (it used to raise KeyError: 'meta'), a text file (it used
    to suggest allow_pickle), object arrays, a missing file."""
    foreign = tmp_path / "episode.npz"
    np.savez(foreign, states=np.zeros((3, 14)), actions=np.zeros((2, 4)))
    with pytest.raises(ValueError, match=r"not a Solution file .*lacks the arrays X, X_pre.*holds actions, states"):
        Solution.load(foreign)
    garbage = tmp_path / "notes.npz"
    garbage.write_text("not an archive")
    with pytest.raises(ValueError, match="not an .npz archive") as err:
        Solution.load(garbage)
    assert "allow_pickle" not in str(err.value)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, X=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match="nothing is ever unpickled") as err:
        Solution.load(pickled)
    assert "allow_pickle" not in str(err.value)
    with pytest.raises(FileNotFoundError, match="no Solution file"):
        Solution.load(tmp_path / "missing.npz")


def test_control_refuses_out_of_range_knots_and_non_finite_states(al_solution):
    sol = al_solution
    x = sol.X[0].copy()
    np.testing.assert_array_equal(sol.control(len(sol.U) - 1, sol.X[len(sol.U) - 1]), sol.U[-1])
    for k in (-1, len(sol.U)):
        with pytest.raises(ValueError, match=r"k must be a knot index in 0 \.\. "):
            sol.control(k, x)
    with pytest.raises(TypeError, match="k must be an integer"):
        sol.control(1.0, x)
    bad = x.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="x must be finite"):
        sol.control(0, bad)
    with pytest.raises(ValueError, match=r"x must have shape \(14,\)"):
        sol.control(0, x[:7])


def test_saved_file_needs_no_pickle_and_is_written_atomically(al_solution, tmp_path, monkeypatch):
    path = tmp_path / "out" / "sol.npz"  # the parent directory is created
    al_solution.save(path)
    al_solution.save(path)  # overwriting goes through a temporary file too
    assert sorted(os.listdir(path.parent)) == ["sol.npz"], "a temporary file was left behind"
    with np.load(path, allow_pickle=False) as data:
        names = set(data.files)
        for name in data.files:
            assert data[name].dtype != object, name
    assert set(ARRAYS) <= names and {"log", "log_events", "meta"} <= names
    before = path.read_bytes()
    # an object array is refused before anything is written
    bad = dataclasses.replace(al_solution, X=np.array([object()], dtype=object))
    with pytest.raises(TypeError):
        bad.save(tmp_path / "out" / "bad.npz")
    assert sorted(os.listdir(path.parent)) == ["sol.npz"]

    # a write that fails half-way leaves the previous file intact and no temporary file behind
    def half_write(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", half_write)
    with pytest.raises(OSError, match="disk full"):
        al_solution.save(path)
    monkeypatch.undo()
    assert sorted(os.listdir(path.parent)) == ["sol.npz"]
    assert path.read_bytes() == before
    np.testing.assert_array_equal(Solution.load(path).X, al_solution.X)


def test_load_never_unpickles(tmp_path):
    """A file holding a pickled object array is refused (np.load with allow_pickle=False), not executed."""
    path = tmp_path / "pickled.npz"
    np.savez(path, X=np.array([{"payload": 1}], dtype=object), meta=np.array("{}"))
    with pytest.raises(ValueError, match="nothing is ever unpickled"):
        Solution.load(path)


# ----------------------------------------------------------------------------------------- CLI summary

PLAN_SUMMARY_KEYS = {"al_iterations", "ddp_iterations", "switching_violation", "min_normal_grf",
                     "max_friction_violation", "max_abs_torque", "avg_forward_speed", "cost", "solve_time_s",
                     "time_per_ddp_iteration_s"}
"""The keys ``hsddp-gym plan`` adds to summary.json."""


@pytest.mark.parametrize("method", ["heuristic", "ddp", "al", "al-reb"])
def test_plan_cli_writes_the_summary_keys(method, tmp_path):
    """One cycle (the five-cycle numbers are in the paper-reproduction results): the keys, and for al-reb the
    switching, torque, normal-force and friction bounds (to small tolerances) on this small horizon."""
    from hsddp_gym.cli import main

    out = tmp_path / method
    assert main(["plan", "--method", method, "--cycles", "1", "--out", str(out), "--no-plots", "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert PLAN_SUMMARY_KEYS <= set(s), PLAN_SUMMARY_KEYS - set(s)
    assert s["method"] == method
    if method == "heuristic":
        assert (s["al_iterations"], s["ddp_iterations"], s["time_per_ddp_iteration_s"]) == (0, 0, None)
        return
    assert s["time_per_ddp_iteration_s"] == pytest.approx(s["solve_time_s"] / s["ddp_iterations"], rel=1e-12)
    loaded = Solution.load(out / "solution.npz")
    assert loaded.ddp_iterations == s["ddp_iterations"] and loaded.al_iterations == s["al_iterations"]
    if method == "al-reb":
        assert s["switching_violation"] <= 1e-4 and s["al_iterations"] <= 4
        assert s["max_abs_torque"] <= 33.033 and s["min_normal_grf"] >= -0.1
        assert s["max_friction_violation"] <= 0.1
        assert abs(s["avg_forward_speed"] - 1.0) <= 0.1


# ----------------------------------------------------------------------------------------- validation


@pytest.mark.parametrize("field,value", [
    ("method", "foo"), ("method", "AL"), ("beta", 1.0), ("beta", 0.5), ("beta", float("nan")),
    ("al_tolerance", -1e-4), ("al_tolerance", 0.0), ("ddp_tolerance", -1e-3), ("min_step", -0.1),
    ("mu_min", -1e-6), ("mu_max", 0.0), ("sigma0", -5.0), ("delta_torque0", -0.2), ("delta_grf0", 0.0),
    ("delta_min", -1e-3), ("eps_torque", -1e-5), ("eps_grf", float("nan")), ("eps_growth", 0.0),
    ("delta_factor", 0.0), ("delta_factor", 1.5), ("armijo", -0.1), ("armijo", 0.9), ("step_factor", 1.0),
    ("mu_growth", 1.0), ("time_limit", -1.0), ("max_al_iterations", 0), ("max_ddp_iterations", 0),
    ("max_total_ddp_iterations", 0), ("lambda0", float("inf")),
])
def test_bad_options_raise_value_error_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        SolverOptions(**{field: value})


def test_options_defaults_are_valid_and_method_flags():
    assert SolverOptions().method == "al-reb"
    assert (SolverOptions(method="ddp").use_al, SolverOptions(method="ddp").use_reb) == (False, False)
    assert (SolverOptions(method="al").use_al, SolverOptions(method="al").use_reb) == (True, False)
    assert (SolverOptions(method="al-reb").use_al, SolverOptions(method="al-reb").use_reb) == (True, True)
    with pytest.raises(TypeError, match="options"):
        HSDDP({"method": "al"})


def test_solve_rejects_bad_warm_starts(warm_start):
    problem = fresh_problem()
    solver = HSDDP(SolverOptions(method="ddp", max_ddp_iterations=1))
    N = problem.n_knots
    for U in (warm_start[:-1], warm_start[:, :3], warm_start.ravel(), warm_start[None]):
        with pytest.raises(ValueError, match="U_init"):
            solver.solve(problem, U)
    U_nan = np.array(warm_start)
    U_nan[3, 1] = np.nan
    with pytest.raises(ValueError, match="U_init"):
        solver.solve(problem, U_nan)
    with pytest.raises(ValueError, match="multipliers"):
        solver.solve(problem, warm_start, multipliers=np.zeros(problem.n_phases + 1))
    with pytest.raises(ValueError, match="K_init"):
        solver.solve(problem, warm_start, X_init=np.zeros((N + 1, 14)))
    with pytest.raises(ValueError, match="X_init"):
        solver.solve(problem, warm_start, X_init=np.zeros((N, 14)), K_init=np.zeros((N, 4, 14)))
