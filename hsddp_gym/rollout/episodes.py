"""The episode loop: one seeded episode of a policy in an env, seen by observers; the episodes' statistics.

[`run_episode`][run_episode] is the one loop of the package: the rollouts and demos, the datasets' recording
([`hsddp_gym.datasets.recording.record_episode`][hsddp_gym.datasets.recording.record_episode]), DAgger's relabelling
rollouts, the learners' evaluation and every experiment play their episodes through it. What they keep of an episode is
an observer's job: an object with ``on_reset(env, obs, info)`` and ``on_step(env, action, obs, reward, terminated,
truncated, info)`` (either may be missing), called after the reset and after every step
([`FrameRecorder`][FrameRecorder], [`Returns`][Returns], the datasets' decision recorder, the tasks' measures).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np


@dataclasses.dataclass
class EpisodeResult:
    """One episode. ``states (T+1, 14)`` (x position included), ``actions (T, 4)``, ``rewards (T,)``.

    ``wall_time``: the policy and the simulation, observers excluded (the real-time factor's denominator)."""

    seed: int
    episode_return: float
    length: int
    fell: bool
    forward_speed: float
    wall_time: float
    simulated_time: float
    states: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    frames: list | None = None
    policy_stats: dict | None = None


class FrameRecorder:
    """Observer: the ``env.render()`` frames of an episode (the reset's and one per step) in `frames` (the
    env needs ``render_mode="rgb_array"``)."""

    def __init__(self) -> None:
        self.frames: list = []

    def on_reset(self, env, obs, info) -> None:
        self.frames = [env.render()]

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.frames.append(env.render())


class Returns:
    """Observer: the episode's return summed step by step (`total`), its length (`steps`) and the
    reset's and the last step's ``info`` (`first_info`, `last_info`)."""

    def __init__(self) -> None:
        self.total, self.steps, self.first_info, self.last_info = 0.0, 0, None, None

    def on_reset(self, env, obs, info) -> None:
        self.total, self.steps, self.first_info, self.last_info = 0.0, 0, info, info

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.total += float(reward)
        self.steps += 1
        self.last_info = info


def reset_options_of(policy, options: dict | None = None) -> dict | None:
    """The reset options of an episode of ``policy``: its ``reset_options`` attribute (the expert's start, see
    [`hsddp_gym.rollout.policies.make_policy`][hsddp_gym.rollout.policies.make_policy]) updated with ``options``; None
    when neither has any."""
    own = getattr(policy, "reset_options", None)
    if own is None:
        return options
    return {**own, **(options or {})}


def run_episode(env, policy, seed: int, options: dict | None = None, max_steps: int | None = None,
                observers=(), render: bool = False) -> EpisodeResult:
    """Run one episode of ``env`` with ``policy`` (a callable ``obs -> action (4,)`` with ``reset()``) from
    ``env.reset(seed=seed, options=reset_options_of(policy, options))`` until it terminates, is truncated or has run
    ``max_steps`` steps.

    ``observers`` see the reset and every step (see the module docstring); the time they take is not counted in
    ``wall_time``. ``render``: collect the frames into ``EpisodeResult.frames`` (a [`FrameRecorder`][FrameRecorder]).
    """
    frames = FrameRecorder() if render else None
    observers = (*observers, frames) if frames is not None else tuple(observers)
    resets = [o.on_reset for o in observers if hasattr(o, "on_reset")]
    steps_seen = [o.on_step for o in observers if hasattr(o, "on_step")]
    obs, info = env.reset(seed=int(seed), options=reset_options_of(policy, options))
    policy.reset()
    for f in resets:
        f(env, obs, info)
    states = [np.concatenate([info["qpos"], info["qvel"]])]
    actions, rewards = [], []
    fell = False
    t0 = time.perf_counter()
    observer_time = 0.0
    steps = 0
    while True:
        action = policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        actions.append(np.asarray(action, dtype=np.float32))
        rewards.append(float(reward))
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        if steps_seen:
            t_seen = time.perf_counter()
            for f in steps_seen:
                f(env, action, obs, reward, terminated, truncated, info)
            observer_time += time.perf_counter() - t_seen
        if terminated:
            fell = True
            break
        if truncated or (max_steps is not None and steps >= max_steps):
            break
    wall = time.perf_counter() - t0 - observer_time
    dt = float(env.unwrapped.dt)
    states = np.array(states)
    sim_time = steps * dt
    stats = getattr(policy, "stats", None)
    return EpisodeResult(seed=int(seed), episode_return=float(np.sum(rewards)), length=steps, fell=fell,
                         forward_speed=float((states[-1, 0] - states[0, 0]) / sim_time), wall_time=wall,
                         simulated_time=sim_time, states=states, actions=np.array(actions),
                         rewards=np.array(rewards), frames=frames.frames if frames is not None else None,
                         policy_stats={k: (list(v) if isinstance(v, list) else v) for k, v in stats.items()}
                         if isinstance(stats, dict) else None)


def summarize(results: list[EpisodeResult]) -> dict:
    """``mean_return``, ``std_return``, ``falls``, ``mean_forward_speed``, ``mean_episode_length``,
    ``real_time_factor`` (simulated / wall time over all episodes) and, for planners, ``replans``,
    ``planner_failures``, ``time_budget_stops``, ``mean_replan_ms``, ``max_replan_ms``."""
    returns = np.array([r.episode_return for r in results])
    out = {
        "episodes": len(results),
        "seeds": [r.seed for r in results],
        "mean_return": float(returns.mean()),
        "std_return": float(returns.std()),
        "returns": returns.tolist(),
        "falls": int(sum(r.fell for r in results)),
        "mean_forward_speed": float(np.mean([r.forward_speed for r in results])),
        "mean_episode_length": float(np.mean([r.length for r in results])),
        "real_time_factor": float(sum(r.simulated_time for r in results) / max(sum(r.wall_time for r in results),
                                                                              1e-12)),
    }
    stats = [r.policy_stats for r in results if r.policy_stats]
    if stats and "replans" in stats[0]:
        solve_ms = [ms for s in stats for ms in s.get("solve_ms", [])]
        out.update(replans=int(sum(s["replans"] for s in stats)),
                   planner_failures=int(sum(s["planner_failures"] for s in stats)),
                   time_budget_stops=int(sum(s.get("time_budget_stops", 0) for s in stats)),
                   mean_replan_ms=float(np.mean(solve_ms)) if solve_ms else None,
                   max_replan_ms=float(np.max(solve_ms)) if solve_ms else None)
    else:
        out.update(replans=0, planner_failures=0, time_budget_stops=0, mean_replan_ms=None, max_replan_ms=None)
    return out
