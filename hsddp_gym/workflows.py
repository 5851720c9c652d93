"""The jobs behind the CLI commands, callable from Python: planning outputs, seeded rollouts of a named policy."""

from __future__ import annotations

from pathlib import Path

from hsddp_gym.util.io import write_json


# ----------------------------------------------------------------------------------------------- plan
def write_plan_outputs(result, out: Path, plots: bool) -> dict:
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
                                    touchdowns={result.method: td})
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
ROLLOUT_POLICIES = ("mpc", "expert", "heuristic", "random")
ROLLOUT_ENVS = ("hsddp_gym/Bounding-v0", "hsddp_gym/BoundingMuJoCo-v0")


def make_policy(name: str, env, seed: int = 0, mpc_options=None):
    """A policy for ``env`` by name (``mpc``, ``expert``, ``heuristic`` or ``random``) and the reset
    options it needs (the expert starts from its plan's initial state)."""
    from hsddp_gym.planners.policies.expert import PlanTrackingExpert
    from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
    from hsddp_gym.planners.policies.random_policy import RandomPolicy

    if name == "mpc":
        from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy

        return MPCPolicy.from_env(env, options=mpc_options or MPCOptions()), None
    if name == "expert":
        from hsddp_gym.planners.tasks import plan_bounding

        sol = plan_bounding("al-reb", cycles=5).solution
        return PlanTrackingExpert.from_env(env, solution=sol), {"state": sol.X[0]}
    if name == "heuristic":
        return HeuristicPolicy.from_env(env), None
    if name == "random":
        return RandomPolicy.from_env(env, seed=seed), None
    raise ValueError(f"policy must be one of {ROLLOUT_POLICIES}, got {name!r}")


def run_rollouts(policy_name: str, episodes: int, seed: int, out: Path, video: bool = False,
                 env_kwargs: dict | None = None, push: list | None = None, quiet: bool = False,
                 max_episode_steps: int | None = None, mpc_recovery: bool = False, mpc_options=None,
                 env_id: str = "hsddp_gym/Bounding-v0") -> dict:
    """Run seeded episodes, write ``summary.json`` (and a GIF of the first episode) into ``out``.

    ``max_episode_steps`` overrides the env's 1000-step time limit (None: keep it); ``mpc_recovery`` runs the
    MPC with its push-robust settings (:meth:`hsddp_gym.planners.policies.mpc.MPCOptions.push_recovery`),
    ``mpc_options`` with any
    :class:`hsddp_gym.planners.policies.mpc.MPCOptions` (not both). ``env_id``: ``hsddp_gym/Bounding-v0`` (the
    exact-LCP env) or ``hsddp_gym/BoundingMuJoCo-v0`` (its MuJoCo twin)."""
    import gymnasium as gym
    from tqdm import tqdm

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.planners.policies.evaluation import run_episode, summarize

    out.mkdir(parents=True, exist_ok=True)
    env_kwargs = dict(env_kwargs or {})
    limit = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
    if env_id not in ROLLOUT_ENVS:
        raise ValueError(f"env_id must be one of {ROLLOUT_ENVS}, got {env_id!r}")
    env = gym.make(env_id, render_mode="rgb_array" if video else None, **env_kwargs, **limit)
    if (mpc_recovery or mpc_options is not None) and policy_name != "mpc":
        raise ValueError(f"mpc_recovery and mpc_options apply to the mpc policy only, got policy {policy_name!r}")
    if mpc_recovery and mpc_options is not None:
        raise ValueError("give mpc_recovery or mpc_options, not both")
    if mpc_recovery:
        from hsddp_gym.planners.policies.mpc import MPCOptions

        mpc_options = MPCOptions.push_recovery()
    policy, options = make_policy(policy_name, env, seed, mpc_options=mpc_options)
    if push is not None:
        options = dict(options or {})
        options["push"] = push  # {"delta_v": (3,), "time": t}
    results = []
    for i in tqdm(range(episodes), desc=f"{policy_name} episodes", disable=quiet):
        results.append(run_episode(env, policy, seed + i, options=options, render=video and i == 0))
    summary = summarize(results)
    summary.update(policy=policy_name, env_id=env_id, env_kwargs=env_kwargs, push=push, first_seed=seed,
                   max_episode_steps=env.spec.max_episode_steps, mpc_recovery=bool(mpc_recovery))
    if mpc_options is not None:
        import dataclasses

        summary["mpc_options"] = dataclasses.asdict(mpc_options)
    if mpc_options is not None or mpc_recovery:
        summary.update(recoveries=sum((r.policy_stats or {}).get("recoveries", 0) for r in results),
                       fallback_steps=sum((r.policy_stats or {}).get("fallback_steps", 0) for r in results))
    if video and results and results[0].frames:
        from hsddp_gym.viz.render import save_gif

        save_gif(results[0].frames, out / "episode0.gif", fps=env.metadata.get("render_fps", 30))
        summary["video"] = "episode0.gif"
    from hsddp_gym.util.io import write_npz

    write_npz(out / "episode0.npz", states=results[0].states, actions=results[0].actions,
              rewards=results[0].rewards)
    write_json(out / "summary.json", summary)
    env.close()
    return summary


def run_demo(out: Path, cycles: int = 5, episodes: int = 1, video: bool = True, quiet: bool = False,
             max_episode_steps: int | None = None) -> dict:
    """The main job (``hsddp-gym demo``): the heuristic warm start and the HS-DDP plan of ``cycles`` bounding
    cycles (figures and ``solution.npz`` in ``out``), then ``episodes`` seeded HS-DDP MPC episodes in
    ``hsddp_gym/Bounding-v0`` (``out/mpc``, a GIF of the first with ``video``). Returns the summary written to
    ``out/summary.json``."""
    from hsddp_gym.planners.tasks import plan_bounding
    from hsddp_gym.viz import plotting

    print(f"[1/3] heuristic bounding controller (the warm start), {cycles} cycles of 80/72/72/72 ms ...")
    heur = plan_bounding("heuristic", cycles=cycles)
    print("[2/3] HS-DDP plan (impact-aware DDP + AL switching constraints + relaxed barriers) ...")
    plan = plan_bounding("al-reb", cycles=cycles, verbose=not quiet)
    robot = plan.problem.dynamics.robot
    plotting.plot_motion_strips(robot, {"heuristic warm start": heur.X, "HS-DDP (al-reb)": plan.X},
                                out / "motion.png")
    plotting.plot_states({"heuristic": heur.X, "HS-DDP": plan.X}, plan.problem.dt, out / "states.png",
                         target_speed=1.0)
    plotting.plot_convergence({"al-reb": plan.solution}, out / "convergence.png")
    plan.solution.save(out / "solution.npz")
    print(f"[3/3] HS-DDP MPC in hsddp_gym/Bounding-v0: {episodes} seeded episode(s) ...")
    mpc = run_rollouts("mpc", episodes, 0, out / "mpc", video=video, quiet=quiet,
                       max_episode_steps=max_episode_steps)
    summary = {"heuristic_plan": heur.summary, "hsddp_plan": plan.summary, "mpc_in_env": mpc,
               "files": ["motion.png", "states.png", "convergence.png", "solution.npz", "mpc/summary.json"]
               + (["mpc/episode0.gif"] if video else [])}
    write_json(out / "summary.json", summary)
    return summary
