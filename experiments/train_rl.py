"""RL baselines on hsddp_gym/Bounding-v0 (or --env): PPO and SAC with RL-Zoo hyperparameters, several training seeds.

Hyperparameters (hsddp_gym.learning.sb3.PRESETS, from rl-baselines3-zoo hyperparams/*.yml), ``--preset``:

* PPO ``hopper`` (default; Hopper-v3, a task that ends on falls like this one): VecNormalize (obs + reward),
  1 env (``--n-envs``), n_steps 512, batch 32, gamma 0.999, gae_lambda 0.99, lr 9.80828e-5, clip 0.2,
  n_epochs 5, ent_coef 2.3e-3, max_grad_norm 0.7, vf_coef 0.836, policy_kwargs log_std_init -2,
  ortho_init False, ReLU, pi/vf [256, 256].
* PPO ``halfcheetah`` (HalfCheetah-v3, never terminates): n_steps 512, batch 64, gamma 0.98, gae_lambda 0.92,
  lr 2.0633e-5, clip 0.1, n_epochs 20, ent_coef 4e-4, max_grad_norm 0.8, vf_coef 0.58, the same policy_kwargs.
* SAC: SB3 defaults (lr 3e-4, buffer 1e6, batch 256, tau 0.005, gamma 0.99, train_freq 1, gradient_steps 1,
  auto entropy, [256, 256] ReLU) + learning_starts 10000.

Each run writes into OUT/ALGO/seedS: model.zip, vecnormalize.{pkl,npz} (PPO), train.monitor.csv,
evaluations.npz, best_model.zip / best_vecnormalize.npz (the checkpoint of the best training-time evaluation),
curve.csv / eval_curve.csv / curve.png (return vs env steps) and summary.json (hyperparameters, wall time, the
protocol evaluations on seeds 0..9: ``eval`` the final weights' mean action, ``eval_best`` the best checkpoint's,
``eval_stochastic`` the final weights' own draws; each printed per seed and as a mean with its 95 % interval). One
run is the same as ``hsddp-gym train --algo ALGO --steps N --seed S --out DIR``.

Usage:
    python experiments/train_rl.py --algos ppo sac --seeds 0 --steps 50000 --out runs/rl      # short check
    python experiments/train_rl.py --algos ppo sac --seeds 0 1 2 3 4 --steps 1000000 --out runs/rl  # the protocol
    python experiments/train_rl.py --algos ppo --preset parallel --vector-env --seeds 0 1 2 \\
        --steps 100000000 --time-limit 1200 --eval-freq 500000 --out runs/rl_parallel     # 64 robots, 20 min each
    python experiments/train_rl.py --env hsddp_gym/Pronking-v0 --algos sac --seeds 0 --steps 1000000 \\
        --time-limit 1500 --eval-freq 10000 --out runs/rl_pronk                           # the pronking task

``--env`` picks the env every run trains and is evaluated in (hsddp_gym.learning.sb3.ENV_IDS; default
hsddp_gym/Bounding-v0); every one of them has a compiled vector env (``--vector-env``) and takes the robustness
conditions (``--train-condition``; a task's without ``--vector-env``). ``--residual SCALE`` learns a residual on the
task's plan-tracking expert (``hsddp_gym.learning.residual``).

The machine is shared: one torch thread per run, runs one after the other. Measured throughput on this
2-core machine (shared) is printed at the end of every run (env steps / wall second).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.learning.reporting import mean_ci95
from hsddp_gym.learning.residual import check_residual_scale
from hsddp_gym.learning.sb3 import (
    ALGOS,
    ENV_ID,
    ENV_IDS,
    OPTION_HELP,
    check_env_id,
    check_train_condition,
    hyperparameters,
    parse_learning_rate,
    train_sb3,
)

EVALS = ("eval", "eval_best", "eval_stochastic")
"""The protocol evaluations of each run's summary: the final weights' mean action, the best checkpoint's mean action
(chosen by the training-time evaluations, on their own seeds), the final weights' own draws."""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", choices=ENV_IDS, default=ENV_ID,
                   help="the env to train and evaluate in (default: %(default)s)")
    p.add_argument("--algos", nargs="+", choices=ALGOS, default=list(ALGOS), help="algorithms (default: both)")
    p.add_argument("--seeds", nargs="+", type=int, default=[0], help="training seeds, one run each (default: 0)")
    p.add_argument("--steps", type=int, default=1_000_000, help="env steps per run (default: %(default)s)")
    p.add_argument("--out", default="runs/rl", help="runs go to OUT/ALGO/seedS (default: %(default)s)")
    p.add_argument("--learning-starts", type=int, default=None, help="SAC override (zoo: 10000)")
    p.add_argument("--eval-freq", type=int, default=None,
                   help="env steps between training-time evaluations (they pick the best checkpoint)")
    p.add_argument("--select-episodes", type=int, default=5,
                   help="episodes of each training-time evaluation: the best checkpoint is the one with the highest "
                        "mean return over that many episodes (default: %(default)s)")
    p.add_argument("--eval-episodes", type=int, default=10, help="final evaluation episodes (seeds 0..)")
    p.add_argument("--progress", action="store_true", help="SB3 progress bar")
    p.add_argument("--preset", choices=("hopper", "halfcheetah", "parallel"), default="hopper",
                   help="hyperparameter set: RL-Zoo Hopper-v3 or HalfCheetah-v3, or (PPO) legged_gym's massively "
                        "parallel PPO on a CPU, for --vector-env (default: %(default)s)")
    p.add_argument("--n-envs", type=int, default=None, help="envs stepped together (default: the preset's)")
    p.add_argument("--vector-env", action="store_true",
                   help="step the --n-envs training robots in the compiled vector env (one numba call for all)")
    p.add_argument("--time-limit", type=float, default=None,
                   help="wall-clock budget per run [s]: training stops there and reports the steps that fit")
    p.add_argument("--hidden", default=None,
                   help="hidden layer sizes of every network, actor and critic alike, comma-separated, e.g. 128,128 "
                        "(default: the preset's; SAC 256,256)")
    p.add_argument("--learning-rate", default=None, help=OPTION_HELP["learning_rate"])
    p.add_argument("--sde", action="store_true", help=OPTION_HELP["sde"])
    p.add_argument("--log-std-init", type=float, default=None, help=OPTION_HELP["log_std_init"])
    p.add_argument("--train-condition", default=None, metavar="CONDITION",
                   help="train every robot under this condition of the robustness suite (domain randomization), "
                        "e.g. push_x3 (three random pushes an episode) or push; the evaluations that pick and score "
                        "the policy stay on the unperturbed task; with --vector-env only conditions of env "
                        "arguments and pushes (default: none)")
    p.add_argument("--residual", type=float, default=None, metavar="SCALE",
                   help="learn a residual on the task's plan-tracking expert with this scale in (0, 2] "
                        "(hsddp_gym.learning.residual; not with --vector-env) (default: the learner acts alone)")
    args = p.parse_args(argv)
    try:
        check_env_id(args.env, args.vector_env, args.train_condition)
    except ValueError as e:
        p.error(f"--train-condition: {e}")
    if args.residual is not None:
        try:
            check_residual_scale(args.residual, "--residual")
        except ValueError as e:
            p.error(str(e))
        if args.vector_env:
            p.error("--residual: given with --vector-env (the expert acts per robot): train it in single envs")
    if args.train_condition is not None:
        try:
            check_train_condition(args.train_condition, vector_env=args.vector_env)
        except ValueError as e:
            p.error(f"--train-condition: {e}")
    if args.select_episodes < 1:
        p.error(f"--select-episodes must be >= 1, got {args.select_episodes}")
    if args.n_envs is not None and args.n_envs < 1:
        p.error(f"--n-envs must be >= 1, got {args.n_envs}")
    if args.sde and args.algos != ["ppo"]:
        p.error(f"--sde is offered for PPO only: give --algos ppo, got {' '.join(args.algos)}")
    if args.preset == "parallel" and args.algos != ["ppo"]:
        p.error(f"--preset parallel is a PPO preset: give --algos ppo, got {' '.join(args.algos)}")
    rows = []
    for algo in args.algos:
        for seed in args.seeds:
            out = Path(args.out) / algo / f"seed{seed}"
            overrides = ({"learning_starts": args.learning_starts}
                         if algo == "sac" and args.learning_starts is not None else {})
            if args.n_envs is not None:
                overrides["n_envs"] = args.n_envs
            if args.learning_rate is not None:
                try:
                    overrides["learning_rate"] = parse_learning_rate(args.learning_rate)
                except ValueError as e:
                    p.error(f"--learning-rate: {e}")
            if args.sde:
                overrides["sde"] = True
            if args.log_std_init is not None:
                overrides["log_std_init"] = args.log_std_init
            if args.hidden is not None:
                try:
                    overrides["net_arch"] = [int(w) for w in args.hidden.split(",")]
                except ValueError:
                    p.error(f"--hidden: must be comma-separated integers, got {args.hidden!r}")
            try:
                hyperparameters(algo, overrides, args.preset)
            except ValueError as e:  # name the option whose value hyperparameters() refused
                flag = {"learning_rate": "--learning-rate", "net_arch": "--hidden",
                        "log_std_init": "--log-std-init"}.get(str(e).split()[0])
                p.error(f"{flag}: {e}" if flag else str(e))
            res = train_sb3(algo, args.steps, seed, out, overrides=overrides or None, eval_freq=args.eval_freq,
                            eval_episodes=args.select_episodes, final_eval_episodes=args.eval_episodes,
                            progress=args.progress,
                            time_limit=args.time_limit, preset=args.preset, vector_env=args.vector_env,
                            train_condition=args.train_condition, env_id=args.env, residual_scale=args.residual)
            s = res.summary
            evals = {k: s.get(k) or {} for k in EVALS}
            rows.append((algo, seed, s["steps"], s["wall_time_s"], evals))
            nan = float("nan")
            print(f"{algo} seed {seed}: {s['steps']} steps in {s['wall_time_s']:.0f} s "
                  f"({s['steps'] / s['wall_time_s']:.0f} steps/s); " + "; ".join(
                      f"{k} {e.get('mean_return', nan):.1f} +- {e.get('std_return', nan):.1f}, falls "
                      f"{e.get('falls')}/{e.get('episodes')}" for k, e in evals.items() if e) + f" -> {out}",
                  flush=True)
    print("\n| algo | seed | env steps | wall [s] | " + " | ".join(f"{k}: return, falls" for k in EVALS) + " |\n|"
          + "---|" * (4 + len(EVALS)))
    for algo, seed, steps, wall, evals in rows:
        cells = [f"{e['mean_return']:.1f} ± {e['std_return']:.1f}, {e['falls']}/{e['episodes']}" if e else "-"
                 for e in evals.values()]
        print(f"| {algo} | {seed} | {steps} | {wall:.0f} | " + " | ".join(cells) + " |")
    for algo in args.algos:  # over the training seeds: the mean and its 95 % Student-t interval
        for k in EVALS:
            means = [e[k]["mean_return"] for a, _, _, _, e in rows if a == algo and e[k]]
            if len(means) >= 2:
                mean, half = mean_ci95(means)
                falls = sum(e[k]["falls"] for a, _, _, _, e in rows if a == algo and e[k])
                print(f"{algo} {k}: return over {len(means)} seeds {mean:.1f} ± {half:.1f} (95 % interval of the "
                      f"mean), falls {falls}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
