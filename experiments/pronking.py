"""The pronking task (``hsddp_gym/Pronking-v0``): the expert, BC, DAgger and SAC on unseen seeds, and the expert in the
MuJoCo twin.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9500-9519, seeds no dataset
uses) of the default task (1 m/s, 1000 steps, reset noise 0.01); per episode the return, a fall, the mean forward
speed, the fraction of control steps with matching contact flags and the task's success
(:func:`hsddp_gym.envs.pronking.pronking_success`).

    python experiments/pronking.py --mujoco --bc runs/pronk_bc_s0 runs/pronk_bc_s1 runs/pronk_bc_s2 \\
        --dagger runs/pronk_dagger_s0 runs/pronk_dagger_s1 runs/pronk_dagger_s2 --sac runs/pronk_sac_s0 \\
        --record results/tasks/pronking.json --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs, ``--sac`` takes ``hsddp-gym train
--algo sac --env hsddp_gym/Pronking-v0 --out DIR`` runs, each evaluated with its final weights and its best
checkpoint (the best training-time evaluation, on the run's own seeds), both with the mean action.
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=9500, help="first evaluation seed (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per policy (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR), one per "
                                                       "training seed")
    p.add_argument("--dagger", nargs="*", default=[], help="DAgger runs (hsddp-gym train --algo dagger --env "
                                                           "hsddp_gym/Pronking-v0 --out DIR), one per training seed")
    p.add_argument("--sac", nargs="*", default=[], help="SAC runs (hsddp-gym train --algo sac --env "
                                                        "hsddp_gym/Pronking-v0 --out DIR), one per training seed; "
                                                        "final weights and best checkpoint")
    p.add_argument("--mujoco", action="store_true", help="also run the expert in hsddp_gym/PronkingMuJoCo-v0")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/pronking.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the BC runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    import json
    from pathlib import Path

    for flag, runs, algo in (("--bc", args.bc, "bc"), ("--dagger", args.dagger, "dagger"), ("--sac", args.sac, "sac")):
        for run in runs:
            f = Path(run) / "summary.json"
            if not f.exists():
                p.error(f"{flag}: {run} has no summary.json (not a finished hsddp-gym train run)")
            train = json.loads(f.read_text())
            if train.get("algo") != algo or (algo != "bc" and train.get("env_id") != PRONKING):
                p.error(f"{flag}: {run} is a {train.get('algo')} run in {train.get('env_id')}, not {algo} in "
                        f"{PRONKING}")

    from hsddp_gym.learning.reporting import imitation_run_fields
    from hsddp_gym.workflows import load_policy, pronking_expert

    seeds = list(range(args.seed, args.seed + args.episodes))
    rows = [evaluate("expert", PRONKING, pronking_expert, seeds, args.quiet)]
    if args.mujoco:
        rows.append(evaluate("expert", PRONKING_MUJOCO, pronking_expert, seeds, args.quiet))
    bc_rows = []
    for run in args.bc:
        fields = imitation_run_fields(run, "bc")
        row = evaluate(f"BC (training seed {fields['training_seed']})", PRONKING,
                       lambda env, run=run: load_policy(f"bc:{run}", env), seeds, args.quiet)
        bc_rows.append({**row, **fields})
    dagger_rows = []
    for run in args.dagger:
        fields = imitation_run_fields(run, "dagger")
        rounds = f"{fields['rounds']} round{'s' if fields['rounds'] != 1 else ''}"
        row = evaluate(f"DAgger, {rounds} (training seed {fields['training_seed']})", PRONKING,
                       lambda env, run=run: load_policy(f"dagger:{run}", env), seeds, args.quiet)
        dagger_rows.append({**row, **fields})
    sac_rows = []
    for run in args.sac:
        from hsddp_gym.learning.sb3 import load_trained_policy

        train = json.loads((Path(run) / "summary.json").read_text())
        for checkpoint in ("final", "best"):
            if checkpoint == "best" and not train.get("best_checkpoint"):
                continue
            name = "final weights" if checkpoint == "final" else "best checkpoint"
            row = evaluate(f"SAC (training seed {train['seed']}, {name})", PRONKING,
                           lambda env, run=run, c=checkpoint: load_trained_policy(run, env, checkpoint=c), seeds,
                           args.quiet)
            best = train.get("best_checkpoint") or {}
            row.update(run=str(run), training_seed=int(train["seed"]), checkpoint=checkpoint,
                       env_steps=int(train["steps"]) if checkpoint == "final" else int(best["env_step"]),
                       total_env_steps=int(train["steps"]), train_wall_time_s=float(train["wall_time_s"]),
                       time_limit_s=train.get("time_limit_s"), preset=train.get("preset"),
                       hyperparameters=train["hyperparameters"])
            sac_rows.append(row)
    if args.record:
        from hsddp_gym.reports.store import invoked_command, without_option, write_record

        data = {"env_id": PRONKING, "seeds": seeds, "target_speed": 1.0, "rows": rows, "bc": bc_rows,
                "dagger": dagger_rows, "sac": sac_rows,
                "success_rule": "no fall, mean forward speed within 20 % of the target, >= 80 % of control steps "
                                "with matching contact flags (hsddp_gym.envs.pronking.pronking_success)"}
        write_record(args.record, data, "The pronking task: the HS-DDP pronk expert (Pronking-v0 and its MuJoCo "
                                        "twin), BC from its demonstrations, DAgger labelled by it and SAC on unseen "
                                        "seeds.",
                     command=list(args.made_with) + [invoked_command(without_option(argv, "--made-with"))])
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
