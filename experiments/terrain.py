"""The terrain task (``hsddp_gym/Terrain-v0``): the terrain-aware MPC expert, the flat-ground MPC and the heuristic.

Each policy plays one episode per seed of the registered task (a new ``"random_mixed"`` profile per reset seed: steps
up to 3 cm, slopes up to 0.1, levels within 15 cm, flat for x < 0.6 m; 1 m/s, 1000 steps). The policies:

* ``mpc-terrain``: ``MPCPolicy(EnvInterface.from_env(env), MPCOptions(), terrain=env_terrain(env))``, the MPC given
  each episode's terrain as privileged information (``docs/policies/mpc.md#terrain``);
* ``mpc``: the same MPC without it (it plans for flat ground, the feet on the ground setting its height);
* ``heuristic``: ``HeuristicPolicy`` (flat ground).

Three blocks of seeds by default (:data:`SEED_USE` says what each was used for before the recorded run): 9800-9819,
on which the flat-ground MPC's falls were diagnosed, 9820-9839, the held-out block of the terrain-aware MPC's first
evaluation, and 9840-9859, used by no run before the table's first record. Per episode: the return, a fall (and when and
where), the mean forward speed and, for the MPCs, the re-plans that failed.

With ``--bc`` / ``--dagger`` (``hsddp-gym train --algo bc|dagger --out DIR`` runs from a Terrain-v0 dataset of the
terrain-aware MPC, the task's expert, evaluated with their final weights) a fourth block, 9860-9879
(``--learner-seed``), plays the terrain-aware MPC and every learner on the same seeds, none of which a dataset or
training run used:

    hsddp-gym dataset --env hsddp_gym/Terrain-v0 --policy mpc --episodes 24 --workers 1 --seed 1000 \\
        --action-noise 0.01 --out runs/terrain_mpc24_dart
    hsddp-gym train --algo bc --dataset runs/terrain_mpc24_dart --seed 0 --out runs/terrain_bc_s0   # seeds 0, 1, 2
    hsddp-gym train --algo dagger --env hsddp_gym/Terrain-v0 --dataset runs/terrain_mpc24_dart --rounds 4 \\
        --episodes-per-round 8 --seed 0 --out runs/terrain_dagger4_s0                              # seeds 0, 1
    python experiments/terrain.py --bc runs/terrain_bc_s0 runs/terrain_bc_s1 runs/terrain_bc_s2 \\
        --dagger runs/terrain_dagger4_s0 runs/terrain_dagger4_s1 --record results/tasks/terrain.json \\
        --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

The record keeps one line per episode (:data:`EPISODE_FIELDS`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

TERRAIN = "hsddp_gym/Terrain-v0"
POLICIES = ("mpc-terrain", "mpc", "heuristic")
SEED_USE = {
    9800: "the flat-ground MPC's falls were diagnosed on them",
    9820: "held out while the terrain-aware MPC was designed; its first evaluation on them had no fall, and the failed "
          "re-plans it had on slopes (9838, 9839) then led to the slope term of the switching constraint's gradient",
    9840: "used by no run before this table's first record",
}
"""What each default block of seeds (by its first seed) was used for before the recorded run."""
LABELS = {
    "mpc-terrain": "MPCPolicy(..., terrain=env_terrain(env))",
    "mpc": "MPCPolicy(EnvInterface.from_env(env), MPCOptions())",
    "heuristic": "HeuristicPolicy",
}
LEARNER_SEED = 9860
"""The first seed of the learners' block (``--bc`` / ``--dagger``), used by no run before the recorded one."""
LEARNER_USE = ("the learners beside the terrain-aware MPC, their expert: used by no dataset, training run or "
               "evaluation in Terrain-v0 before this record")
EPISODE_FIELDS = ("seed", "return", "length", "fell", "speed", "max_level", "planner_failures", "fall_x")
"""The per-episode values of a row, in order (``planner_failures`` None for a policy without a planner,
``fall_x`` the trunk x [m] at a fall, None without one; the fall's time is ``length`` control steps)."""


def _fixed(value: float, digits: int) -> float:
    """``value`` to ``digits`` decimals (a compact record)."""
    return float(f"{float(value):.{digits}f}")


def make_policy(name: str, env):
    """The policy ``name`` (:data:`POLICIES`) for ``env``: ``mpc-terrain`` the terrain-aware MPC (the MPC of the
    Terrain-v0 task), ``mpc`` the flat-ground one, ``heuristic``."""
    from hsddp_gym.rollout.policies import PolicySpec
    from hsddp_gym.rollout.policies import make_policy as make

    if name not in POLICIES:
        raise ValueError(f"policy must be one of {list(POLICIES)}, got {name!r}")
    if name == "mpc-terrain":
        return make(PolicySpec("mpc", env_id=TERRAIN), env)
    return make(PolicySpec(name), env)


def run_block(name: str, seeds, quiet: bool = False, make=None, label: str | None = None) -> dict:
    """Play ``name`` on ``hsddp_gym/Terrain-v0`` once per seed (``make``: ``env -> policy``, default
    :func:`make_policy`; ``label``: default :data:`LABELS`'s): the summary and one line per episode
    (:data:`EPISODE_FIELDS`)."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.rollout.episodes import run_episode

    env = gym.make(TERRAIN)
    policy = make(env) if make is not None else make_policy(name, env)
    episodes = []
    t0 = time.perf_counter()
    for seed in seeds:
        r = run_episode(env, policy, int(seed))
        stats = getattr(policy, "stats", {})
        levels = np.abs(env.unwrapped.terrain.levels)
        ep = {"seed": int(seed), "return": _fixed(r.episode_return, 2), "length": int(r.length), "fell": bool(r.fell),
              "speed": _fixed(r.forward_speed, 4), "max_level": _fixed(float(levels.max()), 4),
              "planner_failures": int(stats["planner_failures"]) if "planner_failures" in stats else None,
              "fall_x": _fixed(float(r.states[-1, 0]), 3) if r.fell else None}
        episodes.append(ep)
    env.close()
    returns = np.array([e["return"] for e in episodes])
    row = {"policy": name, "label": label or LABELS[name], "seeds": [int(seeds[0]), int(seeds[-1])],
           "episodes": len(episodes), "falls": int(sum(e["fell"] for e in episodes)),
           "fell_seeds": [e["seed"] for e in episodes if e["fell"]],
           "mean_return": float(returns.mean()), "std_return": float(returns.std()),
           "mean_speed": float(np.mean([e["speed"] for e in episodes])),
           "wall_time_s": _fixed(time.perf_counter() - t0, 1)}
    if any(e["planner_failures"] is not None for e in episodes):
        row["planner_failures"] = int(sum(e["planner_failures"] or 0 for e in episodes))
    row["per_episode"] = [[e[k] for k in EPISODE_FIELDS] for e in episodes]
    if not quiet:
        print(f"{name:12s} seeds {seeds[0]}-{seeds[-1]}  falls {row['falls']}/{row['episodes']} "
              f"{row['fell_seeds']}  return {row['mean_return']:.1f} ± {row['std_return']:.1f}  speed "
              f"{row['mean_speed']:.3f}  ({row['wall_time_s']:.0f} s)", flush=True)
    return row


def _train_summary(parser, flag: str, run: str, algo: str) -> dict:
    """The ``summary.json`` of a finished ``hsddp-gym train --algo ALGO`` run in Terrain-v0 (else a usage error)."""
    f = Path(run) / "summary.json"
    if not f.exists():
        parser.error(f"{flag}: {run} has no summary.json (not a finished hsddp-gym train run)")
    train = json.loads(f.read_text())
    if train.get("algo") != algo or train.get("env_id") != TERRAIN:
        parser.error(f"{flag}: {run} is a {train.get('algo')} run in {train.get('env_id')}, not {algo} in {TERRAIN}")
    return train


def learner_rows(bc, dagger, seeds, quiet: bool = False) -> list[dict]:
    """The terrain-aware MPC and the learners (``bc`` / ``dagger``: run directories with their ``summary.json``)
    on ``seeds``: one row each, the learners' with their samples and training time."""
    from hsddp_gym.rollout.policies import make_policy as load_policy

    rows = [run_block("mpc-terrain", seeds, quiet)]
    for algo, runs in (("bc", bc), ("dagger", dagger)):
        for run, train in runs:
            if algo == "bc":
                label = f"BC (training seed {train['seed']})"
                extra = {"demonstrations": int(train["demonstrations"]), "transitions": int(train["transitions"])}
            else:
                cfg = train["config"]
                label = (f"DAgger, {cfg['rounds']} iteration{'s' if cfg['rounds'] != 1 else ''} (training seed "
                         f"{train['seed']})")
                extra = {"initial_demonstrations": train.get("initial_demonstrations"),
                         "expert_labels": int(train["expert_labels"]), "transitions": int(train["transitions"]),
                         "rounds": int(cfg["rounds"]), "episodes_per_round": int(cfg["episodes_per_round"])}
            row = run_block(algo, seeds, quiet, make=lambda env, spec=f"{algo}:{run}": load_policy(spec, env),
                            label=label)
            per_episode = row.pop("per_episode")
            row.update(run=str(run), training_seed=int(train["seed"]), dataset_id=train.get("dataset_id"), **extra,
                       train_wall_time_s=_fixed(train["wall_time_s"], 1), per_episode=per_episode)
            rows.append(row)
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--policies", nargs="+", default=list(POLICIES), choices=POLICIES,
                   help="policies to evaluate (default: all)")
    p.add_argument("--first-seeds", nargs="+", type=int, default=sorted(SEED_USE),
                   help="the first seed of each block of seeds (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per block (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR) on a "
                                                       "Terrain-v0 dataset, one per training seed")
    p.add_argument("--dagger", nargs="*", default=[], help="DAgger runs (hsddp-gym train --algo dagger --env "
                                                           "hsddp_gym/Terrain-v0 --out DIR), one per training seed")
    p.add_argument("--learner-seed", type=int, default=LEARNER_SEED,
                   help="the first seed of the learners' block, --episodes seeds (default: %(default)s)")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/terrain.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the learners' runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    if args.episodes < 1:
        p.error(f"--episodes must be >= 1, got {args.episodes}")
    bc = [(run, _train_summary(p, "--bc", run, "bc")) for run in args.bc]
    dagger = [(run, _train_summary(p, "--dagger", run, "dagger")) for run in args.dagger]
    from hsddp_gym.reports.store import machine_info

    machine = machine_info()
    rows = []
    for first in args.first_seeds:
        seeds = list(range(first, first + args.episodes))
        for name in args.policies:
            rows.append(run_block(name, seeds, args.quiet))
    blocks = [{"seeds": [first, first + args.episodes - 1], "use": SEED_USE.get(first, "not stated")}
              for first in args.first_seeds]
    if bc or dagger:
        seeds = list(range(args.learner_seed, args.learner_seed + args.episodes))
        rows += learner_rows(bc, dagger, seeds, args.quiet)
        blocks.append({"seeds": [seeds[0], seeds[-1]],
                       "use": LEARNER_USE if args.learner_seed == LEARNER_SEED else "not stated"})
    if args.record:
        from hsddp_gym.reports.store import invoked_command, without_option, write_record

        data = {"env_id": TERRAIN, "target_speed": 1.0, "episode_steps": 1000, "seed_blocks": blocks,
                "episode_fields": list(EPISODE_FIELDS), "rows": rows}
        write_record(args.record, data, "The terrain task: the terrain-aware HS-DDP MPC (the episode's terrain as "
                                        "privileged information), the flat-ground MPC, the heuristic, and BC and "
                                        "DAgger from the terrain-aware MPC's demonstrations on "
                                        "hsddp_gym/Terrain-v0.", machine=machine,
                     command=list(args.made_with) + [invoked_command(without_option(argv, "--made-with"))])
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
