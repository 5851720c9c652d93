"""Conditions of a real robot (hsddp_gym.envs.perturbations.HARDWARE_CONDITIONS): a latency other than the announced
one, a constant sensor bias, pushes timed by the contact phase; seeded, validated, outside the suite."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.core.observation import ObservationLayout
from hsddp_gym.envs.perturbations import (
    CONDITIONS,
    HARDWARE_CONDITIONS,
    PHASE_PUSH_DELTA_V,
    SENSOR_BIAS,
    SENSOR_BIAS_RANGE,
    SUITE,
    ActionDelay,
    HardwareCondition,
    ObservationBias,
    ObservationNoise,
    PhasePush,
    RandomPush,
    episode_perturbation,
    get_condition,
    make_env,
    observation_entries,
    wrapper_info_keys,
)
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy

ENV_ID = "hsddp_gym/Bounding-v0"
DELAYS = {"delay_5ms_announced_0ms": (1, 0), "delay_10ms_announced_5ms": (2, 1), "delay_5ms_announced_10ms": (1, 2),
          "delay_15ms_announced_10ms": (3, 2), "delay_jitter": (2, 2)}


def _actions(n, seed=0):
    return np.random.default_rng(seed).uniform(-0.3, 0.3, size=(n, 4)).astype(np.float32)


def _rollout(env, seed, n=30):
    obs, info = env.reset(seed=seed)
    out = [obs]
    for a in _actions(n, seed):
        obs, _, terminated, truncated, info = env.step(a)
        out.append(obs)
        if terminated or truncated:
            break
    return np.array(out)


# ------------------------------------------------------------------------------------------------ registry
def test_hardware_conditions_are_extra_and_not_for_the_vector_env():
    assert set(HARDWARE_CONDITIONS) == set(DELAYS) | {"sensor_bias", "sensor_bias_random", "sensor_bias_x2",
                                                      "push_flight", "push_stance", "noise_bias_latency"}
    combined = get_condition("noise_bias_latency")
    assert combined.observation_noise == get_condition("obs_noise").observation_noise
    assert (combined.action_delay, combined.announced_delay) == (2, 1)
    assert combined.observation_bias == get_condition("sensor_bias_random").observation_bias
    assert get_condition("sensor_bias_x2").observation_bias == {"bias": {"pitch": 0.06, "dx": 0.1, "z": -0.04}}
    assert not set(SUITE) & set(HARDWARE_CONDITIONS) and len(SUITE) == 13 and "push_x3" in CONDITIONS
    for name in HARDWARE_CONDITIONS:
        cond = get_condition(name)
        assert isinstance(cond, HardwareCondition) and cond.description
        assert not cond.acts_through_env_arguments and cond.as_dict()["name"] == name
    # the suite's conditions keep their definitions
    assert get_condition("delay_10ms").as_dict() == {"name": "delay_10ms", "description": get_condition(
        "delay_10ms").description, "env_kwargs": {}, "observation_noise": None, "action_delay": 2, "push": None}


def test_every_hardware_condition_is_deterministic_per_seed():
    """Whole heuristic episodes (the pushes come after 1 s): the same seed, the same episode and perturbation."""
    for name in HARDWARE_CONDITIONS:
        runs = []
        for _ in range(2):
            env = make_env(name)
            _, infos = _heuristic_run(env, 11, 1000)
            runs.append((np.array([np.concatenate([i["qpos"], i["qvel"]]) for i in infos]),
                         episode_perturbation(env)))
        np.testing.assert_array_equal(runs[0][0], runs[1][0])
        assert runs[0][1] == runs[1][1] and runs[0][1]
        if name.startswith("push_"):
            assert runs[0][1]["push_applied"] is not None
    assert episode_perturbation(gym.make(ENV_ID)) == {}


# ------------------------------------------------------------------------------------------------ latency
@pytest.mark.parametrize("name", list(DELAYS))
def test_the_announced_delay_is_what_the_policies_read(name):
    from hsddp_gym.planners.policies.mpc import MPCPolicy

    executed, announced = DELAYS[name]
    env = make_env(name)
    env.reset(seed=0)
    cond = get_condition(name)
    assert cond.action_delay == executed and cond.announced_delay == announced
    assert env.get_wrapper_attr("action_delay_steps") == announced
    assert EnvInterface.from_env(env).action_delay_steps == announced
    mpc = MPCPolicy.from_env(env)
    assert mpc.announced_delay == mpc.action_delay == announced  # the estimate starts at the announced delay
    if name != "delay_jitter":
        assert env.get_wrapper_attr("executed_delay_steps") == executed


@pytest.mark.parametrize("steps, announced", [(2, 1), (1, 2), (1, 0), (3, 2)])
def test_the_executed_delay_is_the_configured_one(steps, announced):
    env = ActionDelay(gym.make(ENV_ID), steps, announced=announced)
    env.reset(seed=0)
    acts = _actions(8)
    for t, a in enumerate(acts):
        executed = env.step(a)[4]["executed_action"]
        np.testing.assert_array_equal(executed, acts[t - steps] if t >= steps else np.zeros(4, np.float32))
    assert env.action_delay_steps == announced and env.executed_delay_steps == steps


def test_delay_jitter_draws_the_executed_delay_per_episode_from_the_seed():
    env = make_env("delay_jitter")
    delays = {}
    for seed in range(40):
        env.reset(seed=seed)
        delays[seed] = env.get_wrapper_attr("executed_delay_steps")
        assert env.get_wrapper_attr("action_delay_steps") == 2
    assert set(delays.values()) == {1, 2, 3}
    other = make_env("delay_jitter")
    for seed in (3, 17, 3):
        other.reset(seed=seed)
        assert other.get_wrapper_attr("executed_delay_steps") == delays[seed]
    # the executed actions follow the drawn delay
    seed = next(s for s, d in delays.items() if d == 3)
    env.reset(seed=seed)
    acts = _actions(5)
    executed = [env.step(a)[4]["executed_action"] for a in acts]
    np.testing.assert_array_equal(executed[3], acts[0])
    np.testing.assert_array_equal(executed[2], np.zeros(4, np.float32))


def test_a_plain_delay_draws_nothing():
    env = ActionDelay(gym.make(ENV_ID), 2)
    env.reset(seed=4)
    env.reset()
    assert env._rng is None and env.executed_delay_steps == env.action_delay_steps == 2


def test_action_delay_validation_names_the_argument():
    with pytest.raises(ValueError, match="announced"):
        ActionDelay(gym.make(ENV_ID), 1, announced=-1)
    with pytest.raises(TypeError, match="announced"):
        ActionDelay(gym.make(ENV_ID), 1, announced=1.5)
    with pytest.raises(ValueError, match="jitter"):
        ActionDelay(gym.make(ENV_ID), 1, jitter=2)
    with pytest.raises(ValueError, match="jitter"):
        ActionDelay(gym.make(ENV_ID), 1, jitter=-1)
    with pytest.raises(ValueError, match="steps"):
        ActionDelay(gym.make(ENV_ID), -1)


# ------------------------------------------------------------------------------------------------ sensor bias
def test_observation_entries_follow_the_layout():
    for layout in (ObservationLayout(True), ObservationLayout(False)):
        entries = observation_entries(layout)
        assert ("x" in entries) == (not layout.exclude_current_positions)
        assert entries["z"] == layout.qpos.start + 1 - layout.skipped_qpos
        assert entries["dx"] == layout.qvel.start and entries["dpitch"] == layout.qvel.start + 2
        assert sorted(entries.values()) == list(range(layout.qpos.start, layout.qvel.stop))


@pytest.mark.parametrize("exclude", [True, False])
def test_sensor_bias_is_added_to_exactly_the_named_entries(exclude):
    kwargs = {"exclude_current_positions_from_observation": exclude}
    env = ObservationBias(gym.make(ENV_ID, **kwargs), bias=SENSOR_BIAS)
    clean = gym.make(ENV_ID, **kwargs)
    entries = observation_entries(env.unwrapped.observation_layout)
    expected = np.zeros(env.unwrapped.observation_layout.size)
    for name, value in SENSOR_BIAS.items():
        expected[entries[name]] = value
    obs, info = env.reset(seed=2)
    ref, ref_info = clean.reset(seed=2)
    assert info["observation_bias"] == SENSOR_BIAS
    np.testing.assert_array_equal(info["qvel"], ref_info["qvel"])  # info keeps the true state
    for a in [None, *_actions(20)]:
        if a is not None:
            obs, _, _, _, info = env.step(a)
            ref, _, _, _, ref_info = clean.step(a)
            np.testing.assert_array_equal(info["qpos"], ref_info["qpos"])
        untouched = expected == 0.0
        np.testing.assert_array_equal(obs[untouched], ref[untouched])
        np.testing.assert_allclose(obs[~untouched], ref[~untouched] + expected[~untouched], atol=1e-6)
        assert obs.dtype == ref.dtype


def test_sensor_bias_condition_is_the_documented_fixed_bias():
    env = make_env("sensor_bias")
    for seed in (0, 1):
        assert env.reset(seed=seed)[1]["observation_bias"] == {"z": -0.02, "pitch": 0.03, "dx": 0.05}
    assert wrapper_info_keys(env) == {"observation_bias"}


def test_random_sensor_bias_is_drawn_per_episode_from_the_seed_within_its_range():
    env, other = make_env("sensor_bias_random"), make_env("sensor_bias_random")
    draws = []
    for seed in range(30):
        bias = env.reset(seed=seed)[1]["observation_bias"]
        assert set(bias) == set(SENSOR_BIAS_RANGE)
        assert all(abs(bias[n]) <= SENSOR_BIAS_RANGE[n] for n in bias)
        draws.append([bias[n] for n in SENSOR_BIAS_RANGE])
    draws = np.array(draws)
    assert len(np.unique(draws[:, 0])) == 30  # a new bias every episode
    assert (draws.min(axis=0) < -0.5 * np.array(list(SENSOR_BIAS_RANGE.values()))).all()
    assert other.reset(seed=7)[1]["observation_bias"] == env.reset(seed=7)[1]["observation_bias"]
    # constant within the episode
    obs0 = env.reset(seed=7)[0]
    clean = gym.make(ENV_ID)
    ref0 = clean.reset(seed=7)[0]
    a = _actions(1)[0]
    d0 = obs0 - ref0
    d1 = env.step(a)[0] - clean.step(a)[0]
    np.testing.assert_allclose(d0, d1, atol=1e-6)


def test_observation_bias_validation_names_the_argument():
    make = lambda: gym.make(ENV_ID)  # noqa: E731
    with pytest.raises(TypeError, match="bias"):
        ObservationBias(make(), bias=[0.1])
    with pytest.raises(ValueError, match="bias.*contact_front"):
        ObservationBias(make(), bias={"contact_front": 0.1})
    with pytest.raises(ValueError, match="bias"):
        ObservationBias(make(), bias={"x": 0.1})  # not observed by default
    with pytest.raises(ValueError, match=r"bias\['pitch'\]"):
        ObservationBias(make(), bias={"pitch": float("nan")})
    with pytest.raises(ValueError, match=r"random_bias\['z'\]"):
        ObservationBias(make(), random_bias={"z": -0.01})
    with pytest.raises(TypeError, match="random_bias"):
        ObservationBias(make(), random_bias=0.1)


# ------------------------------------------------------------------------------------------------ phase pushes
def _heuristic_run(env, seed, steps):
    """Run the heuristic; the step at which a push was applied, with its info, and every info."""
    policy = HeuristicPolicy(EnvInterface.from_env(env))
    obs, info = env.reset(seed=seed)
    policy.reset()
    infos, at = [info], None
    for k in range(steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        infos.append(info)
        if "push_applied" in info:
            at = k + 1
            assert np.allclose(obs[env.unwrapped.observation_layout.qvel], info["qvel"], atol=1e-5)
        if terminated or truncated:
            break
    return at, infos


@pytest.mark.parametrize("phase", ["flight", "stance"])
def test_a_phase_push_comes_at_the_first_step_of_its_phase_after_its_time(phase):
    env = PhasePush(gym.make(ENV_ID), phase=phase, time_range=(0.3, 0.5))
    plain = gym.make(ENV_ID)
    for seed in (0, 1, 2):
        at, infos = _heuristic_run(env, seed, 200)
        drawn = infos[0]["phase_push"]
        assert at is not None and drawn["phase"] == phase
        push = infos[at]["push_applied"]
        contact = infos[at]["contact"]
        assert push["contact"] == contact.tolist() and push["delta_v"] == drawn["delta_v"]
        assert (not contact.any()) if phase == "flight" else contact.any()
        assert push["time"] >= drawn["earliest_time"] - 1e-9
        # no earlier step after the push time was in the phase
        for info in infos[1:at]:
            if info["time"] >= drawn["earliest_time"]:
                assert info["contact"].any() == (phase == "flight")
        # the push changed the trunk velocities by delta_v at that step, nothing before it
        _, ref = _heuristic_run(plain, seed, at)
        for k in range(at):
            np.testing.assert_array_equal(infos[k]["qvel"], ref[k]["qvel"])
        np.testing.assert_allclose(infos[at]["qvel"][:3] - ref[at]["qvel"][:3], push["delta_v"], atol=1e-9)
        np.testing.assert_array_equal(infos[at]["qvel"][3:], ref[at]["qvel"][3:])
        assert env.applied == push and episode_perturbation(env) == {"push_applied": push}


def test_phase_pushes_draw_what_random_push_draws_and_are_seeded():
    for name, phase in (("push_flight", "flight"), ("push_stance", "stance")):
        env = make_env(name)
        assert env.get_wrapper_attr("max_delta_v") == PHASE_PUSH_DELTA_V == (1.0, 1.0, 7.0)
        ref = RandomPush(gym.make(ENV_ID), max_delta_v=PHASE_PUSH_DELTA_V)
        for seed in (0, 5):
            drawn = env.reset(seed=seed)[1]["phase_push"]
            push = ref.reset(seed=seed)[1]["push"]
            assert drawn == {"delta_v": push["delta_v"], "earliest_time": push["time"], "phase": phase}
            assert 1.0 <= drawn["earliest_time"] <= 4.0
        assert wrapper_info_keys(env) == {"phase_push", "push_applied"}


def test_no_phase_push_at_or_after_a_fall():
    """A push due at the step that ends the episode in a fall is not applied."""
    fall = np.array([1.0, -1.0, 1.0, -1.0], np.float32)
    plain = gym.make(ENV_ID)
    plain.reset(seed=0)
    steps, terminated = 0, False
    while not terminated and steps < 400:
        _, _, terminated, _, info = plain.step(fall)
        steps += 1
    assert terminated
    phase = "stance" if info["contact"].any() else "flight"
    t = info["time"] - 0.5 * plain.unwrapped.dt
    env = PhasePush(gym.make(ENV_ID), phase=phase, time_range=(t, t))
    env.reset(seed=0)
    for _ in range(steps):
        _, _, terminated, _, last = env.step(fall)
        assert "push_applied" not in last
    assert terminated and env.applied is None and last["time"] == info["time"]


def test_phase_push_validation_names_the_argument():
    with pytest.raises(ValueError, match="phase"):
        PhasePush(gym.make(ENV_ID), phase="air")
    with pytest.raises(ValueError, match="time_range"):
        PhasePush(gym.make(ENV_ID), time_range=(2.0, 1.0))
    with pytest.raises(ValueError, match="max_delta_v"):
        PhasePush(gym.make(ENV_ID), max_delta_v=(1.0, -1.0, 1.0))
    with pytest.raises(TypeError, match="below any observation wrapper"):
        PhasePush(ObservationNoise(gym.make(ENV_ID)))


# ------------------------------------------------------------------------------------------------ the script
def test_robustness_script_records_the_drawn_perturbation_and_explains_the_conditions(experiment, capsys):
    script = experiment("robustness")
    run = script.run_one(("heuristic", {"kind": "heuristic"}, "delay_jitter", 3, 10, "bounding"))
    assert run["perturbation"]["announced_delay_steps"] == 2
    assert run["perturbation"]["executed_delay_steps"] in (1, 2, 3)
    run = script.run_one(("heuristic", {"kind": "heuristic"}, "default", 3, 10, "bounding"))
    assert "perturbation" not in run
    with pytest.raises(SystemExit):
        script.main(["--help"])
    text = "".join(capsys.readouterr().out.split())
    for word in ("delay_10ms_announced_5ms", "delay_jitter", "sensor_bias_random", "push_flight", "push_stance",
                 "push_x3"):
        assert word in text
