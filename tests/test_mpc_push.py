"""The MPC after a push: the speed reference governor (``MPCOptions.speed_ramp``, :meth:`MPCPolicy.plan_speed`) and
the gait clock's lost-stance rule (``lost_stance_steps``), and the push grid of ``experiments/push_robustness.py``."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy
from hsddp_gym.rollout.episodes import run_episode

GRID_5MS_NO_INTEGRAL = {"planner_dt": 0.005, "speed_integral_gain": None, "max_iterations": 3,
                        "feedback_iterations": None}
"""The MPC with a 5 ms planner grid, no integral speed action, 3 DDP iterations per re-plan and feedback re-plans
solved as the others: the configuration the pushes of the tests pinned to it were picked on."""


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


def test_speed_governor_and_lost_stance_rule_survive_a_push_the_mpc_without_them_falls_after():
    """Seed 100, ``[-1.5, 0, 0]`` at t = 1 s: without the speed reference governor (``speed_ramp``) and the
    lost-stance rule (``lost_stance_steps``) the MPC falls within 0.5 s of the push; with them it bounds on.

    Pinned to the configuration these two mechanisms were measured on (``GRID_5MS_NO_INTEGRAL``): with the default
    options (the 2.5 ms grid and the integral speed action together) the MPC falls on this one push (about twice the
    suite's largest); with either of the two alone it survives it."""
    push = {"push": {"delta_v": [-1.5, 0.0, 0.0], "time": 1.0}}
    env = make_env()
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


def test_options_from_a_record_of_an_earlier_version():
    """``MPCOptions.from_record``: the stored options of a dataset come back; ``weights`` None (the paper's weights,
    the default of earlier versions) is ``"paper"``; a field this version does not have is left out with a warning
    naming it; anything else is checked as ``MPCOptions`` checks it."""
    import dataclasses
    import json

    stored = json.loads(json.dumps(dataclasses.asdict(MPCOptions(durations=(0.08, 0.1, 0.08, 0.1)))))
    assert MPCOptions.from_record(stored) == MPCOptions(durations=(0.08, 0.1, 0.08, 0.1))
    old = {**stored, "weights": None, "plan_retouch": True}
    with pytest.warns(UserWarning, match="plan_retouch"):
        assert MPCOptions.from_record(old).weights == "paper"
    with pytest.raises(ValueError, match="weights"):
        MPCOptions.from_record({"weights": "mine"})
    with pytest.raises(TypeError, match="options"):
        MPCOptions.from_record([("weights", "paper")])


def test_plan_speed_is_the_target_moved_at_most_speed_ramp_from_the_measured_speed():
    x = np.zeros(14)
    policy = MPCPolicy()  # target 1.0 m/s, speed_ramp 0.5
    for vx, expected in ((1.2, 1.0), (0.6, 1.0), (-0.5, 0.0), (2.5, 2.0)):
        x[7] = vx
        assert policy.plan_speed(x) == pytest.approx(expected)
    assert MPCPolicy(options=MPCOptions(speed_ramp=None)).plan_speed(x) == 1.0
    assert MPCPolicy().weights == "later"
    assert MPCPolicy(EnvInterface(target_speed=2.0)).weights == "later"  # one gait at every speed
    assert MPCPolicy(EnvInterface(target_speed=2.0), MPCOptions(weights="paper")).weights == "paper"
    for bad in ({"speed_ramp": 0.0}, {"speed_ramp": -1.0}, {"lost_stance_steps": -1}, {"lost_stance_steps": 1.5},
                {"weights": "mine"}, {"weights": None}):
        with pytest.raises((ValueError, TypeError), match=next(iter(bad))):
            MPCOptions(**bad)


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

    assert MPCOptions().lost_stance_steps == 1
    env = make_env()
    policy = MPCPolicy.from_env(env, options=MPCOptions(lost_stance_steps=lost_stance_steps))
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
        assert policy.stats["replans"] == replans + 1 and policy._problem.schedule.modes[0] == Mode.FLIGHT
    else:
        assert policy.clock.phase == stance_phase


def _push_episode(options: MPCOptions, seed: int):
    """One ``make_env("push_flight")`` episode of the MPC: (fell, the times [s] at which its clock was in a double
    stance, the applied push ``info["push_applied"]``)."""
    from hsddp_gym.envs.perturbations import make_env as make_perturbed_env
    from hsddp_gym.planners.policies.mpc import DOUBLE_STANCE_PHASE

    env = make_perturbed_env("push_flight")
    policy = MPCPolicy.from_env(env, options=options)
    obs, _ = env.reset(seed=seed)
    policy.reset()
    double, push = [], None
    try:
        for k in range(env.spec.max_episode_steps):
            obs, _, terminated, truncated, info = env.step(policy(obs))
            push = info.get("push_applied", push)
            if policy.clock.phase == DOUBLE_STANCE_PHASE:
                double.append((k + 1) * env.unwrapped.dt)
            if terminated or truncated:
                return terminated, double, push
    finally:
        env.close()
    return False, double, push


def test_a_landing_on_both_feet_is_planned_as_a_double_stance():
    """Development seed 40008 of ``push_flight``: a push in a flight at t = 3.435 s (Δv = (+0.25, +0.07) m/s,
    -4.7 rad/s) brings the robot down on both feet at 3.61 s. The default plans the landing as a 40 ms double stance,
    then the stance of the foot that landed, and bounds on; planned as that stance (``double_stance=None``) and
    re-planned only every 20 ms (``replan_feedback=None``) it falls at 3.99 s. Either mechanism alone catches this
    landing (``double_stance=None`` bounds here, and so does ``replan_feedback=None``)."""
    fell, double, push = _push_episode(MPCOptions(), 40008)
    assert push["time"] == pytest.approx(3.435, abs=0.01)
    assert not fell
    assert double and push["time"] < double[0] < push["time"] + 0.3  # entered at the landing, never before the push
    # each double stance lasts its 40 ms (8 control steps), none follows another at once
    runs = np.split(np.array(double), np.flatnonzero(np.diff(double) > 0.0051) + 1)
    assert all(len(run) <= 8 for run in runs)
    assert all(b[0] - a[-1] > 0.05 for a, b in zip(runs, runs[1:]))
    # without it
    fell_off, double_off, _ = _push_episode(MPCOptions(double_stance=None, replan_feedback=None), 40008)
    assert fell_off and not double_off
