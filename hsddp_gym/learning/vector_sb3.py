"""The compiled vector env of an env of the bounding family
(``gym.make_vec(ID, vectorization_mode="vector_entry_point")``:
[`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv] for ``Bounding-v0``,
[`TaskVectorEnv`][hsddp_gym.envs.task_vector.TaskVectorEnv] for the task envs) as a Stable-Baselines3 ``VecEnv``, so
that PPO / SAC train on N robots whose physics runs in one call.

SB3 resets a finished env itself and returns the reset observation, with the last one in
``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` (truncated, not terminated):
[`make_sb3_vec_env`][make_sb3_vec_env] runs the vector env with ``autoreset_mode="same_step"``, which gives exactly
that. """

from __future__ import annotations

from typing import Any

import numpy as np

from hsddp_gym.util.extras import require

INFO_FORWARD = ("x_velocity", "reward_forward", "reward_ctrl", "reward_healthy", "invalid_state")
"""Scalar info keys of the vector env copied into each SB3 ``infos[i]`` (besides the SB3 keys); a task's
``"success"`` also becomes SB3's ``"is_success"`` at the end of an episode."""

DEFAULT_ENV_ID = "hsddp_gym/Bounding-v0"


def make_sb3_vec_env(num_envs: int, seed: int | None = None, max_episode_steps: int | None = 1000,
                     env_id: str = DEFAULT_ENV_ID, **env_kwargs):
    """A `stable_baselines3.common.vec_env.VecEnv` over ``gym.make_vec(env_id, num_envs,
    vectorization_mode="vector_entry_point", ...)``.

    Args:
        num_envs: robots (>= 1). seed: the seed of the first reset (robot ``i`` gets ``seed + i``, as SB3's
            ``VecEnv.seed``); None: random. max_episode_steps: the time limit (None: none).
        env_id: a registered env with a vector entry point (``Bounding-v0`` and its task envs).
        **env_kwargs: the env's arguments (see its vector env).
    """
    require(["stable_baselines3"], "make_sb3_vec_env")
    import gymnasium as gym
    from gymnasium.vector import AutoresetMode
    from stable_baselines3.common.vec_env import VecEnv

    import hsddp_gym  # noqa: F401  (registers the envs)

    if not isinstance(env_id, str) or env_id not in gym.registry:
        raise ValueError(f"env_id must be a registered env id, got {env_id!r}")
    if gym.spec(env_id).vector_entry_point is None:
        raise ValueError(f"env_id {env_id!r} has no compiled vector env (no vector entry point)")

    class BoundingSB3VecEnv(VecEnv):
        """SB3 ``VecEnv`` over a compiled vector env of the bounding family (same-step autoreset). ``venv``: the
        vector env."""

        def __init__(self, venv) -> None:
            self.venv = venv
            self._actions = None
            super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

        def reset(self):
            seeds = self._seeds if any(s is not None for s in self._seeds) else None
            obs, info = self.venv.reset(seed=seeds)
            self.reset_infos = [{} for _ in range(self.num_envs)]
            self._reset_seeds()
            self._reset_options()
            return obs

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = np.asarray(actions)

        def step_wait(self):
            if self._actions is None:
                raise RuntimeError("step_wait() called without step_async()")
            obs, reward, terminated, truncated, info = self.venv.step(self._actions)
            self._actions = None
            done = terminated | truncated
            infos: list[dict[str, Any]] = []
            for i in range(self.num_envs):
                src = info["final_info"] if done[i] else info
                item = {key: src[key][i].item() for key in INFO_FORWARD}
                if done[i]:
                    item["terminal_observation"] = info["final_obs"][i]
                    item["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                    if "success" in src:
                        item["is_success"] = bool(src["success"][i])
                infos.append(item)
            return obs, reward.astype(np.float32), done, infos

        def close(self) -> None:
            self.venv.close()

        def _indices(self, indices) -> list[int]:
            if indices is None:
                return list(range(self.num_envs))
            if isinstance(indices, int):
                return [indices]
            return list(indices)

        def get_attr(self, attr_name: str, indices=None) -> list[Any]:
            """An attribute of each robot's single env (the vector env's ``envs``), or of its template when the
            robots share one compiled simulation (every robot has the same settings)."""
            envs = getattr(self.venv, "envs", None)
            if envs is not None:
                return [getattr(envs[i], attr_name) for i in self._indices(indices)]
            value = getattr(self.venv.template, attr_name)
            return [value for _ in self._indices(indices)]

        def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
            raise AttributeError(f"set_attr({attr_name!r}): the robots of a compiled vector env are stepped "
                                 "together and cannot be changed one by one; build a new vector env instead")

        def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
            raise AttributeError(f"env_method({method_name!r}): the robots of a compiled vector env are stepped "
                                 "together, not through their env objects")

        def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
            return [False for _ in self._indices(indices)]

        def get_images(self):
            raise NotImplementedError(f"{type(self.venv).__name__} does not render")

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                        max_episode_steps=max_episode_steps, autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
    sb3_env = BoundingSB3VecEnv(venv)
    if seed is not None:
        sb3_env.seed(int(seed))
    return sb3_env
