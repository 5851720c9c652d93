"""The compiled vector env ([`hsddp_gym.envs.vector.BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv]) as a
Stable-Baselines3 ``VecEnv``, so that PPO / SAC train on N robots stepped by one call.

SB3 resets a finished env itself and returns the reset observation, with the last one in
``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` (truncated, not terminated):
[`make_sb3_vec_env`][make_sb3_vec_env] runs the vector env with ``autoreset_mode="same_step"``, which gives exactly
that. """

from __future__ import annotations

from typing import Any

import numpy as np

from hsddp_gym.util.extras import require

INFO_FORWARD = ("x_velocity", "reward_forward", "reward_ctrl", "reward_healthy", "invalid_state")
"""Scalar info keys of the vector env copied into each SB3 ``infos[i]`` (besides the SB3 keys)."""


def make_sb3_vec_env(num_envs: int, seed: int | None = None, max_episode_steps: int | None = 1000,
                     **env_kwargs):
    """A `stable_baselines3.common.vec_env.VecEnv` over ``BoundingVectorEnv(num_envs, ...)``.

    Args:
        num_envs: robots (>= 1). seed: the seed of the first reset (robot ``i`` gets ``seed + i``, as SB3's
            ``VecEnv.seed``); None: random. max_episode_steps: the time limit (None: none).
        **env_kwargs: [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] arguments (see ``BoundingVectorEnv``).
    """
    require(["stable_baselines3"], "make_sb3_vec_env")
    from gymnasium.vector import AutoresetMode
    from stable_baselines3.common.vec_env import VecEnv

    from hsddp_gym.envs.vector import BoundingVectorEnv

    class BoundingSB3VecEnv(VecEnv):
        """SB3 ``VecEnv`` over a ``BoundingVectorEnv`` (same-step autoreset). ``venv``: the vector env."""

        def __init__(self, venv: BoundingVectorEnv) -> None:
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
            """An attribute of the single env (its template: every robot has the same settings)."""
            value = getattr(self.venv.template, attr_name)
            return [value for _ in self._indices(indices)]

        def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
            raise AttributeError(f"set_attr({attr_name!r}): the robots of a BoundingVectorEnv share one compiled "
                                 "simulation and cannot be changed one by one; build a new vector env instead")

        def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
            raise AttributeError(f"env_method({method_name!r}): a BoundingVectorEnv has no per-robot env objects")

        def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
            return [False for _ in self._indices(indices)]

        def get_images(self):
            raise NotImplementedError("BoundingVectorEnv does not render")

    venv = BoundingVectorEnv(num_envs=num_envs, max_episode_steps=max_episode_steps,
                             autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
    sb3_env = BoundingSB3VecEnv(venv)
    if seed is not None:
        sb3_env.seed(int(seed))
    return sb3_env
