"""Speed of the HS-DDP MPC in hsddp_gym/Bounding-v0: re-plan wall time and real-time factor.

Usage: python experiments/bench_mpc.py [--seconds 3] [--replan-period 0.02] [--planner-dt 0.005]
       [--max-iterations 3] [--horizon 0.296]
Real-time factor = simulated time / wall time of the whole closed loop (env simulation + policy).
Goal: >= 1 on the 2-core development machine. Run it on a quiet machine: it is single-threaded.
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
    parser.add_argument("--replan-period", type=float, default=None, help="override MPCOptions.replan_period [s]")
    parser.add_argument("--planner-dt", type=float, default=None, help="override MPCOptions.planner_dt [s]")
    parser.add_argument("--max-iterations", type=int, default=None, help="override MPCOptions.max_iterations")
    parser.add_argument("--horizon", type=float, default=None, help="override MPCOptions.horizon [s]")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import dataclasses
    import warnings

    import gymnasium as gym

    import hsddp_gym  # noqa: F401
    from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy

    warnings.simplefilter("ignore", RuntimeWarning)
    over = {k: v for k, v in (("replan_period", args.replan_period), ("planner_dt", args.planner_dt),
                              ("max_iterations", args.max_iterations), ("horizon", args.horizon)) if v is not None}
    opts = dataclasses.replace(MPCOptions(), **over)
    env = gym.make("hsddp_gym/Bounding-v0", max_episode_steps=100000)
    dt = env.unwrapped.dt
    policy = MPCPolicy.from_env(env, options=opts)
    obs, _ = env.reset(seed=args.seed)
    steps = int(round(args.seconds / dt))
    if steps < 1:
        parser.error(f"--seconds must cover at least one control step of {dt} s, got {args.seconds}")
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
          f"(first plan {ms[0]:.0f} ms, excluded); budget at real time {1e3 * opts.replan_period:.0f} ms")
    rtf = sim / wall
    print(f"real-time factor: {rtf:.2f} (goal >= 1: {'met' if rtf >= 1 else 'missed'}, ratio {rtf:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
