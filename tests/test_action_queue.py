"""The learners' latency queue (``BCConfig.action_queue``): the actions sent that the env has not executed yet.

What is checked: the features are exactly the contents of :class:`ActionDelay`'s queue at every step (and its
first slot is the action the env executes next); a learner acting in a delayed env sees the same inputs as
:func:`build_inputs` rebuilds from the recorded episode (training and acting agree), the action it was told was
sent included; datasets recorded under named conditions carry each episode's delay; BC and DAgger train with the
queue; bad input names ``action_queue``.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.datasets.generation import generate_dataset
from hsddp_gym.datasets.recording import inform_sent_action
from hsddp_gym.envs.perturbations import ActionDelay
from hsddp_gym.learning.bc import BCConfig, MLPPolicy, train_bc
from hsddp_gym.learning.dagger import DAggerConfig, train_dagger
from hsddp_gym.learning.demonstrations import Demonstrations, load_demonstrations
from hsddp_gym.learning.features import QUEUE_SLOT_SIZE, action_queue_features, build_inputs
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy

torch = pytest.importorskip("torch")
torch.set_num_threads(1)


def delayed_env(steps: int) -> gym.Env:
    return ActionDelay(gym.make("hsddp_gym/Bounding-v0", max_episode_steps=40), steps)


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_queue_features_are_the_wrappers_queue(delay):
    env = delayed_env(delay)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    sent, queues, executed = [], [], []
    for _ in range(25):
        queues.append([np.array(a, dtype=np.float64) for a in env._queue])
        a = rng.uniform(-1, 1, 4).astype(np.float32)
        sent.append(a)
        _, _, term, trunc, info = env.step(a)
        executed.append(info["executed_action"])
        assert not (term or trunc)
    feats = action_queue_features(np.array(sent), delay, slots=2).reshape(25, 2, QUEUE_SLOT_SIZE)
    for t in range(25):
        assert len(queues[t]) == delay
        for j in range(2):
            if j < delay:
                np.testing.assert_array_equal(feats[t, j, :4], queues[t][j])
                assert feats[t, j, 4] == 1.0
            else:
                assert not feats[t, j].any()
        if delay:  # the first slot is what the env executes at this step
            np.testing.assert_array_equal(feats[t, 0, :4], executed[t])
    env.close()


def test_queue_features_reject_a_delay_beyond_the_slots():
    with pytest.raises(ValueError, match="action_queue"):
        action_queue_features(np.zeros((5, 4)), 3, slots=2)
    with pytest.raises(ValueError, match="sent"):
        action_queue_features(np.zeros((5, 3)), 1, slots=2)


def random_policy(interface: EnvInterface, slots: int, features: str = "obs") -> MLPPolicy:
    rng = np.random.default_rng(1)
    cfg = BCConfig(hidden=(16,), features=features, action_queue=slots)
    n_in = interface.layout.size + (7 if features == "gait_clock" else 0) + QUEUE_SLOT_SIZE * slots
    weights = [(rng.normal(0, 0.3, (16, n_in)), rng.normal(0, 0.1, 16)), (rng.normal(0, 0.3, (4, 16)),
                                                                            rng.normal(0, 0.1, 4))]
    return MLPPolicy(interface, weights=weights, obs_mean=np.zeros(n_in), obs_std=np.ones(n_in), config=cfg)


@pytest.mark.parametrize("features", ["obs", "gait_clock"])
def test_acting_and_training_see_the_same_queue(features):
    """A learner in a 2-step-delayed env, its actions perturbed before they are sent (DART noise, told through
    note_sent_action): its inputs at every step equal build_inputs' from the recorded episode."""
    env = delayed_env(2)
    interface = EnvInterface.from_env(env)
    assert interface.action_delay_steps == 2
    policy = random_policy(interface, slots=2, features=features)
    seen = []
    forward = policy.forward
    policy.forward = lambda z: (seen.append(np.array(z[0])), forward(z))[1]
    rng = np.random.default_rng(4)
    obs, _ = env.reset(seed=5)
    policy.reset()
    O, S = [], []
    for _ in range(30):
        a = policy.act(obs)
        sent = np.clip(a + 0.1 * rng.standard_normal(4), -1, 1).astype(np.float32)
        inform_sent_action(policy, sent)
        O.append(obs)
        S.append(sent)
        obs, _, term, trunc, _ = env.step(sent)
        if term or trunc:
            break
    T = len(O)
    demos = Demonstrations(np.array(O, dtype=np.float32), np.zeros((T, 4), np.float32), np.zeros(T, np.int64),
                           sent_actions=np.array(S), action_delay=np.full(T, 2))
    clock = policy.clock
    inputs = build_inputs(demos, policy.config, clock, interface.layout)
    np.testing.assert_allclose(np.array(seen), inputs, rtol=0, atol=1e-6)  # float32 observations
    q = inputs[:, -2 * QUEUE_SLOT_SIZE:].reshape(T, 2, QUEUE_SLOT_SIZE)
    assert not q[:2, 0, :4].any() and q[2, 0, :4].any()  # zero torques first, then the sent actions
    np.testing.assert_allclose(q[5, 1, :4], S[4], atol=1e-7)
    env.close()


def test_queue_without_delay_is_empty_and_bad_settings_are_refused():
    policy = random_policy(EnvInterface(), slots=1)
    assert policy.delay == 0 and not policy._queue_features().any()
    with pytest.raises(ValueError, match="action_queue"):
        random_policy(EnvInterface(action_delay_steps=2), slots=1)
    with pytest.raises(ValueError, match="action_queue"):
        BCConfig(action_queue=-1)
    with pytest.raises(TypeError, match="action_queue"):
        BCConfig(action_queue=1.5)
    demos = Demonstrations(np.zeros((3, 17), np.float32), np.zeros((3, 4), np.float32), np.zeros(3, np.int64))
    with pytest.raises(ValueError, match="action_queue"):
        build_inputs(demos, BCConfig(action_queue=1))


@pytest.fixture(scope="module")
def delayed_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("queue") / "ds"
    generate_dataset("heuristic", 3, out, seed=0, max_episode_steps=40, progress=False, action_noise=0.05,
                     conditions=["default", "delay_5ms", "delay_10ms"])
    return out


def test_datasets_carry_each_episodes_delay_and_sent_actions(delayed_dataset):
    from hsddp_gym import datasets

    demos = load_demonstrations(delayed_dataset, fmt="npz")
    flat = datasets.load_npz(delayed_dataset)
    for i, delay in enumerate((0, 1, 2)):
        rows = demos.episode == i
        assert set(demos.action_delay[rows].tolist()) == {delay}
        np.testing.assert_array_equal(demos.sent_actions[rows], flat.episode(i)["actions"])
    assert not np.array_equal(demos.sent_actions, demos.actions)  # DART noise: the labels are clean
    mini = load_demonstrations(delayed_dataset, fmt="minari")
    np.testing.assert_array_equal(mini.sent_actions, demos.sent_actions)
    np.testing.assert_array_equal(mini.action_delay, demos.action_delay)
    first = demos.first_episodes(2)
    assert first.action_delay.max() == 1 and len(first.sent_actions) == len(first)


def test_bc_and_dagger_train_with_the_queue(delayed_dataset):
    demos = load_demonstrations(delayed_dataset, fmt="npz")
    cfg = BCConfig(hidden=(32,), epochs=3, action_queue=2, seed=0)
    policy, _ = train_bc(demos, cfg)
    assert policy.obs_mean.shape == (17 + 2 * QUEUE_SLOT_SIZE,)
    env = delayed_env(2)
    acting = policy.with_interface(EnvInterface.from_env(env))
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(acting.act(obs))
    assert len(acting._sent) == 2
    env.close()
    dcfg = DAggerConfig(rounds=1, episodes_per_round=2, beta_decay=0.5, bc=dataclasses.replace(cfg, epochs=2),
                        max_episode_steps=15, conditions=("delay_10ms",))
    res = train_dagger(lambda env, seed: HeuristicPolicy(EnvInterface.from_env(env)), dcfg, initial=demos,
                       progress=False)
    assert res.data.action_delay is not None
    assert set(res.data.action_delay[res.data.episode >= 3].tolist()) == {2}
    assert len(res.data.sent_actions) == len(res.data)
