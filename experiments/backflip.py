"""The backflip task (``hsddp_gym/Backflip-v0``): the HS-DDP backflip expert, BC (and DAgger) on unseen seeds, and the
expert in the MuJoCo twin.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9600-9619, seeds no dataset
uses) of the default task (400 steps = 2 s, reset noise 0.01); per episode the return, a fall, the lowest pitch, the
final pitch, the lowest trunk clearance and the task's success (``info["success"]`` at the episode's last step:
:func:`hsddp_gym.envs.backflip.backflip_success`).

    hsddp-gym dataset --env hsddp_gym/Backflip-v0 --policy expert --episodes 24 --seed 1000 --action-noise 0.01 \\
        --out runs/backflip_expert24_dart
    hsddp-gym train --algo bc --dataset runs/backflip_expert24_dart --seed 0 --out runs/backflip_bc_s0
    python experiments/backflip.py --mujoco --bc runs/backflip_bc_s0 ... --record results/tasks/backflip.json \\
        --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs (BC's dataset and DAgger's env must
be Backflip-v0's), evaluated with their final weights.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

BACKFLIP = "hsddp_gym/Backflip-v0"
BACKFLIP_MUJOCO = "hsddp_gym/BackflipMuJoCo-v0"
PER_EPISODE = ("seed", "return", "length", "fell", "success", "final_pitch")
"""The per-episode values the record keeps."""


def run_episodes(env, policy, seeds) -> list[dict]:
    """Play one episode per seed; per episode: seed, return, length, fell, lowest and final pitch, lowest trunk
    clearance, success."""
    out = []
    for seed in seeds:
        policy.reset()
        obs, info = env.reset(seed=int(seed))
        ret, n, min_pitch, clearance = 0.0, 0, float(info["qpos"][2]), float(info["trunk_clearance"])
        while True:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            ret += reward
            n += 1
            min_pitch = min(min_pitch, float(info["qpos"][2]))
            clearance = min(clearance, float(info["trunk_clearance"]))
            if terminated or truncated:
                break
        out.append({"seed": int(seed), "return": round(float(ret), 3), "length": n, "fell": bool(terminated),
                    "min_pitch": round(min_pitch, 4), "final_pitch": round(float(info["qpos"][2]), 4),
                    "min_trunk_clearance": round(clearance, 4), "success": bool(info["success"])})
    return out


def summary(episodes: list[dict]) -> dict:
    r = np.array([e["return"] for e in episodes])
    return {"episodes": len(episodes), "mean_return": float(r.mean()), "std_return": float(r.std()),
            "successes": int(sum(e["success"] for e in episodes)), "falls": int(sum(e["fell"] for e in episodes)),
            "mean_final_pitch": float(np.mean([e["final_pitch"] for e in episodes])),
            "mean_min_pitch": float(np.mean([e["min_pitch"] for e in episodes])),
            "min_trunk_clearance": float(np.min([e["min_trunk_clearance"] for e in episodes]))}


def evaluate(label: str, env_id: str, make, seeds, quiet: bool) -> dict:
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)

    env = gym.make(env_id)
    policy = make(env)
    t = time.perf_counter()
    eps = run_episodes(env, policy, seeds)
    env.close()
    row = {"label": label, "env_id": env_id, **summary(eps), "wall_time_s": time.perf_counter() - t,
           "per_episode": [{k: e[k] for k in PER_EPISODE} for e in eps]}
    if not quiet:
        print(f"{label:28s} {env_id:30s} return {row['mean_return']:8.1f} ± {row['std_return']:6.1f}  success "
              f"{row['successes']}/{row['episodes']}  falls {row['falls']}  final pitch {row['mean_final_pitch']:.3f}"
              f"  min trunk clearance {row['min_trunk_clearance']:.3f} m", flush=True)
    return row


def _without_made_with(argv) -> list[str]:
    import sys

    out, skip = [], False
    for a in (sys.argv[1:] if argv is None else list(argv)):
        if a == "--made-with":
            skip = True
        elif skip and a.startswith("--"):
            skip = False
        if not skip:
            out.append(a)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=9600, help="first evaluation seed (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per policy (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR) on a "
                                                       "Backflip-v0 dataset, one per training seed")
    p.add_argument("--dagger", nargs="*", default=[], help="DAgger runs (hsddp-gym train --algo dagger --env "
                                                           "hsddp_gym/Backflip-v0 --out DIR), one per training seed")
    p.add_argument("--mujoco", action="store_true", help="also run the expert in hsddp_gym/BackflipMuJoCo-v0")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/backflip.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the learners' runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    import json
    from pathlib import Path

    for flag, runs, algo in (("--bc", args.bc, "bc"), ("--dagger", args.dagger, "dagger")):
        for run in runs:
            f = Path(run) / "summary.json"
            if not f.exists():
                p.error(f"{flag}: {run} has no summary.json (not a finished hsddp-gym train run)")
            train = json.loads(f.read_text())
            if train.get("algo") != algo or train.get("env_id") != BACKFLIP:
                p.error(f"{flag}: {run} is a {train.get('algo')} run in {train.get('env_id')}, not {algo} in "
                        f"{BACKFLIP}")

    from hsddp_gym.workflows import backflip_expert, load_policy

    seeds = list(range(args.seed, args.seed + args.episodes))
    rows = [evaluate("expert", BACKFLIP, backflip_expert, seeds, args.quiet)]
    if args.mujoco:
        rows.append(evaluate("expert", BACKFLIP_MUJOCO, backflip_expert, seeds, args.quiet))
    bc_rows = []
    for run in args.bc:
        train = json.loads((Path(run) / "summary.json").read_text())
        row = evaluate(f"BC (training seed {train['seed']})", BACKFLIP,
                       lambda env, run=run: load_policy(f"bc:{run}", env), seeds, args.quiet)
        row.update(run=str(run), training_seed=int(train["seed"]), transitions=int(train["transitions"]),
                   demonstrations=int(train["demonstrations"]), train_wall_time_s=float(train["wall_time_s"]),
                   dataset_id=train.get("dataset_id"))
        bc_rows.append(row)
    dagger_rows = []
    for run in args.dagger:
        train = json.loads((Path(run) / "summary.json").read_text())
        cfg = train["config"]
        rounds = f"{cfg['rounds']} round{'s' if cfg['rounds'] != 1 else ''}"
        row = evaluate(f"DAgger, {rounds} (training seed {train['seed']})", BACKFLIP,
                       lambda env, run=run: load_policy(f"dagger:{run}", env), seeds, args.quiet)
        row.update(run=str(run), training_seed=int(train["seed"]), expert_labels=int(train["expert_labels"]),
                   transitions=int(train["transitions"]), initial_demonstrations=train.get("initial_demonstrations"),
                   rounds=int(cfg["rounds"]), episodes_per_round=int(cfg["episodes_per_round"]),
                   train_wall_time_s=float(train["wall_time_s"]))
        dagger_rows.append(row)
    if args.record:
        from hsddp_gym.reports.store import invoked_command, write_record

        data = {"env_id": BACKFLIP, "seeds": seeds, "max_episode_steps": 400, "rows": rows, "bc": bc_rows,
                "dagger": dagger_rows,
                "success_rule": "no fall (the trunk never touched the ground), a full turn, and at the end upright "
                                "(pitch within 0.3 rad of -2 pi, trunk at least 0.15 m high) on both feet and still "
                                "(trunk speed <= 0.3 m/s, pitch rate <= 1 rad/s) "
                                "(hsddp_gym.envs.backflip.backflip_success)"}
        write_record(args.record, data, "The backflip task: the HS-DDP backflip expert (Backflip-v0 and its MuJoCo "
                                        "twin) and BC (and DAgger) from its demonstrations on unseen seeds.",
                     command=list(args.made_with) + [invoked_command(_without_made_with(argv))])
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
