"""The PPO / SAC baselines: [`train_sb3`][train_sb3] trains PPO or SAC with RL-Zoo hyperparameters
([`PRESETS`][hsddp_gym.learning.sb3.presets.PRESETS]): by default those of Hopper-v3
([`PPO_HOPPER_HYPERPARAMS`][hsddp_gym.learning.sb3.presets.PPO_HOPPER_HYPERPARAMS]; SAC's are its HalfCheetah-v3
defaults, [`SAC_HYPERPARAMS`][hsddp_gym.learning.sb3.presets.SAC_HYPERPARAMS]), a task that ends on a fall like this
one; ``preset="halfcheetah"`` gives the HalfCheetah-v3 set
([`PPO_HYPERPARAMS`][hsddp_gym.learning.sb3.presets.PPO_HYPERPARAMS]; ``user_needs.md`` §2.2). It writes into ``out``:

* ``model.zip``: the SB3 model (``PPO.load`` / ``SAC.load``, or
  [`load_trained_policy`][hsddp_gym.learning.sb3.runs.load_trained_policy], which reads only the weights, never
  unpickles);
* ``vecnormalize.pkl`` (SB3's format, PPO only) and ``vecnormalize.npz`` (the same running statistics as
  plain arrays);
* ``train.monitor.csv`` (SB3 ``Monitor``: return, length, time of every training episode),
  ``evaluations.npz`` (``EvalCallback``: deterministic evaluations during training);
* ``curve.csv`` (training episodes: ``env_step, episode_return, episode_length``), ``eval_curve.csv``
  (``env_step, mean_return, std_return``) and ``curve.png`` (needs matplotlib);
* ``summary.json``: algorithm, hyperparameters, seed, steps, wall time, final evaluation.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from hsddp_gym.learning.sb3.presets import (
    ALGOS,
    DEFAULT_PRESET,
    ENV_ID,
    ENV_IDS,
    hyperparameters,
    model_kwargs,
)
from hsddp_gym.learning.sb3.runs import BEST_MODEL, BEST_VECNORMALIZE, load_trained_policy, read_monitor, write_curves
from hsddp_gym.util.io import atomic_path, write_json, write_npz


@dataclasses.dataclass
class TrainResult:
    """What [`train_sb3`][train_sb3] wrote: ``out`` and the ``summary`` dict (also in ``out/summary.json``)."""

    out: Path
    summary: dict


def check_env_id(env_id, vector_env: bool = False, train_condition=None) -> str:
    """``env_id`` (None: `ENV_ID`) if [`train_sb3`][train_sb3] trains in it, else ``ValueError`` naming it; every env
    of [`ENV_IDS`][hsddp_gym.learning.sb3.presets.ENV_IDS] has a compiled vector env (``vector_env``); the robustness
    conditions (``train_condition``) apply to every one of them, those of pushes and env arguments also through the
    vector env of Bounding-v0 (the task envs' conditions are drawn in each task's window: single envs)."""
    if env_id is None:
        return ENV_ID
    if not isinstance(env_id, str) or env_id not in ENV_IDS:
        raise ValueError(f"env_id must be one of {ENV_IDS}, got {env_id!r}")
    if env_id != ENV_ID and train_condition is not None and vector_env:
        raise ValueError(f"env_id {env_id!r} takes a train_condition without vector_env only (its pushes are drawn "
                         f"in the task's window by the single env's wrapper), got {train_condition!r}")
    return env_id


def check_train_condition(name, env_kwargs: dict | None = None, vector_env: bool = False):
    """The [`Condition`][hsddp_gym.envs.perturbations.conditions.Condition] called ``name`` for training robots (None:
    none), with ``ValueError`` naming ``train_condition`` for an unknown name, for env arguments it sets that
    ``env_kwargs`` sets too, and (``vector_env``) for observation noise or latency, which the compiled vector env does
    not offer."""
    if name is None:
        return None
    from hsddp_gym.envs.perturbations.conditions import CONDITIONS

    if not isinstance(name, str) or name not in CONDITIONS:
        raise ValueError(f"train_condition must be one of {list(CONDITIONS)} or None, got {name!r}")
    condition = CONDITIONS[name]
    both = sorted(set(condition.env_kwargs) & set(env_kwargs or {}))
    if both:
        raise ValueError(f"train_condition {name!r} sets {both} itself; do not give them in env_kwargs too")
    if vector_env and not condition.acts_through_env_arguments:
        raise ValueError(f"train_condition {name!r} has observation noise or latency, which the compiled vector "
                         "env does not offer: train without vector_env (--vector-env) for it")
    return condition


def _make_venv(n_envs: int, seed: int, env_kwargs: dict, max_episode_steps: int | None, monitor_path: Path | None,
               vector_env: bool = False, condition=None, env_id: str = ENV_ID, residual_scale: float | None = None):
    """The training (or evaluation) envs of ``env_id``; ``condition`` (a checked
    [`Condition`][hsddp_gym.envs.perturbations.conditions.Condition] or None) perturbs every one of them;
    ``residual_scale``: each is a [`ResidualEnv`][hsddp_gym.learning.residual.ResidualEnv] on the task's expert."""
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    import hsddp_gym  # noqa: F401  (registers the env)

    if vector_env:  # the compiled vector env: one call steps all robots' physics; one monitor file for all
        from hsddp_gym.learning.vector_sb3 import make_sb3_vec_env

        steps = gym.spec(env_id).max_episode_steps if max_episode_steps is None else int(max_episode_steps)
        extra = {} if condition is None else dict(condition.env_kwargs)
        if condition is not None and condition.push is not None:
            extra["push"] = dict(condition.push)
        return VecMonitor(make_sb3_vec_env(n_envs, seed=seed, max_episode_steps=steps, env_id=env_id, **env_kwargs,
                                           **extra),
                          filename=None if monitor_path is None else str(monitor_path))

    def make(i):
        def _init():
            kw = dict(env_kwargs)
            if max_episode_steps is not None:
                kw["max_episode_steps"] = int(max_episode_steps)
            env = gym.make(env_id, **kw) if condition is None else condition.make(env_id=env_id, **kw)
            if residual_scale is not None:
                from hsddp_gym.learning.residual import ResidualEnv

                env = ResidualEnv(env, residual_scale)
            filename = None
            if monitor_path is not None:
                filename = str(monitor_path) if n_envs == 1 else str(monitor_path).replace(".monitor.csv",
                                                                                          f"_{i}.monitor.csv")
            return Monitor(env, filename=filename)
        return _init

    venv = DummyVecEnv([make(i) for i in range(n_envs)])
    venv.seed(seed)
    return venv


def save_vecnormalize_npz(venv, path) -> Path:
    """The running observation/return statistics of a ``VecNormalize`` as plain arrays (no pickle)."""
    return write_npz(path, obs_mean=venv.obs_rms.mean, obs_var=venv.obs_rms.var, obs_count=np.array(venv.obs_rms.count),
                     ret_mean=np.array(venv.ret_rms.mean), ret_var=np.array(venv.ret_rms.var),
                     clip_obs=np.array(venv.clip_obs), clip_reward=np.array(venv.clip_reward),
                     epsilon=np.array(venv.epsilon), gamma=np.array(venv.gamma),
                     norm_obs=np.array(venv.norm_obs), norm_reward=np.array(venv.norm_reward))


def train_sb3(algo: str, steps: int, seed: int, out, env_kwargs: dict | None = None,
              max_episode_steps: int | None = None, overrides: dict | None = None, eval_freq: int | None = None,
              eval_episodes: int = 5, final_eval_episodes: int = 10, threads: int = 1, progress: bool = False,
              verbose: int = 0, time_limit: float | None = None, preset: str = DEFAULT_PRESET,
              vector_env: bool = False, train_condition: str | None = None, residual_scale: float | None = None,
              env_id: str | None = None) -> TrainResult:
    """Train PPO or SAC on ``Bounding-v0`` (or ``env_id``) and write the files of the module docstring into ``out``.

    Args:
        algo: ``"ppo"`` or ``"sac"``. steps: env steps. seed: seeds the model, the env and the evaluation env.
        env_kwargs: ``gym.make`` keyword arguments. max_episode_steps: time-limit override (None: 1000).
        overrides: hyperparameters replacing the documented ones (e.g. ``{"learning_starts": 100}``,
            ``{"n_envs": 4}``: that many envs in a ``DummyVecEnv``, stepped together).
        vector_env: step the ``n_envs`` training robots with the env's compiled vector env
            ([`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv] for Bounding-v0,
            [`TaskVectorEnv`][hsddp_gym.envs.task_vector.TaskVectorEnv] for the tasks, through
            [`hsddp_gym.learning.vector_sb3`][hsddp_gym.learning.vector_sb3], one ``train.monitor.csv`` for all) instead
            of a ``DummyVecEnv`` of single envs. Same transitions (``tests/test_vector_env.py``,
            ``tests/test_task_vector_env.py``).
        preset: the RL-Zoo hyperparameter set ([`PRESETS`][hsddp_gym.learning.sb3.presets.PRESETS]; default
            ``"hopper"``, a terminating task).
        eval_freq: env steps between deterministic evaluations of ``eval_episodes`` episodes (None:
            ``max(steps // 10, 1000)``; 0: none).
        final_eval_episodes: after training, evaluate the saved policy with the comparison protocol
            ([`evaluate_policy_episodes`][hsddp_gym.learning.reporting.evaluate_policy_episodes]: seeds 0, 1, ...,
            deterministic) into ``summary["eval"]`` (0: skip).
        threads: ``torch.set_num_threads`` (1 by default: the machines are shared).
        train_condition: a condition of the robustness registry
            ([`hsddp_gym.envs.perturbations.CONDITIONS`][hsddp_gym.envs.perturbations.conditions.CONDITIONS], e.g.
            ``"push_x3"``) under which every training robot runs (domain randomization: pushes, env arguments; with
            ``vector_env`` observation noise and latency are refused); the evaluations, training-time and final, stay on
            the unperturbed task. None: none.
        time_limit: wall-clock budget of the training [s] (None: none). Training stops at the first env step
            after it, so ``summary["steps"]`` is the budget that fit (``"stopped_by_time_limit"`` says so).
            Such a run is not reproducible step for step; rerun it with ``steps = summary["steps"]`` for that.
        env_id: the env to train and evaluate in, one of [`ENV_IDS`][ENV_IDS] (None: Bounding-v0); the others take a
            ``train_condition`` without ``vector_env`` only.
        residual_scale: learn a residual on the task's plan-tracking expert
            ([`hsddp_gym.learning.residual`][hsddp_gym.learning.residual]: the env gets ``clip(a_expert + scale · r,
            -1, 1)``, the learner sees the expert's action) with this scale in (0, 2]; None: the learner acts alone.
            Not with ``vector_env``. Stored in ``summary.json``, so
            [`load_trained_policy`][load_trained_policy] rebuilds the run's env.
    """
    from hsddp_gym.util.extras import require

    require(["stable_baselines3", "torch"], f"train_sb3 ({algo})")
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback
    from stable_baselines3.common.vec_env import VecNormalize

    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    if int(steps) < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    if time_limit is not None and not float(time_limit) > 0:
        raise ValueError(f"time_limit must be > 0 seconds or None, got {time_limit!r}")
    env_kwargs = dict(env_kwargs or {})
    env_id = check_env_id(env_id, bool(vector_env), train_condition)
    if residual_scale is not None:
        from hsddp_gym.learning.residual import check_residual_scale

        residual_scale = check_residual_scale(residual_scale)
        if vector_env:
            raise ValueError("residual_scale is not offered with vector_env (the expert acts per robot): train the "
                             "residual in single envs")
    condition = check_train_condition(train_condition, env_kwargs, bool(vector_env))
    torch.set_num_threads(int(threads))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    hp = hyperparameters(algo, overrides, preset)
    if not isinstance(vector_env, (bool, np.bool_)):
        raise TypeError(f"vector_env must be a bool, got {type(vector_env).__name__}")
    venv = _make_venv(hp["n_envs"], seed, env_kwargs, max_episode_steps, out / "train.monitor.csv",
                      vector_env=bool(vector_env), condition=condition, env_id=env_id, residual_scale=residual_scale)
    # the evaluation env is wrapped as the training env (SB3 copies VecNormalize's statistics wrapper by wrapper)
    eval_venv = _make_venv(1, seed + 10_000, env_kwargs, max_episode_steps, None, vector_env=bool(vector_env),
                           env_id=env_id, residual_scale=residual_scale)
    if hp["normalize"]:
        gamma = hp.get("gamma", 0.99)
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=gamma)
        eval_venv = VecNormalize(eval_venv, norm_obs=True, norm_reward=False, gamma=gamma, training=False)
    cls = PPO if algo == "ppo" else SAC
    model = cls("MlpPolicy", venv, seed=seed, device="cpu", verbose=verbose, **model_kwargs(hp))
    if residual_scale is not None:
        from hsddp_gym.learning.residual import zero_mean_action

        zero_mean_action(model)  # the learner starts as the expert
    callbacks = []
    eval_freq = max(int(steps) // 10, 1000) if eval_freq is None else int(eval_freq)
    best = None
    if eval_freq > 0:
        best = _save_best(out, venv if hp["normalize"] else None)
        # EvalCallback counts calls, one per step of all n_envs robots: eval_freq env steps are that many / n_envs
        callbacks.append(EvalCallback(eval_venv, n_eval_episodes=eval_episodes,
                                      eval_freq=max(eval_freq // int(hp["n_envs"]), 1),
                                      log_path=str(out), deterministic=True, verbose=0, callback_on_new_best=best))
    t0 = time.perf_counter()
    timer = None
    if time_limit is not None:
        timer = _wall_clock_limit(float(time_limit), t0)
        callbacks.append(timer)
    model.learn(total_timesteps=int(steps), callback=CallbackList(callbacks) if callbacks else None,
                progress_bar=progress)
    wall = time.perf_counter() - t0
    with atomic_path(out / "model.zip", suffix=".zip") as tmp:
        model.save(tmp)
    files = ["model.zip", "train.monitor.csv"]
    if hp["normalize"]:
        venv.save(str(out / "vecnormalize.pkl"))
        save_vecnormalize_npz(venv, out / "vecnormalize.npz")
        files += ["vecnormalize.pkl", "vecnormalize.npz"]
    if (out / "evaluations.npz").exists():
        files.append("evaluations.npz")
    if best is not None and best.record is not None:
        files += [BEST_MODEL] + ([BEST_VECNORMALIZE] if hp["normalize"] else [])
    files += write_curves(out, algo, env_id=env_id)
    summary = {
        "algo": algo, "env_id": env_id, "env_kwargs": env_kwargs, "max_episode_steps": max_episode_steps,
        "seed": int(seed), "steps": int(model.num_timesteps), "requested_steps": int(steps),
        "preset": preset, "hyperparameters": hp, "vector_env": bool(vector_env),
        "residual": None if residual_scale is None else {"base": "expert", "scale": residual_scale},
        "train_condition": None if condition is None else condition.as_dict(), "wall_time_s": wall,
        "threads": int(threads), "eval_freq": eval_freq,
        "time_limit_s": time_limit, "stopped_by_time_limit": bool(timer is not None and timer.stopped),
        "eval_episodes": eval_episodes, "files": files,
        "training_episodes": _count_monitor_episodes(out / "train.monitor.csv"),
        "best_checkpoint": best.record if best is not None else None,
    }
    venv.close()
    eval_venv.close()
    write_json(out / "summary.json", summary)
    if final_eval_episodes > 0:
        from hsddp_gym.learning.reporting import eval_brief, evaluate_policy_episodes

        summary["eval"] = eval_brief(evaluate_policy_episodes(load_trained_policy(out), final_eval_episodes, 0,
                                                               env_kwargs, max_episode_steps, env_id=env_id))
        # the policy as it acted in training: draws of its own distribution (seeded; a Gaussian PPO policy's mean
        # can fall where its draws bound, README "RL baselines")
        summary["eval_stochastic"] = eval_brief(evaluate_policy_episodes(
            load_trained_policy(out, deterministic=False), final_eval_episodes, 0, env_kwargs, max_episode_steps,
            env_id=env_id))
        if summary["best_checkpoint"] is not None:
            # the checkpoint chosen by the training-time evaluations (their own seeds), under the same protocol
            summary["eval_best"] = eval_brief(evaluate_policy_episodes(
                load_trained_policy(out, checkpoint="best"), final_eval_episodes, 0, env_kwargs, max_episode_steps,
                env_id=env_id))
        write_json(out / "summary.json", summary)
    return TrainResult(out, summary)


def _save_best(out: Path, venv):
    """An SB3 callback for ``EvalCallback(callback_on_new_best=...)``: writes the model ([`BEST_MODEL`][BEST_MODEL])
    and, with ``VecNormalize`` (``venv``), its observation statistics of that moment
    ([`BEST_VECNORMALIZE`][BEST_VECNORMALIZE], which go on changing after), and keeps ``record`` = ``{"env_step",
    "mean_return"}`` of the evaluation."""
    from stable_baselines3.common.callbacks import BaseCallback

    class SaveBest(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.record = None

        def _on_step(self) -> bool:
            with atomic_path(out / BEST_MODEL, suffix=".zip") as tmp:
                self.model.save(tmp)
            if venv is not None:
                save_vecnormalize_npz(venv, out / BEST_VECNORMALIZE)
            self.record = {"env_step": int(self.model.num_timesteps),
                           "mean_return": float(self.parent.best_mean_reward)}
            return True

    return SaveBest()


def _wall_clock_limit(seconds: float, start: float):
    """An SB3 callback that stops ``learn`` once ``seconds`` have passed since ``start`` (``perf_counter``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class WallClockLimit(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.stopped = False

        def _on_step(self) -> bool:
            if time.perf_counter() - start >= seconds:
                self.stopped = True
            return not self.stopped

    return WallClockLimit()


def _count_monitor_episodes(path: Path) -> int:
    return int(len(read_monitor(path)))
