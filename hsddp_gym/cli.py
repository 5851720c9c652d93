"""The ``hsddp-gym`` command line.

Every subcommand writes into ``--out DIR``: a ``summary.json`` with the numbers, plus figures and data.
Run ``hsddp-gym SUBCOMMAND --help`` for the options of each.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from hsddp_gym.registry import DATASET_ENVS, MPC_ENVS
from hsddp_gym.rollout.policies import POLICIES, parse_policy_spec, required_modules
from hsddp_gym.util.extras import MissingExtraError, require
from hsddp_gym.util.io import write_json
from hsddp_gym.util.parallel import add_backend_arguments, check_backend
from hsddp_gym.util.validation import UsageError, check_output_dir
from hsddp_gym.workflows import ROLLOUT_ENVS, run_rollouts, write_plan_outputs


def _number(kind, low: float, high: float = float("inf"), low_open: bool = False, what: str = ""):
    """An argparse ``type``: a finite ``kind(text)`` within ``[low, high]`` (``(low, high]`` with ``low_open``)."""

    def parse(text: str):
        value = kind(text)
        if not ((value > low if low_open else value >= low) and value <= high):  # NaN fails every comparison
            raise argparse.ArgumentTypeError(f"{text} (allowed: {what})")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its "invalid ... value" message
    return parse


_positive_int = _number(int, 1, what="an integer >= 1")
_positive_float = _number(float, 0.0, high=1e300, low_open=True, what="a finite number > 0")
_nonnegative_int = _number(int, 0, what="an integer >= 0")
_nonnegative_float = _number(float, 0.0, high=1e300, what="a finite number >= 0")
_fraction = _number(float, 0.0, 1.0, what="a number in [0, 1]")
_finite_float = _number(float, -1e300, 1e300, what="a finite number")
_seed = _number(int, 0, what="an integer >= 0 (a seed)")


def _condition(text: str) -> str:
    """An argparse ``type``: a name of ``hsddp_gym.envs.perturbations.CONDITIONS``."""
    from hsddp_gym.envs.perturbations import CONDITIONS

    if text not in CONDITIONS:
        raise argparse.ArgumentTypeError(f"{text} (allowed: {', '.join(CONDITIONS)})")
    return text


_condition.__name__ = "condition"


def _check_conditions(args, flag: str = "--condition") -> None:
    """UsageError when ``args.condition`` and ``--target-speed`` both set the target speed."""
    if not args.condition or args.target_speed is None:
        return
    from hsddp_gym.envs.perturbations import get_condition

    both = [c for c in args.condition if "target_speed" in get_condition(c).env_kwargs]
    if both:
        raise UsageError("--target-speed", f"given with {flag} {' '.join(both)}, which set the target speed",
                         "either --target-speed or speed conditions")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``error: --option: value (allowed: ...)`` on stderr, exit code 2."""

    def error(self, message: str):
        message = message[len("argument "):] if message.startswith("argument ") else message
        self.exit(2, f"error: {message} (see {self.prog} --help)\n")


def _version() -> str:
    import hsddp_gym

    return hsddp_gym.__version__


def cmd_plan(args) -> int:
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.tasks import WarmStartDivergedError, plan_bounding

    out = check_output_dir(args.out, "--out")
    if not args.no_plots:
        require(["matplotlib"], "hsddp-gym plan (its figures; or pass --no-plots)")
    options = SolverOptions(max_al_iterations=args.max_al_iterations, max_ddp_iterations=args.max_ddp_iterations)
    try:
        result = plan_bounding(args.method, cycles=args.cycles, speed=args.speed, options=options,
                               verbose=not args.quiet)
    except WarmStartDivergedError as exc:  # e.g. --method heuristic on a long horizon: the rollout tumbles
        print(f"error: {exc}", file=sys.stderr)
        return 1
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
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.tasks import run_sto

    out = check_output_dir(args.out, "--out")
    _check_duration_bounds(args)
    if args.periodic and args.cycles != 1:
        raise UsageError("--cycles", f"{args.cycles} with --periodic", "1: the periodic task optimizes one cycle")
    if args.periodic_weight is not None and not args.periodic:
        raise UsageError("--periodic-weight", "given without --periodic", "only with --periodic")

    def progress(rec):
        if not args.quiet:
            tt = rec.get("total_time")
            print(f"  STO iteration {rec['iteration']:>3d}: {rec['status']:<12} "
                  + (f"total time {tt:.4f} s, cost {rec['cost']:.4g}, sum g^2 {rec['switching_violation']:.2e}"
                     if tt is not None else ""), flush=True)

    periodic = {"periodic": True} if args.periodic else {}
    if args.periodic_weight is not None:
        periodic["periodic_weight"] = args.periodic_weight
    res, summary = run_sto(args.method, iterations=args.iterations, cycles=args.cycles,
                           second_order=args.second_order, callback=progress, min_duration=args.min_duration,
                           max_duration=args.max_duration, z_velocity=args.z_velocity,
                           grf_tracking=args.grf_tracking == "on", terminal_half=args.terminal_half == "on",
                           solver_options=SolverOptions(al_max_abs_tolerance=args.max_touchdown_error), **periodic)
    res.solution.save(out / "solution.npz")
    summary["command"] = args.command_line
    write_json(out / "summary.json", summary)
    print(f"{args.method}: total time {summary['initial_total_time']:.4f} s -> {summary['total_time']:.4f} s "
          f"({100 * summary['reduction']:.1f} % reduction) in {summary['iterations']} iterations; "
          f"durations [ms] {[round(1e3 * d, 1) for d in summary['mode_durations']]}; max |g| "
          f"{1e3 * summary['max_touchdown_error']:.2f} mm")
    print(f"wrote {out / 'summary.json'}")
    return 0


def _check_duration_bounds(args) -> None:
    """``--min-duration`` < ``--max-duration`` (an omitted one is STOOptions' default)."""
    import dataclasses

    from hsddp_gym.planners.optimizer.sto import STOOptions

    defaults = {f.name: f.default for f in dataclasses.fields(STOOptions)}
    lo = args.min_duration if args.min_duration is not None else defaults["min_duration"]
    hi = args.max_duration if args.max_duration is not None else defaults["max_duration"]
    if not lo < hi:
        option = "--min-duration" if args.min_duration is not None else "--max-duration"
        raise UsageError(option, f"min duration {lo} s >= max duration {hi} s"
                         + ("" if args.min_duration is not None and args.max_duration is not None
                            else " (the other bound is the default)"), "--min-duration < --max-duration")
    from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS

    start = getattr(args, "durations", None) or PAPER_BOUNDING_DURATIONS  # the optimization starts from them
    allowed = f"--min-duration <= {min(start):g} s and --max-duration >= {max(start):g} s (the initial durations)"
    if lo > min(start):
        raise UsageError("--min-duration", f"{lo} s is above the initial mode duration {min(start):g} s", allowed)
    if hi < max(start):
        raise UsageError("--max-duration", f"{hi} s is below the initial mode duration {max(start):g} s", allowed)


def _check_push(push, max_episode_steps) -> None:
    from hsddp_gym.envs.bounding import DEFAULT_FRAME_SKIP, DEFAULT_MAX_EPISODE_STEPS, DEFAULT_SIM_TIMESTEP

    t = push[0]
    steps = max_episode_steps or DEFAULT_MAX_EPISODE_STEPS
    duration = steps * DEFAULT_FRAME_SKIP * DEFAULT_SIM_TIMESTEP  # the CLI's env keeps the default control period
    if not 0.0 <= t < duration:
        raise UsageError("--push", f"T = {t} s", f"a push time 0 <= T < {duration:g} s, the episode length")
    for label, v in zip(("DVX", "DVZ", "DPITCH"), push[1:]):
        if not abs(v) < 1e300:
            raise UsageError("--push", f"{label} = {v}", "finite velocity changes [m/s, m/s, rad/s]")


def cmd_rollout(args) -> int:
    out = check_output_dir(args.out, "--out")
    parse_policy_spec(args.policy, "--policy")
    require(required_modules(args.policy) + (["PIL"] if args.video else [])
            + (["mujoco"] if args.simulator == "mujoco" else []),
            f"hsddp-gym rollout --policy {args.policy}" + (" --video" if args.video else "")
            + (" --simulator mujoco" if args.simulator == "mujoco" else ""))
    env_kwargs = {}
    if args.target_speed is not None:
        env_kwargs["target_speed"] = args.target_speed
    push = None
    if args.push is not None:
        _check_push(args.push, args.max_episode_steps)
        t, dvx, dvz, dw = args.push
        push = {"delta_v": [dvx, dvz, dw], "time": t}
    summary = run_rollouts(args.policy, args.episodes, args.seed, out, video=args.video, env_kwargs=env_kwargs,
                           push=push, quiet=args.quiet, max_episode_steps=args.max_episode_steps,
                           env_id=ROLLOUT_ENVS[args.simulator == "mujoco"])
    for k in ("mean_return", "std_return", "falls", "mean_forward_speed", "mean_episode_length", "real_time_factor",
              "replans", "planner_failures", "mean_replan_ms"):
        v = summary.get(k)
        print(f"  {k:<22} {v:.4g}" if isinstance(v, float) else f"  {k:<22} {v}")
    print(f"wrote {out / 'summary.json'}")
    return 0


# ----------------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from hsddp_gym.workflows import run_demo

    check_output_dir(args.out, "--out")
    require(["matplotlib"] + ([] if args.no_video else ["PIL"]),
            "hsddp-gym demo (its figures" + (")" if args.no_video else " and GIF; or pass --no-video)"))
    summary = run_demo(Path(args.out), cycles=args.cycles, episodes=args.episodes, video=not args.no_video,
                       quiet=args.quiet, max_episode_steps=args.max_episode_steps)
    for name in ("warm_start", "hsddp_plan"):
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
DATASET_POLICIES = POLICIES
TRAIN_ALGOS = ("bc", "dagger", "ppo", "sac")


def _learning_rate(text: str) -> float | str:
    """A learning rate: a number > 0, or ``lin_<number>`` (RL-Zoo's linear decay; ppo/sac only, checked later)."""
    from hsddp_gym.learning.sb3 import parse_learning_rate

    try:
        return parse_learning_rate(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc


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
    from hsddp_gym.datasets.storage import check_dataset_id

    out = check_output_dir(args.out, "--out")
    if out.exists() and not args.overwrite:
        raise UsageError("--out", f"{args.out!r} already exists", "a new directory, or --overwrite to replace it")
    if args.dataset_id is not None:
        check_dataset_id(args.dataset_id, "--dataset-id")
    require(["minari", "h5py"], "hsddp-gym dataset (it writes a Minari dataset)")
    _check_conditions(args)
    if args.condition is not None and args.env != DATASET_ENVS[0]:
        raise UsageError("--condition", f"given with --env {args.env}",
                         f"--condition with --env {DATASET_ENVS[0]} only (the conditions perturb Bounding-v0)")
    if args.policy == "expert" and args.env == MPC_ENVS[1]:
        raise UsageError("--policy", f"expert with --env {args.env}",
                         "mpc (the terrain-aware MPC, the task's expert), heuristic or random")
    env_kwargs = {} if args.target_speed is None else {"target_speed": args.target_speed}
    if args.address is not None and args.backend != "ray":
        raise UsageError("--address", f"{args.address!r} without --backend ray", "only with --backend ray")
    if args.backend == "ray":
        require(["ray"], "hsddp-gym dataset --backend ray")
        try:
            check_backend("ray", args.address)
        except ValueError as exc:
            raise UsageError("--address", str(exc), "'auto', 'ray://host:10001' or 'host:6379'") from None
    try:
        res = generate_dataset(args.policy, args.episodes, args.out, seed=args.seed, workers=args.workers,
                               backend=args.backend, address=args.address,
                               dataset_id=args.dataset_id, overwrite=args.overwrite, env_kwargs=env_kwargs,
                               max_episode_steps=args.max_episode_steps, include_gains=args.gains,
                               progress=not args.quiet, action_noise=args.action_noise, resume=not args.no_resume,
                               conditions=args.condition, env_id=args.env)
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
             if not res.resumed_episodes else "")
          + f"; {res.total_time_s:.1f} s in all (reference-score episodes {m['reference_time_s']:.1f} s"
          + (f", expert plan {m['plan_time_s']:.1f} s" if m.get("plan_time_s") else "") + ", writing)")
    if args.condition:
        counts = {c: m["episode_conditions"].count(c) for c in dict.fromkeys(args.condition)}
        print("  episodes per condition: " + ", ".join(f"{c} {n}" for c, n in counts.items()))
    print(f"  ref_max_score {m['ref_max_score']:.4g} ({m['ref_max_score_source']}), ref_min_score "
          f"{m['ref_min_score']:.4g} (random policy)")
    print(f"wrote {res.path}/ (minari/, episodes.npz, metadata.json); load with "
          f"hsddp_gym.datasets.load_minari('{res.path}') or MINARI_DATASETS_PATH={res.path}/minari "
          f"minari.load_dataset('{res.dataset_id}')")
    return 0


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

            recorded = read_metadata(resolve_dataset_dir(args.dataset[0], "--dataset")).get("env_id") or DATASET_ENVS[0]
            if env is not None and env != recorded:
                raise UsageError("--env", f"{env}, but --dataset {args.dataset[0]} was recorded in {recorded}",
                                 "the dataset's env")
            env = recorded
        if args.expert is None:
            args.expert = "mpc" if env in (None, *MPC_ENVS) else "expert"
        args.env = env
    if args.env is None:
        return
    if args.algo == "bc":
        raise UsageError("--env", "given with --algo bc", "--algo dagger, ppo or sac (bc evaluates in the env of "
                                                          "its dataset's metadata)")
    if args.env == DATASET_ENVS[0]:
        return
    for flag, given in (("--vector-env", args.vector_env), ("--condition", bool(args.condition)),
                        ("--estimator", args.estimator), ("--action-queue", bool(args.action_queue))):
        if given:
            raise UsageError(flag, f"given with --env {args.env}", f"only with --env {DATASET_ENVS[0]}")
    if args.algo == "dagger" and args.env == MPC_ENVS[1]:
        if args.expert == "expert":
            raise UsageError("--expert", f"expert with --env {args.env}", "mpc (the terrain-aware MPC) or heuristic")
        return
    if args.algo == "dagger" and args.expert != "expert":
        raise UsageError("--expert", f"{args.expert} with --env {args.env}",
                         f"expert (the task's HS-DDP plan tracker) with --env {args.env}")


def _check_train(args) -> None:
    """Everything about ``train``'s options that can be checked before training (UsageError / MissingExtraError)."""
    check_output_dir(args.out, "--out")
    for flag, given in (("--gain-copies", args.gain_copies), ("--gain-noise", args.gain_noise is not None)):
        if given and args.algo != "bc":
            raise UsageError(flag, f"given with --algo {args.algo}", "--algo bc")
    if args.speed_input and args.algo not in ("bc", "dagger"):
        raise UsageError("--speed-input", f"given with --algo {args.algo}", "--algo bc or dagger")
    if args.action_queue and args.algo not in ("bc", "dagger"):
        raise UsageError("--action-queue", f"given with --algo {args.algo}", "--algo bc or dagger")
    for flag, given in (("--workers", args.workers is not None), ("--estimator", args.estimator)):
        if given and args.algo != "dagger":
            raise UsageError(flag, f"given with --algo {args.algo}", "--algo dagger")
    if args.condition and args.algo not in ("dagger", "ppo", "sac"):
        raise UsageError("--condition", f"given with --algo {args.algo}", "--algo dagger, ppo or sac")
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
    if args.estimator and args.action_queue:
        raise UsageError("--action-queue", "given with --estimator (its prediction over the delay replaces the "
                         "queue)", "one of them")
    _check_conditions(args)
    if args.gain_noise is not None and not args.gain_copies:
        raise UsageError("--gain-noise", "given without --gain-copies", "with --gain-copies N (N >= 1)")
    if args.n_envs is not None and args.algo not in ("ppo", "sac"):
        raise UsageError("--n-envs", f"given with --algo {args.algo}", "--algo ppo or sac")
    if args.vector_env and args.algo not in ("ppo", "sac"):
        raise UsageError("--vector-env", f"given with --algo {args.algo}", "--algo ppo or sac")
    if args.sde and args.algo != "ppo":
        raise UsageError("--sde", f"given with --algo {args.algo}", "--algo ppo")
    if args.log_std_init is not None and args.algo != "ppo":
        raise UsageError("--log-std-init", f"given with --algo {args.algo}", "--algo ppo")
    if isinstance(args.lr, str) and args.algo not in ("ppo", "sac"):
        raise UsageError("--lr", f"{args.lr} (a schedule) with --algo {args.algo}", "a number (Adam's step)")
    if args.algo in ("ppo", "sac"):
        if args.steps is None:
            raise UsageError("--steps", "missing", f"a number of env steps (required for --algo {args.algo})")
        if args.learning_starts is not None and args.algo == "ppo":
            raise UsageError("--learning-starts", "given with --algo ppo", "--algo sac")
        if args.preset == "parallel" and args.algo != "ppo":
            raise UsageError("--preset", f"parallel given with --algo {args.algo}", "hopper or halfcheetah")
        from hsddp_gym.learning.sb3 import hyperparameters

        try:
            hyperparameters(args.algo, _sb3_overrides(args), args.preset)
        except ValueError as exc:  # name the option whose value the hyperparameters refused
            key = str(exc).split()[0]
            raise UsageError(_SB3_OVERRIDE_FLAGS.get(key, "--algo"), str(exc),
                             "see hsddp-gym train --help") from exc
        require(["stable_baselines3", "torch"], f"hsddp-gym train --algo {args.algo}")
        return
    if args.algo == "bc" and args.dataset is None:
        raise UsageError("--dataset", "missing", "a dataset directory written by `hsddp-gym dataset` (required "
                                                 "for --algo bc)")
    if args.curve and args.algo != "bc":
        raise UsageError("--curve", f"given with --algo {args.algo}", "--algo bc")
    needs = ["torch"] + (["minari", "h5py"] if args.dataset is not None and args.format == "minari" else [])
    require(needs, f"hsddp-gym train --algo {args.algo}" + (" --format minari" if "minari" in needs else ""))
    if args.dataset is None:
        if args.demos is not None:
            raise UsageError("--demos", "given without --dataset", "--demos with --dataset")
        return
    from hsddp_gym.datasets.storage import read_metadata, resolve_dataset_dir

    if len(args.dataset) > 1 and args.algo not in ("bc", "dagger"):
        raise UsageError("--dataset", f"{len(args.dataset)} datasets with --algo {args.algo}",
                         "several only with --algo bc or dagger")
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
    if args.algo in ("ppo", "sac"):
        from hsddp_gym.learning.sb3 import train_sb3

        overrides = _sb3_overrides(args)
        res = train_sb3(args.algo, args.steps, args.seed, out, env_kwargs=env_kwargs,
                        max_episode_steps=args.max_episode_steps, overrides=overrides or None,
                        eval_freq=args.eval_freq, final_eval_episodes=args.eval_episodes, progress=not args.quiet,
                        time_limit=args.time_limit, preset=args.preset, vector_env=args.vector_env,
                        train_condition=args.condition[0] if args.condition else None, env_id=args.env)
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
                              estimator=bool(args.estimator),
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
                        "controller; random: uniform actions; in Pronking-v0 expert tracks a 4-cycle HS-DDP pronk "
                        "plan periodically from the env's (noisy) start, in GapJump-v0 / BoxJump-v0 the HS-DDP "
                        "jump plan then its cycle after the jump looped, in StandToBound-v0 / BoundPronkBound-v0 / "
                        "BoundToStop-v0 the HS-DDP transition plan then its bounding cycle looped or its last "
                        "posture held, in Backflip-v0 the HS-DDP backflip plan "
                        "then holds its landing posture; in Terrain-v0 mpc is the terrain-aware MPC (given each "
                        "episode's terrain) and there is no expert (default: %(default)s)")
    p.add_argument("--env", choices=DATASET_ENVS, default=DATASET_ENVS[0],
                   help="the env the episodes are recorded in; the default dataset id follows it "
                        "(hsddp_gym/bounding/POLICY-v0, hsddp_gym/pronking/POLICY-v0, hsddp_gym/backflip/POLICY-v0, "
                        "hsddp_gym/terrain/POLICY-v0, ...) "
                        "(default: %(default)s)")
    p.add_argument("--episodes", type=_positive_int, default=10,
                   help="episodes; episode i is reset with seed --seed + i (default: %(default)s)")
    p.add_argument("--workers", type=_positive_int, default=1,
                   help="worker processes (1: in this process), or the CPUs of the local Ray instance with "
                        "--backend ray; the data do not depend on it (default: %(default)s)")
    add_backend_arguments(p)
    p.add_argument("--seed", type=_seed, default=0, help="seed of episode 0 (default: %(default)s)")
    p.add_argument("--out", required=True, help="dataset directory (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out (the old dataset stays until the new one is complete) and "
                        "discard checkpoints of an interrupted run with other settings")
    p.add_argument("--no-resume", action="store_true",
                   help="discard the checkpoints of an interrupted run (OUT's hidden sibling .NAME.partial) and "
                        "start over; by default a rerun with the same settings resumes from them and a rerun "
                        "with other settings refuses")
    p.add_argument("--dataset-id", default=None,
                   help="Minari dataset id (default: hsddp_gym/bounding/POLICY-v0, with --env "
                        "hsddp_gym/Pronking-v0 hsddp_gym/pronking/POLICY-v0, with hsddp_gym/Backflip-v0 "
                        "hsddp_gym/backflip/POLICY-v0)")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit override (default: the env's 1000)")
    p.add_argument("--target-speed", type=_finite_float, default=None,
                   help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--gains", action="store_true", help="also store the plan's feedback gains (4x14 per step)")
    p.add_argument("--action-noise", type=_nonnegative_float, default=0.0,
                   help="DART noise injection: execute the policy's action plus Gaussian noise of this std "
                        "(normalized units, e.g. 0.04) and store the clean action in infos/expert_action, the "
                        "label BC/DAgger use; ref_max_score then comes from 5 noise-free episodes (default: 0, "
                        "no noise)")
    p.add_argument("--condition", type=_condition, nargs="+", default=None, metavar="NAME",
                   help="demonstrations under perturbations: names of hsddp_gym.envs.perturbations.CONDITIONS "
                        "(e.g. push obs_noise delay_10ms speed_2.0; repeats weight them); episode i runs in the "
                        "(i mod n)-th, its perturbation seeded by its seed, recorded in the metadata "
                        "(episode_conditions, episode_target_speeds). The expert acts on the true state; the "
                        "stored observations are the perturbed ones (default: the plain env)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_dataset)

    from hsddp_gym.learning.sb3 import OPTION_HELP  # numpy-only at import; SB3 and torch load when training

    p = sub.add_parser("train", help="train a baseline: behaviour cloning, DAgger, PPO or SAC",
                       description="bc: MLP 2x256 ReLU, Adam 1e-3, MSE on normalized actions, on --dataset; dagger: "
                                   "BC + relabelling rounds by --expert with beta = BETA_DECAY**round; ppo / sac: "
                                   "Stable-Baselines3 with RL-Zoo hyperparameters (--preset: Hopper-v3 by default, or "
                                   "HalfCheetah-v3; hsddp_gym.learning.sb3). "
                                   "Writes the model, summary.json (with training wall time and a 10-episode "
                                   "deterministic evaluation, seeds 0..9) and curve.csv / curve.png into --out.")
    p.add_argument("--algo", choices=TRAIN_ALGOS, required=True,
                   help="bc: behaviour cloning on --dataset; dagger: DAgger relabelled by --expert; ppo / sac: "
                        "Stable-Baselines3 RL on hsddp_gym/Bounding-v0 (or --env)")
    p.add_argument("--env", choices=DATASET_ENVS, default=None,
                   help="ppo/sac/dagger: the env to train and evaluate in (default: hsddp_gym/Bounding-v0; dagger: "
                        "the env of --dataset's metadata if given); hsddp_gym/Pronking-v0, hsddp_gym/Backflip-v0 and "
                        "the jumps take no --vector-env, --condition, --estimator or --action-queue, and dagger labels "
                        "them with --expert expert (the task's plan tracker); bc: refused, it evaluates in the env of "
                        "its dataset")
    p.add_argument("--seed", type=_seed, default=0,
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
    p.add_argument("--preset", choices=("hopper", "halfcheetah", "parallel"), default="hopper",
                   help="ppo/sac: the RL-Zoo hyperparameters of Hopper-v3 (a task that ends on falls, like this "
                        "one) or HalfCheetah-v3; ppo only: parallel, legged_gym's massively parallel PPO on a CPU "
                        "(64 robots x 128 steps per update, 4 minibatches; use with --vector-env) "
                        "(hsddp_gym.learning.sb3.PRESETS; default: %(default)s)")
    p.add_argument("--n-envs", type=_positive_int, default=None,
                   help="ppo/sac: envs stepped together in one DummyVecEnv (default: the preset's, 1)")
    p.add_argument("--vector-env", action="store_true",
                   help="ppo/sac: step the --n-envs training robots with the compiled vector env "
                        "(hsddp_gym.envs.vector, one numba call for all) instead of a DummyVecEnv of single envs")
    p.add_argument("--sde", action="store_true", help=OPTION_HELP["sde"])
    p.add_argument("--log-std-init", type=float, default=None, help=OPTION_HELP["log_std_init"])
    p.add_argument("--time-limit", type=_positive_float, default=None,
                   help="ppo/sac: wall-clock training budget [s]; training stops there and summary.json records "
                        "the steps that fit (--steps is then the upper bound)")
    p.add_argument("--dataset", nargs="+", default=None,
                   help="bc (required) / dagger (optional round-0 data): a dataset directory written by "
                        "`hsddp-gym dataset`, or several (pooled, e.g. at several target speeds)")
    p.add_argument("--speed-input", action="store_true",
                   help="bc/dagger: the env's target speed as one more input of the MLP (for demonstrations at "
                        "several target speeds; dagger: with --condition speed_... rollouts)")
    p.add_argument("--action-queue", type=_nonnegative_int, default=0,
                   help="bc/dagger: slots of the latency queue in the MLP's input: the actions sent that the env "
                        "has not executed yet (the env's action delay of them, e.g. --condition delay_5ms: 1), as the "
                        "MPC's latency compensation uses them; needs demonstrations that record their conditions "
                        "(0: none; default: %(default)s)")
    p.add_argument("--format", choices=("minari", "npz"), default="minari",
                   help="read the dataset through minari.load_dataset or its episodes.npz (default: %(default)s)")
    p.add_argument("--demos", type=_positive_int, default=None,
                   help="bc/dagger: use only the first DEMOS episodes of --dataset (default: all)")
    p.add_argument("--epochs", type=_positive_int, default=50, help="bc/dagger: BC epochs (default: %(default)s)")
    p.add_argument("--batch-size", type=_positive_int, default=256,
                   help="bc/dagger: minibatch size of the BC updates (default: %(default)s)")
    p.add_argument("--lr", type=_learning_rate, default=None,
                   help="bc/dagger: Adam's step (default: 1e-3); ppo/sac: " + OPTION_HELP["learning_rate"])
    p.add_argument("--features", choices=("obs", "gait_clock"), default="obs",
                   help="bc/dagger: MLP inputs; gait_clock appends the MPC's gait clock (phase one-hot, time in "
                        "phase, cycle sin/cos) rebuilt from the observation history, since the MPC's phase drifts "
                        "from the observation clock (default: %(default)s)")
    p.add_argument("--hidden", type=_int_list, default=None,
                   help="hidden layer sizes, e.g. 128,128 (bc/dagger: the MLP, default 256,256; "
                        "ppo/sac: every network, actor and critic alike, default the preset's)")
    p.add_argument("--weight-decay", type=_nonnegative_float, default=0.0,
                   help="bc/dagger: Adam weight decay (default: 0)")
    p.add_argument("--lr-decay", action="store_true", help="bc/dagger: cosine learning-rate decay to 0 over the epochs")
    p.add_argument("--gain-copies", type=_nonnegative_int, default=0,
                   help="bc: perturbed copies of every demonstration labelled with the expert's feedback law "
                        "u + K dx (needs a dataset made with --gains; hsddp_gym.learning.gain_labels); 0: off "
                        "(default: %(default)s)")
    p.add_argument("--gain-noise", type=_nonnegative_float, nargs=2, metavar=("POS_STD", "VEL_STD"), default=None,
                   help="bc: standard deviations of the state offsets of --gain-copies, positions [m, rad] "
                        "and velocities [m/s, rad/s] (default: 0.01 0.1)")
    p.add_argument("--curve", type=_int_list, default=None,
                   help="bc: comma-separated numbers of demonstration episodes for the learning curve, e.g. 1,5,10")
    p.add_argument("--expert", choices=("mpc", "expert", "heuristic"), default=None,
                   help="dagger: the labelling expert; in hsddp_gym/Pronking-v0, Backflip-v0 and the jumps only "
                        "expert, the task's plan tracker (default: mpc; expert in those two)")
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
    p.add_argument("--condition", type=_condition, nargs="+", default=None, metavar="NAME",
                   help="dagger: run the relabelling rollouts under perturbations, names of "
                        "hsddp_gym.envs.perturbations.CONDITIONS (episode j of a round in the (j mod n)-th); the "
                        "learner acts on the perturbed observation, the MPC labels the true state and is told the "
                        "action sent; ppo/sac: one name, under which every training robot runs (e.g. push_x3: "
                        "three random pushes an episode; with --vector-env only env arguments and pushes), while the "
                        "evaluations stay on the plain env (default: the plain env)")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="dagger: processes running each round's rollouts; results do not depend on it "
                        "(default: 1)")
    p.add_argument("--estimator", action="store_true",
                   help="dagger: the learner acts behind the MPC's perception (EstimatedStatePolicy: the state "
                        "filter's estimate predicted over the action delay); the rollouts store what it sees there, "
                        "and it is meant to be evaluated behind it (robustness.py --estimated); give round-0 data of "
                        "undisturbed envs")
    p.add_argument("--warm-start", action="store_true",
                   help="dagger: rounds >= 1 fine-tune the previous round's network (and keep its input "
                        "standardization) for --epochs instead of retraining from scratch")
    p.add_argument("--eval-episodes", type=_nonnegative_int, default=10,
                   help="final deterministic evaluation episodes, seeds 0.. (dagger: also after every round) "
                        "(default: %(default)s; 0: none)")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit override for training/evaluation episodes (default: the env's 1000)")
    p.add_argument("--target-speed", type=_finite_float, default=None,
                   help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_train)
# ----------------------------------------------------------------------------------------------- end dataset, train


# ----------------------------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="hsddp-gym",
        description="HS-DDP (Li & Wensing, RA-L 2020) for the planar MIT Mini Cheetah: plan bounding gaits, "
                    "optimize switching times, run the planner as MPC in the Gymnasium env.")
    parser.add_argument("--version", action="version", version=f"hsddp-gym {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="plan a 5-cycle bound with HS-DDP from the heuristic warm start; write "
                                    "figures and a summary",
                       description="The main job: the HS-DDP (al-reb) plan of the paper's bounding task "
                                   "beside its warm start (the heuristic controller up to 5 cycles, a repeated "
                                   "cycle of the solved 5-cycle plan beyond), figures (motion.png, states.png, "
                                   "convergence.png), "
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
                                   "state; warm start: the heuristic controller up to 5 cycles, beyond them the "
                                   "solved 5-cycle plan with its 4th cycle repeated) and write summary.json, the "
                                   "solution and figures.")
    p.add_argument("--method", choices=("heuristic", "ddp", "al", "al-reb"), default="al-reb",
                   help="heuristic: the heuristic controller's rollout alone (it diverges in cycle 10); ddp: "
                        "impact-aware DDP ignoring switching constraints; al: + augmented Lagrangian on them; "
                        "al-reb: + relaxed barriers on torque, normal force and friction (default: %(default)s)")
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
    p.add_argument("--policy", default="mpc", metavar="{mpc,expert,heuristic,random,bc:DIR,dagger:DIR,sb3:DIR}",
                   help="mpc: HS-DDP model-predictive control; expert: tracks a 5-cycle al-reb plan (episodes "
                        "start at the plan's initial state); heuristic: the warm-start controller; random: uniform "
                        "actions; bc:DIR / dagger:DIR / sb3:DIR (or ppo:DIR, sac:DIR): the policy trained by "
                        "`hsddp-gym train ... --out DIR` (default: %(default)s)")
    p.add_argument("--episodes", type=_positive_int, default=10, help="episodes (default: %(default)s)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the first episode (default: %(default)s)")
    p.add_argument("--target-speed", type=_finite_float, default=None,
                   help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--push", type=float, nargs=4, metavar=("T", "DVX", "DVZ", "DPITCH"), default=None,
                   help="push at episode time T [s]: add (DVX, DVZ) [m/s] and DPITCH [rad/s] to the trunk velocity")
    p.add_argument("--max-episode-steps", type=_positive_int, default=None,
                   help="time limit in control steps of 5 ms (default: the env's 1000)")
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
    p.add_argument("--z-velocity", choices=("paper", "code"), default="paper",
                   help="vertical-velocity references at the phase ends: paper = 0 (the paper's text), code = the "
                        "authors' +1 m/s after a stance, -1 m/s before a touchdown (default: %(default)s)")
    p.add_argument("--grf-tracking", choices=("on", "off"), default="on",
                   help="the authors' ground-force tracking term in the running cost; the paper has none "
                        "(default: %(default)s)")
    p.add_argument("--terminal-half", choices=("on", "off"), default="on",
                   help="the authors' 1/2 in the terminal costs; the paper's eq. 33 has none (default: %(default)s)")
    p.add_argument("--max-touchdown-error", type=_positive_float, default=None, metavar="METRES",
                   help="Algorithm 1 also stops only when every landing foot is within this height of the ground "
                        "(max |g|; the authors' later code: 0.001); default: sum g^2 <= 1e-4 only, as the paper")
    p.add_argument("--periodic", action="store_true",
                   help="the periodic task: back stance, flight, front stance, flight, back stance, ending in the "
                        "start state up to x (a gait that can be repeated); needs --cycles 1")
    p.add_argument("--periodic-weight", type=_positive_float, default=None,
                   help="scale of the periodic terminal penalty (default: 1e5; needs --periodic)")
    p.add_argument("--out", default="runs/sto", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no per-iteration lines")
    p.set_defaults(func=cmd_sto)
    _add_learning_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI. A user error (a bad option value, a missing extra) prints one line ``error: ...`` on
    stderr and returns 2; options are checked before any long work starts."""
    with contextlib.suppress(AttributeError, ValueError):  # progress lines as they happen when piped
        sys.stdout.reconfigure(line_buffering=True)
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    args.command_line = " ".join(["hsddp-gym", *argv])  # recorded in summaries (the arguments actually parsed)
    try:
        return int(args.func(args) or 0)
    except (UsageError, MissingExtraError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
