"""The MPC after a push: the speed reference governor (``SpeedOptions.ramp``,
:meth:`~hsddp_gym.planners.policies.mpc.speed.SpeedReference.plan_speed`), the schedule estimator's lost-stance rule
(``ScheduleOptions.lost_stance_steps``), the options' records, and the push grid of
``experiments/push_robustness.py``."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy


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


def test_speed_governor_and_lost_stance_rule_leave_unpushed_bounding_unchanged():
    """While bounding, the speed stays within ``speed_ramp`` of the target and no stance foot lifts early: the
    same actions as without either mechanism (the start-up's speed rate limit, which does act, off in both)."""
    env = make_env()
    bare = MPCPolicy.from_env(env, options=MPCOptions().replace(speed_ramp=None, lost_stance_steps=0,
                                                               speed_acceleration=None))
    obs, _ = env.reset(seed=1)
    _, a_bare = run(env, bare, obs, 200)
    obs, _ = env.reset(seed=1)
    _, a_default = run(env, MPCPolicy.from_env(env, options=MPCOptions().replace(speed_acceleration=None)), obs, 200)
    np.testing.assert_array_equal(a_bare, a_default)


def test_options_from_a_record_grouped_or_flat():
    """``MPCOptions.from_record``: grouped records (``dataclasses.asdict``) and the flat records of earlier versions
    come back; a setting this version fixes loads silently when it holds the value this version uses (``weights``
    None, the paper's weights then, counts as ``"paper"``) and is left out with a warning naming it otherwise, as is an
    unknown name; every value is checked as the groups check it."""
    import dataclasses

    fast = MPCOptions().replace(durations=(0.08, 0.1, 0.08, 0.1), touchdown_height=None)
    stored = json.loads(json.dumps(dataclasses.asdict(fast)))
    assert MPCOptions.from_record(stored) == fast
    flat = json.loads(json.dumps(fast.flat()))
    assert MPCOptions.from_record(flat) == fast
    assert set(flat) == set(MPCOptions().flat()) and len(flat) == 40  # 34 of the bound, 6 of a motion
    same = {**flat, "method": "al-reb", "weights": "later", "fine_dt": None, "reb_delta": 0.2, "latency_steps": 0}
    assert MPCOptions.from_record(same) == fast
    with pytest.warns(UserWarning, match="weights=.paper.*plan_retouch"):
        assert MPCOptions.from_record({**flat, "weights": None, "plan_retouch": True}) == fast
    with pytest.warns(UserWarning, match="schedule.no_such"):
        MPCOptions.from_record({"schedule": {"restep": False, "no_such": 1}})
    assert MPCOptions.from_record(None) == MPCOptions() == MPCOptions.from_record({})
    with pytest.raises(ValueError, match="debounce_steps"):
        MPCOptions.from_record({"debounce_steps": 0})
    with pytest.raises(TypeError, match="options"):
        MPCOptions.from_record([("weights", "paper")])
    with pytest.raises(TypeError, match="schedule"):
        MPCOptions.from_record({"schedule": [1]})


def test_options_replace_takes_flat_names_and_groups_and_refuses_unknown_ones():
    from hsddp_gym.planners.policies.mpc import ReplanOptions
    from hsddp_gym.planners.policies.mpc.options import GROUPS

    o = MPCOptions().replace(replan_period=0.01, restep=False, min_stance_force=None)
    assert o.replan.period == 0.01 and o.schedule.restep is False and o.min_stance_force is None
    assert o.plan == MPCOptions().plan  # the rest stays
    assert MPCOptions().replace(replan=ReplanOptions(period=0.01)).replan.period == 0.01
    with pytest.raises(ValueError, match="no setting 'fine_dt'"):
        MPCOptions().replace(fine_dt=0.001)
    with pytest.raises(TypeError, match="replan must be a ReplanOptions"):
        MPCOptions(replan={"period": 0.01})
    fields = [f for cls in GROUPS.values() for f in cls.__dataclass_fields__]
    assert len(MPCOptions.__dataclass_fields__) <= 20 and len(fields) + 1 == len(MPCOptions().flat())


def test_plan_speed_is_the_target_moved_at_most_speed_ramp_from_the_measured_speed():
    x = np.zeros(14)
    policy = MPCPolicy()  # target 1.0 m/s, speed ramp 0.5
    for vx, expected in ((1.2, 1.0), (0.6, 1.0), (-0.5, 0.0), (2.5, 2.0)):
        x[7] = vx
        assert policy.speed.plan_speed(x) == pytest.approx(expected)
    assert MPCPolicy(options=MPCOptions().replace(speed_ramp=None)).speed.plan_speed(x) == 1.0
    for bad in ({"speed_ramp": 0.0}, {"speed_ramp": -1.0}, {"lost_stance_steps": -1}, {"lost_stance_steps": 1.5}):
        with pytest.raises((ValueError, TypeError), match=next(iter(bad)).split("_")[-1]):
            MPCOptions().replace(**bad)


def test_push_robustness_experiment_records_every_episode(tmp_path, experiment):
    """``experiments/push_robustness.py``: per-episode records, totals, the same results with 2 workers."""
    push = experiment("push_robustness")
    assert push.POLICIES == ("mpc", "mpc-options", "heuristic", "random")
    argv = ["--policies", "heuristic", "mpc", "--push", "0", "0", "10", "--seeds", "1", "--first-seed",
            "101", "--times", "1.0", "--steps", "240"]
    assert push.main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert push.main(argv + ["--out", str(tmp_path / "b"), "--workers", "2"]) == 0
    a = json.loads((tmp_path / "a" / "push_robustness.json").read_text())
    b = json.loads((tmp_path / "b" / "push_robustness.json").read_text())
    assert a["results"] == b["results"] and a["push_times_s"] == [1.0]
    cells = {p: a["results"][p]["[+0, +0, +10]"] for p in ("heuristic", "mpc")}
    assert cells["heuristic"]["falls"] == 1
    run = cells["mpc"]["runs"][0]
    assert run["seed"] == 101 and cells["mpc"]["falls"] == int(run["fell"])
    assert (run["fall_time_s"] is None) == (not run["fell"])
    assert set(run) == {"seed", "push_time_s", "fell", "fall_time_s", "planner_failures"}
    table = (tmp_path / "a" / "push_robustness.md").read_text()
    f = cells["mpc"]["falls"]
    assert f"| [+0, +0, +10] | 1/1 | {f}/1 |" in table and f"| total | 1/1 | {f}/1 |" in table
    with pytest.raises(SystemExit):
        push.main(["--workers", "0", "--out", str(tmp_path / "c")])
    # an ablation: any MPCOptions through --mpc-options, recorded in the JSON
    assert push.main(argv[:1] + ["mpc-options"] + argv[3:] + ["--mpc-options", '{"planner_dt": 0.005}', "--out",
                                                              str(tmp_path / "d")]) == 0
    d = json.loads((tmp_path / "d" / "push_robustness.json").read_text())
    cell = d["results"]["mpc-options"]["[+0, +0, +10]"]
    assert d["mpc_options"] == {"planner_dt": 0.005} and cell["falls"] == int(cell["runs"][0]["fell"])
    for bad in ([], ["--mpc-options", '{"no_such_field": 1}']):
        with pytest.raises(SystemExit):
            push.main(["--policies", "mpc-options", "--out", str(tmp_path / "e"), *bad])


@pytest.mark.parametrize("lost_stance_steps", [1, 2])
def test_a_stance_foot_observed_in_the_air_is_never_planned_on_the_ground(lost_stance_steps):
    """Early in a stance, one observation reports the stance foot off the ground. With the default
    ``lost_stance_steps=1`` the gait clock leaves the stance in that very update and the MPC re-plans at once from
    the flight that lands the foot: no plan holds an airborne foot on the ground. With 2 the clock stays in the
    stance for that observation."""
    from hsddp_gym.core.conventions import BACK, FRONT, Mode
    from hsddp_gym.core.observation import DEFAULT_LAYOUT

    assert MPCOptions().schedule.lost_stance_steps == 1
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions().replace(lost_stance_steps=lost_stance_steps))
    obs, _ = env.reset(seed=3)
    for _ in range(400):  # into steady bounding, then to the first control step of a stance
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
        c = policy.clock
        if c.phase in (0, 2) and 0.0 < c.tau <= 0.01 and env.unwrapped.time > 0.5:
            break
    else:
        pytest.fail("no stance start found")
    stance_phase = policy.clock.phase
    foot = BACK if stance_phase == 0 else FRONT
    obs, _, _, _, _ = env.step(policy(obs))
    replans = policy.stats["replans"]
    flagged = np.array(obs, copy=True)
    flagged[DEFAULT_LAYOUT.contact.start + foot] = 0.0  # the stance foot reported in the air
    policy(flagged)
    if lost_stance_steps == 1:
        assert policy.clock.mode == Mode.FLIGHT and policy.clock.phase == (stance_phase - 1) % 4
        # the re-plan of this very step starts from the flight
        assert policy.stats["replans"] == replans + 1 and policy.law.plan.problem.schedule.modes[0] == Mode.FLIGHT
    else:
        assert policy.clock.phase == stance_phase
