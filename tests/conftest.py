"""Shared fixtures for the foundation tests: the robot, the hybrid dynamics, a seeded generator, and
finite-difference / random-state helpers (the ``tools`` fixture, so test modules never import conftest).

``dynamics`` is function-scoped on purpose: a ``HybridDynamics`` owns Pinocchio ``Data`` scratch space,
and a fresh one per test keeps tests independent of each other's call history (building one costs ~1 ms).
"""

from __future__ import annotations

import types

import numpy as np
import pytest

from hsddp_gym.core.conventions import NQ, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.references import paper_initial_state

SEED = 20200601
"""Seed of the ``rng`` fixture (every test gets its own generator with this seed)."""

MODES = tuple(Mode)
CONTACT_MODES = (Mode.FRONT_STANCE, Mode.BACK_STANCE, Mode.DOUBLE_STANCE)
INTEGRATORS = ("euler", "semi_implicit")

FD_EPS = 1e-5
"""Central-difference step: truncation ~eps^2 and round-off ~1e-16/eps balance near 1e-5 here (measured)."""
FD_TOL = 1e-5
"""Max error relative to max(1, |reference|) allowed between an analytical derivative and its FD estimate."""


@pytest.fixture(scope="session")
def robot() -> CheetahModel:
    return CheetahModel()


@pytest.fixture
def dynamics(robot) -> HybridDynamics:
    """A fresh paper-default dynamics (dt = 1 ms, forward Euler) for each test."""
    return HybridDynamics(robot)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(SEED)


def random_state(rng: np.random.Generator, q_scale: float = 0.05, v_scale: float = 0.3) -> np.ndarray:
    """A physically sensible state: the paper's initial state (mid back stance, knees bent, moving forward)
    with Gaussian perturbations, so contact KKT systems stay well conditioned."""
    x = paper_initial_state()
    x[:NQ] += rng.normal(0.0, q_scale, NQ)
    x[NQ:] += rng.normal(0.0, v_scale, NX - NQ)
    return x


def random_control(rng: np.random.Generator, scale: float = 15.0) -> np.ndarray:
    """Joint torques well inside the 33 N m limit."""
    return rng.uniform(-scale, scale, NU)


def fd_jacobian(f, x: np.ndarray, eps: float = FD_EPS) -> np.ndarray:
    """Central finite-difference Jacobian ``(m, n)`` of ``f: (n,) -> (m,)`` at ``x``."""
    x = np.asarray(x, dtype=np.float64)
    f0 = np.atleast_1d(f(x))
    J = np.empty((f0.size, x.size))
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = eps
        J[:, i] = (np.atleast_1d(f(x + dx)) - np.atleast_1d(f(x - dx))) / (2.0 * eps)
    return J


def max_rel_err(value: np.ndarray, reference: np.ndarray) -> float:
    """``max |value - reference| / max(1, |reference|)`` elementwise."""
    value = np.asarray(value, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    assert value.shape == reference.shape, (value.shape, reference.shape)
    return float(np.max(np.abs(value - reference) / np.maximum(1.0, np.abs(reference))))


def random_rollout(env, seed: int, n: int = 60, action_seed: int = 0) -> list:
    """``env`` reset with ``seed``, then up to ``n`` steps of uniform actions in ``(-0.3, 0.3)`` drawn with
    ``action_seed``: the first observation and every step's observation with its reward appended (to compare
    trajectories for determinism)."""
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(action_seed)
    out = [obs]
    for _ in range(n):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-0.3, 0.3, 4).astype(np.float32))
        out.append(np.append(obs, reward))
        if terminated or truncated:
            break
    return out


def assert_same_datasets(a, b, ignore=()) -> None:
    """Two datasets (directories or ``episodes.npz``) hold the same arrays: episodes, boundaries, seeds and every
    ``infos`` key but those in ``ignore`` (e.g. the wall-clock ``solve_ms``)."""
    from hsddp_gym.datasets.storage import load_npz

    da, db = load_npz(a), load_npz(b)
    for k in ("observations", "actions", "rewards", "terminations", "truncations", "episode_starts",
              "episode_seeds"):
        np.testing.assert_array_equal(getattr(da, k), getattr(db, k), err_msg=k)
    assert set(da.infos) == set(db.infos)
    for k in set(da.infos) - set(ignore):
        np.testing.assert_array_equal(da.infos[k], db.infos[k], err_msg=k)


HEADLESS_HUMAN_RENDER_WARNING = "render_mode='human' needs an interactive matplotlib backend"
"""Gymnasium's checker renders in human mode; on a headless machine the envs warn that they cannot (expected)."""


def assert_gymnasium_checker_passes(env) -> None:
    """Gymnasium's env checker passes on ``env`` (its unwrapped env) with no warning but the headless one."""
    import warnings

    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    unexpected = [str(w.message) for w in caught if HEADLESS_HUMAN_RENDER_WARNING not in str(w.message)]
    assert not unexpected, unexpected


def assert_sb3_checker_passes(env) -> None:
    """Stable-Baselines3's env checker passes on ``env`` (unwrapped), every warning an error (skipped without SB3)."""
    import warnings

    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, warn=True)


@pytest.fixture(scope="session")
def tools() -> types.SimpleNamespace:
    """The helpers and constants above: ``tools.random_state(rng)``, ``tools.fd_jacobian(f, x)``, ..."""
    return types.SimpleNamespace(random_state=random_state, random_control=random_control, fd_jacobian=fd_jacobian,
                                 max_rel_err=max_rel_err, FD_EPS=FD_EPS, FD_TOL=FD_TOL, SEED=SEED, MODES=MODES,
                                 CONTACT_MODES=CONTACT_MODES, INTEGRATORS=INTEGRATORS,
                                 assert_same_datasets=assert_same_datasets, random_rollout=random_rollout,
                                 assert_gymnasium_checker_passes=assert_gymnasium_checker_passes,
                                 assert_sb3_checker_passes=assert_sb3_checker_passes)


@pytest.fixture(scope="session")
def experiment():
    """Load a script of ``experiments/`` as a module: ``experiment("push_gif").main([...])``."""
    import importlib.util
    import sys
    from pathlib import Path

    def load(name: str):
        path = Path(__file__).resolve().parents[1] / "experiments" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # so that its functions pickle into worker processes
        if str(path.parent) not in sys.path:  # and spawn-started workers import it by its name
            sys.path.append(str(path.parent))
        spec.loader.exec_module(module)
        return module

    return load
