"""Residual RL on the HS-DDP plan tracker: a learner adds a bounded correction to the task expert's action.

The task's plan-tracking expert ([`make_policy("expert", env)`][hsddp_gym.rollout.policies.make_policy]: the HS-DDP
plan's torques and its feedback law, ``u = û + K (x − x̂)``) acts; the learner sees the observation with the expert's
action appended and outputs ``r`` in ``[-1, 1]^4``; the env receives

    a = clip(a_expert + scale · r, -1, 1).

A zero residual is the expert itself, and training starts there ([`zero_mean_action`][zero_mean_action]): from the
expert's success it learns what the fixed plan cannot do (recover from noise and pushes), on the task's own reward:
the "residual policy on top of the tracker" of
trajectory-optimization-guided RL (Johannink et al. 2019; OPT-Mimic, Fuchioka et al. 2023, learns its tracker from
scratch instead). [`ResidualEnv`][ResidualEnv] is the env a learner trains in, [`ResidualPolicy`][ResidualPolicy] the
trained learner and the expert together as one [`Policy`][hsddp_gym.planners.policies.base.Policy] in the plain env;
both compose the action with [`residual_action`][residual_action] and the learner's input with
[`residual_observation`][residual_observation], so the two act alike step for step (``tests/test_residual.py``).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.planners.policies.base import Policy
from hsddp_gym.util.validation import real_array

RESIDUAL_BASES = ("expert",)
"""The policies a residual can be added to: the task's plan-tracking expert."""


def check_residual_scale(scale, name: str = "residual_scale") -> float:
    """``scale`` as a float in ``(0, 2]`` (the residual's share of the action range), else ValueError naming
    ``name``."""
    if isinstance(scale, bool) or not isinstance(scale, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number in (0, 2], got {scale!r}")
    s = float(scale)
    if not (math.isfinite(s) and 0.0 < s <= 2.0):
        raise ValueError(f"{name} must be a number in (0, 2], got {scale!r}")
    return s


def residual_action(base_action, residual, scale: float) -> np.ndarray:
    """The action the env receives: ``clip(base_action + scale * clip(residual, -1, 1), -1, 1)``, float32 (4,).
    ``residual`` must be 4 finite numbers (ValueError naming ``residual`` otherwise: nothing is broadcast)."""
    r = real_array(residual, "residual").astype(np.float64, copy=False)
    if r.shape != (NU,):
        raise ValueError(f"residual must have shape ({NU},), got {r.shape}")
    if not np.isfinite(r).all():
        raise ValueError(f"residual must be finite, got {r}")
    a = np.asarray(base_action, dtype=np.float64) + scale * np.clip(r, -1.0, 1.0)
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def residual_observation(obs, base_action) -> np.ndarray:
    """The learner's input: the env's observation with the expert's action appended, float32 ``(obs_dim + 4,)``."""
    return np.concatenate([np.asarray(obs, dtype=np.float32), np.asarray(base_action, dtype=np.float32)])


def residual_observation_space(space: gym.spaces.Box) -> gym.spaces.Box:
    """The env's observation box extended by the expert's action (4 entries in ``[-1, 1]``)."""
    low = np.concatenate([space.low, -np.ones(NU, dtype=space.dtype)])
    high = np.concatenate([space.high, np.ones(NU, dtype=space.dtype)])
    return gym.spaces.Box(low, high, dtype=np.float32)


def zero_mean_action(model) -> None:
    """Zero the last layer of an SB3 PPO or SAC model's action mean (weights and bias), so that its mean residual is 0
    at every input and a residual learner starts as the expert. The backflip's plan tolerates little: a residual of a
    random bias up to ±0.3 plus noise of 0.1, at scale 0.2, fell in 4 of 5 episodes, 3 of them within 0.2 s, and a
    first training run from a freshly initialized network ended its episodes after about 37 steps. Exploration then
    comes from the policy's own noise (``log_std_init``)."""
    import torch as th

    policy = model.policy
    layer = policy.actor.mu if hasattr(policy, "actor") else policy.action_net
    if not isinstance(layer, th.nn.Linear):
        raise TypeError(f"model: expected a Linear last layer of the action mean, got {type(layer).__name__}")
    with th.no_grad():
        layer.weight.zero_()
        layer.bias.zero_()


class ResidualEnv(gym.Wrapper):
    """The env a residual learner trains in: actions are residuals on the task expert's action
    ([`residual_action`][residual_action]); observations carry the expert's action
    ([`residual_observation`][residual_observation]). The expert is built once for the wrapped env
    (``make_policy(base, env)``), reset with every episode, and its reset options (the bounding expert starts at its
    plan's first state) are applied under the caller's. ``info`` gains ``"base_action"`` (the expert's action of the
    step, (4,) float32).

    Args:
        env: a task env of the bounding family (or its twin), possibly wrapped.
        scale: the residual's scale in ``(0, 2]`` ([`check_residual_scale`][check_residual_scale]).
        base: one of [`RESIDUAL_BASES`][RESIDUAL_BASES].
    """

    def __init__(self, env: gym.Env, scale: float, base: str = "expert") -> None:
        super().__init__(env)
        from hsddp_gym.rollout.policies import make_policy

        if base not in RESIDUAL_BASES:
            raise ValueError(f"base must be one of {list(RESIDUAL_BASES)}, got {base!r}")
        if not isinstance(env.observation_space, gym.spaces.Box) or env.action_space.shape != (NU,):
            raise TypeError(f"env must have a Box observation space and 4 actions, got {env.observation_space} and "
                            f"{env.action_space}")
        self.scale = check_residual_scale(scale, "scale")
        self.base_name = base
        self.base = make_policy(base, env)
        """The expert the residual is added to."""
        self.observation_space = residual_observation_space(env.observation_space)
        self._base_action = np.zeros(NU, dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        own = getattr(self.base, "reset_options", None)
        merged = {**(own or {}), **(options or {})} or None
        obs, info = self.env.reset(seed=seed, options=merged)
        self.base.reset()
        self._base_action = np.asarray(self.base(obs), dtype=np.float32)
        return residual_observation(obs, self._base_action), info

    def step(self, action):
        a = residual_action(self._base_action, action, self.scale)
        obs, reward, terminated, truncated, info = self.env.step(a)
        info["base_action"] = self._base_action
        self._base_action = (np.zeros(NU, dtype=np.float32) if terminated or truncated
                             else np.asarray(self.base(obs), dtype=np.float32))
        return residual_observation(obs, self._base_action), reward, terminated, truncated, info


class ResidualPolicy(Policy):
    """A trained residual learner and its expert as one policy of the plain env: ``act(obs) = residual_action(b,
    learner(residual_observation(obs, b)), scale)`` with ``b = base(obs)``. ``reset_options`` are the expert's.

    Args:
        base: the expert (a [`Policy`][hsddp_gym.planners.policies.base.Policy] of the env).
        learner: the trained residual (a policy whose input is [`residual_observation`][residual_observation]).
        scale: the residual's scale it was trained with.
    """

    def __init__(self, base: Policy, learner: Policy, scale: float) -> None:
        super().__init__(base.interface)
        self.base = base
        self.learner = learner
        self.scale = check_residual_scale(scale, "scale")
        self.reset_options = getattr(base, "reset_options", None)

    def reset(self) -> None:
        self.base.reset()
        self.learner.reset()

    def act(self, obs: np.ndarray) -> np.ndarray:
        b = np.asarray(self.base(obs), dtype=np.float32)
        return residual_action(b, self.learner(residual_observation(obs, b)), self.scale)
