"""The perturbation suite (hsddp_gym.envs.perturbations): seeded, documented behaviour, validation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym.envs.perturbations import (
    CONDITIONS,
    HARDWARE_CONDITIONS,
    SUITE,
    ActionDelay,
    Condition,
    ObservationNoise,
    RandomPush,
    get_condition,
    make_env,
)
from hsddp_gym.planners.policies.base import EnvInterface

ENV_ID = "hsddp_gym/Bounding-v0"


def _actions(n, seed=0):
    return np.random.default_rng(seed).uniform(-0.3, 0.3, size=(n, 4)).astype(np.float32)


def test_observation_noise_is_seeded_and_leaves_flags_clock_and_info_clean():
    env = ObservationNoise(gym.make(ENV_ID), position_std=0.01, velocity_std=0.1)
    clean = gym.make(ENV_ID)
    layout = env.unwrapped.observation_layout
    diffs = []
    for seed in range(40):
        obs, info = env.reset(seed=seed)
        ref, ref_info = clean.reset(seed=seed)
        np.testing.assert_array_equal(info["qvel"], ref_info["qvel"])  # info holds the true state
        np.testing.assert_array_equal(obs[layout.contact], ref[layout.contact])
        np.testing.assert_array_equal(obs[layout.phase], ref[layout.phase])
        diffs.append(obs - ref)
        again, _ = env.reset(seed=seed)
        np.testing.assert_array_equal(obs, again)  # a function of the seed
    d = np.array(diffs)
    pos_std = d[:, layout.qpos].std()
    vel_std = d[:, layout.qvel].std()
    assert 0.008 < pos_std < 0.012 and 0.08 < vel_std < 0.12
    # steps are noisy too, with fresh noise every step
    env.reset(seed=1)
    clean.reset(seed=1)
    a = _actions(3)
    o1 = env.step(a[0])[0]
    r1 = clean.step(a[0])[0]
    o2 = env.step(a[1])[0]
    r2 = clean.step(a[1])[0]
    e1, e2 = (o1 - r1)[layout.qvel], (o2 - r2)[layout.qvel]
    assert np.all(e1 != 0) and not np.allclose(e1, e2)


def test_zero_noise_is_the_identity():
    env = ObservationNoise(gym.make(ENV_ID), 0.0, 0.0)
    clean = gym.make(ENV_ID)
    np.testing.assert_array_equal(env.reset(seed=4)[0], clean.reset(seed=4)[0])


@pytest.mark.parametrize("steps", [1, 2])
def test_action_delay_executes_old_actions(steps):
    env = ActionDelay(gym.make(ENV_ID), steps)
    ref = gym.make(ENV_ID)
    env.reset(seed=2)
    ref.reset(seed=2)
    acts = _actions(8)
    executed = [np.zeros(4, np.float32)] * steps + list(acts)
    for t, a in enumerate(acts):
        obs, _, _, _, info = env.step(a)
        ref_obs = ref.step(executed[t])[0]
        np.testing.assert_array_equal(info["executed_action"], executed[t])
        np.testing.assert_array_equal(obs, ref_obs)
    assert EnvInterface.from_env(env).action_delay_steps == steps
    assert EnvInterface.from_env(ref).action_delay_steps == 0
    # a reset empties the queue
    env.reset(seed=2)
    assert np.all(env.step(acts[0])[4]["executed_action"] == 0)


def test_action_delay_rejects_bad_actions_at_once():
    env = ActionDelay(gym.make(ENV_ID), 2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step([0.0, np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="action"):
        env.step([0.0, 0.0])


def test_random_push_is_seeded_in_range_and_applied():
    env = RandomPush(gym.make(ENV_ID), time_range=(0.02, 0.05), max_delta_v=(0.8, 0.8, 5.0))
    pushes = []
    for seed in range(30):
        _, info = env.reset(seed=seed)
        p = info["push"]
        assert 0.02 <= p["time"] <= 0.05
        assert all(abs(v) <= m for v, m in zip(p["delta_v"], (0.8, 0.8, 5.0)))
        assert env.reset(seed=seed)[1]["push"] == p
        pushes.append(p["delta_v"])
    assert np.std(np.array(pushes), axis=0).min() > 0.1
    # the push is applied: compare with the same episode without a push
    _, info = env.reset(seed=7)
    ref = gym.make(ENV_ID)
    ref.reset(seed=7)
    push = info["push"]
    a = np.zeros(4, np.float32)
    for _ in range(12):  # 60 ms, past the push
        info = env.step(a)[4]
        ref_info = ref.step(a)[4]
    dv = np.asarray(info["qvel"][:3]) - np.asarray(ref_info["qvel"][:3])
    assert np.linalg.norm(dv) > 0.2 * np.linalg.norm(np.asarray(push["delta_v"]) * [1, 1, 0.19])
    with pytest.raises(ValueError, match="push"):
        env.reset(seed=0, options={"push": [0.0, 0.0, 1.0]})


def _run(env, steps, push_at=None):
    """``(steps, 28)`` qpos/qvel after each zero-torque step; ``push_at = (step, delta_v)`` pushes through
    ``apply_push`` before that step."""
    a, out = np.zeros(4, np.float32), []
    for i in range(steps):
        if push_at is not None and i == push_at[0]:
            env.unwrapped.apply_push(push_at[1])
        info = env.step(a)[4]
        out.append(np.concatenate([info["qpos"], info["qvel"]]))
    return np.array(out)


def test_push_schedule_applies_every_push_at_its_time():
    """The env's ``push`` option as a list: each push at the first simulation step at or after its time, in time
    order whatever the list's order; one push in a list is that push; a schedule entry is validated by index."""
    p1 = {"delta_v": [0.3, -0.2, 2.0], "time": 0.0123}
    p2 = {"delta_v": [-0.4, 0.1, -3.0], "time": 0.05}  # the start of control step 10
    env, ref = gym.make(ENV_ID), gym.make(ENV_ID)
    env.reset(seed=4, options={"push": [p2, p1]})
    ref.reset(seed=4, options={"push": p1})
    both, one_then_two = _run(env, 20), _run(ref, 20, push_at=(10, p2["delta_v"]))
    np.testing.assert_array_equal(both, one_then_two)
    plain = gym.make(ENV_ID)
    plain.reset(seed=4)
    unpushed = _run(plain, 20)
    assert not np.array_equal(both[2], unpushed[2]) and np.array_equal(both[1], unpushed[1])  # p1 in step 2
    env.reset(seed=4, options={"push": [p1]})
    ref.reset(seed=4, options={"push": p1})
    np.testing.assert_array_equal(_run(env, 20), _run(ref, 20))
    with pytest.raises(ValueError, match=r"options\['push'\]\[1\]\['time'\]"):
        env.reset(seed=0, options={"push": [p1, {"delta_v": [0.0, 0.0, 1.0], "time": -1.0}]})
    with pytest.raises(ValueError, match=r"options\['push'\]\[0\]"):
        env.reset(seed=0, options={"push": [{"delta_v": [0.0, 0.0, 1.0]}]})


def test_random_push_count_draws_one_push_per_slot():
    """``RandomPush(count=3)``: three seeded pushes, push j in the j-th third of ``time_range``, each within
    ``max_delta_v``, all applied; ``count=1`` is the single push (a dict) it always drew."""
    env = RandomPush(gym.make(ENV_ID), time_range=(1.0, 4.0), count=3)
    single = RandomPush(gym.make(ENV_ID), time_range=(1.0, 4.0))
    for seed in range(20):
        pushes = env.reset(seed=seed)[1]["push"]
        assert isinstance(pushes, list) and len(pushes) == 3 and pushes == env.last_push
        for j, p in enumerate(pushes):
            assert 1.0 + j <= p["time"] <= 2.0 + j
            assert all(abs(v) <= m for v, m in zip(p["delta_v"], (0.8, 0.8, 5.0)))
        assert env.reset(seed=seed)[1]["push"] == pushes
        # the first push is the single push's draw (same generator, same order of draws) but in the first slot
        first = single.reset(seed=seed)[1]["push"]
        assert isinstance(first, dict) and first["delta_v"] == pushes[0]["delta_v"]
    with pytest.raises(ValueError, match="count"):
        RandomPush(gym.make(ENV_ID), count=0)
    # the three pushes reach the trunk: the run equals one with the schedule given to the env directly
    pushes = env.reset(seed=5)[1]["push"]
    direct = gym.make(ENV_ID)
    direct.reset(seed=5, options={"push": pushes})
    pushed = _run(env, 900)
    np.testing.assert_array_equal(pushed, _run(direct, 900))
    # and each one changes the motion: up to the step of push j the run equals the one with the pushes before it
    for j, p in enumerate(pushes):
        partial = gym.make(ENV_ID)
        partial.reset(seed=5, options={"push": pushes[:j]})
        i = int(p["time"] // env.unwrapped.dt)  # the control step in which push j happens
        before = _run(partial, i + 1)
        np.testing.assert_array_equal(pushed[:i], before[:i])
        assert not np.array_equal(pushed[i], before[i])


def test_suite_is_every_condition_but_the_training_ones():
    assert SUITE == ("default", "reset_noise_x4", "obs_noise", "delay_5ms", "delay_10ms", "push", "friction_0.4",
                     "mass_+15", "mass_-15", "speed_0.5", "speed_1.25", "speed_1.5", "speed_2.0")
    assert set(CONDITIONS) - set(SUITE) == ({"push_x3"} | {n for n in CONDITIONS if n.startswith("contact_")}
                                            | set(HARDWARE_CONDITIONS))
    assert get_condition("push_x3").push == {"count": 3}


def test_wrapper_validation_names_the_argument():
    with pytest.raises(ValueError, match="velocity_std"):
        ObservationNoise(gym.make(ENV_ID), 0.01, -0.1)
    with pytest.raises(ValueError, match="steps"):
        ActionDelay(gym.make(ENV_ID), -1)
    with pytest.raises(ValueError, match="time_range"):
        RandomPush(gym.make(ENV_ID), time_range=(2.0, 1.0))
    with pytest.raises(TypeError, match="max_delta_v"):
        RandomPush(gym.make(ENV_ID), max_delta_v=(1.0, 1.0))
    with pytest.raises(ValueError, match="max_delta_v"):
        RandomPush(gym.make(ENV_ID), max_delta_v=(1.0, -1.0, 1.0))
    with pytest.raises(ValueError, match="trunk_mass_scale"):
        gym.make(ENV_ID, trunk_mass_scale=0.0)


def test_trunk_mass_scale_changes_the_simulated_robot_only():
    heavy = gym.make(ENV_ID, trunk_mass_scale=1.15).unwrapped
    nominal = gym.make(ENV_ID).unwrapped
    assert heavy.robot.total_mass == pytest.approx(nominal.robot.total_mass + 0.15 * 5.46)
    # physics, in flight: the same hip torques turn the heavier (more inertial) trunk less
    state = nominal.init_state.copy()
    state[1] += 0.2
    state[7:] = 0.0
    rates = []
    for env in (heavy, nominal):
        env.reset(options={"state": state})
        for _ in range(2):
            info = env.step(np.array([0.5, 0.0, 0.5, 0.0], np.float32))[4]
        rates.append(abs(info["qvel"][2]))
    assert 0.8 < rates[0] / rates[1] < 0.95


def test_registry_builds_every_condition_and_rejects_unknown_ones():
    for name, cond in CONDITIONS.items():
        assert cond.name == name and cond.description
        env = make_env(name)
        obs, info = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        for key, value in cond.env_kwargs.items():
            assert getattr(env.unwrapped, key if key != "friction" else "sim").__class__ is not None
            if key == "friction":
                assert env.unwrapped.sim.mu == value
            else:
                assert getattr(env.unwrapped, key) == value
        assert EnvInterface.from_env(env).action_delay_steps == cond.announced_delay
        assert ("push" in info) == (cond.push is not None)
        env.close()
    with pytest.raises(ValueError, match="condition"):
        get_condition("nope")
    with pytest.raises(ValueError, match="target_speed"):
        get_condition("speed_2.0").make(target_speed=1.0)
    custom = Condition("mine", "custom", {"friction": 0.5}, observation_noise=(0.0, 0.05), action_delay=1)
    env = make_env(custom, max_episode_steps=5)
    assert isinstance(env, ObservationNoise) and env.unwrapped.sim.mu == 0.5
    assert env.get_wrapper_attr("action_delay_steps") == 1
    assert set(custom.as_dict()) == {"name", "description", "env_kwargs", "observation_noise", "action_delay",
                                     "push"}


def test_conditions_run_in_every_simulator():
    """``make_env(condition, simulator=...)``: the same perturbation (kwargs, wrappers) on the MuJoCo twin and the
    planner's own model; an unknown simulator is named in the error."""
    from hsddp_gym.envs.perturbations import SIMULATORS

    pytest.importorskip("mujoco")
    for simulator, env_id in SIMULATORS.items():
        env = make_env("friction_0.4", simulator=simulator)
        assert env.spec.id == env_id and env.unwrapped.sim.mu == 0.4
        env.close()
    env = make_env("mass_+15", simulator="mujoco")
    base = make_env("default", simulator="mujoco")
    assert env.unwrapped.sim.model.body_mass[1] == pytest.approx(1.15 * base.unwrapped.sim.model.body_mass[1])
    env = make_env("push", simulator="mujoco")
    obs, info = env.reset(seed=3)
    assert "push" in info and isinstance(env, RandomPush)
    with pytest.raises(ValueError, match="simulator"):
        make_env("default", simulator="isaac")


def test_robustness_experiment_table_json_workers_and_combine(tmp_path, experiment):
    import json

    rob = experiment("robustness")
    argv = ["--policies", "heuristic", "--conditions", "default", "delay_10ms", "push", "--seeds", "2",
            "--first-seed", "11", "--max-steps", "250", "--quiet"]
    assert rob.main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert rob.main(argv + ["--out", str(tmp_path / "b"), "--workers", "2"]) == 0
    a = json.loads((tmp_path / "a" / "robustness.json").read_text())
    b = json.loads((tmp_path / "b" / "robustness.json").read_text())
    strip = [{k: v for k, v in r.items() if k != "wall_time_s"} for c in a["results"]["heuristic"].values()
             for r in c["runs"]]
    strip_b = [{k: v for k, v in r.items() if k != "wall_time_s"} for c in b["results"]["heuristic"].values()
               for r in c["runs"]]
    assert strip == strip_b and a["seeds"] == [11, 12]
    cells = a["results"]["heuristic"]
    # the heuristic cannot take 10 ms of latency (it falls on nearly every full episode; in 250 steps at least one of 2)
    assert cells["delay_10ms"]["falls"] >= 1 and cells["default"]["falls"] == 0
    assert (tmp_path / "a" / "robustness.png").exists()
    table = (tmp_path / "a" / "robustness.md").read_text()
    assert "| delay_10ms" in table and f"**{cells['delay_10ms']['falls']}/2**" in table
    assert rob.main(["--out", str(tmp_path / "c"), "--combine", str(tmp_path / "a" / "robustness.json"),
                     str(tmp_path / "b" / "robustness.json")]) == 0
    c = json.loads((tmp_path / "c" / "robustness.json").read_text())
    assert set(c["results"]) == {"heuristic@a", "heuristic@b"}
    skipped = tmp_path / "d"
    assert rob.main(argv[:4] + ["--seeds", "1", "--max-steps", "3", "--quiet", "--learned", f"bc={tmp_path}/none",
                                "--out", str(skipped)]) == 0
    assert "bc" in json.loads((skipped / "robustness.json").read_text())["skipped"]
    # explicit seeds: the same episodes as the range run's
    listed = tmp_path / "f"
    assert rob.main(argv + ["--out", str(listed), "--seed-list", "12"]) == 0
    f = json.loads((listed / "robustness.json").read_text())
    assert f["seeds"] == [12]
    for cond, cell in f["results"]["heuristic"].items():
        run = {k: v for k, v in cell["runs"][0].items() if k != "wall_time_s"}
        assert run == {k: v for k, v in cells[cond]["runs"][1].items() if k != "wall_time_s"}
    for bad in (["--workers", "0"], ["--learned", "xyz=dir"], ["--policies", "mpc-options"],
                ["--combine", str(tmp_path / "missing.json")], ["--simulator", "isaac"], ["--seed-list", "-1"],
                ["--seed-list", "3", "3"], ["--policies"], ["--policies", "--learned", f"bc={tmp_path}/none"]):
        with pytest.raises(SystemExit):
            rob.main(["--out", str(tmp_path / "e"), *bad])
