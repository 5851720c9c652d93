"""The online estimate of an action delay (:class:`hsddp_gym.planners.policies.latency.DelayEstimator`): it finds
the executed delay from the response to the policy's own actions when the announced one is wrong, stays where it is
when the announced one is right or when the actions do not tell the delays apart, and names bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the env)
from hsddp_gym.core.observation import state_from_observation
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.perturbations import ActionDelay
from hsddp_gym.planners.policies.estimation import ContactModelPredictor
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
from hsddp_gym.planners.policies.latency import DelayEstimator


def _estimates(executed: int, announced: int, steps: int = 120, seed: int = 3, constant: bool = False) -> list[int]:
    """The estimate after each control step of a heuristic-driven episode behind ``ActionDelay(executed,
    announced=announced)`` (the heuristic ignores the delay; it only supplies actions that vary)."""
    env = ActionDelay(BoundingEnv(), executed, announced=announced)
    policy = HeuristicPolicy.from_env(env)
    est = DelayEstimator(ContactModelPredictor(env.unwrapped.dt), announced, search=1)
    obs, _ = env.reset(seed=seed)
    layout = env.unwrapped.observation_layout
    sent = [np.zeros(4)] * est.history
    x_prev, out = None, []
    for _ in range(steps):
        y = state_from_observation(obs, layout)[0]
        if x_prev is not None:
            out.append(est.update(x_prev, y, np.array(sent[-est.history:]) * env.unwrapped.torque_limit))
        x_prev = y
        action = np.full(4, 0.1, dtype=np.float32) if constant else policy.predict(obs, deterministic=True)[0]
        sent.append(np.asarray(action, dtype=np.float64))
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    return out


@pytest.mark.parametrize("executed, announced", [(2, 1), (1, 2), (1, 0), (3, 2)])
def test_a_wrongly_announced_delay_is_found_within_a_few_steps(executed, announced):
    estimates = _estimates(executed, announced)
    first = estimates.index(executed)
    assert first <= 25  # 125 ms (measured with these actions: 2 to 19 steps)
    assert all(d == executed for d in estimates[first:])


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_a_rightly_announced_delay_is_kept(delay):
    assert set(_estimates(delay, delay)) == {delay}


def test_actions_that_do_not_tell_the_delays_apart_move_nothing():
    """A constant action: every candidate delay executes the same torque, so no evidence and no switch."""
    assert set(_estimates(2, 1, steps=60, constant=True)) == {1}


def test_candidates_and_bad_arguments():
    predictor = ContactModelPredictor(0.005)
    assert DelayEstimator(predictor, 0).candidates == (0, 1)
    assert DelayEstimator(predictor, 2, search=1).candidates == (1, 2, 3) and DelayEstimator(predictor, 2).history == 4
    assert DelayEstimator(predictor, 2, search=0).candidates == (2,)
    for kwargs, name in (({"announced": -1}, "announced"), ({"announced": 1, "search": -1}, "search"),
                         ({"announced": 1, "forgetting": 1.0}, "forgetting"),
                         ({"announced": 1, "margin": 0.0}, "margin"),
                         ({"announced": 1, "velocity_scale": np.zeros(7)}, "velocity_scale")):
        with pytest.raises(ValueError, match=name):
            DelayEstimator(predictor, **kwargs)
    with pytest.raises(TypeError, match="predictor"):
        DelayEstimator(object(), 1)
    est = DelayEstimator(predictor, 1)
    with pytest.raises(ValueError, match="torques"):
        est.update(np.zeros(14), np.zeros(14), np.zeros((2, 4)))
