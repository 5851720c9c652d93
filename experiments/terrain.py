"""The terrain task (``hsddp_gym/Terrain-v0``): the terrain-aware MPC expert, the flat-ground MPC and the heuristic.

Each policy plays one episode per seed of the registered task (a new ``"random_mixed"`` profile per reset seed: steps
up to 3 cm, slopes up to 0.1, levels within 15 cm, flat for x < 0.6 m; 1 m/s, 1000 steps). The policies:

* ``mpc-terrain``: ``MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=env_terrain(env))``, the MPC given
  each episode's terrain as privileged information (``docs/policies/mpc.md#terrain``);
* ``mpc``: the same MPC without it (it plans for flat ground, the feet on the ground setting its height);
* ``heuristic``: ``HeuristicPolicy`` (flat ground).

Three blocks of seeds by default (:data:`SEED_USE` says what each was used for before the recorded run): 9800-9819,
on which the flat-ground MPC's falls were diagnosed, 9820-9839, the held-out block of the terrain-aware MPC's first
evaluation, and 9840-9859, used by no run before the recorded one. Per episode: the return, a fall (and when and
where), the mean forward speed and, for the MPCs, the re-plans that failed.

    python experiments/terrain.py --record results/tasks/terrain.json
"""

from __future__ import annotations

import argparse
import time

import numpy as np

TERRAIN = "hsddp_gym/Terrain-v0"
POLICIES = ("mpc-terrain", "mpc", "heuristic")
SEED_USE = {
    9800: "the flat-ground MPC's falls were diagnosed on them",
    9820: "held out while the terrain-aware MPC was designed; its first evaluation on them had no fall, and the failed "
          "re-plans it had on slopes (9838, 9839) then led to the slope term of the switching constraint's gradient",
    9840: "used by no run before this record",
}
"""What each default block of seeds (by its first seed) was used for before the recorded run."""
LABELS = {
    "mpc-terrain": "MPCPolicy(..., terrain=env_terrain(env))",
    "mpc": "MPCPolicy(EnvInterface.from_env(env), MPCOptions())",
    "heuristic": "HeuristicPolicy",
}


def _fixed(value: float, digits: int) -> float:
    """``value`` to ``digits`` decimals (a compact record)."""
    return float(f"{float(value):.{digits}f}")


def make_policy(name: str, env):
    """The policy ``name`` (:data:`POLICIES`) for ``env``."""
    from hsddp_gym.planners.policies import HeuristicPolicy, MPCOptions, MPCPolicy
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.planners.policies.mpc import env_terrain

    interface = EnvInterface.from_env(env)
    if name == "mpc-terrain":
        return MPCPolicy(interface, MPCOptions(), terrain=env_terrain(env))
    if name == "mpc":
        return MPCPolicy(interface, MPCOptions())
    if name == "heuristic":
        return HeuristicPolicy(interface)
    raise ValueError(f"policy must be one of {list(POLICIES)}, got {name!r}")


def run_block(name: str, seeds, quiet: bool = False) -> dict:
    """Play ``name`` on ``hsddp_gym/Terrain-v0`` once per seed: the summary and one entry per episode."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.planners.policies.evaluation import run_episode

    env = gym.make(TERRAIN)
    policy = make_policy(name, env)
    episodes = []
    t0 = time.perf_counter()
    for seed in seeds:
        r = run_episode(env, policy, int(seed))
        stats = getattr(policy, "stats", {})
        levels = np.abs(env.unwrapped.terrain.levels)
        ep = {"seed": int(seed), "return": _fixed(r.episode_return, 2), "length": int(r.length), "fell": bool(r.fell),
              "speed": _fixed(r.forward_speed, 4), "max_level": _fixed(float(levels.max()), 4)}
        if r.fell:
            ep["fall_time"] = _fixed(r.length * float(env.unwrapped.dt), 3)
            ep["fall_x"] = _fixed(float(r.states[-1, 0]), 3)
        if "planner_failures" in stats:
            ep["planner_failures"] = int(stats["planner_failures"])
        episodes.append(ep)
    env.close()
    returns = np.array([e["return"] for e in episodes])
    row = {"policy": name, "label": LABELS[name], "seeds": [int(seeds[0]), int(seeds[-1])], "episodes": len(episodes),
           "falls": int(sum(e["fell"] for e in episodes)), "fell_seeds": [e["seed"] for e in episodes if e["fell"]],
           "mean_return": float(returns.mean()), "std_return": float(returns.std()),
           "mean_speed": float(np.mean([e["speed"] for e in episodes])),
           "wall_time_s": _fixed(time.perf_counter() - t0, 1), "per_episode": episodes}
    if any("planner_failures" in e for e in episodes):
        row["planner_failures"] = int(sum(e.get("planner_failures", 0) for e in episodes))
    if not quiet:
        print(f"{name:12s} seeds {seeds[0]}-{seeds[-1]}  falls {row['falls']}/{row['episodes']} "
              f"{row['fell_seeds']}  return {row['mean_return']:.1f} ± {row['std_return']:.1f}  speed "
              f"{row['mean_speed']:.3f}  ({row['wall_time_s']:.0f} s)", flush=True)
    return row


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--policies", nargs="+", default=list(POLICIES), choices=POLICIES,
                   help="policies to evaluate (default: all)")
    p.add_argument("--first-seeds", nargs="+", type=int, default=sorted(SEED_USE),
                   help="the first seed of each block of seeds (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per block (default: %(default)s)")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/terrain.json)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    if args.episodes < 1:
        p.error(f"--episodes must be >= 1, got {args.episodes}")
    from hsddp_gym.reports.store import machine_info

    machine = machine_info()
    rows = []
    for first in args.first_seeds:
        seeds = list(range(first, first + args.episodes))
        for name in args.policies:
            rows.append(run_block(name, seeds, args.quiet))
    if args.record:
        from hsddp_gym.reports.store import write_record

        data = {"env_id": TERRAIN, "target_speed": 1.0, "episode_steps": 1000,
                "seed_blocks": [{"seeds": [first, first + args.episodes - 1],
                                 "use": SEED_USE.get(first, "not stated")} for first in args.first_seeds],
                "rows": rows}
        write_record(args.record, data, "The terrain task: the terrain-aware HS-DDP MPC (the episode's terrain as "
                                        "privileged information), the flat-ground MPC and the heuristic on "
                                        "hsddp_gym/Terrain-v0.", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
