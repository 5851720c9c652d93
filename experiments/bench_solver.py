"""Benchmark HS-DDP Algorithm 1 on the paper's 1480-knot problem: where the time of a solve goes.

The problem is paper task 1 (``HybridProblem.bounding(5)``: 5 bounding cycles of 80/72/72/72 ms at
h = 1 ms, 1480 knots, 19 resets; ``--cycles N`` for N cycles, 296 knots each), warm-started by
``bounding_warm_start`` (the heuristic controller up to 5 cycles; beyond, the solved 5-cycle plan with its
4th cycle repeated, not timed) and solved with al-reb.
Before timing, one small solve (one cycle) warms numba's JIT (compile or cache load of the backward
pass), so compile time is excluded. The solve is then repeated ``--repeats`` times with fresh solvers;
the best and the median are reported, with a breakdown per DDP iteration of the best run:

* dynamics derivatives: the solver's separate linearization passes (``timings["linearize"]``) plus the
  reset-map Jacobians (``timings["reset_jacobians"]``). The solver also linearizes *inside* the first
  (full-step) line-search rollout of every DDP iteration and inside the warm-start rollout (speculative,
  kept when the full step is accepted); that part is counted under the line search and estimated
  separately from the instrumented rollouts (mean time with linearization minus mean time without);
* cost derivatives (``timings["cost_derivatives"]``); backward pass (``timings["backward"]``, all
  attempts including regularization retries); line search (``timings["line_search"]``) per trial;
* the rest of the solve (warm-start rollout, objective evaluations outside the line search, logging).

Goals: <= 50 ms per DDP iteration and the whole al-reb solve <= 5 s; ratios measured/goal are printed.
Optionally an MPC-like warm re-solve (from the previous solution, few DDP iterations) and a cProfile
of one solve (``--profile``, top 10 functions by cumulative time).

``--horizons 1 5 10 20`` instead times the solve against the horizon: for each number of cycles, the warm start
(timed apart) and ``--repeats`` solves; it prints the time per DDP iteration, per knot, the iterations, the
constraints' worst values and the solve time, and fits the time per DDP iteration to the knots (the solver's
work per iteration is linear in the knots).

Usage::

    python experiments/bench_solver.py [--repeats 3] [--cycles 5] [--profile] [--mpc-iterations 3]
    python experiments/bench_solver.py --horizons 1 5 10 20 [--repeats 3] [--record FILE.json]
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import io
import os
import platform
import pstats
import statistics
import time

import numpy as np
import pinocchio as pin

import hsddp_gym.planners.optimizer.hsddp as hsddp_module
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.metrics import trajectory_summary
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.tasks import bounding_warm_start, heuristic_warm_start
from hsddp_gym.reports.store import machine_info, write_record

GOAL_MS_PER_DDP_ITERATION = 50.0
GOAL_SOLVE_S = 5.0


class RolloutMeter:
    """Wraps ``hsddp_gym.planners.optimizer.hsddp.rollout_policy`` (the solver looks it up at call time) to time every
    rollout, split into plain rollouts and rollouts that also linearize (``lin`` given)."""

    def __init__(self) -> None:
        self.original = hsddp_module.rollout_policy
        self.reset()

    def reset(self) -> None:
        self.plain: list[float] = []
        self.with_lin: list[float] = []

    def __enter__(self) -> RolloutMeter:
        original = self.original

        def timed(*args, **kwargs):
            lin = kwargs.get("lin", args[8] if len(args) > 8 else None)
            t = time.perf_counter()
            out = original(*args, **kwargs)
            (self.plain if lin is None else self.with_lin).append(time.perf_counter() - t)
            return out

        hsddp_module.rollout_policy = timed
        return self

    def __exit__(self, *exc) -> None:
        hsddp_module.rollout_policy = self.original


@dataclasses.dataclass
class Run:
    solve_s: float
    ddp_iterations: int
    al_iterations: int
    status: str
    objective: float
    timings: dict
    n_linearize: int
    n_dyn_linearize: int
    n_backward: int
    rollouts_plain: list
    rollouts_lin: list


def timed_solve(problem: HybridProblem, U: np.ndarray, options: SolverOptions, meter: RolloutMeter,
                **solve_kwargs) -> tuple[Run, HSDDP, object]:
    """One solve with a fresh solver; counts the solver's linearization and backward-pass calls."""
    solver = HSDDP(options)
    counts = {"linearize": 0, "backward": 0, "dyn_linearize": 0}
    lin_method, back_method = solver._linearize, solver._backward
    dyn = problem.dynamics
    dyn_linearize = type(dyn).linearize

    def dyn_lin(*a, **k):
        counts["dyn_linearize"] += 1
        return dyn_linearize(dyn, *a, **k)

    def linearize(*a, **k):
        counts["linearize"] += 1
        return lin_method(*a, **k)

    def backward(*a, **k):
        counts["backward"] += 1
        return back_method(*a, **k)

    solver._linearize, solver._backward = linearize, backward  # instance attributes shadow the methods
    dyn.linearize = dyn_lin
    meter.reset()
    try:
        t = time.perf_counter()
        sol = solver.solve(problem, U, **solve_kwargs)
        elapsed = time.perf_counter() - t
    finally:
        del dyn.linearize
    run = Run(elapsed, sol.ddp_iterations, sol.al_iterations, sol.status, sol.objective, dict(sol.timings),
              counts["linearize"], counts["dyn_linearize"], counts["backward"], list(meter.plain),
              list(meter.with_lin))
    return run, solver, sol


def calibrate(problem: HybridProblem, sol, cs, repeat: int = 5) -> dict:
    """Best-of-``repeat`` times [s] of the pieces of a line-search trial around the solved trajectory (the
    feedback policy with ``eps = 1``): a plain rollout, a rollout with fused linearization, a separate
    linearization pass, an objective evaluation. Measured outside the solve (warm caches): a lower bound."""
    from hsddp_gym.core.dynamics import Linearization
    from hsddp_gym.planners.optimizer.hsddp import _Traj
    from hsddp_gym.planners.optimizer.objective import Objective

    rollout = hsddp_module.rollout_policy
    tr = _Traj(problem.n_knots, problem.n_phases)
    lin = Linearization(problem.n_knots)
    obj = Objective(problem)
    policy = (sol.U, sol.X, sol.K, sol.k_ff, 1.0)  # a full-step line-search trial around the solution

    def best(fn):
        out = []
        for _ in range(repeat):
            t = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t)
        return min(out)

    return {
        "rollout": best(lambda: rollout(problem, tr, *policy)),
        "rollout_lin": best(lambda: rollout(problem, tr, *policy, lin=lin)),
        "linearize": best(lambda: problem.dynamics.linearize(sol.X, sol.U, problem.modes, lin, problem.h)),
        "evaluate": best(lambda: obj.evaluate(sol.X, sol.X_pre, sol.U, sol.GRF, cs)),
    }


def breakdown(run: Run, n_knots: int, cal: dict, n_resets: int = 19) -> list[dict]:
    """Print the per-DDP-iteration table of one run (``cal``: :func:`calibrate`; ``n_resets`` switches of the
    problem); returns its rows (``name``, ``total_ms``, ``ms_per_iteration``)."""
    table = []
    tm = run.timings
    it = max(run.ddp_iterations, 1)
    trials = int(tm.get("line_search_trials", 0))
    lin_sep = tm.get("linearize", 0.0)
    resets = tm.get("reset_jacobians", 0.0)
    cost = tm.get("cost_derivatives", 0.0)
    back = tm.get("backward", 0.0)
    ls = tm.get("line_search", 0.0)
    plain, withlin = run.rollouts_plain, run.rollouts_lin
    # the first rollout of a solve is the warm start (outside the line search); with the speculative
    # linearization it is a rollout with ``lin``, and so is the full-step trial of every DDP iteration
    warm = withlin[0] if withlin else (plain[0] if plain else 0.0)
    n_spec = max(len(withlin) - 1, 0)
    fused_each = max(cal["rollout_lin"] - cal["rollout"], 0.0)
    other = run.solve_s - (lin_sep + resets + cost + back + ls + warm)

    def row(name, total_s, calls=None, note="", knots=True):
        ms_it = 1e3 * total_s / it
        table.append({"name": name.strip(), "total_ms": 1e3 * total_s, "ms_per_iteration": ms_it})
        extra = " " * 34
        if calls == 0:
            extra = f"{0:5d} calls" + " " * 23
        elif calls:
            extra = f"{calls:5d} x {1e3 * total_s / calls:7.2f} ms"
            extra += f" = {1e6 * total_s / calls / n_knots:6.2f} us/knot" if knots else " " * 17
        print(f"  {name:<46}{1e3 * total_s:8.1f} ms {ms_it:7.2f} ms/it  {extra} {note}".rstrip())

    print(f"  {'per solve / per DDP iteration':<46}{'total':>11} {'per DDP it':>12}  calls x per call = per knot")
    row("dynamics derivatives, separate passes", lin_sep, run.n_dyn_linearize, "timings['linearize']")
    row(f"reset-map Jacobians ({n_resets} per linearization)", resets, run.n_linearize, "timings['reset_jacobians']",
        knots=False)
    row("  = linearize + reset_jacobians", lin_sep + resets)
    row("cost derivatives", cost, run.n_linearize, "(per linearization)")
    row("backward pass", back, run.n_backward, "(incl. regularization retries)")
    row("line search", ls, trials, "(per trial)")
    row("  rollouts with fused linearization (eps = 1)", float(np.sum(withlin[1:])), n_spec)
    row("  rollouts without (eps < 1)", float(np.sum(plain)), len(plain))
    row("  ~ of which fused dynamics derivatives", fused_each * n_spec, n_spec, "(calibrated, see below)")
    row("warm-start rollout" + (" + linearization" if withlin else ""), warm, 1)
    row("other (objective values, AL updates, logging)", other)
    row("TOTAL", run.solve_s, run.ddp_iterations, "(per DDP iteration)")
    derivs = lin_sep + resets + fused_each * len(withlin)
    print(f"  all dynamics derivatives (separate + fused, incl. warm start): ~{1e3 * derivs:.0f} ms = "
          f"{1e3 * derivs / it:.1f} ms per DDP iteration; {run.n_linearize} linearizations "
          f"({run.n_dyn_linearize} separate passes) for {run.ddp_iterations} DDP iterations")
    print(f"  calibration around the solution (outside the solve, best of 5): policy rollout "
          f"{1e3 * cal['rollout']:.1f} ms ({1e6 * cal['rollout'] / n_knots:.1f} us/knot), rollout + linearization "
          f"{1e3 * cal['rollout_lin']:.1f} ms ({1e6 * cal['rollout_lin'] / n_knots:.1f} us/knot), separate "
          f"linearize pass {1e3 * cal['linearize']:.1f} ms ({1e6 * cal['linearize'] / n_knots:.1f} us/knot), "
          f"objective evaluation {1e3 * cal['evaluate']:.2f} ms")
    return table


def horizon_study(cycles_list: list[int], options: SolverOptions, repeats: int) -> dict:
    """Time the solve for each number of cycles of ``cycles_list`` (best of ``repeats`` fresh solvers; the warm
    start timed apart); print one row each and a least-squares fit of the time per DDP iteration to the knots.

    Returns the record's data: ``rows`` (one dict per horizon) and ``fit`` (``us_per_knot``, ``intercept_ms``)."""
    rows = []
    print(f"{'cycles':>6} {'knots':>6} {'warm start':>11} {'DDP it':>6} {'AL it':>5} {'solve s':>8} {'ms/it':>7} "
          f"{'us/knot':>7} {'max|u|':>7} {'min fz':>7} {'max fric':>8} {'max|g| m':>9}  status")
    for cycles in cycles_list:
        problem = HybridProblem.bounding(cycles)
        t = time.perf_counter()
        guess = bounding_warm_start(problem, options)
        warm_s = time.perf_counter() - t
        runs = []
        for _ in range(repeats):
            solver = HSDDP(options)
            t = time.perf_counter()
            sol = solver.solve(problem, **guess.solve_arguments())
            runs.append((time.perf_counter() - t, sol))
        per_it = [1e3 * el / max(so.ddp_iterations, 1) for el, so in runs]
        best_s, sol = min(runs, key=lambda r: r[0])
        summ = trajectory_summary(problem, sol.X, sol.X_pre, sol.U, sol.GRF)
        row = {"cycles": cycles, "knots": problem.n_knots, "warm_start": guess.source, "warm_start_s": warm_s,
               "ddp_iterations": sol.ddp_iterations, "al_iterations": sol.al_iterations, "status": sol.status,
               "solve_s": {"best": best_s, "median": statistics.median(el for el, _ in runs)},
               "ms_per_ddp_iteration": {"best": min(per_it), "median": statistics.median(per_it)},
               "us_per_knot": 1e3 * min(per_it) / problem.n_knots,
               "max_abs_torque": summ["max_abs_torque"], "torque_limit": problem.constraints.torque_limit,
               "min_normal_grf": summ["min_normal_grf"], "max_friction_violation": summ["max_friction_violation"],
               "max_touchdown_error": summ["max_touchdown_error"], "avg_forward_speed": summ["avg_forward_speed"]}
        rows.append(row)
        print(f"{cycles:>6} {problem.n_knots:>6} {warm_s:>9.2f} s {sol.ddp_iterations:>6} {sol.al_iterations:>5} "
              f"{best_s:>8.3f} {row['ms_per_ddp_iteration']['best']:>7.2f} {row['us_per_knot']:>7.2f} "
              f"{row['max_abs_torque']:>7.2f} {row['min_normal_grf']:>7.1f} {row['max_friction_violation']:>8.3f} "
              f"{row['max_touchdown_error']:>9.2e}  {sol.status} ({guess.source} warm start)")
    knots = np.array([r["knots"] for r in rows], dtype=float)
    ms = np.array([r["ms_per_ddp_iteration"]["best"] for r in rows])
    fit = None
    if len(rows) >= 2 and np.ptp(knots) > 0:
        slope, intercept = np.polyfit(knots, ms, 1)
        fit = {"us_per_knot": 1e3 * float(slope), "intercept_ms": float(intercept)}
        print(f"least-squares fit: time per DDP iteration = {fit['intercept_ms']:.2f} ms + "
              f"{fit['us_per_knot']:.2f} us x knots")
    return {"method": options.method, "repeats": repeats, "rows": rows, "fit": fit}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     epilog=__doc__.split("\n\n", 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="timed solves; best and median reported "
                                                               "(default %(default)s)")
    parser.add_argument("--cycles", type=int, default=5, help="bounding cycles (default %(default)s: the paper's "
                                                             "1480-knot problem)")
    parser.add_argument("--method", choices=("ddp", "al", "al-reb"), default="al-reb",
                        help="Algorithm 1 variant (default %(default)s)")
    parser.add_argument("--mpc-iterations", type=int, default=3,
                        help="max_total_ddp_iterations of the MPC-like warm re-solve; 0 skips it (default %(default)s)")
    parser.add_argument("--profile", action="store_true", help="cProfile one extra solve; print the top 10 "
                                                                "functions by cumulative time")
    parser.add_argument("--horizons", type=int, nargs="+", default=None, metavar="CYCLES",
                        help="time the solve for each of these numbers of cycles instead (e.g. 1 5 10 20): time per "
                             "DDP iteration and per knot, iterations, constraints, solve time")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the measurements as a record of the results store (results/speed/solver.json;"
                             " with --horizons results/speed/solver_horizons.json)")
    args = parser.parse_args(argv)
    machine = machine_info()
    if args.repeats < 1 or args.cycles < 1 or args.mpc_iterations < 0:
        parser.error("--repeats and --cycles must be >= 1, --mpc-iterations >= 0")
    if args.horizons is not None and min(args.horizons) < 1:
        parser.error(f"--horizons: every number of cycles must be >= 1, got {args.horizons}")

    options = SolverOptions(method=args.method)
    print(f"HS-DDP solver benchmark -- Python {platform.python_version()}, numpy {np.__version__}, "
          f"Pinocchio {pin.__version__}, {os.cpu_count()} CPUs, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")

    # warm numba's JIT (and Pinocchio's first-call allocations) on a small problem: excluded from the timings
    small = HybridProblem.bounding(1)
    t = time.perf_counter()
    HSDDP(options).solve(small, heuristic_warm_start(small).U)
    print(f"JIT warm-up: one {small.n_knots}-knot solve took {time.perf_counter() - t:.2f} s "
          "(numba compile / cache load; excluded from everything below)")

    if args.horizons is not None:
        print(f"time per DDP iteration against the horizon, method {args.method}, best of {args.repeats} solves:")
        data = horizon_study(args.horizons, options, args.repeats)
        if args.record:
            write_record(args.record, data, "HS-DDP's time per DDP iteration, iterations and constraints against "
                         f"the horizon ({min(args.horizons)} to {max(args.horizons)} bounding cycles)", machine=machine)
            print(f"wrote {args.record}")
        return 0

    problem = HybridProblem.bounding(args.cycles)
    t = time.perf_counter()
    warm = bounding_warm_start(problem, options)
    t_warm = time.perf_counter() - t
    warm_kwargs = {k: v for k, v in warm.solve_arguments().items() if k != "U_init"}
    n = problem.n_knots
    print(f"problem: {args.cycles} bounding cycles, {n} knots, {problem.n_phases} phases "
          f"({problem.n_phases - 1} resets), method {args.method}; {warm.source} warm start {1e3 * t_warm:.0f} ms "
          "(not timed below)\n")

    runs = []
    with RolloutMeter() as meter:
        for r in range(args.repeats):
            run, solver, sol = timed_solve(problem, warm.U, options, meter, **warm_kwargs)
            runs.append(run)
            print(f"repeat {r + 1}: {run.solve_s:.3f} s, {run.ddp_iterations} DDP iterations, "
                  f"{run.al_iterations} AL iterations, {1e3 * run.solve_s / max(run.ddp_iterations, 1):.1f} ms per "
                  f"DDP iteration, status {run.status}, objective {run.objective:.6g}")
    times = [r.solve_s for r in runs]
    per_it = [1e3 * r.solve_s / max(r.ddp_iterations, 1) for r in runs]
    best = runs[int(np.argmin(times))]
    if len({r.ddp_iterations for r in runs}) != 1 or len({r.objective for r in runs}) != 1:
        print("WARNING: repeats differ in iterations or objective (the solver should be deterministic)")

    print(f"\nbreakdown of the best run ({best.solve_s:.3f} s, {best.ddp_iterations} DDP iterations):")
    table = breakdown(best, n, calibrate(problem, sol, solver.last_constraint_state), problem.n_phases - 1)

    best_s, med_s = min(times), statistics.median(times)
    best_it, med_it = min(per_it), statistics.median(per_it)
    print(f"\nsolve time:           best {best_s:.3f} s, median {med_s:.3f} s  over {args.repeats} repeats; "
          f"{best.ddp_iterations} DDP iterations")
    print(f"time per DDP iteration: best {best_it:.1f} ms, median {med_it:.1f} ms "
          f"({1e3 * best_it / n:.1f} us per knot per iteration, best)")
    print(f"goal: <= {GOAL_MS_PER_DDP_ITERATION:.0f} ms per DDP iteration -> measured/goal = "
          f"{best_it / GOAL_MS_PER_DDP_ITERATION:.2f} (best), {med_it / GOAL_MS_PER_DDP_ITERATION:.2f} (median)")
    print(f"goal: whole {args.method} solve <= {GOAL_SOLVE_S:.0f} s -> measured/goal = "
          f"{best_s / GOAL_SOLVE_S:.2f} (best), {med_s / GOAL_SOLVE_S:.2f} (median)")

    record = {"cycles": args.cycles, "knots": n, "method": args.method, "repeats": args.repeats,
              "ddp_iterations": best.ddp_iterations, "al_iterations": best.al_iterations,
              "solve_s": {"best": best_s, "median": med_s}, "ms_per_ddp_iteration": {"best": best_it, "median": med_it},
              "breakdown": table, "goal_ms_per_ddp_iteration": GOAL_MS_PER_DDP_ITERATION, "goal_solve_s": GOAL_SOLVE_S,
              "mpc_resolves": []}
    if args.mpc_iterations > 0:
        mpc_opts = dataclasses.replace(options, max_total_ddp_iterations=args.mpc_iterations)
        cs = solver.last_constraint_state
        print(f"\nMPC-like warm re-solves (max_total_ddp_iterations={args.mpc_iterations}, continuing the outer-loop "
              "state of the last solve; best of the repeats):")
        cases = {
            "same x0, U of the previous solution": (problem, dict()),
            "x0 perturbed (+0.05 m/s forward, +1 cm height), feedback warm start U + K (x - X)": (
                problem.with_x0(problem.x0 + np.eye(problem.x0.size)[7] * 0.05 + np.eye(problem.x0.size)[1] * 0.01),
                dict(X_init=sol.X, K_init=sol.K)),
        }
        with RolloutMeter() as meter:
            for name, (pr, kw) in cases.items():
                rs = [timed_solve(pr, sol.U, mpc_opts, meter, constraint_state=cs, **kw)[0]
                      for _ in range(args.repeats)]
                rb = min(rs, key=lambda r: r.solve_s)
                print(f"  {name}: {1e3 * rb.solve_s:.1f} ms, {rb.ddp_iterations} DDP iterations, status {rb.status}, "
                      f"objective {rb.objective:.6g} (previous {sol.objective:.6g})")
                record["mpc_resolves"].append({"case": name, "ms": 1e3 * rb.solve_s,
                                               "ddp_iterations": rb.ddp_iterations})
    if args.record:
        horizon = "five-cycle" if args.cycles == 5 else f"{args.cycles}-cycle"
        write_record(args.record, record, "HS-DDP's time per DDP iteration and its breakdown on the paper's "
                     f"{horizon} bounding problem", machine=machine)
        print(f"wrote {args.record}")

    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        psol = HSDDP(options).solve(problem, **warm.solve_arguments())
        prof.disable()
        s = io.StringIO()
        pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(10)
        print(f"\ncProfile of one solve ({psol.ddp_iterations} DDP iterations; profiling overhead inflates the "
              "times), top 10 by cumulative time:")
        lines = s.getvalue().strip().splitlines()
        start = next((i for i, line in enumerate(lines) if line.lstrip().startswith("ncalls")), 0)
        print("\n".join(lines[start:]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
