"""The jobs behind the CLI commands, callable from Python: planning outputs, seeded rollouts of a named policy."""

from __future__ import annotations

from pathlib import Path

from hsddp_gym.registry import ENV_TASKS, task_of_env
from hsddp_gym.rollout.policies import (
    LEARNED_POLICIES,
    POLICIES,
    PolicySpec,
    make_policy,
    parse_policy_spec,
    required_modules,
)
from hsddp_gym.util.io import write_json


# ----------------------------------------------------------------------------------------------- plan
def write_plan_outputs(result, out: Path, plots: bool) -> dict:
    """Write a [`PlanResult`][hsddp_gym.planners.tasks.PlanResult] into ``out``: ``solution.npz`` (or
    ``trajectory.npz`` for the heuristic) and, with ``plots``, the figures (needs matplotlib, checked before
    anything is written). Returns ``{kind: file name}``."""
    if plots:
        from hsddp_gym.util.extras import require

        require(["matplotlib"], "the plan's figures (plots=True; CLI: drop them with --no-plots)")
    files = {}
    pr = result.problem
    if result.solution is not None:
        result.solution.save(out / "solution.npz")
        files["solution"] = "solution.npz"
    else:
        from hsddp_gym.util.io import write_npz

        write_npz(out / "trajectory.npz", X=result.X, X_pre=result.X_pre, U=result.U, GRF=result.GRF)
        files["trajectory"] = "trajectory.npz"
    if plots:
        from hsddp_gym.viz import plotting

        robot = pr.dynamics.robot
        td = [tuple(float(c) for c in robot.foot_positions(result.X_pre[i, :7])[f])
              for i, f in enumerate(pr.touchdown) if f >= 0]
        plotting.plot_motion_strips(robot, {result.method: result.X}, out / "motion.png",
                                    touchdowns={result.method: td}, dt=pr.dt)
        plotting.plot_states({result.method: result.X}, pr.dt, out / "states.png", target_speed=None)
        plotting.plot_forces_torques(pr.dt, result.U, result.GRF, pr.constraints.torque_limit,
                                     pr.constraints.friction, out / "forces_torques.png", stance=pr.stance, foot=0,
                                     title=f"{result.method}: front foot GRF and joint torques")
        files.update(motion="motion.png", states="states.png", forces_torques="forces_torques.png")
        if result.solution is not None:
            plotting.plot_convergence({result.method: result.solution}, out / "convergence.png")
            files["convergence"] = "convergence.png"
    return files


# ----------------------------------------------------------------------------------------------- rollout
ROLLOUT_POLICIES = POLICIES
ROLLOUT_ENVS = tuple(ENV_TASKS)
"""The envs [`run_rollouts`][run_rollouts] runs in: every registered env (each task's env and its twins)."""


def load_policy(spec: str, env=None):
    """A trained policy from a ``hsddp-gym train`` run: ``"bc:DIR"``, ``"dagger:DIR"`` or ``"sb3:DIR"``
    (``"ppo:DIR"``, ``"sac:DIR"``); ``env``: the env it will act in (None: the env of the run's settings)."""
    kind, run = parse_policy_spec(spec, "spec")
    if run is None:
        raise ValueError(f"spec must name a trained policy ({', '.join(f'{k}:DIR' for k in LEARNED_POLICIES)}), "
                         f"got {spec!r}; use make_policy for {spec!r}")
    return make_policy(spec, env)


def run_rollouts(policy_name: str, episodes: int, seed: int, out: Path, video: bool = False,
                 env_kwargs: dict | None = None, push: list | None = None, quiet: bool = False,
                 max_episode_steps: int | None = None, mpc_options=None,
                 env_id: str = "hsddp_gym/Bounding-v0", record: dict | None = None) -> dict:
    """Run seeded episodes, write ``summary.json`` (and a GIF of the first episode) into ``out``.

    ``max_episode_steps`` overrides the env's registered time limit (None: keep it); ``mpc_options``: the MPC's
    [`hsddp_gym.planners.policies.mpc.MPCOptions`][hsddp_gym.planners.policies.mpc.options.MPCOptions] (None: the
    defaults; for ``policy_name`` "mpc" only). ``env_id``: any registered env ([`ROLLOUT_ENVS`][ROLLOUT_ENVS]: each
    task's env and its twins); the policy is built for it ([`make_policy`][hsddp_gym.rollout.policies.make_policy]: the
    task's expert, the terrain-aware MPC where the task's MPC is) and its episodes start from the policy's
    ``reset_options``. ``record``: further entries of ``summary.json`` (e.g. the CLI's ``transfer``)."""
    import gymnasium as gym
    from tqdm import tqdm

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.rollout.episodes import run_episode, summarize
    from hsddp_gym.util.extras import require
    from hsddp_gym.util.validation import check_output_dir

    parse_policy_spec(policy_name, "policy_name")
    out = check_output_dir(out, "out")
    if env_id not in ROLLOUT_ENVS:
        raise ValueError(f"env_id must be one of {ROLLOUT_ENVS}, got {env_id!r}")
    if mpc_options is not None and policy_name != "mpc":
        raise ValueError(f"mpc_options applies to the mpc policy only, got policy {policy_name!r}")
    require(required_modules(policy_name) + (["PIL"] if video else []), f"rollouts of {policy_name}"
            + (" with a video" if video else ""))
    out.mkdir(parents=True, exist_ok=True)
    (out / "episode0.gif").unlink(missing_ok=True)  # a GIF of an earlier run must not pass for this one's
    env_kwargs = dict(env_kwargs or {})
    limit = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
    env = gym.make(env_id, render_mode="rgb_array" if video else None, **env_kwargs, **limit)
    spec = policy_name if mpc_options is None else PolicySpec(policy_name, options=mpc_options,
                                                               env_id=task_of_env(env).env_id)
    policy = make_policy(spec, env, seed)
    options = None if push is None else {"push": push}  # {"delta_v": (3,), "time": t}
    results = []
    for i in tqdm(range(episodes), desc=f"{policy_name} episodes", disable=quiet):
        results.append(run_episode(env, policy, seed + i, options=options, render=video and i == 0))
    summary = summarize(results)
    summary.update(policy=policy_name, env_id=env_id, env_kwargs=env_kwargs, push=push, first_seed=seed,
                   max_episode_steps=env.spec.max_episode_steps)
    summary.update(record or {})
    if mpc_options is not None:
        import dataclasses

        summary["mpc_options"] = dataclasses.asdict(mpc_options)
    if video and results and results[0].frames:
        from hsddp_gym.viz.render import gif_timing, save_gif

        fps = env.metadata.get("render_fps", 30)
        frames = results[0].frames
        stride, durations = gif_timing(len(frames), fps)
        caption = (f"real time: every {stride}{'th' if stride > 3 else ('nd' if stride == 2 else 'rd')} of the "
                   f"{1000.0 / fps:g}-ms frames, {durations[0]} ms each" if stride > 1 else
                   f"real time, {1000.0 / fps:g} ms per frame")
        if not quiet:
            print(f"writing {out / 'episode0.gif'}: {len(durations)} frames, {sum(durations) / 1000:.2f} s, "
                  f"{caption} ...", flush=True)
        save_gif(frames, out / "episode0.gif", fps=fps)
        summary.update(video="episode0.gif", video_playback=caption, video_frames=len(durations))
    from hsddp_gym.util.io import write_npz

    write_npz(out / "episode0.npz", states=results[0].states, actions=results[0].actions,
              rewards=results[0].rewards)
    write_json(out / "summary.json", summary)
    env.close()
    return summary


def run_demo(out: Path, cycles: int = 5, episodes: int = 1, video: bool = True, quiet: bool = False,
             max_episode_steps: int | None = None) -> dict:
    """The main job (``hsddp-gym demo``): the HS-DDP plan of ``cycles`` bounding cycles beside its warm start (the
    heuristic controller's rollout up to five cycles, a repeated cycle of the solved five-cycle plan beyond;
    [`bounding_warm_start`][hsddp_gym.planners.tasks.bounding_warm_start]), figures and ``solution.npz`` in ``out``,
    then ``episodes`` seeded HS-DDP MPC episodes in ``hsddp_gym/Bounding-v0`` (``out/mpc``, a GIF of the first with
    ``video``). Returns the summary written to ``out/summary.json`` (``warm_start``, ``hsddp_plan``,
    ``mpc_in_env``, ``files``)."""
    from hsddp_gym.planners.optimizer.metrics import trajectory_summary
    from hsddp_gym.planners.tasks import plan_bounding
    from hsddp_gym.util.extras import require
    from hsddp_gym.util.validation import check_output_dir

    out = check_output_dir(out, "out")
    require(["matplotlib"] + (["PIL"] if video else []), "the demo (figures" + (" and the GIF)" if video else ")"))
    from hsddp_gym.viz import plotting

    print(f"[1/2] HS-DDP plan of {cycles} bounding cycles of 80/72/72/72 ms (impact-aware DDP + AL switching "
          "constraints + relaxed barriers) from its warm start ...")
    plan = plan_bounding("al-reb", cycles=cycles, verbose=not quiet)
    warm = plan.warm_start
    source = plan.summary["warm_start"]
    warm_summary = trajectory_summary(plan.problem, warm.X, warm.X_pre, warm.U, warm.GRF)
    warm_summary.update(source=source)
    robot = plan.problem.dynamics.robot
    plotting.plot_motion_strips(robot, {f"warm start ({source})": warm.X, "HS-DDP (al-reb)": plan.X},
                                out / "motion.png", dt=plan.problem.dt)
    plotting.plot_states({f"warm start ({source})": warm.X, "HS-DDP": plan.X}, plan.problem.dt, out / "states.png",
                         target_speed=1.0)
    plotting.plot_convergence({"al-reb": plan.solution}, out / "convergence.png")
    plan.solution.save(out / "solution.npz")
    print(f"[2/2] HS-DDP MPC in hsddp_gym/Bounding-v0: {episodes} seeded episode(s) ...")
    mpc = run_rollouts("mpc", episodes, 0, out / "mpc", video=video, quiet=quiet,
                       max_episode_steps=max_episode_steps)
    summary = {"warm_start": warm_summary, "hsddp_plan": plan.summary, "mpc_in_env": mpc,
               "files": ["motion.png", "states.png", "convergence.png", "solution.npz", "mpc/summary.json"]
               + (["mpc/episode0.gif"] if video else [])}
    write_json(out / "summary.json", summary)
    return summary
