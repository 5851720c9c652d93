"""Running policies in the env: seeded episodes, their statistics, and the frames for a video."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hsddp_gym.planners.policies.base import Policy


@dataclasses.dataclass
class EpisodeResult:
    """One episode. ``states (T+1, 14)`` (x position included), ``actions (T, 4)``, ``rewards (T,)``."""

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


def run_episode(env, policy: Policy, seed: int, options: dict | None = None, render: bool = False,
                max_steps: int | None = None) -> EpisodeResult:
    """Run one episode of ``env`` (a ``gym.make``'d ``Bounding-v0``) with ``policy`` from ``reset(seed)``.

    ``render`` collects ``env.render()`` frames (the env needs ``render_mode="rgb_array"``); the rendering time
    is not counted in ``wall_time`` (so the real-time factor measures the policy and the simulation only).
    """
    obs, info = env.reset(seed=int(seed), options=options)
    policy.reset()
    states = [np.concatenate([info["qpos"], info["qvel"]])]
    actions, rewards = [], []
    frames = [env.render()] if render else None
    fell = False
    t0 = time.perf_counter()
    render_time = 0.0
    steps = 0
    while True:
        action = policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        actions.append(np.asarray(action, dtype=np.float32))
        rewards.append(float(reward))
        states.append(np.concatenate([info["qpos"], info["qvel"]]))
        if render:
            t_render = time.perf_counter()
            frames.append(env.render())
            render_time += time.perf_counter() - t_render
        if terminated:
            fell = True
            break
        if truncated or (max_steps is not None and steps >= max_steps):
            break
    wall = time.perf_counter() - t0 - render_time
    dt = float(env.unwrapped.dt)
    states = np.array(states)
    sim_time = steps * dt
    stats = getattr(policy, "stats", None)
    return EpisodeResult(seed=int(seed), episode_return=float(np.sum(rewards)), length=steps, fell=fell,
                         forward_speed=float((states[-1, 0] - states[0, 0]) / sim_time), wall_time=wall,
                         simulated_time=sim_time, states=states, actions=np.array(actions),
                         rewards=np.array(rewards), frames=frames,
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
