"""Throughput of ``hsddp_gym/Bounding-v0`` (single process), and HalfCheetah-v5 for comparison.

Prints env steps/s and simulated 1-ms steps/s for ``frame_skip=1`` and the default frame skip, under
random actions (a mix of flight, impacts, stance and sliding) and under zero torque from a standing
start (mostly double stance: the contact-solver path), and whether each row meets the goal of
20,000 simulated steps/s; for the default frame skip, both with the energy-consistent stepping (the default)
and with the legacy scheme (``energy_consistent=False``), and their ratio (goal >= 0.8), timed interleaved
in short chunks so that a load change on a shared machine hits both alike. When ``gymnasium[mujoco]`` is
installed it also times HalfCheetah-v5 (MuJoCo,
0.01 s timestep, frame_skip 5, both read from the env) in the same run and prints the ratios of env steps/s
and of simulated steps/s (the issue's comparison: about 42,000 MuJoCo steps/s on this kind of machine).

Usage::

    python experiments/bench_env.py [--seconds 3] [--seed 0] [--record results/speed/env.json]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import hsddp_gym  # noqa: F401  (registers the env)
from hsddp_gym.envs.bounding import DEFAULT_FRAME_SKIP, DEFAULT_SIM_TIMESTEP, BoundingEnv
from hsddp_gym.reports.store import machine_info, write_record

GOAL_SIM_STEPS_PER_S = 20_000
GOAL_RATIO_TO_LEGACY = 0.8


def time_env(env: gym.Env, seconds: float, seed: int, policy: str) -> tuple[float, int]:
    """Step ``env`` for about ``seconds`` wall-clock seconds (resetting on episode end).

    Returns:
        ``(env steps per second, env steps taken)``.
    """
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    shape = env.action_space.shape
    zeros = np.zeros(shape, dtype=np.float32)
    actions = rng.uniform(-1.0, 1.0, size=(4096,) + shape).astype(np.float32)
    steps = 0
    start = time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(100):
            action = actions[steps % len(actions)] if policy == "random" else zeros
            _, _, terminated, truncated, _ = env.step(action)
            steps += 1
            if terminated or truncated:
                env.reset()
        now = time.perf_counter()
        if now >= deadline:
            break
    return steps / (now - start), steps


def standing_state(env: BoundingEnv) -> np.ndarray:
    """A posture with both feet on the ground (hips 0.25 pi, knees -0.5 pi), at rest."""
    q = np.array([0.0, 0.0, 0.0, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    q[1] = -env.robot.foot_heights(q).min()
    return np.concatenate([q, np.zeros(7)])


class _StandingStart(gym.Wrapper):
    """Reset to a standing posture so that zero torque exercises the double-contact solver path."""

    def reset(self, *, seed=None, options=None):
        return self.env.reset(seed=seed, options={"state": standing_state(self.env.unwrapped)})


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="wall-clock seconds per measurement")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the measurements as a record of the results store (results/speed/env.json)")
    args = parser.parse_args(argv)
    machine = machine_info()
    record = {"seconds": args.seconds, "rows": [], "interleaved": [], "halfcheetah": None}
    if not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds}")

    print(f"Bounding-v0, single process, {args.seconds:g} s per row (goal: >= {GOAL_SIM_STEPS_PER_S:,} "
          "simulated 1-ms steps/s)")
    print(f"{'scheme':>8} {'frame_skip':>10} {'actions':>14} {'env steps/s':>12} {'sim steps/s':>12} "
          f"{'x real time':>11} {'goal':>6}")
    results = {}
    rows = [(fs, policy, True) for fs in sorted({1, DEFAULT_FRAME_SKIP}) for policy in ("random", "zero-standing")]
    rows += [(DEFAULT_FRAME_SKIP, policy, False) for policy in ("random", "zero-standing")]
    for frame_skip, policy, consistent in rows:
        env = BoundingEnv(frame_skip=frame_skip, terminate_when_unhealthy=(policy == "random"),
                          energy_consistent=consistent)
        if policy == "zero-standing":
            env = _StandingStart(env)
        rate, _ = time_env(env, args.seconds, args.seed, "random" if policy == "random" else "zero")
        sim_rate = rate * frame_skip
        sim_dt = env.unwrapped.sim_timestep
        results[(frame_skip, policy, consistent)] = rate
        record["rows"].append({"scheme": "energy" if consistent else "legacy", "frame_skip": frame_skip,
                               "actions": policy, "env_steps_per_s": rate, "sim_steps_per_s": sim_rate})
        verdict = "meets" if sim_rate >= GOAL_SIM_STEPS_PER_S else "MISSES"
        print(f"{'energy' if consistent else 'legacy':>8} {frame_skip:>10} {policy:>14} {rate:>12,.0f} "
              f"{sim_rate:>12,.0f} {sim_rate * sim_dt:>11.1f} {verdict:>6}")
        env.close()
    for policy in ("random", "zero-standing"):
        envs = {}
        for consistent in (True, False):
            env = BoundingEnv(terminate_when_unhealthy=(policy == "random"), energy_consistent=consistent)
            envs[consistent] = _StandingStart(env) if policy == "zero-standing" else env
        steps = {True: 0, False: 0}
        wall = {True: 0.0, False: 0.0}
        chunk = max(0.05, args.seconds / 10.0)
        for i in range(20):  # alternate 10 chunks each; each chunk resets its env (same seed: same states)
            consistent = i % 2 == 0
            rate, n = time_env(envs[consistent], chunk, args.seed, "random" if policy == "random" else "zero")
            steps[consistent] += n
            wall[consistent] += n / rate
        ratio = (steps[True] / wall[True]) / (steps[False] / wall[False])
        record["interleaved"].append({"actions": policy, "energy_env_steps_per_s": steps[True] / wall[True],
                                      "legacy_env_steps_per_s": steps[False] / wall[False], "ratio": ratio})
        print(f"interleaved, frame_skip {DEFAULT_FRAME_SKIP}, {policy}: energy-consistent "
              f"{steps[True] / wall[True]:,.0f}, legacy {steps[False] / wall[False]:,.0f} env steps/s, "
              f"ratio {ratio:.3f} (goal >= {GOAL_RATIO_TO_LEGACY})")

    try:
        import mujoco  # noqa: F401

        cheetah = gym.make("HalfCheetah-v5")
    except Exception as exc:  # gymnasium[mujoco] missing (ImportError / DependencyNotInstalled)
        print(f"HalfCheetah-v5 skipped: gymnasium[mujoco] is not installed ({type(exc).__name__}: {exc})")
        _write(args, record, machine)
        return
    cheetah_skip = int(cheetah.unwrapped.frame_skip)
    cheetah_dt = float(cheetah.unwrapped.model.opt.timestep)
    rate, _ = time_env(cheetah, args.seconds, args.seed, "random")
    cheetah.close()
    cheetah_sim = rate * cheetah_skip
    ours = results[(DEFAULT_FRAME_SKIP, "random", True)]
    ours_sim = ours * DEFAULT_FRAME_SKIP
    print(f"HalfCheetah-v5 (MuJoCo, frame_skip {cheetah_skip}, {1e3 * cheetah_dt:g} ms timestep, "
          f"{1e3 * cheetah_skip * cheetah_dt:g} ms per env step): {rate:,.0f} env steps/s "
          f"({cheetah_sim:,.0f} MuJoCo steps/s, {cheetah_sim * cheetah_dt:.1f}x real time)")
    print(f"ratio Bounding-v0 (frame_skip {DEFAULT_FRAME_SKIP}, random actions) / HalfCheetah-v5: "
          f"env steps/s {ours / rate:.3f}, simulated steps/s {ours_sim / cheetah_sim:.3f}, "
          f"simulated time per wall second {ours_sim * DEFAULT_SIM_TIMESTEP / (cheetah_sim * cheetah_dt):.3f}")
    record["halfcheetah"] = {"env_steps_per_s": rate, "sim_steps_per_s": cheetah_sim, "frame_skip": cheetah_skip,
                             "timestep": cheetah_dt, "ratio_env_steps": ours / rate}
    _write(args, record, machine)


def _write(args, record: dict, machine: dict) -> None:
    if args.record:
        write_record(args.record, record, "Bounding-v0's single-process throughput (energy-consistent and legacy "
                     "schemes) beside HalfCheetah-v5's, measured in the same run", machine=machine)
        print(f"wrote {args.record}")


if __name__ == "__main__":
    main()
