"""The pronking task (``hsddp_gym/Pronking-v0``): the expert and BC on unseen seeds, and the expert in the MuJoCo twin.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9500-9519, seeds no dataset
uses) of the default task (1 m/s, 1000 steps, reset noise 0.01); per episode the return, a fall, the mean forward
speed, the fraction of control steps with matching contact flags and the task's success
(:func:`hsddp_gym.envs.pronking.pronking_success`).

    python experiments/pronking.py --mujoco --bc runs/pronk_bc_s0 runs/pronk_bc_s1 runs/pronk_bc_s2 \\
        --record results/tasks/pronking.json --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."
"""

from __future__ import annotations

import argparse
import time

import numpy as np

PRONKING = "hsddp_gym/Pronking-v0"
PRONKING_MUJOCO = "hsddp_gym/PronkingMuJoCo-v0"


def run_episodes(env, policy, seeds) -> list[dict]:
    """Play one episode per seed; per episode: seed, return, length, fell, mean speed, match fraction, success."""
    from hsddp_gym.envs.pronking import contact_match_fraction, pronking_success

    out = []
    target = float(env.unwrapped.target_speed)
    for seed in seeds:
        policy.reset()
        obs, _ = env.reset(seed=int(seed))
        ret, speeds, contacts, fell = 0.0, [], [], False
        while True:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            ret += reward
            speeds.append(info["x_velocity"])
            contacts.append(info["contact"])
            if terminated or truncated:
                fell = bool(terminated)
                break
        speed, match = float(np.mean(speeds)), contact_match_fraction(contacts)
        out.append({"seed": int(seed), "return": float(ret), "length": len(speeds), "fell": fell,
                    "mean_speed": speed, "match_fraction": match,
                    "success": pronking_success(fell, speed, match, target)})
    return out


def summary(episodes: list[dict]) -> dict:
    r = np.array([e["return"] for e in episodes])
    return {"episodes": len(episodes), "mean_return": float(r.mean()), "std_return": float(r.std()),
            "successes": int(sum(e["success"] for e in episodes)), "falls": int(sum(e["fell"] for e in episodes)),
            "mean_speed": float(np.mean([e["mean_speed"] for e in episodes])),
            "mean_match_fraction": float(np.mean([e["match_fraction"] for e in episodes])),
            "min_match_fraction": float(np.min([e["match_fraction"] for e in episodes]))}


def evaluate(label: str, env_id: str, make, seeds, quiet: bool) -> dict:
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)

    env = gym.make(env_id)
    policy = make(env)
    t = time.perf_counter()
    eps = run_episodes(env, policy, seeds)
    env.close()
    row = {"label": label, "env_id": env_id, **summary(eps), "wall_time_s": time.perf_counter() - t, "per_episode": eps}
    if not quiet:
        print(f"{label:28s} {env_id:30s} return {row['mean_return']:8.1f} ± {row['std_return']:6.1f}  success "
              f"{row['successes']}/{row['episodes']}  falls {row['falls']}  speed {row['mean_speed']:.3f}  match "
              f"{row['mean_match_fraction']:.3f} (min {row['min_match_fraction']:.3f})", flush=True)
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
    p.add_argument("--seed", type=int, default=9500, help="first evaluation seed (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per policy (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR), one per "
                                                       "training seed")
    p.add_argument("--mujoco", action="store_true", help="also run the expert in hsddp_gym/PronkingMuJoCo-v0")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/pronking.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the BC runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)

    from hsddp_gym.workflows import load_policy, pronking_expert

    seeds = list(range(args.seed, args.seed + args.episodes))
    rows = [evaluate("expert", PRONKING, pronking_expert, seeds, args.quiet)]
    if args.mujoco:
        rows.append(evaluate("expert", PRONKING_MUJOCO, pronking_expert, seeds, args.quiet))
    bc_rows = []
    import json
    from pathlib import Path

    for run in args.bc:
        train = json.loads((Path(run) / "summary.json").read_text())
        row = evaluate(f"BC (training seed {train['seed']})", PRONKING,
                       lambda env, run=run: load_policy(f"bc:{run}", env), seeds, args.quiet)
        row.update(run=str(run), training_seed=int(train["seed"]), transitions=int(train["transitions"]),
                   demonstrations=int(train["demonstrations"]), train_wall_time_s=float(train["wall_time_s"]),
                   dataset_id=train.get("dataset_id"))
        bc_rows.append(row)
    if args.record:
        from hsddp_gym.reports.store import invoked_command, write_record

        data = {"env_id": PRONKING, "seeds": seeds, "target_speed": 1.0, "rows": rows, "bc": bc_rows,
                "success_rule": "no fall, mean forward speed within 20 % of the target, >= 80 % of control steps "
                                "with matching contact flags (hsddp_gym.envs.pronking.pronking_success)"}
        write_record(args.record, data, "The pronking task: the HS-DDP pronk expert (Pronking-v0 and its MuJoCo "
                                        "twin) and BC from its demonstrations on unseen seeds.",
                     command=list(args.made_with) + [invoked_command(_without_made_with(argv))])
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
