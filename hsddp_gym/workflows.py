"""The jobs behind the CLI commands, callable from Python: planning outputs, seeded rollouts of a named policy."""

from __future__ import annotations

from pathlib import Path

from hsddp_gym.util.io import write_json


# ----------------------------------------------------------------------------------------------- plan
def write_plan_outputs(result, out: Path, plots: bool) -> dict:
    """Write a :class:`~hsddp_gym.planners.tasks.PlanResult` into ``out``: ``solution.npz`` (or
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
ROLLOUT_POLICIES = ("mpc", "expert", "heuristic", "random")
ROLLOUT_ENVS = ("hsddp_gym/Bounding-v0", "hsddp_gym/BoundingMuJoCo-v0")
LEARNED_POLICIES = ("bc", "dagger", "sb3", "ppo", "sac")
"""Prefixes of learned policies, ``KIND:DIR`` with ``DIR`` the ``--out`` of ``hsddp-gym train``: ``bc`` and
``dagger`` load its ``policy.npz`` (an :class:`~hsddp_gym.learning.bc.MLPPolicy`, NumPy inference, no torch),
``sb3`` (or ``ppo`` / ``sac``) its ``model.zip`` + ``vecnormalize.npz`` (needs stable-baselines3)."""
_POLICY_ALLOWED = ("mpc, expert, heuristic, random, or bc:DIR, dagger:DIR, sb3:DIR (also ppo:DIR, sac:DIR) with "
                   "DIR the --out of `hsddp-gym train`")
_RUN_FILES = {"bc": "policy.npz", "dagger": "policy.npz", "ppo": "model.zip", "sac": "model.zip"}
_KIND_ALGOS = {"bc": ("bc", "dagger"), "dagger": ("bc", "dagger"), "sb3": ("ppo", "sac"), "ppo": ("ppo",),
               "sac": ("sac",)}


def parse_policy_spec(spec: str, name: str = "policy") -> tuple[str, Path | None]:
    """``(kind, run_dir)`` of a policy name: one of :data:`ROLLOUT_POLICIES` (``run_dir`` None) or
    ``KIND:DIR`` with ``KIND`` in :data:`LEARNED_POLICIES` and ``DIR`` a finished ``hsddp-gym train`` run of
    a matching algorithm (``sb3`` matches ppo and sac, ``bc`` and ``dagger`` both MLP runs).

    Raises:
        UsageError (a ValueError naming ``name``): an unknown name, a missing or unfinished run directory,
        or a run of another algorithm.
    """
    import json

    from hsddp_gym.util.validation import UsageError

    if not isinstance(spec, str):
        raise UsageError(name, f"{spec!r} is not a policy name", _POLICY_ALLOWED)
    if spec in ROLLOUT_POLICIES:
        return spec, None
    kind, sep, path = spec.partition(":")
    if not sep or kind not in LEARNED_POLICIES or not path:
        raise UsageError(name, f"unknown policy {spec!r}", _POLICY_ALLOWED)
    run = Path(path)
    summary_file = run / "summary.json"
    if not summary_file.is_file():
        problem = "does not exist" if not run.exists() else "has no summary.json (not a finished training run)"
        raise UsageError(name, f"{kind}:{path}: {str(run)!r} {problem}", _POLICY_ALLOWED)
    try:
        algo = json.loads(summary_file.read_text()).get("algo")
    except (ValueError, AttributeError):
        algo = None
    if algo not in _KIND_ALGOS[kind]:
        raise UsageError(name, f"{kind}:{path}: the run in {str(run)!r} is a {algo!r} run",
                         f"{kind}: runs of {' or '.join(_KIND_ALGOS[kind])}")
    if not (run / _RUN_FILES[algo]).is_file():
        raise UsageError(name, f"{kind}:{path}: {str(run / _RUN_FILES[algo])!r} is missing",
                         f"a finished `hsddp-gym train --algo {algo}` run directory")
    return kind, run


def required_modules(policy: str) -> list[str]:
    """The optional packages a policy name needs (see :func:`hsddp_gym.util.extras.require`)."""
    kind = policy.partition(":")[0]
    return ["stable_baselines3", "torch"] if kind in ("sb3", "ppo", "sac") else []


def load_policy(spec: str, env=None):
    """A trained policy from a ``hsddp-gym train`` run: ``"bc:DIR"``, ``"dagger:DIR"`` or ``"sb3:DIR"``
    (``"ppo:DIR"``, ``"sac:DIR"``); ``env``: the env it will act in (None: the env of the run's settings)."""
    kind, run = parse_policy_spec(spec, "spec")
    if run is None:
        raise ValueError(f"spec must name a trained policy ({', '.join(f'{k}:DIR' for k in LEARNED_POLICIES)}), "
                         f"got {spec!r}; use make_policy for {spec!r}")
    return make_policy(spec, env)[0]


def is_pronking_env(env) -> bool:
    """Whether ``env`` (wrapped or not) is an env of the pronking task (``hsddp_gym/Pronking-v0`` or its MuJoCo
    twin)."""
    from hsddp_gym.envs.pronking import PronkingTask

    return isinstance(getattr(env, "unwrapped", env), PronkingTask)


def pronking_expert(env, cycles: int = 4):
    """The pronking expert for ``env``: :func:`hsddp_gym.planners.policies.experts.pronking_expert` tracking
    ``plan_pronk(cycles, target_speed)`` (:mod:`hsddp_gym.planners.motions`, solved once per speed and process,
    about 0.2 s) periodically; the env starts at the plan's start, so no reset options are needed."""
    from hsddp_gym.planners.policies import experts
    from hsddp_gym.planners.policies.base import EnvInterface

    speed = float(getattr(env, "unwrapped", env).target_speed)
    return experts.pronking_expert(EnvInterface.from_env(env), pronk_plan(speed, cycles))


_PRONK_PLANS: dict = {}


def pronk_plan(speed: float = 1.0, cycles: int = 4):
    """The HS-DDP pronk plan (a :class:`~hsddp_gym.planners.optimizer.solution.Solution`) at ``speed`` [m/s],
    cached per ``(speed, cycles)``."""
    from hsddp_gym.planners.motions import plan_pronk

    key = (float(speed), int(cycles))
    if key not in _PRONK_PLANS:
        _PRONK_PLANS[key] = plan_pronk(int(cycles), float(speed)).solution
    return _PRONK_PLANS[key]


def is_backflip_env(env) -> bool:
    """Whether ``env`` (wrapped or not) is an env of the backflip task (``hsddp_gym/Backflip-v0`` or its MuJoCo
    twin)."""
    from hsddp_gym.envs.backflip import BackflipTask

    return isinstance(getattr(env, "unwrapped", env), BackflipTask)


def backflip_expert(env):
    """The backflip expert for ``env``: :func:`hsddp_gym.planners.policies.experts.backflip_expert` tracking
    :func:`backflip_plan` for the env's control period (solved once per process, about 3 s); the env starts at the
    plan's start, so no reset options are needed."""
    from hsddp_gym.planners.policies import experts
    from hsddp_gym.planners.policies.base import EnvInterface

    return experts.backflip_expert(EnvInterface.from_env(env), backflip_plan(backflip_hold(env)))


def backflip_hold(env) -> int:
    """Plan knots (1 ms) per control period of ``env``: the ``hold`` of :func:`backflip_plan`."""
    return max(1, int(float(getattr(env, "unwrapped", env).dt) / 1e-3 + 0.5))


_BACKFLIP_PLANS: dict = {}


def backflip_plan(hold: int = 5):
    """The HS-DDP backflip plan for a control held ``hold`` plan knots
    (:func:`hsddp_gym.planners.motions.plan_backflip_held`), cached per ``hold``."""
    from hsddp_gym.planners.motions import plan_backflip_held

    key = int(hold)
    if key not in _BACKFLIP_PLANS:
        _BACKFLIP_PLANS[key] = plan_backflip_held(key)
    return _BACKFLIP_PLANS[key]


def is_jump_env(env) -> bool:
    """Whether ``env`` (wrapped or not) is an env of a jump task (``hsddp_gym/GapJump-v0``, ``hsddp_gym/BoxJump-v0``
    or their MuJoCo twins)."""
    from hsddp_gym.envs.jumps import JumpTask

    return isinstance(getattr(env, "unwrapped", env), JumpTask)


def jump_expert(env):
    """The jump expert for ``env``: :func:`hsddp_gym.planners.policies.experts.jump_expert` tracking
    :func:`jump_plan` of the env's task for its control period (solved once per process, about 1 s); the env starts
    at the plan's start, so no reset options are needed."""
    from hsddp_gym.planners.policies import experts
    from hsddp_gym.planners.policies.base import EnvInterface

    plan = jump_plan(getattr(env, "unwrapped", env).task, backflip_hold(env))
    return experts.jump_expert(EnvInterface.from_env(env), plan)


_JUMP_PLANS: dict = {}


def jump_plan(motion: str, hold: int = 5):
    """The HS-DDP jump plan of ``motion`` (``"gap_jump"`` or ``"box_jump"``) for a control held ``hold`` plan knots
    (:func:`hsddp_gym.planners.motions.plan_jump_held`), cached per ``(motion, hold)``."""
    from hsddp_gym.planners.motions import plan_jump_held

    key = (str(motion), int(hold))
    if key not in _JUMP_PLANS:
        _JUMP_PLANS[key] = plan_jump_held(key[0], key[1])
    return _JUMP_PLANS[key]


def is_transition_env(env) -> bool:
    """Whether ``env`` (wrapped or not) is an env of a gait-transition task (``hsddp_gym/StandToBound-v0``,
    ``hsddp_gym/BoundPronkBound-v0``, ``hsddp_gym/BoundToStop-v0`` or their MuJoCo twins)."""
    from hsddp_gym.envs.transitions import TransitionTask

    return isinstance(getattr(env, "unwrapped", env), TransitionTask)


def transition_expert(env):
    """The transition expert for ``env``: :func:`hsddp_gym.planners.policies.experts.transition_expert`
    tracking :func:`transition_plan` of the env's task for its control period (solved once per process, about 1 s);
    the env starts at the plan's start, so no reset options are needed."""
    from hsddp_gym.planners.policies import experts
    from hsddp_gym.planners.policies.base import EnvInterface

    task = getattr(env, "unwrapped", env).task
    return experts.transition_expert(EnvInterface.from_env(env), transition_plan(task, backflip_hold(env)), task)


_TRANSITION_PLANS: dict = {}


def transition_plan(motion: str, hold: int = 5):
    """The HS-DDP plan of the gait transition ``motion`` (``hsddp_gym.planners.motions.TRANSITIONS``) for a control
    held ``hold`` plan knots (:func:`hsddp_gym.planners.motions.plan_transition_held`, with the expert's cycles
    ``hsddp_gym.planners.policies.experts.TRANSITION_PLAN_CYCLES``), cached per ``(motion, hold)``."""
    from hsddp_gym.planners.motions import plan_transition_held
    from hsddp_gym.planners.policies.experts import TRANSITION_PLAN_CYCLES

    key = (str(motion), int(hold))
    if key not in _TRANSITION_PLANS:
        _TRANSITION_PLANS[key] = plan_transition_held(key[0], key[1], cycles=TRANSITION_PLAN_CYCLES[key[0]])
    return _TRANSITION_PLANS[key]


def is_terrain_env(env) -> bool:
    """Whether ``env`` is ``hsddp_gym/Terrain-v0`` (by its spec), whose ``mpc`` is the terrain-aware MPC
    (``MPCPolicy(..., terrain=env_terrain(env))``, as in :class:`hsddp_gym.datasets.recording.PolicySpec`)."""
    from hsddp_gym.datasets.recording import TERRAIN_ENV_ID

    spec = getattr(env, "spec", None)
    return getattr(spec, "id", None) == TERRAIN_ENV_ID


def task_expert(env):
    """The plan-tracking expert of ``env``'s task (pronking, backflip, a jump), or None for Bounding-v0's."""
    if is_pronking_env(env):
        return pronking_expert(env)
    if is_backflip_env(env):
        return backflip_expert(env)
    if is_jump_env(env):
        return jump_expert(env)
    if is_transition_env(env):
        return transition_expert(env)
    return None


def make_policy(name: str, env, seed: int = 0, mpc_options=None):
    """A policy for ``env`` by name (``mpc``, ``expert``, ``heuristic``, ``random``, or a trained policy
    ``bc:DIR`` / ``dagger:DIR`` / ``sb3:DIR``, see :func:`parse_policy_spec`) and the reset options it needs
    (the expert starts from its plan's initial state; in the pronking task it is :func:`pronking_expert`, in the
    backflip task :func:`backflip_expert`, in the jump tasks :func:`jump_expert`; in ``hsddp_gym/Terrain-v0``
    ``mpc`` is the terrain-aware MPC, given each episode's terrain, as in its datasets, :func:`is_terrain_env`)."""
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.planners.policies.experts import bounding_expert
    from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
    from hsddp_gym.planners.policies.random_policy import RandomPolicy

    kind, run = parse_policy_spec(name, "policy")
    if run is not None:
        if kind in ("bc", "dagger"):
            from hsddp_gym.learning.ensemble import load_mlp_learner

            interface = EnvInterface.from_env(env) if env is not None else EnvInterface()
            return load_mlp_learner(run, interface), None  # behind the MPC's perception if trained behind it
        from hsddp_gym.util.extras import require

        require(required_modules(name), f"the policy {name}")
        from hsddp_gym.learning.sb3 import load_trained_policy

        return load_trained_policy(run, env), None
    if name == "mpc":
        from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy, env_terrain

        terrain = env_terrain(env) if is_terrain_env(env) else None
        return MPCPolicy.from_env(env, options=mpc_options or MPCOptions(), terrain=terrain), None
    if name == "expert":
        expert = task_expert(env)
        if expert is not None:
            return expert, None
        from hsddp_gym.planners.tasks import plan_bounding

        sol = plan_bounding("al-reb", cycles=5).solution
        return bounding_expert(EnvInterface.from_env(env), sol), {"state": sol.X[0]}
    if name == "heuristic":
        return HeuristicPolicy.from_env(env), None
    return RandomPolicy.from_env(env, seed=seed), None


def run_rollouts(policy_name: str, episodes: int, seed: int, out: Path, video: bool = False,
                 env_kwargs: dict | None = None, push: list | None = None, quiet: bool = False,
                 max_episode_steps: int | None = None, mpc_options=None,
                 env_id: str = "hsddp_gym/Bounding-v0") -> dict:
    """Run seeded episodes, write ``summary.json`` (and a GIF of the first episode) into ``out``.

    ``max_episode_steps`` overrides the env's 1000-step time limit (None: keep it); ``mpc_options``: the MPC's
    :class:`hsddp_gym.planners.policies.mpc.MPCOptions` (None: the defaults; for ``policy_name`` "mpc" only).
    ``env_id``: ``hsddp_gym/Bounding-v0`` (the exact-LCP env) or ``hsddp_gym/BoundingMuJoCo-v0`` (its MuJoCo twin)."""
    import gymnasium as gym
    from tqdm import tqdm

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.planners.policies.evaluation import run_episode, summarize
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
    policy, options = make_policy(policy_name, env, seed, mpc_options=mpc_options)
    if push is not None:
        options = dict(options or {})
        options["push"] = push  # {"delta_v": (3,), "time": t}
    results = []
    for i in tqdm(range(episodes), desc=f"{policy_name} episodes", disable=quiet):
        results.append(run_episode(env, policy, seed + i, options=options, render=video and i == 0))
    summary = summarize(results)
    summary.update(policy=policy_name, env_id=env_id, env_kwargs=env_kwargs, push=push, first_seed=seed,
                   max_episode_steps=env.spec.max_episode_steps)
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
    :func:`~hsddp_gym.planners.tasks.bounding_warm_start`), figures and ``solution.npz`` in ``out``, then
    ``episodes`` seeded HS-DDP MPC episodes in ``hsddp_gym/Bounding-v0`` (``out/mpc``, a GIF of the first with
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
