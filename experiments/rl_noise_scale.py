"""How much of an RL policy's bounding rests on its exploration noise: the comparison protocol (episodes seeded
0, 1, ..., default env, 1000-step limit) with the policy's own draws, their noise's standard deviation scaled by
each ``--scales`` value: 0 is the mean action (the protocol's deterministic policy), 1 the draws it was trained
with (gSDE: noise weights held for ``sde_sample_freq`` steps). A policy whose return and falls change with the
scale acts differently without the noise it was trained with (e.g. PPO with SB3's white Gaussian noise).

Writes ``noise_scale.md`` and ``noise_scale.json`` (every episode's return, falls, speed; the command) into
``--out`` atomically and prints the table.

Usage::

    python experiments/rl_noise_scale.py --runs runs/rl_lin36/ppo/seed0 runs/ppo_sde37/ppo/seed0 \\
        --out runs/noise_scale [--checkpoint final] [--scales 0 0.25 0.5 1] [--episodes 10] [--noise-seed 0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from hsddp_gym.util.io import atomic_path, write_json


def _scale(text: str) -> float:
    value = float(text)
    if not value >= 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"a scale must be a finite number >= 0, got {text!r}")
    return value


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", nargs="+", required=True,
                   help="PPO/SAC run directories written by train_sb3 (hsddp-gym train / train_rl.py)")
    p.add_argument("--out", required=True, help="output directory (noise_scale.md, noise_scale.json)")
    p.add_argument("--checkpoint", choices=("final", "best"), default="final",
                   help="the run's final weights or its best training-time checkpoint (default: %(default)s)")
    p.add_argument("--scales", type=_scale, nargs="+", default=[0.0, 0.25, 0.5, 1.0],
                   help="multipliers of the noise's standard deviation, 0 = the mean action (default: 0 0.25 0.5 1)")
    p.add_argument("--episodes", type=int, default=10, help="episodes per run and scale, seeds 0.. (default: 10)")
    p.add_argument("--noise-seed", type=int, default=0,
                   help="seed of the policy's noise generator, reset at every episode (default: %(default)s)")
    p.add_argument("--max-episode-steps", type=int, default=None, help="time limit override (default: 1000)")
    args = p.parse_args(argv)
    if args.episodes < 1:
        p.error(f"--episodes must be >= 1, got {args.episodes}")
    missing = [r for r in args.runs if not (Path(r) / "summary.json").exists()]
    if missing:
        p.error(f"--runs: no summary.json in {missing} (not a train_sb3 run directory)")

    from hsddp_gym.learning.reporting import evaluate_policy_episodes
    from hsddp_gym.learning.sb3 import load_trained_policy

    rows = []
    with tqdm(total=len(args.runs) * len(args.scales), desc="runs x scales", unit="cell") as bar:
        for run in args.runs:
            for scale in args.scales:
                policy = (load_trained_policy(run, checkpoint=args.checkpoint) if scale == 0.0 else
                          load_trained_policy(run, deterministic=False, noise_seed=args.noise_seed,
                                              checkpoint=args.checkpoint, noise_scale=scale))
                res = evaluate_policy_episodes(policy, args.episodes, 0, max_episode_steps=args.max_episode_steps)
                rows.append({"run": str(run), "scale": scale, "mean_return": res["mean_return"],
                             "std_return": res["std_return"], "falls": res["falls"], "episodes": res["episodes"],
                             "mean_forward_speed": res["mean_forward_speed"], "returns": res["returns"]})
                bar.update()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"# Own draws with the noise scaled ({args.checkpoint} weights, {args.episodes} episodes, seeds 0.., "
             f"noise seed {args.noise_seed})", "",
             "`python experiments/rl_noise_scale.py " + " ".join(sys.argv[1:] if argv is None else argv) + "`", "",
             "| run | noise scale | return | falls | speed [m/s] |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['run']} | {r['scale']:g}{' (mean action)' if r['scale'] == 0 else ''} | "
                     f"{r['mean_return']:.1f} ± {r['std_return']:.1f} | {r['falls']}/{r['episodes']} | "
                     f"{r['mean_forward_speed']:.2f} |")
    with atomic_path(out / "noise_scale.md") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    write_json(out / "noise_scale.json", {"command": ["experiments/rl_noise_scale.py",
                                                      *(sys.argv[1:] if argv is None else argv)],
                                          "checkpoint": args.checkpoint, "noise_seed": args.noise_seed,
                                          "rows": rows})
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
