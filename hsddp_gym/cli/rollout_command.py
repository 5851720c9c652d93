"""``hsddp-gym rollout``: seeded episodes of a policy (built-in or trained) in any registered env
([`hsddp_gym.workflows.run_rollouts`][hsddp_gym.workflows.run_rollouts]), after checking that the policy exists there
and that a trained policy runs in the env it was trained in (or is transferred on purpose, ``--transfer``)."""

from __future__ import annotations

import sys

from hsddp_gym.cli import env_choices, parsing
from hsddp_gym.registry import TASKS
from hsddp_gym.rollout.policies import parse_policy_spec, required_modules
from hsddp_gym.util.extras import require
from hsddp_gym.util.validation import UsageError, check_output_dir
from hsddp_gym.workflows import run_rollouts

SUMMARY_KEYS = ("mean_return", "std_return", "falls", "mean_forward_speed", "mean_episode_length", "real_time_factor",
                "replans", "planner_failures", "mean_replan_ms")
"""The summary entries ``rollout`` prints."""


def rollout_env(args, run) -> tuple[str, dict | None]:
    """``(env_id, transfer)``: the env ``--env`` and ``--simulator`` name (without ``--env``: a trained policy's own
    env, else Bounding-v0), and for a trained policy run in another env with ``--transfer`` the record
    ``{"trained_env_id", "env_id", "relation"}`` (None otherwise; a note on stderr says so).

    Raises UsageError: the built-in policy does not exist in the env (``--policy``), ``--simulator`` names no twin
    of the env's task, a trained policy in an env other than its own without ``--transfer`` (``--env``), or
    ``--transfer`` without a trained policy."""
    trained = env_choices.trained_env_id(run) if run is not None else None
    if args.transfer and trained is None:
        raise UsageError("--transfer", f"given with --policy {args.policy}", "only with a trained policy KIND:DIR")
    env_id = args.env or trained or env_choices.DEFAULT_ENV
    if args.simulator is not None:
        env_id = env_choices.simulator_env(env_id, args.simulator)
    env_choices.check_policy_exists(args.policy, env_id)
    if trained is None or trained == env_id:
        return env_id, None
    relation = env_choices.relation(trained, env_id)
    if not args.transfer:
        option = "--env" if args.env is not None else "--simulator"
        raise UsageError(option, f"{env_id}, but --policy {args.policy} was trained in {trained} ({env_id} is "
                                 f"{relation})",
                         f"--env {trained} (the policy's own env), or --transfer to evaluate it in {env_id}")
    print(f"note: --transfer: --policy {args.policy} was trained in {trained} and is evaluated in {env_id} "
          f"({relation})", file=sys.stderr)
    return env_id, {"trained_env_id": trained, "env_id": env_id, "relation": relation}


def cmd_rollout(args) -> int:
    out = check_output_dir(args.out, "--out")
    _, run = parse_policy_spec(args.policy, "--policy")
    env_id, transfer = rollout_env(args, run)
    mujoco = env_choices.needs_mujoco(env_id)
    require(required_modules(args.policy) + (["PIL"] if args.video else []) + (["mujoco"] if mujoco else []),
            f"hsddp-gym rollout --policy {args.policy}" + (" --video" if args.video else "")
            + (f" --env {env_id}" if mujoco else ""))
    env_kwargs = {}
    if args.target_speed is not None:
        env_kwargs["target_speed"] = args.target_speed
    if env_kwargs or args.push is not None:
        env_choices.check_env_settings(env_id, env_kwargs, args.push, args.max_episode_steps)
    push = None
    if args.push is not None:
        t, dvx, dvz, dw = args.push
        push = {"delta_v": [dvx, dvz, dw], "time": t}
    summary = run_rollouts(args.policy, args.episodes, args.seed, out, video=args.video, env_kwargs=env_kwargs,
                           push=push, quiet=args.quiet, max_episode_steps=args.max_episode_steps, env_id=env_id,
                           record={"transfer": transfer} if transfer else None)
    parsing.print_values(summary, SUMMARY_KEYS, 22)
    print(f"wrote {out / 'summary.json'}")
    return 0


def add_parser(sub) -> None:
    """Add ``rollout`` to the subparsers ``sub``."""
    bounding = TASKS["bounding"]
    no_expert = [t.env_id for t in TASKS.values() if t.expert is None]
    terrain_aware = [t.env_id for t in TASKS.values() if t.terrain_aware_mpc]
    motions = [t.env_id for t in TASKS.values() if t.motion is not None]
    p = sub.add_parser("rollout", help="run a policy in any registered env for seeded episodes",
                       description="Run --episodes seeded episodes (seeds --seed, --seed+1, ...) of a policy in "
                                   "--env (hsddp_gym/Bounding-v0 by default) with its default reset noise and time "
                                   "limit (or --max-episode-steps); write summary.json (mean/std return, falls, "
                                   "forward speed, episode length, real-time factor, replans, planner failures, "
                                   "mean replan ms), episode0.npz and, with --video, episode0.gif. A trained "
                                   "policy runs in the env it was trained in (another one only with --transfer).")
    p.add_argument("--policy", default="mpc", metavar="{mpc,expert,heuristic,random,bc:DIR,dagger:DIR,sb3:DIR}",
                   help="mpc: HS-DDP model-predictive control (the bounding MPC; in "
                        f"{', '.join(terrain_aware)} the terrain-aware MPC, given each episode's terrain; in "
                        f"{', '.join(motions)} the motion's MPC, which re-plans what remains of it); expert: "
                        "the task's HS-DDP plan tracker (in Bounding-v0 it tracks a 5-cycle al-reb plan and its "
                        f"episodes start at the plan's initial state; none in {', '.join(no_expert)}); heuristic: "
                        "the warm-start controller; random: uniform actions; bc:DIR / dagger:DIR / sb3:DIR (or "
                        "ppo:DIR, sac:DIR): the policy trained by `hsddp-gym train ... --out DIR`, in the env it was "
                        "trained in (its summary.json's env_id) (default: %(default)s)")
    p.add_argument("--env", choices=env_choices.ENVS, default=None, metavar="ID",
                   help=f"the env to run in, one of {env_choices.env_list_text()} (default: {bounding.env_id}, "
                        "or the env a trained --policy was trained in)")
    p.add_argument("--transfer", action="store_true",
                   help="run a trained --policy in an --env other than the one it was trained in (e.g. its MuJoCo "
                        "twin); a note on stderr says so and summary.json records it under 'transfer' "
                        "(default: refused)")
    p.add_argument("--episodes", type=parsing.positive_int, default=10, help="episodes (default: %(default)s)")
    p.add_argument("--seed", type=parsing.seed, default=0, help="seed of the first episode (default: %(default)s)")
    p.add_argument("--target-speed", type=parsing.finite_float, default=None,
                   help="env target_speed [m/s], where the env takes one (default: the env's)")
    p.add_argument("--push", type=float, nargs=4, metavar=("T", "DVX", "DVZ", "DPITCH"), default=None,
                   help="push at episode time T [s]: add (DVX, DVZ) [m/s] and DPITCH [rad/s] to the trunk velocity")
    p.add_argument("--max-episode-steps", type=parsing.positive_int, default=None,
                   help="time limit in control steps of 5 ms (default: the env's registered limit, "
                        f"{bounding.max_episode_steps} in {bounding.env_id})")
    p.add_argument("--simulator", choices=tuple(env_choices.SIMULATORS), default=None,
                   help="lcp: the task's own env (exact-LCP contacts); mujoco: its MuJoCo twin (soft contacts; "
                        f"needs the extra 'mujoco'), e.g. {bounding.twin_id} for {bounding.env_id} (default: the "
                        "env --env names)")
    p.add_argument("--video", action="store_true", help="write episode0.gif (the first episode, rendered off-screen)")
    p.add_argument("--out", default="runs/rollout", help="output directory (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_rollout)
