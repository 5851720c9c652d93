"""``hsddp-gym train``: a learning baseline (behaviour cloning, DAgger, PPO or SAC) trained into ``--out``.

Each option belongs to the algorithms that use it ([`OPTION_ALGOS`][OPTION_ALGOS], which also groups ``train --help``);
an option given with an ``--algo`` that does not use it is refused by name before anything starts."""

from __future__ import annotations

import sys
from pathlib import Path

from hsddp_gym.cli import env_choices, parsing
from hsddp_gym.cli.env_choices import DEFAULT_ENV
from hsddp_gym.registry import DATASET_ENVS, MPC_ENVS, TASKS, task_of_env_id
from hsddp_gym.util.extras import require
from hsddp_gym.util.validation import UsageError, check_output_dir

ALGOS = ("bc", "dagger", "ppo", "sac")
"""``--algo``'s choices."""
_EVERY = ALGOS
_MLP = ("bc", "dagger")
_IN_ENV = ("dagger", "ppo", "sac")
_SB3 = ("ppo", "sac")
GROUPS = {
    "common": ("common options (--env and --condition: the algorithms that act in an env while training)",
               {"--algo": _EVERY, "--out": _EVERY, "--seed": _EVERY, "--env": _IN_ENV, "--condition": _IN_ENV,
                "--lr": _EVERY, "--hidden": _EVERY, "--eval-episodes": _EVERY, "--max-episode-steps": _EVERY,
                "--target-speed": _EVERY, "--quiet": _EVERY}),
    "bc": ("behaviour cloning (bc, and the BC updates of dagger)",
           {"--dataset": _MLP, "--format": _MLP, "--demos": _MLP, "--epochs": _MLP, "--batch-size": _MLP,
            "--features": _MLP, "--weight-decay": _MLP, "--lr-decay": _MLP, "--speed-input": _MLP,
            "--action-queue": _MLP, "--input-noise": _MLP, "--gain-copies": ("bc",), "--gain-noise": ("bc",),
            "--curve": ("bc",)}),
    "dagger": ("DAgger (dagger)",
               {"--expert": ("dagger",), "--rounds": ("dagger",), "--episodes-per-round": ("dagger",),
                "--beta-decay": ("dagger",), "--rollout-noise": ("dagger",), "--rollout-steps": ("dagger",),
                "--workers": ("dagger",), "--estimator": ("dagger",), "--warm-start": ("dagger",),
                "--keep": ("dagger",)}),
    "sb3": ("PPO and SAC (ppo, sac: Stable-Baselines3)",
            {"--steps": _SB3, "--eval-freq": _SB3, "--preset": _SB3, "--n-envs": _SB3, "--vector-env": _SB3,
             "--residual": _SB3,
             "--time-limit": _SB3, "--sde": ("ppo",), "--log-std-init": ("ppo",), "--learning-starts": ("sac",)}),
}
"""The groups of ``train --help``: ``{key: (title, {option: the algorithms that use it})}``."""
OPTION_ALGOS = {option: algos for _, options in GROUPS.values() for option, algos in options.items()}
"""Every option of ``train`` -> the algorithms that use it."""
_REFUSED_BECAUSE = {"--env": "bc evaluates in the env of its dataset's metadata"}


def _either(names) -> str:
    names = list(names)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def check_algorithm_options(args) -> None:
    """UsageError naming the first option given (``args.given``, in ``train --help``'s order) that ``--algo`` does
    not use."""
    given = getattr(args, "given", set())
    for option, algos in OPTION_ALGOS.items():
        if option[2:].replace("-", "_") in given and args.algo not in algos:
            why = _REFUSED_BECAUSE.get(option)
            raise UsageError(option, f"given with --algo {args.algo}",
                             f"--algo {_either(algos)}" + (f" ({why})" if why else ""))


def _sb3_overrides(args) -> dict:
    """ppo/sac: the hyperparameters the options change (``hsddp_gym.learning.sb3.hyperparameters``' overrides)."""
    overrides = {"learning_starts": args.learning_starts} if args.learning_starts is not None else {}
    for key, value in (("n_envs", args.n_envs), ("net_arch", list(args.hidden) if args.hidden else None),
                       ("sde", True if args.sde else None), ("log_std_init", args.log_std_init),
                       ("learning_rate", args.lr)):
        if value is not None:
            overrides[key] = value
    return overrides


_SB3_OVERRIDE_FLAGS = {"learning_rate": "--lr", "net_arch": "--hidden", "log_std_init": "--log-std-init",
                       "n_envs": "--n-envs", "learning_starts": "--learning-starts"}


def _bc_lr(args) -> float:
    """bc/dagger: ``--lr``, or BCConfig's default step."""
    from hsddp_gym.learning.bc import BCConfig

    return BCConfig.lr if args.lr is None else float(args.lr)


def _bc_extra(args) -> dict:
    extra = {"features": args.features, "weight_decay": args.weight_decay, "lr_decay": bool(args.lr_decay),
             "gain_copies": args.gain_copies, "speed_input": bool(args.speed_input),
             "action_queue": args.action_queue}
    if args.input_noise is not None:
        extra["input_noise"] = tuple(args.input_noise)
    if args.gain_noise is not None:
        extra["gain_position_std"], extra["gain_velocity_std"] = args.gain_noise
    if args.hidden:
        extra["hidden"] = tuple(args.hidden)
    return extra


def _check_train_env(args) -> None:
    """``train --env``: the env of ppo/sac/dagger; Bounding-v0's extras (the compiled vector env, the robustness
    conditions, the MPC expert, the state estimator) only there. dagger: the env defaults to its --dataset's (which
    must match --env) and ``--expert`` to ``mpc`` in Bounding-v0 and Terrain-v0 (there the terrain-aware MPC),
    ``expert`` in the plan-tracking tasks."""
    if args.algo == "dagger":
        env = args.env
        if args.dataset:
            from hsddp_gym.datasets.storage import read_metadata, resolve_dataset_dir

            recorded = read_metadata(resolve_dataset_dir(args.dataset[0], "--dataset")).get("env_id") or DEFAULT_ENV
            if env is not None and env != recorded:
                raise UsageError("--env", f"{env}, but --dataset {args.dataset[0]} was recorded in {recorded}",
                                 "the dataset's env")
            env = recorded
        if args.expert is None:
            args.expert = "mpc" if env in (None, *MPC_ENVS) else "expert"
        args.env = env
    if args.env in (None, DEFAULT_ENV):
        return
    task_condition = args.algo == "dagger" or (args.algo in ("ppo", "sac") and not args.vector_env)  # task-built
    if args.condition and task_condition:
        parsing.check_task_condition_names(args.condition, args.env)
    for flag, given in (("--condition", bool(args.condition) and not task_condition), ("--estimator", args.estimator),
                        ("--action-queue", bool(args.action_queue))):
        if given:
            raise UsageError(flag, f"given with --env {args.env}", f"only with --env {DEFAULT_ENV}")
    from hsddp_gym.learning.sb3 import ENV_IDS

    if args.algo in ("ppo", "sac") and args.env not in ENV_IDS:
        raise UsageError("--env", f"{args.env} with --algo {args.algo}", f"one of {', '.join(ENV_IDS)}")
    if args.algo == "dagger" and task_of_env_id(args.env).expert is None:
        if args.expert == "expert":
            raise UsageError("--expert", f"expert with --env {args.env}", "mpc (the terrain-aware MPC) or heuristic")
        return
    motion_mpc = task_of_env_id(args.env).motion is not None  # the task's mpc re-plans its motion
    if args.algo == "dagger" and args.expert != "expert" and not (motion_mpc and args.expert == "mpc"):
        raise UsageError("--expert", f"{args.expert} with --env {args.env}",
                         f"expert (the task's HS-DDP plan tracker){' or mpc (its MPC)' if motion_mpc else ''} with "
                         f"--env {args.env}")


def _check_train(args) -> None:
    """Everything about ``train``'s options that can be checked before training (UsageError / MissingExtraError)."""
    check_output_dir(args.out, "--out")
    check_algorithm_options(args)
    if args.condition and args.algo in ("ppo", "sac"):
        if len(args.condition) != 1:
            raise UsageError("--condition", f"{len(args.condition)} names with --algo {args.algo}",
                             "one condition for the training robots")
        from hsddp_gym.envs.perturbations import get_condition

        condition = get_condition(args.condition[0])
        if args.vector_env and not condition.acts_through_env_arguments:
            raise UsageError("--condition", f"{condition.name} (observation noise or latency) with --vector-env",
                             "a condition of env arguments and pushes, or no --vector-env")
    _check_train_env(args)
    if args.residual is not None:
        if args.vector_env:
            raise UsageError("--residual", "given with --vector-env", "single envs (no --vector-env): the expert acts "
                             "per robot")
        from hsddp_gym.learning.residual import check_residual_scale

        try:
            check_residual_scale(args.residual, "--residual")
        except ValueError:
            raise UsageError("--residual", f"{args.residual}", "a scale in (0, 2]") from None
    if args.estimator and args.action_queue:
        raise UsageError("--action-queue", "given with --estimator (its prediction over the delay replaces the "
                         "queue)", "one of them")
    parsing.check_conditions(args)
    if getattr(args, "keep", "last") == "best" and not args.eval_episodes:
        raise UsageError("--keep", "best with --eval-episodes 0 (it chooses the round by that evaluation)",
                         "--eval-episodes N (N >= 1) or --keep last")
    if args.gain_noise is not None and not args.gain_copies:
        raise UsageError("--gain-noise", "given without --gain-copies", "with --gain-copies N (N >= 1)")
    if isinstance(args.lr, str) and args.algo not in ("ppo", "sac"):
        raise UsageError("--lr", f"{args.lr} (a schedule) with --algo {args.algo}", "a number (Adam's step)")
    if args.algo in ("ppo", "sac"):
        if args.steps is None:
            raise UsageError("--steps", "missing", f"a number of env steps (required for --algo {args.algo})")
        if args.preset == "parallel" and args.algo != "ppo":
            raise UsageError("--preset", f"parallel given with --algo {args.algo}", "hopper or halfcheetah")
        from hsddp_gym.learning.sb3 import hyperparameters

        try:
            hyperparameters(args.algo, _sb3_overrides(args), args.preset)
        except ValueError as exc:  # name the option whose value the hyperparameters refused
            key = str(exc).split()[0]
            raise UsageError(_SB3_OVERRIDE_FLAGS.get(key, "--algo"), str(exc),
                             "a value the preset's hyperparameters take") from exc
        require(["stable_baselines3", "torch"], f"hsddp-gym train --algo {args.algo}")
        return
    if args.algo == "bc" and args.dataset is None:
        raise UsageError("--dataset", "missing", "a dataset directory written by `hsddp-gym dataset` (required "
                                                 "for --algo bc)")
    needs = ["torch"] + (["minari", "h5py"] if args.dataset is not None and args.format == "minari" else [])
    require(needs, f"hsddp-gym train --algo {args.algo}" + (" --format minari" if "minari" in needs else ""))
    if args.dataset is None:
        if args.demos is not None:
            raise UsageError("--demos", "given without --dataset", "--demos with --dataset")
        return
    from hsddp_gym.datasets.storage import read_metadata, resolve_dataset_dir

    if len(args.dataset) > 1 and args.curve:
        raise UsageError("--curve", f"given with {len(args.dataset)} datasets", "one --dataset")
    args.dataset = [str(resolve_dataset_dir(d, "--dataset")) for d in args.dataset]
    n = min(int(read_metadata(d)["episodes"]) for d in args.dataset)
    if args.demos is not None and args.demos > n:
        what = "the dataset has" if len(args.dataset) == 1 else "the smallest dataset has"
        raise UsageError("--demos", f"{args.demos} episodes, {what} {n}", f"1 .. {n}")
    used = args.demos if args.demos is not None else n
    too_many = [c for c in args.curve or [] if c > used]
    if too_many:
        raise UsageError("--curve", f"{','.join(map(str, too_many))} episodes, "
                         + (f"--demos is {used}" if args.demos is not None else f"the dataset has {n}"),
                         f"numbers of demonstration episodes in 1 .. {used}")


def cmd_train(args) -> int:
    _check_train(args)
    if args.algo != "bc" or args.curve:
        from hsddp_gym.util.extras import EXTRAS, is_installed

        if not is_installed("matplotlib"):
            print(f"note: matplotlib is not installed, so curve.png will not be drawn (curve.csv will); "
                  f"{EXTRAS['matplotlib'][1]}", file=sys.stderr)
    out = Path(args.out)
    env_kwargs = {} if args.target_speed is None else {"target_speed": args.target_speed}
    if env_kwargs and getattr(args, "env", None):
        env_choices.check_env_settings(args.env, env_kwargs, None, None)
    if args.algo in ("ppo", "sac"):
        from hsddp_gym.learning.sb3 import train_sb3

        overrides = _sb3_overrides(args)
        res = train_sb3(args.algo, args.steps, args.seed, out, env_kwargs=env_kwargs,
                        max_episode_steps=args.max_episode_steps, overrides=overrides or None,
                        eval_freq=args.eval_freq, final_eval_episodes=args.eval_episodes, progress=not args.quiet,
                        time_limit=args.time_limit, preset=args.preset, vector_env=args.vector_env,
                        train_condition=args.condition[0] if args.condition else None, env_id=args.env,
                        residual_scale=args.residual)
        summary = res.summary
    elif args.algo == "bc":
        from hsddp_gym.learning.bc import BCConfig, run_bc

        config = BCConfig(epochs=args.epochs, batch_size=args.batch_size, lr=_bc_lr(args), seed=args.seed,
                          **_bc_extra(args))
        dataset = args.dataset[0] if len(args.dataset) == 1 else args.dataset
        summary = run_bc(dataset, out, seed=args.seed, config=config, demos=args.demos, fmt=args.format,
                         eval_episodes=args.eval_episodes, curve=args.curve,
                         env_kwargs=env_kwargs or None, max_episode_steps=args.max_episode_steps,
                         progress=not args.quiet)
    else:
        from hsddp_gym.learning.bc import BCConfig
        from hsddp_gym.learning.dagger import DAggerConfig, run_dagger

        config = DAggerConfig(rounds=args.rounds, episodes_per_round=args.episodes_per_round,
                              beta_decay=args.beta_decay, seed=args.seed, max_episode_steps=args.max_episode_steps,
                              rollout_noise=args.rollout_noise, warm_start=bool(args.warm_start),
                              rollout_steps=args.rollout_steps, conditions=tuple(args.condition or ()),
                              estimator=bool(args.estimator), keep=args.keep,
                              bc=BCConfig(epochs=args.epochs, batch_size=args.batch_size, lr=_bc_lr(args),
                                          seed=args.seed, **_bc_extra(args)))
        summary = run_dagger(args.expert, out, seed=args.seed, config=config,
                             dataset=None if args.dataset is None else
                             args.dataset[0] if len(args.dataset) == 1 else list(args.dataset),
                             demos=args.demos, fmt=args.format, eval_episodes=args.eval_episodes,
                             env_kwargs=env_kwargs, progress=not args.quiet, workers=args.workers or 1,
                             env_id=args.env)
    ev = summary.get("eval") or {}
    used = {"ppo": "steps", "sac": "steps", "bc": "transitions", "dagger": "expert_labels"}[args.algo]
    print(f"{args.algo}: {used} {summary.get(used)}, training wall time {summary.get('wall_time_s', 0.0):.1f} s"
          + (f"; evaluation over {ev['episodes']} episodes: return {ev['mean_return']:.4g} +- "
             f"{ev['std_return']:.4g}, falls {ev['falls']}, forward speed {ev['mean_forward_speed']:.3g} m/s"
             if ev else ""))
    print(f"wrote {out / 'summary.json'}")
    return 0




# ----------------------------------------------------------------------------------------------- parser
def add_parser(sub) -> None:
    """Add ``train`` to the subparsers ``sub``: its options in the argument groups of [`GROUPS`][GROUPS], each help
    starting with the algorithms that use the option."""
    from hsddp_gym.learning.sb3 import ENV_IDS, OPTION_HELP  # numpy-only at import; SB3 and torch load when training

    p = sub.add_parser("train", help="train a baseline: behaviour cloning, DAgger, PPO or SAC",
                       description="bc: MLP 2x256 ReLU, Adam 1e-3, MSE on normalized actions, on --dataset; dagger: "
                                   "BC + relabelling rounds by --expert with beta = BETA_DECAY**round; ppo / sac: "
                                   "Stable-Baselines3 with RL-Zoo hyperparameters (--preset: Hopper-v3 by default, or "
                                   "HalfCheetah-v3; hsddp_gym.learning.sb3). "
                                   "Writes the model, summary.json (with training wall time and a 10-episode "
                                   "deterministic evaluation, seeds 0..9) and curve.csv / curve.png into --out. "
                                   "Each option's help starts with the algorithms that use it; an option given with "
                                   "another --algo is refused.")
    groups = {key: p.add_argument_group(title) for key, (title, _) in GROUPS.items()}

    def add(flag: str, help: str, **kwargs) -> None:
        key = next(k for k, (_, options) in GROUPS.items() if flag in options)
        algos = OPTION_ALGOS[flag]
        groups[key].add_argument(flag, help=f"[{'all algos' if algos == ALGOS else ', '.join(algos)}] {help}",
                                 **kwargs)

    # common
    add("--algo", choices=ALGOS, required=True,
        help="bc: behaviour cloning on --dataset; dagger: DAgger relabelled by --expert; ppo / sac: "
             "Stable-Baselines3 RL on hsddp_gym/Bounding-v0 (or --env)")
    add("--out", required=True, help="output directory (created; files in it are replaced)")
    add("--seed", type=parsing.seed, default=0,
        help="seed of the network initialization and minibatch order (bc/dagger), of the DAgger rollouts, or of the "
             "model and training env (ppo/sac); the final evaluation always uses episode seeds 0.. "
             "(default: %(default)s)")
    add("--env", choices=DATASET_ENVS, default=None, metavar="ID",
        help=f"the env to train and evaluate in (default: {DEFAULT_ENV}; dagger: the env of --dataset's metadata if "
             f"given): dagger any task's env (as `hsddp-gym dataset --env`), ppo/sac {', '.join(ENV_IDS)}; envs "
             f"other than {DEFAULT_ENV} take no --estimator or --action-queue, and --condition only with ppo/sac "
             "without --vector-env")
    add("--condition", type=parsing.condition, nargs="+", default=None, metavar="NAME",
        help="dagger: run the relabelling rollouts under perturbations, names of "
             "hsddp_gym.envs.perturbations.CONDITIONS (episode j of a round in the (j mod n)-th); the learner acts on "
             "the perturbed observation, the expert labels the true state and is told the action sent; in a task's env "
             "the conditions that apply to it, with its push window and sizes; ppo/sac: one "
             "name, under which every training robot runs (e.g. push_x3: three random pushes an episode; with "
             "--vector-env only env arguments and pushes), while the evaluations stay on the plain env (default: the "
             "plain env)")
    add("--lr", type=parsing.learning_rate, default=None,
        help="bc/dagger: Adam's step (default: 1e-3); ppo/sac: " + OPTION_HELP["learning_rate"])
    add("--hidden", type=parsing.int_list, default=None,
        help="hidden layer sizes, e.g. 128,128 (bc/dagger: the MLP, default 256,256; ppo/sac: every network, actor "
             "and critic alike, default the preset's)")
    add("--eval-episodes", type=parsing.nonnegative_int, default=10,
        help="final deterministic evaluation episodes, seeds 0.. (dagger: also after every round) "
             "(default: %(default)s; 0: none)")
    add("--max-episode-steps", type=parsing.positive_int, default=None,
        help="time limit override for training/evaluation episodes (default: the env's registered limit)")
    add("--target-speed", type=parsing.finite_float, default=None, help="env target_speed [m/s] (default: the env's)")
    add("--quiet", action="store_true", help="no progress bars")
    # behaviour cloning
    add("--dataset", nargs="+", default=None,
        help="bc (required) / dagger (optional round-0 data): a dataset directory written by `hsddp-gym dataset`, or "
             "several (pooled, e.g. at several target speeds)")
    add("--format", choices=("minari", "npz"), default="minari",
        help="read --dataset through minari.load_dataset or its episodes.npz (default: %(default)s)")
    add("--demos", type=parsing.positive_int, default=None,
        help="use only the first DEMOS episodes of --dataset (default: all)")
    add("--epochs", type=parsing.positive_int, default=50, help="BC epochs (default: %(default)s)")
    add("--batch-size", type=parsing.positive_int, default=256,
        help="minibatch size of the BC updates (default: %(default)s)")
    add("--features", choices=("obs", "gait_clock"), default="obs",
        help="MLP inputs; gait_clock appends the MPC's gait clock (phase one-hot, time in phase, cycle sin/cos) "
             "rebuilt from the observation history, since the MPC's phase drifts from the observation clock "
             "(default: %(default)s)")
    add("--weight-decay", type=parsing.nonnegative_float, default=0.0, help="Adam weight decay (default: 0)")
    add("--lr-decay", action="store_true", help="cosine learning-rate decay to 0 over the epochs")
    add("--speed-input", action="store_true",
        help="the env's target speed as one more input of the MLP (for demonstrations at several target speeds; "
             "dagger: with --condition speed_... rollouts)")
    add("--action-queue", type=parsing.nonnegative_int, default=0,
        help="slots of the latency queue in the MLP's input: the actions sent that the env has not executed yet (the "
             "env's action delay of them, e.g. --condition delay_5ms: 1), as the MPC's latency compensation uses "
             "them; needs demonstrations that record their conditions (0: none; default: %(default)s)")
    add("--gain-copies", type=parsing.nonnegative_int, default=0,
        help="perturbed copies of every demonstration labelled with the expert's feedback law u + K dx (needs a "
             "dataset made with --gains; hsddp_gym.learning.gain_labels); 0: off (default: %(default)s)")
    add("--input-noise", type=parsing.nonnegative_float, nargs=2, metavar=("POS_STD", "VEL_STD"), default=None,
        help="Gaussian noise on the observed positions [m, rad] and velocities [m/s, rad/s] of every training "
             "minibatch, labels unchanged: the learner acts as the expert would on the true state under observation "
             "noise (e.g. 0.01 0.1, the obs_noise condition's) (default: none)")
    add("--gain-noise", type=parsing.nonnegative_float, nargs=2, metavar=("POS_STD", "VEL_STD"), default=None,
        help="standard deviations of the state offsets of --gain-copies, positions [m, rad] and velocities "
             "[m/s, rad/s] (default: 0.01 0.1)")
    add("--curve", type=parsing.int_list, default=None,
        help="comma-separated numbers of demonstration episodes for the learning curve, e.g. 1,5,10")
    # DAgger
    no_expert = " and ".join(t.env_id for t in TASKS.values() if t.expert is None)
    add("--expert", choices=("mpc", "expert", "heuristic"), default=None,
        help=f"the labelling expert: in {DEFAULT_ENV} mpc, expert or heuristic; in {no_expert} mpc (the "
             "terrain-aware MPC) or heuristic; in the other tasks expert (the task's HS-DDP plan tracker) "
             f"(default: mpc in {' and '.join(MPC_ENVS)}, expert elsewhere)")
    add("--rounds", type=parsing.nonnegative_int, default=4,
        help="relabelling rounds after round 0 (round 0: BC on --dataset or on expert episodes) "
             "(default: %(default)s)")
    add("--episodes-per-round", type=parsing.positive_int, default=5,
        help="rollouts relabelled by the expert per round, and expert episodes of round 0 when no --dataset is "
             "given (default: %(default)s)")
    add("--beta-decay", type=parsing.fraction, default=0.5,
        help="in round i the expert's action is executed with probability beta_i = BETA_DECAY**i, the learner's "
             "otherwise; 0: pure learner rollouts (default: %(default)s)")
    add("--rollout-noise", type=parsing.nonnegative_float, default=0.0,
        help="DART-style noise: Gaussian std (normalized units, e.g. 0.04) added to the executed action of the "
             "relabelling rollouts (rounds >= 1); labels stay the expert's clean action (default: 0, none)")
    add("--rollout-steps", type=parsing.positive_int, default=None,
        help="truncate the relabelling rollouts (rounds >= 1) after this many steps, to spend the label budget on "
             "many starts (the learner's falls happen early); every labelled step counts (default: full episodes)")
    add("--workers", type=parsing.positive_int, default=None,
        help="processes running each round's rollouts; results do not depend on it (default: 1)")
    add("--estimator", action="store_true",
        help="the learner acts behind the MPC's perception (EstimatedStatePolicy: the state filter's estimate "
             "predicted over the action delay); the rollouts store what it sees there, and it is meant to be "
             "evaluated behind it (robustness.py --estimated); give round-0 data of undisturbed envs")
    add("--warm-start", action="store_true",
        help="rounds >= 1 fine-tune the previous round's network (and keep its input standardization) for --epochs "
             "instead of retraining from scratch")
    add("--keep", choices=("last", "best"), default="last",
        help="the learner the run writes: the last round's, or the best round's by its evaluation (--eval-episodes "
             "on seeds 0.., fewest falls, then highest mean return; needs --eval-episodes > 0) (default: "
             "%(default)s)")
    # PPO and SAC
    add("--steps", type=parsing.positive_int, default=None, help="(required) env steps to train for")
    add("--eval-freq", type=parsing.nonnegative_int, default=None,
        help="env steps between evaluations of 5 episodes during training (default: steps/10, at least 1000; "
             "0: none)")
    add("--preset", choices=("hopper", "halfcheetah", "parallel"), default="hopper",
        help="the RL-Zoo hyperparameters of Hopper-v3 (a task that ends on falls, like this one) or HalfCheetah-v3; "
             "ppo only: parallel, legged_gym's massively parallel PPO on a CPU (64 robots x 128 steps per update, "
             "4 minibatches; use with --vector-env) (hsddp_gym.learning.sb3.PRESETS; default: %(default)s)")
    add("--n-envs", type=parsing.positive_int, default=None,
        help="envs stepped together in one DummyVecEnv (default: the preset's, 1)")
    add("--vector-env", action="store_true",
        help="step the --n-envs training robots with the env's compiled vector env (hsddp_gym.envs.vector for "
             "Bounding-v0, hsddp_gym.envs.task_vector for the tasks: the robots' physics in one numba call) instead of "
             "a DummyVecEnv of single envs")
    add("--time-limit", type=parsing.positive_float, default=None,
        help="wall-clock training budget [s]; training stops there and summary.json records the steps that fit "
             "(--steps is then the upper bound)")
    add("--residual", type=parsing.positive_float, default=None, metavar="SCALE",
        help="learn a residual on the task's HS-DDP plan-tracking expert: the env gets clip(expert action + SCALE * "
             "learner action, -1, 1) and the learner also sees the expert's action (hsddp_gym.learning.residual; "
             "SCALE in (0, 2]; not with --vector-env) (default: the learner acts alone)")
    add("--sde", action="store_true", help=OPTION_HELP["sde"])
    add("--log-std-init", type=float, default=None, help=OPTION_HELP["log_std_init"])
    add("--learning-starts", type=parsing.nonnegative_int, default=None,
        help="env steps of random actions before learning starts (default: the zoo's 10000)")
    p.set_defaults(func=cmd_train)
