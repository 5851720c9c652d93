"""Policies in the env: interfaces, plan tracking rules, the MPC's behaviour and failure handling."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.conventions import Mode
from planners.evaluation import run_episode, summarize
from planners.mpc import MPCOptions, MPCPolicy
from planners.policies import EnvInterface, HeuristicPolicy, PlanTrackingExpert, RandomPolicy
from planners.tasks import plan_bounding
from planners.tracking import PlanTracker


@pytest.fixture(scope="module")
def plan():
    return plan_bounding("al-reb", cycles=2).solution


def make_env(**kwargs):
    return gym.make("hsddp_gym/Bounding-v0", **kwargs)


# ------------------------------------------------------------------------------------------ interfaces
@pytest.mark.parametrize("name", ["heuristic", "random", "mpc"])
def test_policy_returns_normalized_float32_actions(name):
    env = make_env()
    policy = {"heuristic": HeuristicPolicy, "random": RandomPolicy, "mpc": MPCPolicy}[name].from_env(env)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        a = policy(obs)
        assert a.shape == (4,) and a.dtype == np.float32
        assert np.all(np.abs(a) <= 1.0)
        obs, *_ = env.step(a)


def test_predict_is_batched_and_matches_the_callable():
    env = make_env()
    obs, _ = env.reset(seed=3)
    single = HeuristicPolicy.from_env(env)
    batched = HeuristicPolicy.from_env(env)
    acts, state = batched.predict(np.stack([obs, obs]), episode_start=np.array([True, True]))
    assert acts.shape == (2, 4) and state is None
    np.testing.assert_array_equal(acts[0], single(obs))
    np.testing.assert_array_equal(acts[1], acts[0])
    a1, _ = batched.predict(obs)
    assert a1.shape == (4,)
    with pytest.raises(ValueError, match="observation"):
        batched.predict(np.zeros((2, 3)))


def test_sb3_evaluate_policy_runs_the_mpc():
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(make_env(max_episode_steps=30))
    policy = MPCPolicy.from_env(env)
    rewards, lengths = evaluate_policy(policy, env, n_eval_episodes=2, deterministic=True,
                                       return_episode_rewards=True)
    assert len(rewards) == 2 and all(n == 30 for n in lengths)


def test_env_interface_from_env_and_validation():
    env = make_env(frame_skip=4)
    it = EnvInterface.from_env(env)
    assert it.control_dt == pytest.approx(0.004) and it.torque_limit == 33.0
    np.testing.assert_allclose(it.action_from_torque([66.0, -66.0, 16.5, 0.0]), [1, -1, 0.5, 0])
    with pytest.raises(ValueError, match="control_dt"):
        EnvInterface(control_dt=0.0)
    with pytest.raises(TypeError, match="interface"):
        HeuristicPolicy(interface="env")


# ------------------------------------------------------------------------------------------ tracking
def _tracker(plan):
    return PlanTracker.from_solution(plan)


def test_tracker_follows_plan_time_and_its_feedback_law(plan):
    tr = _tracker(plan)
    x = plan.X[0] + 0.01
    np.testing.assert_allclose(tr.control(x), plan.U[0] + plan.K[0] @ np.r_[0.0, (x - plan.X[0])[1:]])
    tr.advance(0.0105)
    assert tr.knot == 10 and tr.phase == 0


def test_tracker_jumps_on_early_touchdown(plan):
    tr = _tracker(plan)
    tr.advance(0.08 + 0.02)  # 20 ms into the first flight (front foot lands next)
    assert tr.modes[tr.phase] == Mode.FLIGHT
    tr.sync(Mode.BACK_STANCE)  # the back foot again: not the landing foot, ignored
    assert tr.phase == 1
    tr.sync(Mode.FRONT_STANCE)
    assert tr.phase == 2 and tr.local_time == 0.0


def test_tracker_waits_for_a_late_touchdown(plan):
    tr = _tracker(plan)
    tr.advance(0.08 + 0.05)
    for _ in range(10):
        tr.advance(0.005)  # far past the flight's end
    assert tr.phase == 1 and tr.knot == plan.phase_start[2] - 1
    tr.sync(Mode.FRONT_STANCE)
    assert tr.phase == 2


def test_tracker_finishes_at_the_touchdown_that_ends_the_plan(plan):
    tr = _tracker(plan)
    assert tr.modes[-1] == Mode.FLIGHT and tr.next_modes[-1] == Mode.BACK_STANCE
    tr.phase = tr.n_phases - 1  # the last flight
    tr.advance(0.2)  # far past its end: waits on its last knot
    assert not tr.finished and tr.phase == tr.n_phases - 1
    tr.sync(Mode.FRONT_STANCE)  # not the landing foot
    assert not tr.finished
    tr.sync(Mode.BACK_STANCE)
    assert tr.finished


def test_tracker_lift_off_follows_plan_time(plan):
    tr = _tracker(plan)
    tr.sync(Mode.BACK_STANCE)
    tr.advance(0.085)
    assert tr.modes[tr.phase] == Mode.FLIGHT  # no waiting at the end of a stance


# ------------------------------------------------------------------------------------------ expert, MPC
def test_expert_tracks_its_plan_in_the_env(plan):
    env = make_env(reset_noise_scale=0.0)
    expert = PlanTrackingExpert.from_env(env, solution=plan)
    steps = int(round(plan.times[-1] / env.unwrapped.dt))
    res = run_episode(env, expert, 0, options={"state": plan.X[0]}, max_steps=steps)
    assert not res.fell and res.length == steps
    assert abs(res.states[-1, 0] - plan.X[-1, 0]) < 0.05  # within 5 cm of the plan after 2 cycles
    assert np.mean(expert.errors) < 0.1


def test_expert_hands_over_to_its_fallback_after_the_plan(plan):
    env = make_env(reset_noise_scale=0.0)
    fallback = MPCPolicy.from_env(env)
    expert = PlanTrackingExpert.from_env(env, solution=plan, fallback=fallback)
    steps = int(round(plan.times[-1] / env.unwrapped.dt))
    res = run_episode(env, expert, 0, options={"state": plan.X[0]}, max_steps=steps + 120)
    assert expert.tracker.finished and fallback.stats["replans"] > 0
    assert not res.fell and res.length == steps + 120


def test_mpc_bounds_deterministically():
    env = make_env()
    policy = MPCPolicy.from_env(env)
    a = run_episode(env, policy, 4, max_steps=200)
    b = run_episode(env, MPCPolicy.from_env(env), 4, max_steps=200)
    assert not a.fell and a.length == 200
    np.testing.assert_array_equal(a.actions, b.actions)
    s = summarize([a])
    assert s["replans"] == 50 and s["planner_failures"] == 0
    assert 0.85 < s["mean_forward_speed"] < 1.15


def test_mpc_survives_planner_failures(monkeypatch):
    env = make_env()
    policy = MPCPolicy.from_env(env)
    obs, _ = env.reset(seed=0)
    for _ in range(8):
        obs, *_ = env.step(policy(obs))
    calls = {"n": 0}

    def broken(*args, **kwargs):
        calls["n"] += 1
        raise RuntimeError("solver exploded")

    monkeypatch.setattr(policy._solver, "solve", broken)
    for _ in range(12):
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
    assert calls["n"] >= 2 and policy.stats["planner_failures"] >= 2
    assert policy.tracker is not None  # the last valid plan keeps acting


def test_mpc_latency_delays_the_new_plan():
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions(latency_steps=2))
    res = run_episode(env, policy, 1, max_steps=60)
    assert not res.fell and policy.stats["replans"] >= 10


def test_mpc_options_are_validated():
    with pytest.raises(ValueError, match="replan_period"):
        MPCOptions(replan_period=0.0)
    with pytest.raises(ValueError, match="method"):
        MPCOptions(method="ilqr")
    with pytest.raises(ValueError, match="durations"):
        MPCOptions(durations=(0.1, 0.1))
    with pytest.raises(TypeError, match="options"):
        MPCPolicy(options={"horizon": 0.3})
    assert dataclasses.replace(MPCOptions(), max_iterations=5).max_iterations == 5
