"""Dataset generation throughput (transitions per second) with 1 and 2 worker processes, and on Ray.

Usage: python experiments/bench_datasets.py [--heuristic-episodes 200] [--mpc-episodes 6] [--mpc-steps 300]
       [--workers 1 2] [--ray-workers 2] [--skip-mpc]

``--ray-workers N`` adds a run on a local Ray instance with N CPUs (started once, before the timed runs, so its
start-up is not counted; each Ray worker process still imports the package on its first task, which is counted
like the local workers' start-up).

For each policy and worker count it runs ``hsddp_gym.datasets.generation.generate_dataset`` into a temporary directory
and prints: episodes, transitions, the episode-generation wall time (worker start-up included: spawn-started
processes import numpy, Pinocchio, numba and gymnasium), transitions/s, the start-up time alone (measured
separately as W one-step episodes on a fresh pool) and the rate without it, and the total time including the
random-policy reference episodes and writing Minari + npz (and the per-episode checkpoints that let an
interrupted run resume, which are part of the generation time). The in-process (workers=1) run is warmed up
first (imports, model construction), so it measures steady-state generation. Nothing is kept. The machine's
load average is printed: with other jobs on the cores, 2 workers cannot be twice as fast.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from hsddp_gym.datasets.collection import collect_episodes
from hsddp_gym.datasets.generation import generate_dataset
from hsddp_gym.rollout.policies import PolicySpec


def startup_time(policy: str, workers: int, backend: str = "local") -> float:
    """Wall time of ``workers`` one-step episodes: process start-up and imports (0 for one local worker:
    in-process). For Ray this is an upper bound: a worker that ran a task before is already warm."""
    if workers == 1 and backend == "local":
        return 0.0
    t0 = time.perf_counter()
    collect_episodes(PolicySpec(policy), workers, seed=0, workers=workers, max_episode_steps=1, progress=False,
                     backend=backend)
    return time.perf_counter() - t0


def bench(policy: str, episodes: int, workers: int, max_steps: int | None, backend: str = "local") -> dict:
    start = startup_time(policy, workers, backend) if backend == "local" else 0.0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = generate_dataset(policy, episodes, Path(tmp) / "ds", seed=0, workers=workers,
                               max_episode_steps=max_steps, progress=False, backend=backend)
        total = time.perf_counter() - t0
    steady = max(res.generation_time_s - start, 1e-9)
    return {"policy": policy, "workers": f"{workers} (ray)" if backend == "ray" else workers,
            "episodes": res.episodes, "transitions": res.total_steps,
            "gen_s": res.generation_time_s, "rate": res.total_steps / res.generation_time_s, "total_s": total,
            "startup_s": start, "steady_rate": res.total_steps / steady}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--heuristic-episodes", type=int, default=200,
                   help="episodes of the heuristic policy per worker count (default: %(default)s)")
    p.add_argument("--heuristic-steps", type=int, default=None, help="time limit (default: the env's 1000)")
    p.add_argument("--mpc-episodes", type=int, default=6,
                   help="episodes of the HS-DDP MPC per worker count (default: %(default)s)")
    p.add_argument("--mpc-steps", type=int, default=300, help="MPC time limit per episode (default: %(default)s)")
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2],
                   help="worker counts to measure (default: 1 2)")
    p.add_argument("--ray-workers", type=int, default=None,
                   help="also measure a local Ray instance with this many CPUs (needs the ray extra)")
    p.add_argument("--skip-mpc", action="store_true", help="measure the heuristic only")
    args = p.parse_args(argv)
    rows = []
    jobs = [("heuristic", args.heuristic_episodes, args.heuristic_steps)]
    if not args.skip_mpc:
        jobs.append(("mpc", args.mpc_episodes, args.mpc_steps))
    for policy, _, _ in jobs:  # imports and first-call costs of this process, so that workers=1 is steady state
        collect_episodes(PolicySpec(policy), 1, seed=0, workers=1, max_episode_steps=2, progress=False)
    runs = [(w, "local") for w in args.workers]
    if args.ray_workers is not None:
        import ray

        ray.init(num_cpus=args.ray_workers, include_dashboard=False, log_to_driver=False, configure_logging=False,
                 runtime_env={"env_vars": {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}})
        runs.append((args.ray_workers, "ray"))
    for policy, episodes, steps in jobs:
        for w, backend in runs:
            r = bench(policy, episodes, w, steps, backend)
            rows.append(r)
            print(f"{policy:<10} workers={w}: {r['episodes']} episodes, {r['transitions']} transitions in "
                  f"{r['gen_s']:.2f} s -> {r['rate']:.0f} transitions/s; worker start-up {r['startup_s']:.2f} s, "
                  f"without it {r['steady_rate']:.0f} transitions/s (total with reference episodes and writing: "
                  f"{r['total_s']:.2f} s)", flush=True)
    print(f"\nload average (1, 5, 15 min): {os.getloadavg()} on {os.cpu_count()} cores")
    print("| policy | workers | episodes | transitions | generation [s] | transitions/s | speed-up | "
          "start-up [s] | transitions/s without start-up |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        base = next(b for b in rows if b["policy"] == r["policy"])
        print(f"| {r['policy']} | {r['workers']} | {r['episodes']} | {r['transitions']} | {r['gen_s']:.2f} | "
              f"{r['rate']:.0f} | {r['rate'] / base['rate']:.2f} | {r['startup_s']:.2f} | {r['steady_rate']:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
