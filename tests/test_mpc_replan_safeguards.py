"""The MPC's re-plan safeguards and its raised gait: the augmented Lagrangian's multipliers are not updated between
re-plans (each keeps the ones it was warm-started with), a warm-started re-plan that ends far above the previous plan's
objective is solved again from scratch (``MPCOptions.restart_ratio``), and the plans' reference postures stand the
trunk 4 cm higher than the authors' with the feet where theirs are (``height_offset``,
:func:`hsddp_gym.core.references.end_of_mode_reference`)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.conventions import BACK, FRONT, IZ, NQ, Mode
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.references import end_of_mode_reference
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController
from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy, shift_plan
from hsddp_gym.rollout.episodes import run_episode


@pytest.mark.parametrize("mode, foot", [(Mode.BACK_STANCE, None), (Mode.FRONT_STANCE, None), (Mode.FLIGHT, FRONT),
                                        (Mode.FLIGHT, BACK)])
def test_raised_posture_keeps_the_feet_and_the_pitch(mode, foot):
    model = CheetahModel()
    base = end_of_mode_reference(mode, foot, 1.0)
    raised = end_of_mode_reference(mode, foot, 1.0, height_offset=0.04)
    assert raised[IZ] == pytest.approx(base[IZ] + 0.04, abs=1e-15)
    assert raised[2] == base[2] and np.array_equal(raised[NQ:], base[NQ:])
    np.testing.assert_allclose(model.foot_positions(raised[:NQ]), model.foot_positions(base[:NQ]), atol=1e-10)
    assert not np.allclose(raised[3:NQ], base[3:NQ])  # the legs are extended to reach them
    assert np.array_equal(end_of_mode_reference(mode, foot, 1.0, height_offset=0.0), base)


def test_height_offset_reaches_the_plans_and_the_warm_start_and_is_validated():
    raised = HybridProblem.bounding(1, height_offset=0.04)
    base = HybridProblem.bounding(1)
    np.testing.assert_allclose(raised.XF[:, IZ], base.XF[:, IZ] + 0.04, atol=1e-12)
    ctrl = HeuristicBoundingController(height_offset=0.04)
    assert ctrl._land[FRONT][IZ] == pytest.approx(HeuristicBoundingController()._land[FRONT][IZ] + 0.04)
    for bad in (0.2, float("nan"), "4 cm", True):
        with pytest.raises((ValueError, TypeError), match="height_offset"):
            end_of_mode_reference(Mode.FLIGHT, FRONT, 1.0, height_offset=bad)
        with pytest.raises((ValueError, TypeError), match="height_offset"):
            MPCOptions().replace(height_offset=bad)
    for bad in (1.0, 0.5, -2.0, float("inf")):
        with pytest.raises(ValueError, match="restart_ratio"):
            MPCOptions().replace(restart_ratio=bad)


def _bounding_mpc(steps: int = 60, **options) -> tuple[MPCPolicy, np.ndarray]:
    """The MPC with ``options`` after ``steps`` control steps of seed 0 of ``Bounding-v0`` (steady re-plans), and the
    state (14,) of its last action."""
    env = gym.make("hsddp_gym/Bounding-v0")
    policy = MPCPolicy.from_env(env, options=MPCOptions().replace(**options))
    obs, _ = env.reset(seed=0)
    for _ in range(steps):
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
    env.close()
    return policy, policy.last_prediction.copy()


def _kick(x: np.ndarray) -> np.ndarray:
    """``x`` (14,) after a push: 0.5 m/s up, a nose-up kick of 4 rad/s."""
    x = x.copy()
    x[NQ + IZ] += 0.5
    x[NQ + 2] -= 4.0
    return x


@pytest.mark.parametrize("feedback", [False, True])
def test_a_replan_passes_on_the_multipliers_it_was_warm_started_with(feedback):
    """Whatever the solver does with them, a warm-started re-plan passes on the multipliers of its warm start (the
    previous plan's, shifted phase by phase): no outer-loop update is carried from one re-plan to the next, so a
    touchdown that cannot be met does not wind them up. A periodic re-plan makes no update; a feedback re-plan solved
    further updates them between its outer iterations and keeps the plan, not the updates."""
    policy, x = _bounding_mpc(restart_ratio=None)
    x = _kick(x)
    previous = policy.law.plan
    schedule = policy.schedule.schedule(x)
    problem = policy.planner.problem(x, schedule, policy.speed.plan_speed(x), 0.0)
    warm = shift_plan(problem, x, previous.tracker, previous.solution, previous.multipliers)
    assert warm is not None and np.abs(warm[3]).max() > 0
    plan = policy.planner.plan(x, schedule, policy.speed.plan_speed(x), 0.0, previous, feedback=feedback)
    assert plan is not None and (plan.solution.ddp_iterations > 1) == feedback
    np.testing.assert_array_equal(plan.multipliers, warm[3])
    solved = policy.planner._solver.last_constraint_state.lam
    if feedback:
        assert not np.array_equal(solved, warm[3])  # the outer loop ran
    else:
        np.testing.assert_array_equal(solved, warm[3])


def test_a_warm_start_gone_far_off_is_solved_again_and_the_better_plan_kept():
    """``restart_ratio``: a warm-started re-plan whose objective ends above 10 times the previous plan's is solved
    again from scratch, and the plan with the lower objective is kept (its solver then holds the outer-loop state);
    below the ratio, or with the ratio None, nothing is restarted."""
    import dataclasses

    policy, x = _bounding_mpc()
    x = _kick(x)
    planner, previous = policy.planner, policy.law.plan
    schedule = policy.schedule.schedule(x)
    args = (x, schedule, policy.speed.plan_speed(x), 0.0)
    assert planner.stats["restarts"] == 0
    low = dataclasses.replace(previous, solution=dataclasses.replace(previous.solution, objective=1e-3))
    solver = planner._solver
    warm = planner.plan(*args, previous, feedback=False)  # the same warm start, the true previous objective
    assert planner.stats["restarts"] == 0
    planner._solver = solver
    plan = planner.plan(*args, low, feedback=False)
    assert planner.stats["restarts"] == 1
    kept = planner.stats["restarts_kept"] == 1
    assert plan.solution.objective <= warm.solution.objective
    assert kept == (plan.solution.objective < warm.solution.objective) and (planner._solver is not solver) == kept
    off, x_off = _bounding_mpc(restart_ratio=None)
    off.planner.plan(_kick(x_off), off.schedule.schedule(_kick(x_off)), 1.0, 0.0,
                     dataclasses.replace(off.law.plan, solution=dataclasses.replace(off.law.plan.solution,
                                                                                    objective=1e-3)))
    assert off.stats["restarts"] == 0


def test_unpushed_bounding_never_restarts():
    env = gym.make("hsddp_gym/Bounding-v0")
    policy = MPCPolicy.from_env(env)
    result = run_episode(env, policy, 0, max_steps=300)
    assert not result.fell and policy.stats["replans"] >= 70
    assert policy.stats["restarts"] == 0
