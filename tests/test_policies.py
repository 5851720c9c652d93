"""Policies in the env: interfaces (callable, SB3 predict with batched observations, SB3 BasePolicy adapter),
acting from observations alone, plan tracking rules, the MPC's behaviour and failure handling, and the
``rollout`` / ``demo`` commands."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym import cli
from hsddp_gym.core.conventions import Mode
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.experts import bounding_expert
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy
from hsddp_gym.planners.policies.random_policy import RandomPolicy
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.planners.tasks import plan_bounding
from hsddp_gym.rollout.episodes import run_episode, summarize


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


ALL_POLICIES = ("heuristic", "random", "mpc", "expert")


def _build(name, interface, plan):
    """``(policy, reset options)`` of each kind, built from the env's public settings only."""
    if name == "heuristic":
        return HeuristicPolicy(interface), None
    if name == "random":
        return RandomPolicy(interface, seed=7), None
    if name == "mpc":
        return MPCPolicy(interface), None
    return bounding_expert(interface, plan), {"state": plan.X[0]}


@pytest.mark.parametrize("name", ALL_POLICIES)
def test_sb3_base_policy_adapter_returns_the_callables_actions(name, plan):
    from stable_baselines3.common.policies import BasePolicy

    from hsddp_gym.learning.sb3 import as_sb3_policy

    env = make_env(max_episode_steps=40)
    interface = EnvInterface.from_env(env)
    reference, options = _build(name, interface, plan)
    adapted = as_sb3_policy(_build(name, interface, plan)[0], env.observation_space, env.action_space)
    assert isinstance(adapted, BasePolicy)
    obs, _ = env.reset(seed=2, options=options)
    reference.reset()
    for t in range(40):
        expected = reference(obs)
        got, state = adapted.predict(obs[None], episode_start=np.array([t == 0]), deterministic=True)
        assert got.shape == (1, 4) and got.dtype == np.float32 and state is None
        np.testing.assert_array_equal(got[0], expected, err_msg=f"{name}, step {t}")
        obs, _, terminated, truncated, _ = env.step(expected)
        if terminated or truncated:
            break


@pytest.mark.parametrize("name", ["heuristic", "mpc"])
def test_evaluate_policy_on_a_vec_env_keeps_one_policy_copy_per_env(name, plan):
    """Batched observations (2 envs): each env's episode equals the callable's episode on that env's seed."""
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = DummyVecEnv([lambda: Monitor(make_env(max_episode_steps=25)) for _ in range(2)])
    venv.seed(10)  # env i is reset with seed 10 + i
    policy, _ = _build(name, EnvInterface.from_env(venv.envs[0]), plan)
    rewards, lengths = evaluate_policy(policy, venv, n_eval_episodes=2, deterministic=True,
                                       return_episode_rewards=True)
    assert len(policy._copies) == 2 and policy._copies[0] is not policy._copies[1]
    env = make_env(max_episode_steps=25)
    alone = [run_episode(env, _build(name, EnvInterface.from_env(env), plan)[0], seed) for seed in (10, 11)]
    np.testing.assert_allclose(rewards, [r.episode_return for r in alone], rtol=1e-6)
    assert lengths == [r.length for r in alone]


@pytest.mark.parametrize("name", ["heuristic", "mpc", "expert"])
def test_policies_act_from_the_observation_alone(name, plan):
    """A twin built from the env's public settings, never given the env, fed only the recorded observations
    (after the env has moved on and been closed) reproduces every action: nothing is read from the simulator."""
    env = make_env(max_episode_steps=60)
    interface = EnvInterface.from_env(env)
    policy, options = _build(name, interface, plan)
    obs, _ = env.reset(seed=5, options=options)
    policy.reset()
    observations, actions = [], []
    for _ in range(60):
        observations.append(obs.copy())
        actions.append(policy(obs))
        obs, _, terminated, truncated, _ = env.step(actions[-1])
        if terminated or truncated:
            break
    env.reset(seed=99)
    env.close()
    twin, _ = _build(name, interface, plan)
    twin.reset()
    np.testing.assert_array_equal(np.stack([twin(o) for o in observations]), np.stack(actions))


def test_rendering_time_is_not_counted_in_the_real_time_factor():
    import time

    class SlowRender(gym.Wrapper):
        def render(self):
            time.sleep(0.01)
            return np.zeros((8, 8, 3), dtype=np.uint8)

    env = SlowRender(make_env(max_episode_steps=10))
    res = run_episode(env, HeuristicPolicy.from_env(env), 0, render=True)
    assert len(res.frames) == 11 and res.wall_time < 0.05


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
    expert = bounding_expert(EnvInterface.from_env(env), plan)
    steps = int(round(plan.times[-1] / env.unwrapped.dt))
    res = run_episode(env, expert, 0, options={"state": plan.X[0]}, max_steps=steps)
    assert not res.fell and res.length == steps
    assert abs(res.states[-1, 0] - plan.X[-1, 0]) < 0.05  # within 5 cm of the plan after 2 cycles
    assert np.mean(expert.errors) < 0.1
    # the recorded nominal states are the plan's, one per tracked step, and the errors are their distances
    nominal = np.array(expert.nominal_states)
    assert nominal.shape == (len(expert.errors), 14)
    assert np.all(np.isin(nominal[:, 1], plan.X[:, 1]))
    err = np.linalg.norm(res.states[:len(nominal), 1:7] - nominal[:, 1:7], axis=1)
    np.testing.assert_allclose(expert.errors, err, rtol=1e-5, atol=1e-6)  # observations are float32


def test_expert_hands_over_to_its_fallback_after_the_plan(plan):
    env = make_env(reset_noise_scale=0.0)
    fallback = MPCPolicy.from_env(env)
    expert = bounding_expert(EnvInterface.from_env(env), plan, fallback=fallback)
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
    # every 20 ms (50 in 200 steps), plus one at once when the start-up stance is lost and the clock resyncs
    assert 50 <= s["replans"] <= 52 and s["planner_failures"] == 0
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

    monkeypatch.setattr(policy.planner._solver, "solve", broken)
    for _ in range(12):
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
    assert calls["n"] >= 2 and policy.stats["planner_failures"] >= 2
    assert policy.law.plan is not None  # the last valid plan keeps acting


def test_mpc_replans_from_scratch_with_the_first_plans_iterations(monkeypatch):
    """A re-plan the previous plan cannot warm-start (its phases do not cover the new schedule) is solved from
    scratch with ``warmup_iterations``, not the shifted plan's ``max_iterations``; when the heuristic's rollout
    that warm-starts it diverges, it starts from zero torques instead of failing."""
    env = make_env()
    policy = MPCPolicy.from_env(env)
    obs, _ = env.reset(seed=0)
    for _ in range(8):
        obs, *_ = env.step(policy(obs))
    assert set(policy.stats["iterations"][1:]) == {1}  # shifted plans: one iteration each
    import hsddp_gym.core.rollout
    import hsddp_gym.planners.policies.mpc.planner as planner_module

    monkeypatch.setattr(planner_module, "shift_plan", lambda *args: None)

    def diverged(*args, **kwargs):
        raise RuntimeError("heuristic warm start diverged")

    monkeypatch.setattr(hsddp_gym.core.rollout, "rollout", diverged)
    n = len(policy.stats["iterations"])
    for _ in range(4):
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
    assert len(policy.stats["iterations"]) == n + 1 and policy.stats["planner_failures"] == 0
    assert policy.stats["iterations"][-1] > policy.options.replan.iterations


def test_mpc_counts_replans_stopped_by_the_time_budget():
    """A re-plan that hits ``time_budget`` uses its best iterate (any-time MPC) and is counted, not hidden."""
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions().replace(time_budget=1e-6))
    res = run_episode(env, policy, 0, max_steps=20)
    assert res.length == 20
    assert policy.stats["time_budget_stops"] >= 1
    assert policy.stats["time_budget_stops"] <= policy.stats["replans"]
    # an exception other than the solver's numerical ones is a bug and propagates
    policy.reset()
    policy.planner._solver.solve = lambda *a, **k: (_ for _ in ()).throw(KeyError("bug"))
    obs, _ = env.reset(seed=0)
    with pytest.raises(KeyError):
        policy(obs)


def test_mpc_options_are_validated():
    with pytest.raises(ValueError, match="period"):
        MPCOptions().replace(replan_period=0.0)
    with pytest.raises(ValueError, match="no setting 'method'"):
        MPCOptions().replace(method="ilqr")
    with pytest.raises(ValueError, match="durations"):
        MPCOptions().replace(durations=(0.1, 0.1))
    with pytest.raises(TypeError, match="options"):
        MPCPolicy(options={"horizon": 0.3})
    assert MPCOptions().replace(max_iterations=5).replan.iterations == 5


# ------------------------------------------------------------------------------------------ CLI
SUMMARY_KEYS = ("mean_return", "std_return", "falls", "mean_forward_speed", "mean_episode_length",
                "real_time_factor", "replans", "planner_failures", "mean_replan_ms")


@pytest.mark.parametrize("name", ALL_POLICIES)
def test_cli_rollout_writes_the_summary_and_the_gif(name, tmp_path, capsys):
    out = tmp_path / name
    argv = ["rollout", "--policy", name, "--episodes", "2", "--seed", "3", "--max-episode-steps", "24",
            "--out", str(out), "--quiet"]
    video = name in ("mpc", "random")
    assert cli.main(argv + (["--video"] if video else [])) == 0
    s = json.loads((out / "summary.json").read_text())
    for k in SUMMARY_KEYS:
        assert k in s, k
        if k != "mean_replan_ms" or name == "mpc":  # None for policies that did not re-plan
            assert s[k] is not None and np.isfinite(s[k]), (k, s[k])
    assert s["episodes"] == 2 and s["seeds"] == [3, 4] and s["real_time_factor"] > 0
    assert s["max_episode_steps"] == 24 and s["mean_episode_length"] <= 24
    if name == "mpc":
        assert s["replans"] >= 2 * 6 and s["planner_failures"] == 0 and s["mean_replan_ms"] > 0
        assert s["falls"] == 0 and s["mean_episode_length"] == 24
    else:  # no planner (the expert tracks its offline plan for 1.48 s before its MPC fallback re-plans)
        assert s["replans"] == 0 and s["planner_failures"] == 0 and s["mean_replan_ms"] is None
    printed = capsys.readouterr().out
    assert all(k in printed for k in SUMMARY_KEYS)
    if video:
        from PIL import Image

        assert s["video"] == "episode0.gif"
        with Image.open(out / "episode0.gif") as gif:
            assert gif.n_frames >= 2
    else:
        assert not (out / "episode0.gif").exists()


def test_cli_rollout_after_a_push(tmp_path):
    """``--push``: the default MPC runs the pushed episode and the summary records the push."""
    out = tmp_path / "push"
    argv = ["rollout", "--policy", "mpc", "--episodes", "1", "--seed", "103",
            "--push", "1.0", "0", "0", "10", "--max-episode-steps", "260", "--out", str(out), "--quiet"]
    assert cli.main(argv) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["push"] == {"delta_v": [0.0, 0.0, 10.0], "time": 1.0} and s["episodes"] == 1
    assert s["replans"] > 0 and s["falls"] in (0, 1)


def test_cli_demo_plans_with_hsddp_and_runs_the_mpc(tmp_path):
    out = tmp_path / "demo"
    assert cli.main(["demo", "--cycles", "1", "--episodes", "1", "--max-episode-steps", "20", "--no-video",
                     "--quiet", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["hsddp_plan"]["method"] == "al-reb" and s["hsddp_plan"]["ddp_iterations"] > 0
    mpc = s["mpc_in_env"]
    assert mpc["policy"] == "mpc" and mpc["replans"] > 0 and mpc["mean_episode_length"] == 20
    for name in ("motion.png", "states.png", "convergence.png", "solution.npz", "mpc/summary.json"):
        assert (out / name).exists(), name
