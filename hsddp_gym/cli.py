"""The ``hsddp-gym`` command line.

Every subcommand writes into ``--out DIR``: a ``summary.json`` with the numbers, plus figures and data.
Run ``hsddp-gym SUBCOMMAND --help`` for the options of each.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.util.io import write_json
from hsddp_gym.workflows import ROLLOUT_ENVS, ROLLOUT_POLICIES, run_rollouts, write_plan_outputs


def _number(kind, low: float, high: float = float("inf"), low_open: bool = False, what: str = ""):
    """An argparse ``type``: ``kind(text)`` within ``[low, high]`` (``(low, high]`` with ``low_open``)."""

    def parse(text: str):
        value = kind(text)
        if not ((value > low if low_open else value >= low) and value <= high):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its "invalid ... value" message
    return parse


_positive_int = _number(int, 1, what="a positive integer")
_positive_float = _number(float, 0.0, low_open=True, what="> 0")
_nonnegative_int = _number(int, 0, what="a non-negative integer")
_nonnegative_float = _number(float, 0.0, what=">= 0")
_fraction = _number(float, 0.0, 1.0, what="in [0, 1]")


def cmd_plan(args) -> int:
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.tasks import plan_bounding

    out = Path(args.out)
    options = SolverOptions(max_al_iterations=args.max_al_iterations, max_ddp_iterations=args.max_ddp_iterations)
    result = plan_bounding(args.method, cycles=args.cycles, speed=args.speed, options=options,
                           verbose=not args.quiet)
    summary = dict(result.summary)
    summary["files"] = write_plan_outputs(result, out, not args.no_plots)
    summary["command"] = args.command_line
    write_json(out / "summary.json", summary)
    _print_summary(summary)
    print(f"wrote {out / 'summary.json'}")
    return 0


def _print_summary(summary: dict) -> None:
    keys = ("method", "status", "al_iterations", "ddp_iterations", "switching_violation", "max_abs_torque",
            "min_normal_grf", "max_friction_violation", "avg_forward_speed", "cost", "solve_time_s")
    for k in keys:
        if k in summary:
            v = summary[k]
            print(f"  {k:<24} {v:.6g}" if isinstance(v, float) else f"  {k:<24} {v}")


# ----------------------------------------------------------------------------------------------- sto
def cmd_sto(args) -> int:
    from hsddp_gym.planners.tasks import run_sto

    out = Path(args.out)

    def progress(rec):
        if not args.quiet:
            tt = rec.get("total_time")
            print(f"  STO iteration {rec['iteration']:>3d}: {rec['status']:<12} "
                  + (f"total time {tt:.4f} s, cost {rec['cost']:.4g}, sum g^2 {rec['switching_violation']:.2e}"
                     if tt is not None else ""), flush=True)

    res, summary = run_sto(args.method, iterations=args.iterations, cycles=args.cycles,
                           second_order=args.second_order, callback=progress, min_duration=args.min_duration,
                           max_duration=args.max_duration)
    res.solution.save(out / "solution.npz")
    summary["command"] = args.command_line
    write_json(out / "summary.json", summary)
    print(f"{args.method}: total time {summary['initial_total_time']:.4f} s -> {summary['total_time']:.4f} s "
          f"({100 * summary['reduction']:.1f} % reduction) in {summary['iterations']} iterations; "
          f"durations [ms] {[round(1e3 * d, 1) for d in summary['mode_durations']]}")
    print(f"wrote {out / 'summary.json'}")
    return 0


def cmd_rollout(args) -> int:
    out = Path(args.out)
    env_kwargs = {}
    if args.target_speed is not None:
        env_kwargs["target_speed"] = args.target_speed
    push = None
    if args.push is not None:
        t, dvx, dvz, dw = args.push
        push = {"delta_v": [dvx, dvz, dw], "time": t}
    if args.mpc_recovery and args.policy != "mpc":
        raise SystemExit("error: --mpc-recovery needs --policy mpc")
    summary = run_rollouts(args.policy, args.episodes, args.seed, out, video=args.video, env_kwargs=env_kwargs,
                           push=push, quiet=args.quiet, max_episode_steps=args.max_episode_steps,
                           mpc_recovery=args.mpc_recovery, env_id=ROLLOUT_ENVS[args.simulator == "mujoco"])
    for k in ("mean_return", "std_return", "falls", "mean_forward_speed", "mean_episode_length", "real_time_factor",
              "replans", "planner_failures", "mean_replan_ms"):
        v = summary.get(k)
        print(f"  {k:<22} {v:.4g}" if isinstance(v, float) else f"  {k:<22} {v}")
    print(f"wrote {out / 'summary.json'}")
    return 0


# ----------------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from hsddp_gym.workflows import run_demo

    summary = run_demo(Path(args.out), cycles=args.cycles, episodes=args.episodes, video=not args.no_video,
                       quiet=args.quiet, max_episode_steps=args.max_episode_steps)
    for name in ("heuristic_plan", "hsddp_plan"):
        print(f"{name}:")
        _print_summary(summary[name])
    print("mpc_in_env:")
    for k in ("mean_return", "falls", "mean_forward_speed", "real_time_factor", "mean_replan_ms"):
        v = summary["mpc_in_env"].get(k)
        print(f"  {k:<24} {v:.4g}" if isinstance(v, float) else f"  {k:<24} {v}")
    print(f"wrote {args.out}/summary.json and figures")
    return 0


# ----------------------------------------------------------------------------------------------- dataset, train
# (demonstration datasets and learning baselines: hsddp_gym.datasets, hsddp_gym.learning, hsddp_gym.learning.sb3)
DATASET_POLICIES = ("mpc", "expert", "heuristic", "random")
TRAIN_ALGOS = ("bc", "dagger", "ppo", "sac")


def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"must be comma-separated integers, got {text!r}") from exc
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"must be comma-separated positive integers, got {text!r}")
    return values


def cmd_dataset(args) -> int:
    from hsddp_gym.datasets.generation import generate_dataset, partial_dir

    env_kwargs = {} if args.target_speed is None else {"target_speed": args.target_speed}
    try:
        res = generate_dataset(args.policy, args.episodes, args.out, seed=args.seed, workers=args.workers,
                               dataset_id=args.dataset_id, overwrite=args.overwrite, env_kwargs=env_kwargs,
                               max_episode_steps=args.max_episode_steps, include_gains=args.gains,
                               progress=not args.quiet, action_noise=args.action_noise, resume=not args.no_resume)
    except FileExistsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        partial = partial_dir(args.out)
        done = len(list(partial.glob("episode-*.npz"))) if partial.exists() else 0
        print(f"\ninterrupted: no dataset was written to {args.out}; {done} finished episode(s) are checkpointed "
              f"in {partial}. Rerun the same command to resume (--no-resume to start over).", file=sys.stderr)
        return 130
    m = res.metadata
    recorded = res.episodes - res.resumed_episodes
    print(f"{res.dataset_id}: {res.episodes} episodes, {res.total_steps} transitions, {m['falls']} falls; "
          + (f"{res.resumed_episodes} episode(s) resumed from an interrupted run, " if res.resumed_episodes else "")
          + f"{recorded} generated in {res.generation_time_s:.1f} s with {args.workers} worker(s)"
          + (f" ({res.total_steps / max(res.generation_time_s, 1e-9):.0f} transitions/s)"
             if not res.resumed_episodes else ""))
    print(f"  ref_max_score {m['ref_max_score']:.4g} ({m['ref_max_score_source']}), ref_min_score "
          f"{m['ref_min_score']:.4g} (random policy)")
    print(f"wrote {res.path}/ (minari/, episodes.npz, metadata.json); load with "
          f"hsddp_gym.datasets.load_minari('{res.path}') or MINARI_DATASETS_PATH={res.path}/minari "
          f"minari.load_dataset('{res.dataset_id}')")
    return 0


def _bc_extra(args) -> dict:
    extra = {"features": args.features, "weight_decay": args.weight_decay, "lr_decay": bool(args.lr_decay)}
    if args.hidden:
        extra["hidden"] = tuple(args.hidden)
    return extra


def cmd_train(args) -> int:
    out = Path(args.out)
    env_kwargs = {} if args.target_speed is None else {"target_speed": args.target_speed}
    if args.algo in ("ppo", "sac"):
        from hsddp_gym.learning.sb3 import train_sb3

        if args.steps is None:
            print("error: --steps is required for ppo and sac", file=sys.stderr)
            return 2
        overrides = {"learning_starts": args.learning_starts} if args.learning_starts is not None else None
        if args.learning_starts is not None and args.algo == "ppo":
            print("error: --learning-starts applies to sac only", file=sys.stderr)
            return 2
        res = train_sb3(args.algo, args.steps, args.seed, out, env_kwargs=env_kwargs,
                        max_episode_steps=args.max_episode_steps, overrides=overrides, eval_freq=args.eval_freq,
                        final_eval_episodes=args.eval_episodes, progress=not args.quiet,
                        time_limit=args.time_limit)
        summary = res.summary
    elif args.algo == "bc":
        from hsddp_gym.learning.bc import BCConfig, run_bc

        if args.dataset is None:
            print("error: --dataset is required for bc", file=sys.stderr)
            return 2
        config = BCConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, seed=args.seed,
                          **_bc_extra(args))
        summary = run_bc(args.dataset, out, seed=args.seed, config=config, demos=args.demos, fmt=args.format,
                         eval_episodes=args.eval_episodes, curve=args.curve,
                         env_kwargs=env_kwargs or None, max_episode_steps=args.max_episode_steps,
                         progress=not args.quiet)
    else:
        from hsddp_gym.learning.bc import BCConfig
        from hsddp_gym.learning.dagger import DAggerConfig, run_dagger

        config = DAggerConfig(rounds=args.rounds, episodes_per_round=args.episodes_per_round,
                              beta_decay=args.beta_decay, seed=args.seed, max_episode_steps=args.max_episode_steps,
                              rollout_noise=args.rollout_noise, warm_start=bool(args.warm_start),
                              rollout_steps=args.rollout_steps,
                              bc=BCConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                                          seed=args.seed, **_bc_extra(args)))
        summary = run_dagger(args.expert, out, seed=args.seed, config=config, dataset=args.dataset,
                             demos=args.demos, fmt=args.format, eval_episodes=args.eval_episodes,
                             env_kwargs=env_kwargs, progress=not args.quiet)
    ev = summary.get("eval") or {}
    used = {"ppo": "steps", "sac": "steps", "bc": "transitions", "dagger": "expert_labels"}[args.algo]
    print(f"{args.algo}: {used} {summary.get(used)}, training wall time {summary.get('wall_time_s', 0.0):.1f} s"
          + (f"; evaluation over {ev['episodes']} episodes: return {ev['mean_return']:.4g} +- "
             f"{ev['std_return']:.4g}, falls {ev['falls']}, forward speed {ev['mean_forward_speed']:.3g} m/s"
             if ev else ""))
    print(f"wrote {out / 'summary.json'}")
    return 0


def _add_learning_parsers(sub) -> None:
    p = sub.add_parser("dataset", help="generate a demonstration dataset (Minari + npz) with a policy",
                       description="Run --episodes episodes (episode i reset with seed --seed + i, a fresh policy "
                                   "per episode, so the data do not depend on --workers) in parallel worker "
                                   "processes and write a Minari dataset (OUT/minari, MINARI_DATASETS_PATH=OUT/minari)"
                                   ", OUT/episodes.npz and OUT/metadata.json atomically. infos carry qpos, qvel, "
                                   "contact, the expert's nominal state/action and solver statistics at every step. "
                                   "Finished episodes are checkpointed, so an interrupted run can be resumed by "
                                   "rerunning the same command. See hsddp_gym.datasets.")
    p.add_argument("--policy", choices=DATASET_POLICIES, default="mpc",
                   help="mpc: HS-DDP MPC; expert: tracks the 5-cycle al-reb HS-DDP plan (episodes start at the "
                        "plan's initial state, no reset noise, so they are identical); heuristic: the warm-start "
                        "controller; random: uniform actions (default: %(default)s)")
    p.add_argument("--episodes", type=_positive_int, default=10,
                   help="episodes; episode i is reset with seed --seed + i (default: %(default)s)")
    p.add_argument("--workers", type=_positive_int, default=1,
                   help="worker processes (1: in this process); the data do not depend on it (default: "
                        "%(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of episode 0 (default: %(default)s)")
    p.add_argument("--out", required=True, help="dataset directory (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out (the old dataset stays until the new one is complete) and "
                        "discard checkpoints of an interrupted run with other settings")
    p.add_argument("--no-resume", action="store_true",
                   help="discard the checkpoints of an interrupted run (OUT's hidden sibling .NAME.partial) and "
                        "start over; by default a rerun with the same settings resumes from them and a rerun "
                        "with other settings refuses")
    p.add_argument("--dataset-id", default=None, help="Minari dataset id (default: hsddp_gym/bounding/POLICY-v0)")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit override (default: the env's 1000)")
    p.add_argument("--target-speed", type=float, default=None, help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--gains", action="store_true", help="also store the plan's feedback gains (4x14 per step)")
    p.add_argument("--action-noise", type=_nonnegative_float, default=0.0,
                   help="DART noise injection: execute the policy's action plus Gaussian noise of this std "
                        "(normalized units, e.g. 0.04) and store the clean action in infos/expert_action, the "
                        "label BC/DAgger use; ref_max_score then comes from 5 noise-free episodes (default: 0, "
                        "no noise)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("train", help="train a baseline: behaviour cloning, DAgger, PPO or SAC",
                       description="bc: MLP 2x256 ReLU, Adam 1e-3, MSE on normalized actions, on --dataset; dagger: "
                                   "BC + relabelling rounds by --expert with beta = BETA_DECAY**round; ppo / sac: "
                                   "Stable-Baselines3 with the RL-Zoo HalfCheetah hyperparameters "
                                   "(hsddp_gym.learning.sb3). "
                                   "Writes the model, summary.json (with training wall time and a 10-episode "
                                   "deterministic evaluation, seeds 0..9) and curve.csv / curve.png into --out.")
    p.add_argument("--algo", choices=TRAIN_ALGOS, required=True,
                   help="bc: behaviour cloning on --dataset; dagger: DAgger relabelled by --expert; ppo / sac: "
                        "Stable-Baselines3 RL on hsddp_gym/Bounding-v0")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the network initialization and minibatch order (bc/dagger), of the DAgger "
                        "rollouts, or of the model and training env (ppo/sac); the final evaluation always uses "
                        "episode seeds 0.. (default: %(default)s)")
    p.add_argument("--out", required=True, help="output directory (created; files in it are replaced)")
    p.add_argument("--steps", type=_positive_int, default=None, help="ppo/sac (required): env steps to train for")
    p.add_argument("--eval-freq", type=_nonnegative_int, default=None,
                   help="ppo/sac: env steps between evaluations of 5 episodes during training (default: steps/10, "
                        "at least 1000; 0: none)")
    p.add_argument("--learning-starts", type=_nonnegative_int, default=None,
                   help="sac: env steps of random actions before learning starts (default: the zoo's 10000)")
    p.add_argument("--time-limit", type=_positive_float, default=None,
                   help="ppo/sac: wall-clock training budget [s]; training stops there and summary.json records "
                        "the steps that fit (--steps is then the upper bound)")
    p.add_argument("--dataset", default=None, help="bc (required) / dagger (optional round-0 data): a dataset "
                                                   "directory written by `hsddp-gym dataset`")
    p.add_argument("--format", choices=("minari", "npz"), default="minari",
                   help="read the dataset through minari.load_dataset or its episodes.npz (default: %(default)s)")
    p.add_argument("--demos", type=_positive_int, default=None,
                   help="bc/dagger: use only the first DEMOS episodes of --dataset (default: all)")
    p.add_argument("--epochs", type=_positive_int, default=50, help="bc/dagger: BC epochs (default: %(default)s)")
    p.add_argument("--batch-size", type=_positive_int, default=256,
                   help="bc/dagger: minibatch size of the BC updates (default: %(default)s)")
    p.add_argument("--lr", type=_positive_float, default=1e-3, help="bc/dagger: Adam step (default: %(default)s)")
    p.add_argument("--features", choices=("obs", "gait_clock"), default="obs",
                   help="bc/dagger: MLP inputs; gait_clock appends the MPC's gait clock (phase one-hot, time in "
                        "phase, cycle sin/cos) rebuilt from the observation history, since the MPC's phase drifts "
                        "from the observation clock (default: %(default)s)")
    p.add_argument("--hidden", type=_int_list, default=None, help="bc/dagger: hidden layer sizes (default: 256,256)")
    p.add_argument("--weight-decay", type=_nonnegative_float, default=0.0,
                   help="bc/dagger: Adam weight decay (default: 0)")
    p.add_argument("--lr-decay", action="store_true", help="bc/dagger: cosine learning-rate decay to 0 over the epochs")
    p.add_argument("--curve", type=_int_list, default=None,
                   help="bc: comma-separated numbers of demonstration episodes for the learning curve, e.g. 1,5,10")
    p.add_argument("--expert", choices=("mpc", "expert", "heuristic"), default="mpc",
                   help="dagger: the labelling expert (default: %(default)s)")
    p.add_argument("--rounds", type=_nonnegative_int, default=4,
                   help="dagger: relabelling rounds after round 0 (round 0: BC on --dataset or on expert "
                        "episodes) (default: %(default)s)")
    p.add_argument("--episodes-per-round", type=_positive_int, default=5,
                   help="dagger: rollouts relabelled by the expert per round, and expert episodes of round 0 when "
                        "no --dataset is given (default: %(default)s)")
    p.add_argument("--beta-decay", type=_fraction, default=0.5,
                   help="dagger: in round i the expert's action is executed with probability beta_i = "
                        "BETA_DECAY**i, the learner's otherwise; 0: pure learner rollouts (default: %(default)s)")
    p.add_argument("--rollout-noise", type=_nonnegative_float, default=0.0,
                   help="dagger: DART-style noise: Gaussian std (normalized units, e.g. 0.04) added to the executed "
                        "action of the relabelling rollouts (rounds >= 1); labels stay the expert's clean action "
                        "(default: 0, none)")
    p.add_argument("--rollout-steps", type=_positive_int, default=None,
                   help="dagger: truncate the relabelling rollouts (rounds >= 1) after this many steps, to spend "
                        "the label budget on many starts (the learner's falls happen early); every labelled step "
                        "counts (default: full episodes)")
    p.add_argument("--warm-start", action="store_true",
                   help="dagger: rounds >= 1 fine-tune the previous round's network (and keep its input "
                        "standardization) for --epochs instead of retraining from scratch")
    p.add_argument("--eval-episodes", type=_nonnegative_int, default=10,
                   help="final deterministic evaluation episodes, seeds 0.. (dagger: also after every round) "
                        "(default: %(default)s; 0: none)")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit override for training/evaluation episodes (default: the env's 1000)")
    p.add_argument("--target-speed", type=float, default=None, help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_train)
# ----------------------------------------------------------------------------------------------- end dataset, train


# ----------------------------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hsddp-gym",
        description="HS-DDP (Li & Wensing, RA-L 2020) for the planar MIT Mini Cheetah: plan bounding gaits, "
                    "optimize switching times, run the planner as MPC in the Gymnasium env.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="plan a 5-cycle bound with HS-DDP from the heuristic warm start; write "
                                    "figures and a summary",
                       description="The main job: heuristic warm start, HS-DDP (al-reb) plan of the paper's "
                                   "bounding task, figures (motion.png, states.png, convergence.png), "
                                   "solution.npz, then the HS-DDP MPC bounding in hsddp_gym/Bounding-v0 "
                                   "(mpc/summary.json, mpc/episode0.gif) and summary.json in --out.")
    p.add_argument("--out", default="runs/demo", help="output directory (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=5, help="gait cycles to plan (default: %(default)s)")
    p.add_argument("--episodes", type=_positive_int, default=1,
                   help="MPC episodes to run in the env, seeds 0, 1, ... (default: %(default)s)")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit of the MPC episodes in control steps of 5 ms (default: the env's 1000)")
    p.add_argument("--no-video", action="store_true", help="skip the GIF of the first MPC episode")
    p.add_argument("--quiet", action="store_true", help="do not print the solver's iteration table")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("plan", help="paper task 1: plan a bounding gait with a given method",
                       description="Plan --cycles bounding cycles (80/72/72/72 ms, h = 1 ms, the paper's initial "
                                   "state, heuristic warm start) and write summary.json, the solution and figures.")
    p.add_argument("--method", choices=("heuristic", "ddp", "al", "al-reb"), default="al-reb",
                   help="heuristic: the warm start alone; ddp: impact-aware DDP ignoring switching constraints; "
                        "al: + augmented Lagrangian on them; al-reb: + relaxed barriers on torque, normal force and "
                        "friction (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=5, help="gait cycles (default: %(default)s)")
    p.add_argument("--speed", type=_positive_float, default=1.0,
                   help="desired forward speed [m/s] (default: %(default)s)")
    p.add_argument("--max-al-iterations", type=_positive_int, default=6,
                   help="outer AL iterations at most (default: %(default)s)")
    p.add_argument("--max-ddp-iterations", type=_positive_int, default=10,
                   help="DDP iterations per AL iteration at most (default: %(default)s)")
    p.add_argument("--out", default="runs/plan", help="output directory (default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--quiet", action="store_true", help="do not print the solver's iteration table")
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("rollout", help="run a policy in hsddp_gym/Bounding-v0 for seeded episodes",
                       description="Run --episodes seeded episodes (seeds --seed, --seed+1, ...) of a policy in "
                                   "hsddp_gym/Bounding-v0 with its default reset noise and time limit (or "
                                   "--max-episode-steps); write summary.json (mean/std return, falls, forward "
                                   "speed, episode length, real-time factor, replans, planner failures, mean "
                                   "replan ms), episode0.npz and, with --video, episode0.gif.")
    p.add_argument("--policy", choices=ROLLOUT_POLICIES, default="mpc",
                   help="mpc: HS-DDP model-predictive control; expert: tracks a 5-cycle al-reb plan (episodes "
                        "start at the plan's initial state); heuristic: the warm-start controller; random: uniform "
                        "actions (default: %(default)s)")
    p.add_argument("--episodes", type=_positive_int, default=10, help="episodes (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: %(default)s)")
    p.add_argument("--target-speed", type=float, default=None, help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--push", type=float, nargs=4, metavar=("T", "DVX", "DVZ", "DPITCH"), default=None,
                   help="push at episode time T [s]: add (DVX, DVZ) [m/s] and DPITCH [rad/s] to the trunk velocity")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit in control steps of 5 ms (default: the env's 1000)")
    p.add_argument("--mpc-recovery", action="store_true",
                   help="with --policy mpc: the push-robust settings (MPCOptions.push_recovery(): a 2.5 ms planner "
                        "grid and the push recovery: an immediate re-plan with more iterations when the trunk velocity "
                        "leaves the plan, a double stance when the trunk sinks, the heuristic while a re-plan has "
                        "failed); summary.json then also counts recoveries and fallback_steps")
    p.add_argument("--simulator", choices=("lcp", "mujoco"), default="lcp",
                   help="lcp: hsddp_gym/Bounding-v0 (exact-LCP contacts); mujoco: its MuJoCo twin "
                        "hsddp_gym/BoundingMuJoCo-v0 (soft contacts; needs the extra 'mujoco') (default: %(default)s)")
    p.add_argument("--video", action="store_true", help="write episode0.gif (the first episode, rendered off-screen)")
    p.add_argument("--out", default="runs/rollout", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_rollout)

    p = sub.add_parser("sto", help="paper task 2: switching-time optimization (HS-DDP Algorithm 2 or the "
                                   "open-loop baseline)",
                       description="Optimize the mode durations of --cycles bounding cycles (start 80/72/72/72 ms, "
                                   "task-1 costs, AL parameters and warm start). hsddp: Newton steps on the "
                                   "durations rolled out with the feedback policy (the paper); open-loop: the "
                                   "control held open loop (Xu & Antsaklis). Writes summary.json and solution.npz.")
    p.add_argument("--method", choices=("hsddp", "open-loop"), default="hsddp",
                   help="hsddp: feedback policy in the duration update; open-loop: Xu & Antsaklis baseline "
                        "(default: %(default)s)")
    p.add_argument("--iterations", type=_positive_int, default=30, help="STO iterations at most (default: %(default)s)")
    p.add_argument("--cycles", type=_positive_int, default=1, help="gait cycles (default: %(default)s)")
    p.add_argument("--min-duration", type=_positive_float, default=None,
                   help="shortest mode duration the optimization may reach [s] (default: STOOptions' 0.02)")
    p.add_argument("--max-duration", type=_positive_float, default=None,
                   help="longest mode duration [s] (default: STOOptions' 0.2)")
    p.add_argument("--second-order", action="store_true",
                   help="exact V_zz with the dynamics' second-order terms (slower); default: iLQR's, as the paper")
    p.add_argument("--out", default="runs/sto", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no per-iteration lines")
    p.set_defaults(func=cmd_sto)
    _add_learning_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    args.command_line = " ".join(["hsddp-gym", *argv])  # recorded in summaries (the arguments actually parsed)
    return int(args.func(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
