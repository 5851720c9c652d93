"""Speed of the HS-DDP MPC in hsddp_gym/Bounding-v0: re-plan wall time and real-time factor.

Usage: python experiments/bench_mpc.py [--seconds 3] [--replan-period 0.02] [--planner-dt 0.005]
       [--max-iterations 3] [--horizon 0.296] [--target-speed 1.0] [--mpc-options '{"restart_ratio": null}']
Real-time factor = simulated time / wall time of the whole closed loop (env simulation + policy).
Target: a real-time factor of at least 2 on a 2-core machine. Run it on a quiet machine: it is single-threaded.

The Pinocchio reference, measured in the same run: the wall time of one pass of Pinocchio's dynamics derivatives over
the last plan's knots (``constraintDynamics`` + ``computeConstraintDynamicsDerivatives`` at stance knots,
``computeABADerivatives`` in flight), per DDP iteration (the mean iterations per re-plan), on the plan's own states
and controls: what the re-plan's derivatives cost when they were Pinocchio's calls (a re-plan makes two such passes:
the warm start's rollout and the step's). The same pass of the compiled dynamics
(:func:`hsddp_gym.core.planar_dynamics.linearize_knots`, the numbers to rounding) is printed beside it; the ratio
re-plan / reference compares machines, the ratio of the two passes the dynamics' own speed-up.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated seconds per setting (default 3)")
    parser.add_argument("--replan-period", type=float, default=None, help="override MPCOptions' replan.period [s]")
    parser.add_argument("--planner-dt", type=float, default=None, help="override MPCOptions' plan.planner_dt [s]")
    parser.add_argument("--target-speed", type=float, default=1.0, help="the env's target speed [m/s] (default 1)")
    parser.add_argument("--max-iterations", type=int, default=None, help="override MPCOptions' replan.iterations")
    parser.add_argument("--horizon", type=float, default=None, help="override MPCOptions' plan.horizon [s]")
    parser.add_argument("--mpc-options", default=None, metavar="JSON",
                        help="further MPC settings by their flat names (MPCOptions.replace) as a JSON object, e.g. "
                             "'{\"restart_ratio\": null}' (applied after the flags above)")
    parser.add_argument("--seed", type=int, default=0, help="the env's reset seed (default 0)")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the measurements as a record of the results store (results/speed/mpc.json)")
    args = parser.parse_args(argv)
    import warnings

    import gymnasium as gym

    import hsddp_gym  # noqa: F401
    from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy

    warnings.simplefilter("ignore", RuntimeWarning)
    over = {k: v for k, v in (("replan_period", args.replan_period), ("planner_dt", args.planner_dt),
                              ("max_iterations", args.max_iterations), ("horizon", args.horizon)) if v is not None}
    if args.mpc_options is not None:
        import json

        try:
            extra = json.loads(args.mpc_options)
            if not isinstance(extra, dict):
                raise ValueError("not a JSON object")
        except ValueError as exc:
            parser.error(f"--mpc-options must be a JSON object of MPCOptions fields: {exc}")
        over.update(extra)
    try:
        opts = MPCOptions().replace(**over)
    except (TypeError, ValueError) as exc:
        parser.error(f"bad MPC options: {exc}")
    env = gym.make("hsddp_gym/Bounding-v0", max_episode_steps=100000, target_speed=args.target_speed)
    dt = env.unwrapped.dt
    policy = MPCPolicy.from_env(env, options=opts)
    obs, _ = env.reset(seed=args.seed)
    steps = int(round(args.seconds / dt))
    if steps < 1:
        parser.error(f"--seconds must cover at least one control step of {dt} s, got {args.seconds}")
    from hsddp_gym.reports.store import machine_info, write_record

    machine = machine_info()
    env_time = 0.0
    done = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        a = policy(obs)
        t1 = time.perf_counter()
        obs, _, terminated, truncated, _ = env.step(a)
        env_time += time.perf_counter() - t1
        done += 1
        if terminated:
            print(f"the robot fell after {done} steps; timings cover the steps before the fall")
            break
    wall = time.perf_counter() - t0
    ms = np.array(policy.stats["solve_ms"])
    later = ms[1:] if ms.size > 1 else ms  # the first plan (warm-up iterations) is reported apart
    sim = done * dt
    print(f"hsddp_gym MPC benchmark -- {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    print(f"options: {opts}")
    print(f"simulated {sim:.2f} s ({done} control steps of {1e3 * dt:.0f} ms) in {wall:.2f} s wall")
    print(f"  env simulation: {env_time:.2f} s ({1e6 * env_time / done:.0f} us per control step)")
    print(f"  re-plans: {policy.stats['replans']} (+{policy.stats['planner_failures']} failed, "
          f"{policy.stats['time_budget_stops']} stopped by the time budget), wall time per re-plan: "
          f"mean {later.mean():.1f} ms, median {np.median(later):.1f} ms, max {later.max():.1f} ms "
          f"(first plan {ms[0]:.0f} ms, excluded); budget at real time {1e3 * opts.replan.period:.0f} ms")
    iters = float(np.mean(policy.stats["iterations"][1:] or policy.stats["iterations"]))
    problem = policy.law.plan.problem
    floor_ms = pinocchio_floor_ms(problem, policy.last_solution) * iters
    compiled_ms = compiled_pass_ms(problem, policy.last_solution) * iters
    print(f"  Pinocchio reference: {floor_ms:.2f} ms ({problem.n_knots} knots x {iters:.1f} iterations of "
          f"constraint-dynamics / ABA derivatives); re-plan / reference = {later.mean() / floor_ms:.2f}")
    print(f"  the same pass compiled (hsddp_gym.core.planar_dynamics): {compiled_ms:.2f} ms, "
          f"{floor_ms / compiled_ms:.1f}x faster than Pinocchio's")
    rtf = sim / wall
    print(f"real-time factor: {rtf:.2f} (goal >= 2: {'met' if rtf >= 2 else 'missed'}, ratio {rtf:.2f})")
    if args.record:
        write_record(args.record, {
            "seconds": sim, "control_steps": done, "fell": bool(done < steps), "replans": policy.stats["replans"],
            "planner_failures": policy.stats["planner_failures"], "knots": problem.n_knots,
            "iterations_per_replan": iters,
            "replan_ms": {"mean": float(later.mean()), "median": float(np.median(later)), "max": float(later.max())},
            "replan_period_ms": 1e3 * opts.replan.period, "env_us_per_control_step": 1e6 * env_time / done,
            "pinocchio_reference_ms": floor_ms, "compiled_pass_ms": compiled_ms, "real_time_factor": rtf},
            "The MPC's re-plan time and the closed loop's real-time factor, beside the Pinocchio derivative calls "
            "of the same knots measured in the same run", machine=machine)
        print(f"wrote {args.record}")
    return 0


def compiled_pass_ms(problem, solution, repeats: int = 5) -> float:
    """Wall time [ms] of :func:`hsddp_gym.core.planar_dynamics.linearize_knots` (dynamics and derivatives) over the
    knots of ``problem`` at the states and controls of ``solution`` (best of ``repeats``)."""
    from hsddp_gym.core.dynamics import HybridDynamics, Linearization
    from hsddp_gym.core.planar_dynamics import linearize_knots

    dyn = HybridDynamics()
    n = problem.n_knots
    lin = Linearization(n)
    X, U = np.ascontiguousarray(solution.X), np.ascontiguousarray(solution.U)
    modes = np.ascontiguousarray(problem.modes, dtype=np.int64)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        linearize_knots(X, U, modes, dyn.kernel_params, dyn.scratch.arrays, dyn._tau, lin.lam6, lin.acc, lin.a_q,
                        lin.a_v, lin.a_tau, lin.lam6_q, lin.lam6_v, lin.lam6_tau)
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best


def pinocchio_floor_ms(problem, solution, repeats: int = 5) -> float:
    """Wall time [ms] of one pass of Pinocchio's dynamics derivatives over the knots of ``problem`` at the states
    and controls of ``solution``: ``computeConstraintDynamicsDerivatives`` with the knot's contact models at stance
    knots, ``computeABADerivatives`` in flight (best of ``repeats``)."""
    import pinocchio as pin

    from hsddp_gym.core.conventions import NQ
    from hsddp_gym.core.dynamics import HybridDynamics

    dyn = HybridDynamics()  # its own model and Data objects (stack_notes: never share Data)
    model, free, prox = dyn.model, dyn.model.createData(), dyn._prox
    tau = np.zeros(model.nv)
    calls = []
    for k in range(problem.n_knots):
        q, v = solution.X[k, :NQ].copy(), solution.X[k, NQ:].copy()
        tau[3:] = solution.U[k]
        calls.append((int(problem.modes[k]), q, v, tau.copy()))
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for mode, q, v, tq in calls:
            if mode:
                cs = dyn._contact[mode]
                pin.constraintDynamics(model, cs.data, q, v, tq, cs.models, cs.datas, prox)
                pin.computeConstraintDynamicsDerivatives(model, cs.data, cs.models, cs.datas, prox)
            else:
                pin.computeABADerivatives(model, free, q, v, tq)
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best


if __name__ == "__main__":
    sys.exit(main())
