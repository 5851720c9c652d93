"""The MPC's push recovery (``MPCOptions(recovery=True)``): off by default, triggered only by a plan deviation
above its threshold, an immediate re-plan with more iterations, and the heuristic acting after a failed
recovery re-plan."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.conventions import Mode
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.evaluation import run_episode
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy

ARMED = 110
"""Control steps (0.55 s) after which the recovery is armed (``recovery_after`` = 0.5 s)."""


GRID_5MS_NO_INTEGRAL = {"planner_dt": 0.005, "speed_integral_gain": None}
"""The MPC the push recovery and its tests were built on: the 5 ms planner grid, no integral speed action."""


def make_env():
    return gym.make("hsddp_gym/Bounding-v0")


def run(env, policy, obs, steps):
    actions = []
    for _ in range(steps):
        a = policy(obs)
        actions.append(a)
        obs, _, terminated, _, _ = env.step(a)
        assert not terminated
    return obs, np.array(actions)


def test_recovery_is_off_by_default_and_validated():
    o = MPCOptions()
    assert o.recovery is False and o.recovery_fallback and not o.recovery_handover
    robust = MPCOptions.push_recovery()
    assert robust.recovery and robust.planner_dt == 0.0025 and robust.max_iterations == o.max_iterations
    assert MPCOptions.push_recovery(recovery_window=0.4).recovery_window == 0.4
    with pytest.raises(ValueError, match="recovery_iterations"):
        MPCOptions(recovery_iterations=0)
    with pytest.raises(ValueError, match="recovery_threshold"):
        MPCOptions(recovery_threshold=0.0)
    with pytest.raises(ValueError, match="recovery_window"):
        MPCOptions(recovery_window=-0.1)
    assert MPCPolicy().plan_deviation(np.zeros(14)) == 0.0  # no plan yet


def test_recovery_does_not_change_unpushed_bounding():
    """Without a push the deviation stays under the threshold: the same actions as the plain MPC."""
    env = make_env()
    plain, rec = MPCPolicy.from_env(env), MPCPolicy.from_env(env, options=MPCOptions(recovery=True))
    obs, _ = env.reset(seed=0)
    _, a_plain = run(env, plain, obs, ARMED + 20)
    obs, _ = env.reset(seed=0)
    _, a_rec = run(env, rec, obs, ARMED + 20)
    assert rec.stats["recoveries"] == 0 and rec.stats["fallback_steps"] == 0
    np.testing.assert_array_equal(a_plain, a_rec)


def test_recovery_triggers_only_above_threshold_and_replans_at_once():
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions(recovery=True))
    obs, _ = env.reset(seed=0)
    obs, _ = run(env, policy, obs, ARMED)
    obs = env.unwrapped.apply_push([0.2, 0.0, 0.0])  # small: below the 0.5 m/s threshold
    obs, _ = run(env, policy, obs, 6)
    assert policy.stats["recoveries"] == 0
    while policy._since_replan >= policy.options.replan_period - 2 * policy.interface.control_dt:
        obs, _ = run(env, policy, obs, 1)  # stand right after a periodic re-plan
    obs = env.unwrapped.apply_push([-1.5, 0.0, 0.0])
    x, _, _ = policy._parse(obs)
    assert policy.plan_deviation(x) > policy.options.recovery_threshold
    n = policy.stats["replans"] + policy.stats["planner_failures"]
    policy(obs)
    assert policy.stats["recoveries"] == 1 and policy.recovering
    assert policy.stats["replans"] + policy.stats["planner_failures"] == n + 1  # no wait for the period
    if policy.stats["replans"] > 0 and policy.stats["iterations"]:
        assert policy.stats["iterations"][-1] <= policy.options.recovery_iterations


def test_failed_recovery_replans_hand_over_to_the_heuristic(monkeypatch):
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions(recovery=True))
    obs, _ = env.reset(seed=0)
    obs, _ = run(env, policy, obs, ARMED)

    def broken(*args, **kwargs):
        raise RuntimeError("solver exploded")

    monkeypatch.setattr(policy._solver, "solve", broken)
    obs = env.unwrapped.apply_push([-1.0, 0.0, 0.0])
    obs, _ = run(env, policy, obs, 10)
    assert policy.stats["recoveries"] == 1 and policy.stats["planner_failures"] >= 1
    assert policy.stats["fallback_steps"] >= 9  # the heuristic acts, the episode goes on


def test_speed_governor_and_lost_stance_rule_survive_a_push_the_mpc_without_them_falls_after():
    """Seed 100, ``[-1.5, 0, 0]`` at t = 1 s: without the speed reference governor (``speed_ramp``) and the
    lost-stance rule (``lost_stance_steps``) the MPC falls within 0.5 s of the push; with them it bounds on."""
    push = {"push": {"delta_v": [-1.5, 0.0, 0.0], "time": 1.0}}
    env = make_env()
    # pinned to the MPC these two mechanisms were measured on (GRID_5MS_NO_INTEGRAL): with today's defaults (the
    # 2.5 ms grid and the integral speed action together) the MPC falls on this one push (about twice the suite's
    # largest); with either of the two alone it survives it
    base = GRID_5MS_NO_INTEGRAL
    bare = run_episode(env, MPCPolicy.from_env(env, options=MPCOptions(speed_ramp=None, lost_stance_steps=0, **base)),
                       100, options=push, max_steps=300)
    assert bare.fell and bare.length < 300
    default = run_episode(env, MPCPolicy.from_env(env, options=MPCOptions(**base)), 100, options=push, max_steps=300)
    assert not default.fell


def test_speed_governor_and_lost_stance_rule_leave_unpushed_bounding_unchanged():
    """While bounding, the speed stays within ``speed_ramp`` of the target and no stance foot lifts early: the
    same actions as without either mechanism (the start-up's speed rate limit, which does act, off in both)."""
    env = make_env()
    bare = MPCPolicy.from_env(env, options=MPCOptions(speed_ramp=None, lost_stance_steps=0, speed_acceleration=None))
    obs, _ = env.reset(seed=1)
    _, a_bare = run(env, bare, obs, 200)
    obs, _ = env.reset(seed=1)
    _, a_default = run(env, MPCPolicy.from_env(env, options=MPCOptions(speed_acceleration=None)), obs, 200)
    np.testing.assert_array_equal(a_bare, a_default)


def test_plan_speed_is_the_target_moved_at_most_speed_ramp_from_the_measured_speed():
    x = np.zeros(14)
    policy = MPCPolicy()  # target 1.0 m/s, speed_ramp 0.5
    for vx, expected in ((1.2, 1.0), (0.6, 1.0), (-0.5, 0.0), (2.5, 2.0)):
        x[7] = vx
        assert policy.plan_speed(x) == pytest.approx(expected)
    assert MPCPolicy(options=MPCOptions(speed_ramp=None)).plan_speed(x) == 1.0
    assert MPCPolicy().weights == "paper"
    assert MPCPolicy(EnvInterface(target_speed=2.0)).weights == "paper"  # one gait at every speed
    assert MPCPolicy(EnvInterface(target_speed=2.0), MPCOptions(weights="later")).weights == "later"
    for bad in ({"speed_ramp": 0.0}, {"speed_ramp": -1.0}, {"lost_stance_steps": -1}, {"lost_stance_steps": 1.5},
                {"weights": "mine"}):
        with pytest.raises((ValueError, TypeError), match=next(iter(bad))):
            MPCOptions(**bad)


def test_recovery_ends_a_flight_at_any_touchdown_of_its_landing_foot_only_inside_the_window():
    """``recovery_min_flight`` replaces the clock's ``min_flight`` while recovering, and only then."""
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions(recovery=True))
    x = np.zeros(14)
    policy._update_clock(Mode.FLIGHT, x)
    assert policy.clock.min_flight == policy.options.min_flight == 0.3
    policy._recovery_until = policy._time + 0.1
    policy._update_clock(Mode.FLIGHT, x)
    assert policy.recovering and policy.clock.min_flight == 0.0
    policy._time += 0.2
    policy._update_clock(Mode.FLIGHT, x)
    assert not policy.recovering and policy.clock.min_flight == 0.3
    keep = MPCPolicy.from_env(env, options=MPCOptions(recovery=True, recovery_min_flight=None))
    keep._recovery_until = 1.0
    keep._update_clock(Mode.FLIGHT, x)
    assert keep.recovering and keep.clock.min_flight == 0.3
    with pytest.raises(ValueError, match="recovery_min_flight"):
        MPCOptions(recovery_min_flight=1.5)


NOSE_DOWN = {"push": {"delta_v": [0.0, 0.0, 10.0], "time": 1.0}}
"""A +10 rad/s nose-down pitch-rate push at t = 1 s (seed 103: in the back stance)."""


def test_a_nose_down_push_the_heuristic_does_not_survive_the_recovering_mpc_does_on_its_own():
    """Seed 103: the contact-event heuristic falls after the push; the MPC with ``recovery=True`` bounds on
    without the heuristic fallback ever acting. Without ``recovery_min_flight`` (the clock takes the front
    foot's touchdown 5-10 ms after the back foot's lift-off for a graze) the MPC falls too.

    Pinned to what the recovery was built and measured on: the legacy contact scheme (``energy_consistent=False``;
    with the energy-consistent default the recovering MPC survives seed 103 too but hands 16 control steps to the
    heuristic fallback) and the MPC without the state filter, the start-up speed rate limit and the friction
    margin (with them it bounds on too, with the fallback acting for some steps)."""
    env = gym.make("hsddp_gym/Bounding-v0", energy_consistent=False)
    heuristic = run_episode(env, HeuristicPolicy.from_env(env), 103, options=NOSE_DOWN, max_steps=300)
    assert heuristic.fell
    base = {"state_filter": False, "speed_acceleration": None, "plan_friction": None, **GRID_5MS_NO_INTEGRAL}
    mpc = MPCPolicy.from_env(env, options=MPCOptions(recovery=True, **base))
    res = run_episode(env, mpc, 103, options=NOSE_DOWN, max_steps=300)
    assert not res.fell and res.length == 300
    assert mpc.stats["recoveries"] >= 1 and mpc.stats["fallback_steps"] == 0
    today = run_episode(env, MPCPolicy.from_env(env, options=MPCOptions(recovery=True, **GRID_5MS_NO_INTEGRAL)), 103,
                        options=NOSE_DOWN, max_steps=300)
    assert not today.fell
    graze = run_episode(env, MPCPolicy.from_env(env, options=MPCOptions(recovery=True, recovery_min_flight=None,
                                                                        **base)),
                        103, options=NOSE_DOWN, max_steps=300)
    assert graze.fell


def test_a_downward_push_in_the_back_stance_is_caught_by_a_planned_double_stance():
    """Seed 100, ``[0, -1.5, 0]`` at t = 1 s (mid back stance): the trunk sinks at 1.4 m/s; the recovering MPC
    plans back stance -> double stance -> front stance, reaches the front foot down and bounds on by itself.
    Without the double stance (``recovery_double_stance=None``) it plans a flight, the front foot stays up and
    the trunk falls below the healthy height at about 1.1 s."""
    push = {"push": {"delta_v": [0.0, -1.5, 0.0], "time": 1.0}}
    env = make_env()
    mpc = MPCPolicy.from_env(env, options=MPCOptions(recovery=True, **GRID_5MS_NO_INTEGRAL))
    modes = []
    solve = mpc.replan

    def replan(x, mode):
        ok = solve(x, mode)
        if ok:
            modes.append(tuple(mpc._pending[1].schedule.modes[:3]))
        return ok

    mpc.replan = replan
    res = run_episode(env, mpc, 100, options=push, max_steps=300)
    assert not res.fell and mpc.stats["fallback_steps"] == 0
    assert (Mode.BACK_STANCE, Mode.DOUBLE_STANCE, Mode.FRONT_STANCE) in modes
    single = run_episode(env, MPCPolicy.from_env(env, options=MPCOptions(recovery=True, recovery_double_stance=None,
                                                                         **GRID_5MS_NO_INTEGRAL)),
                         100, options=push, max_steps=300)
    assert single.fell and single.length < 250
    with pytest.raises(ValueError, match="recovery_double_stance"):
        MPCOptions(recovery_double_stance=0.0)


def test_push_robustness_experiment_records_every_episode(tmp_path, experiment):
    """``experiments/push_robustness.py``: per-episode records, totals, the same results with 2 workers."""
    import json

    push = experiment("push_robustness")
    argv = ["--policies", "heuristic", "mpc-recovery", "--push", "0", "0", "10", "--seeds", "1", "--first-seed",
            "103", "--times", "1.0", "--steps", "240"]
    assert push.main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert push.main(argv + ["--out", str(tmp_path / "b"), "--workers", "2"]) == 0
    a = json.loads((tmp_path / "a" / "push_robustness.json").read_text())
    b = json.loads((tmp_path / "b" / "push_robustness.json").read_text())
    assert a["results"] == b["results"] and a["push_times_s"] == [1.0]
    cells = {p: a["results"][p]["[+0, +0, +10]"] for p in ("heuristic", "mpc-recovery")}
    assert cells["heuristic"]["falls"] == 1
    # (the push-recovery preset on today's base -- state filter, speed rate limit, friction margin -- falls on this
    # push; on the base it was built on it bounded on)
    run = cells["mpc-recovery"]["runs"][0]
    assert run["seed"] == 103 and cells["mpc-recovery"]["falls"] == int(run["fell"])
    assert (run["fall_time_s"] is None) == (not run["fell"])
    table = (tmp_path / "a" / "push_robustness.md").read_text()
    f = cells["mpc-recovery"]["falls"]
    assert f"| [+0, +0, +10] | 1/1 | {f}/1 |" in table and f"| total | 1/1 | {f}/1 |" in table
    with pytest.raises(SystemExit):
        push.main(["--workers", "0", "--out", str(tmp_path / "c")])
    # an ablation: any MPCOptions through --mpc-options, recorded in the JSON
    assert push.main(argv[:1] + ["mpc-options"] + argv[3:] + ["--mpc-options", '{"recovery": true}', "--out",
                                                              str(tmp_path / "d")]) == 0
    d = json.loads((tmp_path / "d" / "push_robustness.json").read_text())
    cell = d["results"]["mpc-options"]["[+0, +0, +10]"]
    assert d["mpc_options"] == {"recovery": True} and cell["falls"] == int(cell["runs"][0]["fell"])
    for bad in ([], ["--mpc-options", '{"no_such_field": 1}']):
        with pytest.raises(SystemExit):
            push.main(["--policies", "mpc-options", "--out", str(tmp_path / "e"), *bad])
