"""Any policy as a Stable-Baselines3 ``BasePolicy``.

[`as_sb3_policy`][as_sb3_policy] wraps a [`Policy`][hsddp_gym.planners.policies.base.Policy] (or any callable
``obs (obs_dim,) -> action (act_dim,)``) into a ``stable_baselines3.common.policies.BasePolicy`` whose
``predict(observation, state, episode_start, deterministic)`` and ``_predict(obs_tensor)`` return exactly the
callable's actions (float32, clipped to the action box, which leaves a policy's in-box actions unchanged).
A [`Policy`][Policy] keeps one independent copy per vectorized env and resets the copy whose ``episode_start``
is true, so planners with memory (gait clock, plan cursor, MPC warm start) work with ``evaluate_policy``
and with ``imitation``'s rollout / DAgger tooling. A plain callable is applied row by row and has no memory.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hsddp_gym.planners.policies.base import Policy


def _as_batch_fn(policy) -> Callable:
    """``(obs (n, d) float32, episode_start (n,) bool or None) -> actions (n, m)``."""
    if isinstance(policy, Policy):
        def batch(obs, episode_start):
            acts, _ = policy.predict(obs, episode_start=episode_start, deterministic=True)
            return np.asarray(acts, dtype=np.float32)
        return batch
    if not callable(policy):
        raise TypeError(f"policy must be a hsddp_gym.planners.policies.base.Policy or a callable obs -> action, "
                        f"got {type(policy).__name__}")

    def batch(obs, episode_start):
        return np.stack([np.asarray(policy(o), dtype=np.float32) for o in obs])
    return batch


def as_sb3_policy(policy, observation_space, action_space):
    """Wrap ``policy`` into an SB3 ``BasePolicy`` (see the module docstring).

    Args:
        policy: a [`Policy`][hsddp_gym.planners.policies.base.Policy] (memory handled per env through
            ``episode_start``) or a callable ``obs (obs_dim,) -> action (act_dim,)`` (no memory).
        observation_space: the env's observation space (a ``gymnasium.spaces.Box``).
        action_space: the env's action space (a ``gymnasium.spaces.Box``).

    Returns:
        A ``CallableSB3Policy`` (an ``stable_baselines3.common.policies.BasePolicy``) with no parameters; it
        runs on the CPU and cannot be saved (the callable is arbitrary Python).
    """
    from gymnasium import spaces

    if not isinstance(observation_space, spaces.Box) or not isinstance(action_space, spaces.Box):
        raise TypeError(f"observation_space and action_space must be gymnasium Box spaces, got "
                        f"{type(observation_space).__name__} and {type(action_space).__name__}")
    return _adapter_class()(policy, observation_space, action_space)


_ADAPTER = None


def _adapter_class():
    """The adapter class, defined on first use so that importing this module does not import torch."""
    global _ADAPTER
    if _ADAPTER is not None:
        return _ADAPTER
    import torch as th
    from stable_baselines3.common.policies import BasePolicy

    class CallableSB3Policy(BasePolicy):
        """An SB3 ``BasePolicy`` that delegates to a planner policy or callable (see
        [`as_sb3_policy`][as_sb3_policy])."""

        def __init__(self, policy, observation_space, action_space) -> None:
            super().__init__(observation_space, action_space)
            self.wrapped = policy
            self._batch = _as_batch_fn(policy)

        def _predict(self, observation, deterministic: bool = False):
            obs = observation.detach().cpu().numpy().astype(np.float32, copy=False)
            return th.as_tensor(self._batch(obs.reshape(len(obs), -1), None))

        def predict(self, observation, state=None, episode_start=None, deterministic: bool = False):
            """SB3 protocol; unlike ``BasePolicy.predict`` it passes ``episode_start`` to the wrapped policy
            so that each env's copy is reset at the start of its episode."""
            obs = np.asarray(observation, dtype=np.float32)
            shape = self.observation_space.shape
            single = obs.shape == shape
            if not single and obs.shape[1:] != shape:
                raise ValueError(f"observation must have shape {shape} or (n_envs, *{shape}), got {obs.shape}")
            batch = obs[None] if single else obs
            starts = None if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(len(batch))
            acts = self._batch(batch, starts).reshape((-1, *self.action_space.shape))
            acts = np.clip(acts, self.action_space.low, self.action_space.high)
            return (acts[0] if single else acts), state

        def forward(self, obs, deterministic: bool = False):
            return self._predict(obs, deterministic)

        def save(self, path) -> None:  # noqa: D102
            raise NotImplementedError("a CallableSB3Policy wraps arbitrary Python and cannot be saved; save the "
                                      "underlying planner (e.g. its Solution) instead")

    _ADAPTER = CallableSB3Policy
    return _ADAPTER
