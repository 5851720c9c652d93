"""Speed of the HS-DDP MPC in hsddp_gym/Bounding-v0 (or a task's MPC, ``--env``): re-plan wall time and real-time
factor.

Usage: python experiments/bench_mpc.py [--seconds 3] [--replan-period 0.02] [--planner-dt 0.005]
       [--max-iterations 3] [--horizon 0.296] [--target-speed 1.0] [--mpc-options '{"restart_ratio": null}']
       python experiments/bench_mpc.py --env hsddp_gym/Backflip-v0 hsddp_gym/GapJump-v0 ... [--record FILE.json]
Real-time factor = simulated time / wall time of the whole closed loop (env simulation + policy).
Target: a real-time factor of at least 2 on a 2-core machine. Run it on a quiet machine: it is single-threaded.

With ``--env``, each task env's MPC (``make_policy("mpc", env)``: a motion's MPC re-plans what remains of the motion)
runs one episode (``--seconds``: at most that long), and the bound's MPC in Bounding-v0 runs ``--seconds`` (3 s by
default) in the same run as the reference: per env the real-time factor, the re-plan's wall time and its cost per plan
knot beside the bound's (the goal: no more per knot).

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
    parser.add_argument("--seconds", type=float, default=None,
                        help="simulated seconds per setting (default 3; with --env a task env's whole episode)")
    parser.add_argument("--env", nargs="+", default=None, metavar="ID",
                        help="task envs whose MPC runs (make_policy('mpc', env)), each for one episode, beside the "
                             "bound's MPC as the per-knot reference (default: Bounding-v0 alone, the bound's MPC)")
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
    if args.seconds is not None and args.seconds < 0.005:
        parser.error(f"--seconds must cover at least one control step of 5 ms, got {args.seconds}")
    from hsddp_gym.reports.store import machine_info, write_record

    machine = machine_info()
    if args.env is not None:
        from hsddp_gym.registry import ENV_TASKS

        unknown = [e for e in args.env if e not in ENV_TASKS]
        if unknown:
            parser.error(f"--env: unknown env(s) {unknown}; choose from {sorted(ENV_TASKS)}")
        return task_benchmark(args, opts, machine, write_record)
    env = gym.make("hsddp_gym/Bounding-v0", max_episode_steps=100000, target_speed=args.target_speed)
    dt = env.unwrapped.dt
    policy = MPCPolicy.from_env(env, options=opts)
    loop = closed_loop(env, policy, 3.0 if args.seconds is None else args.seconds, args.seed)
    done, wall, env_time = loop["control_steps"], loop["wall"], loop["env_seconds"]
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
            "seconds": sim, "control_steps": done, "fell": loop["fell"], "replans": policy.stats["replans"],
            "planner_failures": policy.stats["planner_failures"], "knots": problem.n_knots,
            "iterations_per_replan": iters,
            "replan_ms": {"mean": float(later.mean()), "median": float(np.median(later)), "max": float(later.max())},
            "replan_period_ms": 1e3 * opts.replan.period, "env_us_per_control_step": 1e6 * env_time / done,
            "pinocchio_reference_ms": floor_ms, "compiled_pass_ms": compiled_ms, "real_time_factor": rtf},
            "The MPC's re-plan time and the closed loop's real-time factor, beside the Pinocchio derivative calls "
            "of the same knots measured in the same run", machine=machine)
        print(f"wrote {args.record}")
    return 0


def closed_loop(env, policy, seconds: float, seed: int) -> dict:
    """Run ``policy`` in ``env`` from ``env.reset(seed=seed)`` for ``seconds`` of simulated time or until the episode
    ends, with every re-plan's plan knots recorded: ``control_steps``, ``seconds`` (simulated), ``wall``,
    ``env_seconds`` (the env's own share of the wall time), ``fell`` (terminated), ``success`` (``info["success"]`` at
    the end, None without one) and ``knots`` (per re-plan, in the order of ``policy.stats["solve_ms"]``)."""
    knots: list[int] = []
    planners = [policy.planner] + ([policy.gait.planner] if getattr(policy, "gait", None) is not None else [])
    for planner in planners:  # count each re-plan's knots (the planners share one statistics dict, in call order)
        planner.solve = _counting(planner.solve, knots)
    obs, _ = env.reset(seed=seed)
    policy.reset()
    dt = env.unwrapped.dt
    steps = max(1, int(round(seconds / dt)))
    env_time, done, fell, info = 0.0, 0, False, {}
    t0 = time.perf_counter()
    for _ in range(steps):
        a = policy(obs)
        t1 = time.perf_counter()
        obs, _, terminated, truncated, info = env.step(a)
        env_time += time.perf_counter() - t1
        done += 1
        if terminated:
            fell = True
            print(f"the robot fell after {done} steps; timings cover the steps before the fall")
            break
        if truncated:
            break
    return {"control_steps": done, "seconds": done * dt, "wall": time.perf_counter() - t0, "env_seconds": env_time,
            "fell": fell, "success": info.get("success"), "knots": knots}


def _counting(solve, knots: list):
    def counted(problem, *args, **kwargs):
        knots.append(int(problem.n_knots))
        return solve(problem, *args, **kwargs)
    return counted


def per_knot_us(stats: dict, knots: list) -> float:
    """Wall time [us] per plan knot over the re-plans after the first (its warm-up iterations excluded)."""
    ms, n = np.asarray(stats["solve_ms"][1:]), np.asarray(knots[1:len(stats["solve_ms"])])
    return float(1e3 * ms.sum() / max(int(n.sum()), 1))


def task_benchmark(args, opts, machine: dict, write_record) -> int:
    """``--env``: each task env's MPC for one episode, then the bound's MPC as the per-knot reference."""
    import gymnasium as gym

    from hsddp_gym.rollout.policies import PolicySpec, make_policy

    bounding = "hsddp_gym/Bounding-v0"
    rows = {}
    for env_id in [*(e for e in args.env if e != bounding), bounding]:
        reference = env_id == bounding
        env = gym.make(env_id, **({"max_episode_steps": 100000} if reference else {}))
        policy = make_policy(PolicySpec("mpc", opts, env_id=env_id), env)
        if args.seconds is not None:
            seconds = args.seconds
        else:
            seconds = 3.0 if reference else env.spec.max_episode_steps * env.unwrapped.dt
        loop = closed_loop(env, policy, seconds, args.seed)
        ms = np.asarray(policy.stats["solve_ms"][1:] or policy.stats["solve_ms"])
        knots = np.asarray(loop["knots"][1:] or loop["knots"])
        iters = float(np.mean(policy.stats["iterations"][1:] or policy.stats["iterations"]))
        rows[env_id] = {"policy": type(policy).__name__, "seconds": loop["seconds"], "fell": loop["fell"],
                        "success": loop["success"], "replans": policy.stats["replans"],
                        "planner_failures": policy.stats["planner_failures"],
                        "real_time_factor": loop["seconds"] / loop["wall"],
                        "replan_ms": {"mean": float(ms.mean()), "max": float(ms.max())},
                        "knots_mean": float(knots.mean()), "iterations_per_replan": iters,
                        "us_per_knot": per_knot_us(policy.stats, loop["knots"])}
        env.close()
    bound = rows[bounding]
    print(f"hsddp_gym task MPC benchmark -- {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    print(f"{'env':30s} {'policy':16s} {'sim s':>6s} {'RTF':>5s} {'re-plan ms':>10s} {'max':>6s} {'knots':>6s} "
          f"{'us/knot':>8s} {'/bound':>6s}  goal: RTF >= 2")
    for env_id, r in rows.items():
        r["per_knot_ratio_to_bound"] = r["us_per_knot"] / bound["us_per_knot"]
        print(f"{env_id:30s} {r['policy']:16s} {r['seconds']:6.2f} {r['real_time_factor']:5.2f} "
              f"{r['replan_ms']['mean']:10.2f} {r['replan_ms']['max']:6.1f} {r['knots_mean']:6.0f} "
              f"{r['us_per_knot']:8.2f} {r['per_knot_ratio_to_bound']:6.2f}  "
              f"{'met' if r['real_time_factor'] >= 2 else 'missed'}{' (fell)' if r['fell'] else ''}")
    if args.record:
        write_record(args.record, {"envs": rows, "reference": bounding, "seed": args.seed},
                     "Each task's MPC for one episode: real-time factor, re-plan wall time and its cost per plan knot, "
                     "beside the bound's MPC in the same run", machine=machine)
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
