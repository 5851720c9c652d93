"""``hsddp-gym dataset``: a demonstration dataset (Minari + ``episodes.npz`` + ``metadata.json``) recorded with a
policy in one of the tasks' envs
([`hsddp_gym.datasets.generation.generate_dataset`][hsddp_gym.datasets.generation.generate_dataset])."""

from __future__ import annotations

import sys

from hsddp_gym.cli import env_choices, parsing
from hsddp_gym.registry import DATASET_ENVS
from hsddp_gym.rollout.policies import POLICIES
from hsddp_gym.util.extras import require
from hsddp_gym.util.parallel import add_backend_arguments, check_backend
from hsddp_gym.util.validation import UsageError, check_output_dir


def cmd_dataset(args) -> int:
    from hsddp_gym.datasets.generation import generate_dataset, partial_dir
    from hsddp_gym.datasets.storage import check_dataset_id

    out = check_output_dir(args.out, "--out")
    if out.exists() and not args.overwrite:
        raise UsageError("--out", f"{args.out!r} already exists", "a new directory, or --overwrite to replace it")
    if args.dataset_id is not None:
        check_dataset_id(args.dataset_id, "--dataset-id")
    require(["minari", "h5py"], "hsddp-gym dataset (it writes a Minari dataset)")
    parsing.check_conditions(args)
    if args.condition is not None:
        parsing.check_task_condition_names(args.condition, args.env)
    env_choices.check_policy_exists(args.policy, args.env, trained=False)
    env_kwargs = {} if args.target_speed is None else {"target_speed": args.target_speed}
    if env_kwargs:
        env_choices.check_env_settings(args.env, env_kwargs, None, None)
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



def add_parser(sub) -> None:
    """Add ``dataset`` to the subparsers ``sub``."""
    p = sub.add_parser("dataset", help="generate a demonstration dataset (Minari + npz) with a policy",
                       description="Run --episodes episodes (episode i reset with seed --seed + i, a fresh policy "
                                   "per episode, so the data do not depend on --workers) in parallel worker "
                                   "processes and write a Minari dataset (OUT/minari, MINARI_DATASETS_PATH=OUT/minari)"
                                   ", OUT/episodes.npz and OUT/metadata.json atomically. infos carry qpos, qvel, "
                                   "contact, the expert's nominal state/action and solver statistics at every step. "
                                   "Finished episodes are checkpointed, so an interrupted run can be resumed by "
                                   "rerunning the same command. See hsddp_gym.datasets.")
    p.add_argument("--policy", choices=POLICIES, default="mpc",
                   help="mpc: HS-DDP MPC; expert: tracks the 5-cycle al-reb HS-DDP plan (episodes start at the "
                        "plan's initial state, no reset noise, so they are identical); heuristic: the warm-start "
                        "controller; random: uniform actions; in Pronking-v0 expert tracks a 4-cycle HS-DDP pronk "
                        "plan periodically from the env's (noisy) start, in GapJump-v0 / BoxJump-v0 the HS-DDP "
                        "jump plan then its cycle after the jump looped, in StandToBound-v0 / BoundPronkBound-v0 / "
                        "BoundToStop-v0 the HS-DDP transition plan then its bounding cycle looped or its last "
                        "posture held, in Backflip-v0 the HS-DDP backflip plan "
                        "then holds its landing posture; in Terrain-v0 mpc is the terrain-aware MPC (given each "
                        "episode's terrain) and there is no expert (default: %(default)s)")
    p.add_argument("--env", choices=DATASET_ENVS, default=DATASET_ENVS[0], metavar="ID",
                   help=f"the env the episodes are recorded in, a task's env: {', '.join(DATASET_ENVS)}; the "
                        "default --dataset-id follows it (default: %(default)s)")
    p.add_argument("--episodes", type=parsing.positive_int, default=10,
                   help="episodes; episode i is reset with seed --seed + i (default: %(default)s)")
    p.add_argument("--workers", type=parsing.positive_int, default=1,
                   help="worker processes (1: in this process), or the CPUs of the local Ray instance with "
                        "--backend ray; the data do not depend on it (default: %(default)s)")
    add_backend_arguments(p)
    p.add_argument("--seed", type=parsing.seed, default=0, help="seed of episode 0 (default: %(default)s)")
    p.add_argument("--out", required=True, help="dataset directory (must not exist unless --overwrite)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out (the old dataset stays until the new one is complete) and "
                        "discard checkpoints of an interrupted run with other settings")
    p.add_argument("--no-resume", action="store_true",
                   help="discard the checkpoints of an interrupted run (OUT's hidden sibling .NAME.partial) and "
                        "start over; by default a rerun with the same settings resumes from them and a rerun "
                        "with other settings refuses")
    from hsddp_gym.datasets.storage import default_dataset_id

    ids = "; ".join(f"{env}: {default_dataset_id('POLICY', env)}" for env in DATASET_ENVS)
    p.add_argument("--dataset-id", default=None,
                   help=f"Minari dataset id (default: hsddp_gym/TASK/POLICY-v0 of --env's task and --policy; {ids})")
    p.add_argument("--max-episode-steps", type=parsing.positive_int, default=None,
                   help="time limit override (default: the env's registered limit)")
    p.add_argument("--target-speed", type=parsing.finite_float, default=None,
                   help="env target_speed [m/s] (default: the env's)")
    p.add_argument("--gains", action="store_true", help="also store the plan's feedback gains (4x14 per step)")
    p.add_argument("--action-noise", type=parsing.nonnegative_float, default=0.0,
                   help="DART noise injection: execute the policy's action plus Gaussian noise of this std "
                        "(normalized units, e.g. 0.04) and store the clean action in infos/expert_action, the "
                        "label BC/DAgger use; ref_max_score then comes from 5 noise-free episodes (default: 0, "
                        "no noise)")
    p.add_argument("--condition", type=parsing.condition, nargs="+", default=None, metavar="NAME",
                   help="demonstrations under perturbations: names of hsddp_gym.envs.perturbations.CONDITIONS "
                        "(e.g. push obs_noise delay_10ms speed_2.0; repeats weight them); episode i runs in the "
                        "(i mod n)-th, its perturbation seeded by its seed, recorded in the metadata "
                        "(episode_conditions, episode_target_speeds). The expert acts on the true state; the "
                        "stored observations are the perturbed ones; in a task's env the conditions that apply to the "
                        "task, built for it (its push window and sizes) (default: the plain env)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_dataset)
