"""A regression pin of the solver and the MPC loop: a closed-loop MPC episode, one with an action delay (latency
compensation through the contact-model predictor) and a one-shot al-reb solve give the numbers of the reference
recorded from the code: every optimization of the code's speed must leave these numbers bit-identical, and the
reference is re-recorded only when the MPC's default behaviour is meant to change.

Compared to round-off (``rtol`` 1e-9): on this machine the numbers are bit-identical; another CPU or BLAS may
round differently. The reference ``tests/data/mpc_speed_reference.npz`` is written (atomically) by running this
file as a script (``python tests/test_mpc_speed_equivalence.py``); only do so when a result is meant to change.
"""

from __future__ import annotations

import pathlib
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the env)
from hsddp_gym.envs.perturbations import ActionDelay
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.policies.mpc import MPCPolicy
from hsddp_gym.planners.tasks import heuristic_warm_start

REFERENCE = pathlib.Path(__file__).parent / "data" / "mpc_speed_reference.npz"
DEFAULT_STEPS = 300
DELAY_STEPS = 100
DELAY = 2


def mpc_episode(steps: int, delay: int, prefix: str) -> dict[str, np.ndarray]:
    """A seed-0 ``Bounding-v0`` episode of the default MPC (``delay`` > 0: behind an :class:`ActionDelay`).

    Returns, keyed ``prefix + name``: ``actions (steps, 4)`` float32, ``estimates (steps, 14)`` (the filtered state
    of every step), ``predictions (steps, 14)`` (the state each action was computed for) and per re-plan
    (r re-plans) the plan's ``objective (r,)``, ``U0 (r, 4)``, ``K0 (r, 4, 14)``, ``X_end (r, 14)``.
    """
    env = gym.make("hsddp_gym/Bounding-v0")
    if delay:
        env = ActionDelay(env, delay)
    policy = MPCPolicy.from_env(env)
    obs, _ = env.reset(seed=0)
    rec = {k: [] for k in ("actions", "estimates", "predictions", "objective", "U0", "K0", "X_end")}
    replans = 0
    for _ in range(steps):
        a = policy(obs)
        rec["actions"].append(a)
        rec["estimates"].append(policy.last_estimate)
        rec["predictions"].append(policy.last_prediction)
        if policy.stats["replans"] != replans:
            replans = policy.stats["replans"]
            sol = policy.last_solution
            rec["objective"].append(sol.objective)
            rec["U0"].append(sol.U[0])
            rec["K0"].append(sol.K[0])
            rec["X_end"].append(sol.X[-1])
        obs, _, terminated, truncated, _ = env.step(a)
        assert not (terminated or truncated), "the reference episode must not end early"
    env.close()
    return {prefix + k: np.array(v) for k, v in rec.items()}


def one_shot_solve() -> dict[str, np.ndarray]:
    """The al-reb solve of one bounding cycle (h = 1 ms) from the heuristic warm start: the outer AL loop, the line
    search's backtracking and the final gains, which the MPC's one-iteration re-plans never reach. Keys ``solve_*``:
    ``X (N+1, 14)``, ``U (N, 4)``, ``K (ceil(N / 8), 4, 14)`` (every 8th knot's gains), ``multipliers (n,)``,
    ``log (L, 13)`` (the numeric log)."""
    problem = HybridProblem.bounding(1)
    sol = HSDDP(SolverOptions()).solve(problem, heuristic_warm_start(problem).U)
    log = np.array([[r.al_iteration, r.ddp_iteration, r.objective, r.cost, r.al, r.barrier, r.switching_violation,
                     r.max_torque_violation, r.min_normal_grf, r.max_friction_violation, r.step, r.mu, r.expected]
                    for r in sol.log])
    return {"solve_X": sol.X, "solve_U": sol.U, "solve_K": sol.K[::8], "solve_multipliers": sol.multipliers,
            "solve_log": log}


def record() -> dict[str, np.ndarray]:
    """Everything the reference holds."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return {**mpc_episode(DEFAULT_STEPS, 0, "mpc_"), **mpc_episode(DELAY_STEPS, DELAY, "delay_"),
                **one_shot_solve()}


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    with np.load(REFERENCE, allow_pickle=False) as f:
        return dict(f)


@pytest.fixture(scope="module")
def current() -> dict[str, np.ndarray]:
    return record()


@pytest.mark.parametrize("prefix", ["mpc_", "delay_", "solve_"])
def test_matches_reference_to_round_off(reference, current, prefix):
    keys = sorted(k for k in reference if k.startswith(prefix))
    assert keys and keys == sorted(k for k in current if k.startswith(prefix))
    for k in keys:
        assert current[k].dtype == reference[k].dtype and current[k].shape == reference[k].shape, k
        scale = float(np.max(np.abs(reference[k]), initial=1.0))
        np.testing.assert_allclose(current[k], reference[k], rtol=1e-9, atol=1e-12 * scale, err_msg=k)


if __name__ == "__main__":
    from hsddp_gym.util.io import atomic_path

    with atomic_path(REFERENCE, suffix=".npz") as tmp:
        np.savez(tmp, **record())
    print(f"wrote {REFERENCE}", file=sys.stderr)
