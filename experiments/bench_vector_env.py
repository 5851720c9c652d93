"""Throughput of the compiled vector env against the single env and MuJoCo's HalfCheetah-v5, in one run.

Times, under random actions with autoreset on (falls reset the robots, as in training):

* the single env ``gym.make(ID)`` (one robot stepped through the compiled kernel from Python),
* ``HalfCheetah-v5`` (``gym.make``, MuJoCo; needs ``gymnasium[mujoco]``),
* ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")`` for each N,
* with ``--sync``: ``gym.make_vec(ID, num_envs=N, vectorization_mode="sync")`` (N single envs in a
  ``SyncVectorEnv``, what a task env had before its compiled vector env) for each N,

interleaved in ``--rounds`` short chunks so that a load change on a shared machine hits all alike, and prints
env steps (summed over the robots) per CPU second of this process and the ratios to the single env and to
HalfCheetah-v5, with the goals of ``hsddp_gym/Bounding-v0`` (the default ``--env``) at N = 64: >= 10x the single env
and >= 2x HalfCheetah-v5. ``--env`` takes several ids (the task envs: their vector env batches the physics only, and
runs each robot's reward, termination, observation and info in its single env's Python); each env gets its own block
of rows. Everything runs in
one thread (the kernel loops over the robots without ``prange``; the single env and MuJoCo are single-threaded
too), so steps per CPU second are steps per core, and they do not depend on how many other jobs share the
cores (wall-clock rates, also printed, do). The load average of the machine is printed with the results.

Usage::

    python experiments/bench_vector_env.py [--seconds 20] [--sizes 1 8 64 256] [--rounds 5] [--seed 0]
    python experiments/bench_vector_env.py --env hsddp_gym/Backflip-v0 hsddp_gym/Pronking-v0 --sizes 64 --sync
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import numpy as np

import hsddp_gym  # noqa: F401  (registers the env)
from hsddp_gym.core import batch_contact
from hsddp_gym.reports.store import machine_info, write_record

ENV_ID = "hsddp_gym/Bounding-v0"
GOAL_N = 64
GOAL_VS_SINGLE = 10.0
GOAL_VS_HALFCHEETAH = 2.0


class _Single:
    """A single env stepped with random actions, reset when an episode ends."""

    def __init__(self, env_id: str, seed: int) -> None:
        self.env = gym.make(env_id)
        self.env.reset(seed=seed)
        shape = self.env.action_space.shape
        rng = np.random.default_rng(seed)
        self.actions = rng.uniform(-1.0, 1.0, size=(4096,) + shape).astype(np.float32)
        self.k = 0

    def run(self, seconds: float) -> tuple[int, float, float]:
        steps, start, cpu = 0, time.perf_counter(), time.process_time()
        while True:
            for _ in range(50):
                _, _, terminated, truncated, _ = self.env.step(self.actions[self.k % 4096])
                self.k += 1
                steps += 1
                if terminated or truncated:
                    self.env.reset()
            now = time.perf_counter()
            if now - start >= seconds:
                return steps, now - start, time.process_time() - cpu


class _Vector:
    """The vector env of ``n`` robots (``mode``: Gymnasium's vectorization mode) with random actions (autoreset is
    built in)."""

    def __init__(self, env_id: str, n: int, seed: int, mode: str = "vector_entry_point") -> None:
        self.env = gym.make_vec(env_id, num_envs=n, vectorization_mode=mode)
        self.env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        self.actions = rng.uniform(-1.0, 1.0, size=(64, n, 4)).astype(np.float32)
        self.n = n
        self.k = 0

    def run(self, seconds: float) -> tuple[int, float, float]:
        steps, start, cpu = 0, time.perf_counter(), time.process_time()
        while True:
            for _ in range(5):
                self.env.step(self.actions[self.k % 64])
                self.k += 1
                steps += self.n
            now = time.perf_counter()
            if now - start >= seconds:
                return steps, now - start, time.process_time() - cpu


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="total wall-clock seconds per timed configuration (default 20), split into --rounds")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 8, 64, 256],
                        help="numbers of robots N of the vector env (default 1 8 64 256)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the actions and resets (default 0)")
    parser.add_argument("--env", nargs="+", default=[ENV_ID], metavar="ID",
                        help=f"the envs, each with a vector entry point (default {ENV_ID}; the goals are its own)")
    parser.add_argument("--sync", action="store_true",
                        help="also time N single envs in Gymnasium's SyncVectorEnv for each N")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the measurements as a record of the results store "
                             "(results/speed/vector_env.json)")
    args = parser.parse_args(argv)
    if not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    if args.rounds < 1:
        parser.error(f"--rounds must be >= 1, got {args.rounds}")
    if any(n < 1 for n in args.sizes):
        parser.error(f"--sizes must be >= 1, got {args.sizes}")
    for env_id in args.env:
        if env_id not in gym.registry or gym.spec(env_id).vector_entry_point is None:
            parser.error(f"--env: {env_id} is not a registered env with a vector entry point")

    batch_contact.warm_up()
    runners: dict = {}
    try:
        runners["halfcheetah"] = _Single("HalfCheetah-v5", args.seed)
    except Exception as exc:  # noqa: BLE001 - a missing optional dependency is reported, not fatal
        print(f"HalfCheetah-v5 not available ({type(exc).__name__}: {exc}); its ratio is not measured")
    for env_id in args.env:
        runners[(env_id, "single")] = _Single(env_id, args.seed)
        for n in args.sizes:
            runners[(env_id, f"vector N={n}")] = _Vector(env_id, n, args.seed)
            if args.sync:
                runners[(env_id, f"sync N={n}")] = _Vector(env_id, n, args.seed, "sync")
    for runner in runners.values():  # warm the caches and allocators
        runner.run(0.2)
    totals = {name: [0, 0.0, 0.0] for name in runners}
    chunk = args.seconds / args.rounds
    machine = machine_info()
    load_before = os.getloadavg()
    for _ in range(args.rounds):
        for name, runner in runners.items():
            steps, elapsed, cpu = runner.run(chunk)
            totals[name][0] += steps
            totals[name][1] += elapsed
            totals[name][2] += cpu
    load_after = os.getloadavg()
    rate = {name: steps / cpu for name, (steps, _, cpu) in totals.items()}
    wall = {name: steps / elapsed for name, (steps, elapsed, _) in totals.items()}

    print(f"load average (1, 5, 15 min) before {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}, "
          f"after {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}; {os.cpu_count()} cores; "
          f"{args.seconds:g} s per row in {args.rounds} interleaved rounds; one thread each")
    print("env steps per CPU second of this process (per core: everything is single-threaded), and per wall second")
    hc = rate.get("halfcheetah")
    for env_id in args.env:
        print(f"{env_id}\n{'configuration':<16} {'steps/CPU-s':>12} {'x single':>9} {'x HalfCheetah':>14} "
              f"{'steps/wall-s':>13}")
        single = rate[(env_id, "single")]
        for key, r in rate.items():
            if key == "halfcheetah" or key[0] != env_id:
                continue
            vs_hc = f"{r / hc:14.2f}" if hc else f"{'-':>14}"
            print(f"{key[1]:<16} {r:12,.0f} {r / single:9.2f} {vs_hc} {wall[key]:13,.0f}")
    if hc:
        print(f"{'HalfCheetah-v5':<16} {hc:12,.0f} {'':>9} {1.0:14.2f} {wall['halfcheetah']:13,.0f}")
    key = (ENV_ID, f"vector N={GOAL_N}")
    if key in rate:
        ratio_single = rate[key] / rate[(ENV_ID, "single")]
        print(f"goal at N = {GOAL_N}: >= {GOAL_VS_SINGLE:g}x the single env: {ratio_single:.2f}x "
              f"({'met' if ratio_single >= GOAL_VS_SINGLE else 'NOT met'})")
        if hc:
            ratio_hc = rate[key] / hc
            print(f"goal at N = {GOAL_N}: >= {GOAL_VS_HALFCHEETAH:g}x HalfCheetah-v5: {ratio_hc:.2f}x "
                  f"({'met' if ratio_hc >= GOAL_VS_HALFCHEETAH else 'NOT met'})")
    if args.record:
        rows = [{"configuration": key if key == "halfcheetah" else key[1],
                 **({} if key == "halfcheetah" else {"env_id": key[0]}),
                 "env_steps_per_cpu_s": rate[key], "env_steps_per_wall_s": wall[key]} for key in rate]
        write_record(args.record, {"seconds": args.seconds, "rounds": args.rounds, "env_ids": list(args.env),
                                   "rows": rows},
                     "Env steps per CPU second of the compiled vector env against N, the single env and "
                     "HalfCheetah-v5, timed interleaved in one run", machine=machine)
        print(f"wrote {args.record}")


if __name__ == "__main__":
    main()
