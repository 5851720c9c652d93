"""Learning from the expert's feedback gains: the recorded law reproduces the expert's actions, local labels are
that law at perturbed states, and a learner trained with them gets the expert's local slope where plain BC
cannot see it."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import NQ, NU, NX
from hsddp_gym.core.observation import DEFAULT_LAYOUT, build_observation
from hsddp_gym.learning.demonstrations import Demonstrations, FeedbackLaw, load_demonstrations
from hsddp_gym.learning.gain_labels import gain_augmented_pairs

pytest.importorskip("torch")


@pytest.fixture(scope="module")
def mpc_dataset(tmp_path_factory):
    from hsddp_gym.datasets.generation import generate_dataset

    out = tmp_path_factory.mktemp("gains") / "mpc"
    generate_dataset("mpc", 1, out, seed=11, max_episode_steps=60, include_gains=True, progress=False)
    return out


def test_the_recorded_law_reproduces_the_experts_actions(mpc_dataset):
    mpc_demos = load_demonstrations(mpc_dataset, fmt="npz")
    fb = mpc_demos.feedback
    assert fb is not None and fb.gain.shape == (len(mpc_demos), NU, NX)
    assert fb.tracking.sum() > 0.8 * len(mpc_demos)  # the MPC acts with its plan's law almost always
    rows = np.flatnonzero(fb.tracking)
    np.testing.assert_allclose(fb.action(rows=rows), mpc_demos.actions[rows], atol=1e-5)
    assert np.all(fb.gain[:, :, 0] == 0.0)  # the trunk x is never fed back


def test_a_dataset_without_gains_has_no_law(tmp_path):
    from hsddp_gym.datasets.generation import generate_dataset

    generate_dataset("heuristic", 1, tmp_path / "h", max_episode_steps=5, progress=False)
    assert load_demonstrations(tmp_path / "h", fmt="npz").feedback is None


def _synthetic_law(n=50, seed=0):
    rng = np.random.default_rng(seed)
    K = 0.3 * rng.standard_normal((n, NU, NX))
    K[:, :, 0] = 0.0
    fb = FeedbackLaw(state=rng.standard_normal((n, NX)) * 0.1, nominal_state=np.zeros((n, NX)),
                     nominal_action=0.1 * rng.standard_normal((n, NU)), gain=K, tracking=rng.random(n) > 0.3)
    obs = np.stack([build_observation(x, [1, 0], 0.1 * i, 0.296) for i, x in enumerate(fb.state)])
    return fb, obs


def test_local_labels_are_the_law_at_the_perturbed_state():
    fb, obs = _synthetic_law()
    extra = np.zeros((len(obs), 3))  # e.g. gait-clock features after the observation
    inputs = np.concatenate([obs, extra], axis=1)
    X, Y = gain_augmented_pairs(inputs, fb, copies=3, position_std=0.02, velocity_std=0.2, seed=4)
    rows = np.repeat(np.flatnonzero(fb.tracking), 3)
    assert X.shape == (3 * fb.tracking.sum(), inputs.shape[1]) and Y.shape == (len(X), NU)
    dobs = X - inputs[rows]
    assert np.all(dobs[:, DEFAULT_LAYOUT.contact] == 0) and np.all(dobs[:, DEFAULT_LAYOUT.phase] == 0)
    assert np.all(dobs[:, DEFAULT_LAYOUT.size:] == 0)
    dx = np.zeros((len(X), NX))
    dx[:, 1:NQ] = dobs[:, DEFAULT_LAYOUT.qpos]
    dx[:, NQ:] = dobs[:, DEFAULT_LAYOUT.qvel]
    expect = np.clip(fb.nominal_action[rows] + np.einsum("nux,nx->nu", fb.gain[rows], fb.state[rows] + dx), -1, 1)
    np.testing.assert_allclose(Y, expect, atol=1e-12)
    assert 0.01 < dobs[:, DEFAULT_LAYOUT.qpos].std() < 0.03 and 0.1 < dobs[:, DEFAULT_LAYOUT.qvel].std() < 0.3
    X2, Y2 = gain_augmented_pairs(inputs, fb, copies=3, position_std=0.02, velocity_std=0.2, seed=4)
    assert np.array_equal(X, X2) and np.array_equal(Y, Y2)


def test_bad_arguments_are_named():
    fb, obs = _synthetic_law(5)
    with pytest.raises(ValueError, match="copies must be >= 1"):
        gain_augmented_pairs(obs, fb, 0)
    with pytest.raises(ValueError, match="position_std"):
        gain_augmented_pairs(obs, fb, 1, position_std=-1.0)
    with pytest.raises(ValueError, match="feedback has 5 rows, inputs 4"):
        gain_augmented_pairs(obs[:4], fb, 1)
    from hsddp_gym.learning.bc import BCConfig, train_bc

    with pytest.raises(ValueError, match="gain_copies must be >= 0"):
        BCConfig(gain_copies=-1)
    demos = Demonstrations(obs.astype(np.float32), np.zeros((5, NU), np.float32), np.zeros(5, np.int64))
    with pytest.raises(ValueError, match="gain_copies needs demonstrations with the expert's feedback gains"):
        train_bc(demos, BCConfig(gain_copies=2, epochs=1))


def test_gain_labels_teach_the_local_slope_that_one_trajectory_hides():
    """One demonstrated trajectory along a line in state space: plain BC sees the actions only along it, so its
    slope across it is arbitrary; with gain labels the learner's Jacobian follows K."""
    from hsddp_gym.learning.bc import BCConfig, train_bc

    rng = np.random.default_rng(1)
    n = 200
    K = np.zeros((NU, NX))
    K[:, 1:] = 0.2 * rng.standard_normal((NU, NX - 1))
    s = np.linspace(-1.0, 1.0, n)
    direction = np.zeros(NX)
    direction[[1, 2, 8]] = [0.05, 0.1, 0.5]
    base = np.zeros(NX)
    base[1] = 0.3
    states = base + s[:, None] * direction
    fb = FeedbackLaw(states, np.tile(base, (n, 1)), np.zeros((n, NU)), np.tile(K, (n, 1, 1)), np.ones(n, bool))
    obs = np.stack([build_observation(x, [1, 0], 0.0, 0.296) for x in states]).astype(np.float32)
    demos = Demonstrations(obs, fb.action().astype(np.float32), np.zeros(n, np.int64), fb)

    def slope_error(policy):
        x0 = states[n // 2]
        o0 = build_observation(x0, [1, 0], 0.0, 0.296).astype(np.float64)
        J = np.zeros((NU, NX))
        for j in range(1, NX):
            e = 1e-3
            dx = np.zeros(NX)
            dx[j] = e
            o = build_observation(x0 + dx, [1, 0], 0.0, 0.296).astype(np.float64)
            J[:, j] = (policy(o.astype(np.float32)).astype(np.float64) - policy(o0.astype(np.float32))) / e
        return np.linalg.norm(J - K) / np.linalg.norm(K)

    cfg = dict(hidden=(64, 64), epochs=150, batch_size=64, lr=3e-3, seed=0)
    plain, _ = train_bc(demos, BCConfig(**cfg))
    gains, hist = train_bc(demos, BCConfig(**cfg, gain_copies=8, gain_position_std=0.02, gain_velocity_std=0.2))
    assert hist["gain_labels"] == 8 * n and hist["transitions"] == n
    e_plain, e_gain = slope_error(plain), slope_error(gains)
    print(f"relative Jacobian error: plain BC {e_plain:.3f}, with gain labels {e_gain:.3f}")
    assert e_gain < 0.5 * e_plain and e_gain < 0.35


def test_dagger_refuses_gain_labels():
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig

    with pytest.raises(ValueError, match="bc.gain_copies must be 0 for DAgger"):
        DAggerConfig(bc=BCConfig(gain_copies=1))


def test_cli_trains_bc_with_gain_labels(mpc_dataset, tmp_path):
    import json

    from hsddp_gym import cli

    out = tmp_path / "bc_gains"
    assert cli.main(["train", "--algo", "bc", "--dataset", str(mpc_dataset), "--format", "npz", "--gain-copies", "3",
                     "--gain-noise", "0.02", "0.2", "--epochs", "2", "--eval-episodes", "1",
                     "--max-episode-steps", "10", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    law = load_demonstrations(mpc_dataset, fmt="npz").feedback
    assert summary["gain_labels"] == 3 * int(law.tracking.sum()) > 0
    assert summary["config"]["gain_copies"] == 3 and summary["config"]["gain_velocity_std"] == 0.2
