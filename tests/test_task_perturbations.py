"""The perturbation conditions in every task's env: built for each task (its env, or its MuJoCo twin for the contact
conditions), pushes drawn in the task's window with its sizes, conditions that cannot apply refused by name, the
benchmark's episodes recording the task's success, and Bounding-v0's draws unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.envs.perturbations import (
    CONDITIONS,
    PHASE_PUSH_DELTA_V,
    TASK_SUITE,
    HardwareCondition,
    condition_task,
    get_condition,
    make_env,
    task_push,
)
from hsddp_gym.registry import TASKS

TASK_ENVS = [t.env_id for t in TASKS.values()]
EVERY_WRAPPER = HardwareCondition(
    "every_wrapper", "a push, a phase push, noise, a wrongly announced delay and a bias at once", push={},
    observation_noise=(0.01, 0.1), action_delay=2, announced_action_delay=1, observation_bias={"bias": {"dx": 0.05}},
    phase_push={"phase": "stance"})


@pytest.mark.parametrize("env_id", TASK_ENVS)
def test_a_condition_builds_in_every_task_env_and_its_twin(env_id):
    task = condition_task(env_id)
    names = [EVERY_WRAPPER] + (["contact_family"] if "mujoco" in task.twins else [])
    for cond in names:
        env = make_env(cond, env_id=env_id)
        try:
            obs, info = env.reset(seed=5)
            obs, *_ = env.step(np.zeros(4, dtype=np.float32))
            u = env.unwrapped
            assert np.all(np.isfinite(obs))
            twin = cond == "contact_family"
            assert env.spec.id == (task.twin_id if twin else env_id)  # the task's env, not Bounding-v0's
            if twin:
                assert "contact_model" in info
            else:
                assert info["push"]["time"] == pytest.approx(info["phase_push"]["earliest_time"])
                assert env.get_wrapper_attr("action_delay_steps") == 1 and u.dt == pytest.approx(0.005)
        finally:
            env.close()


@pytest.mark.parametrize("name", [n for n, t in TASKS.items() if n != "bounding"])
def test_pushes_come_in_the_task_window_with_its_sizes(name):
    task = TASKS[name]
    lo, hi = task.push_window
    size = np.array(task.push_size)
    env = make_env("push", env_id=task.env_id)
    phase = make_env("push_flight", env_id=task.env_id)
    times = []
    for seed in range(20):
        push = env.reset(seed=seed)[1]["push"]
        times.append(push["time"])
        assert np.all(np.abs(push["delta_v"]) <= size + 1e-12)
        later = phase.reset(seed=seed)[1]["phase_push"]  # the same draw, sized as the bound's phase pushes
        assert later["earliest_time"] == push["time"]
        np.testing.assert_allclose(later["delta_v"], np.array(push["delta_v"]) * np.array(PHASE_PUSH_DELTA_V)
                                   / np.array(TASKS["bounding"].push_size), rtol=1e-12)
    assert lo <= min(times) and max(times) <= hi and max(times) - min(times) > 0.5 * (hi - lo)
    assert hi <= task.max_episode_steps * 0.005  # within the episode
    env.close()
    phase.close()


def test_task_push_scales_the_bound_sizes_and_takes_the_task_window():
    flip = TASKS["backflip"]
    assert task_push({}, TASKS["bounding"]) == {"time_range": (1.0, 4.0), "max_delta_v": (0.8, 0.8, 5.0)}
    assert task_push({"count": 3}, flip) == {"time_range": flip.push_window, "count": 3,
                                             "max_delta_v": (0.4, 0.4, 3.0)}
    assert task_push({"phase": "flight", "max_delta_v": PHASE_PUSH_DELTA_V}, flip, PHASE_PUSH_DELTA_V)[
        "max_delta_v"] == (0.5, 0.5, 4.2)
    assert task_push({"time_range": (0.2, 0.3)}, flip)["time_range"] == (0.2, 0.3)  # a condition's own window wins


def test_bounding_draws_what_it_drew_before():
    """Bounding-v0's pushes at seed 3, as drawn before the conditions knew the tasks."""
    assert make_env("push").reset(seed=3)[1]["push"] == {
        "delta_v": [-0.5226793147835743, -0.5308755716198726, 1.5214915197898937], "time": 2.058209109971924}
    assert make_env("push_x3").reset(seed=3)[1]["push"][2] == {
        "delta_v": [0.4290819653907173, -0.006967314418307247, -2.6954411508179787], "time": 3.2170079951640873}
    assert make_env("push_flight").reset(seed=3)[1]["phase_push"] == {
        "delta_v": [-0.6533491434794678, -0.6635944645248408, 2.130088127705851],
        "earliest_time": 2.058209109971924, "phase": "flight"}
    assert make_env("push", env_id="hsddp_gym/Terrain-v0").reset(seed=3)[1]["push"] == \
        make_env("push").reset(seed=3)[1]["push"]  # terrain keeps the bound's window and sizes


@pytest.mark.parametrize(("condition", "env_id", "simulator", "reason"), [
    ("speed_0.5", "hsddp_gym/StandToBound-v0", None, "fixes its own speed"),
    ("speed_1.5", "hsddp_gym/Backflip-v0", None, "fixes its own speed"),
    ("speed_2.0", "hsddp_gym/Pronking-v0", None, "target speeds are 0.5-1.5 m/s"),
    ("contact_family", "hsddp_gym/Terrain-v0", None, "no mujoco twin"),
    ("default", "hsddp_gym/GapJump-v0", "kkt", "no kkt twin"),
])
def test_a_condition_that_cannot_apply_is_refused_naming_it_and_the_task(condition, env_id, simulator, reason):
    cond = get_condition(condition)
    task = condition_task(env_id)
    assert not cond.applies_to(task, simulator) and reason in cond.refusal(task, simulator)
    with pytest.raises(ValueError, match=f"condition '{condition}' does not apply to the task '{task.name}'.*{reason}"):
        cond.make(simulator=simulator, env_id=env_id)


def test_applicability_lists_the_conditions_of_each_task():
    def applicable(name):
        return {c for c in CONDITIONS if CONDITIONS[c].applies_to(name)}

    speeds = {c for c in CONDITIONS if c.startswith("speed_")}
    assert applicable("bounding") == set(CONDITIONS)
    assert applicable("pronking") == set(CONDITIONS) - {"speed_2.0"}
    assert applicable("terrain") == set(CONDITIONS) - {c for c in CONDITIONS if c.startswith("contact_")}
    for name in ("backflip", "gap_jump", "bound_to_stop"):
        assert applicable(name) == set(CONDITIONS) - speeds
        assert set(TASK_SUITE) <= applicable(name)
    with pytest.raises(ValueError, match="env_id must be a task's env id"):
        get_condition("default").make(env_id="hsddp_gym/BackflipMuJoCo-v0")


def test_the_benchmark_records_each_episode_s_success_in_a_task():
    from hsddp_gym.benchmarks.robustness import (
        merge_task_record,
        policy_spec,
        run_one,
        summarize_cell,
        task_record_entry,
    )

    runs = [run_one(("heuristic", {"kind": "heuristic"}, "push", seed, 4, "bounding", "hsddp_gym/GapJump-v0"))
            for seed in (3, 4)]
    assert [r["success"] for r in runs] == [False, False]  # 4 steps: not across the gap
    cell = summarize_cell(runs)
    assert cell["successes"] == 0 and cell["failed_seeds"] == [3, 4] and cell["speed_error"] is not None
    flat = run_one(("heuristic", {"kind": "heuristic"}, "default", 3, 4, "bounding"))
    assert "success" not in flat and "successes" not in summarize_cell([flat])  # Bounding-v0: as before
    spec = policy_spec({"kind": "expert"}, "hsddp_gym/Backflip-v0")
    assert spec.name == "expert" and spec.task is TASKS["backflip"]

    pushed = summarize_cell([dict(r, fell=i == 1, fall_time_s=0.5 * i) for i, r in enumerate(runs)])
    fine = summarize_cell([dict(r, success=True) for r in runs])
    entry = task_record_entry({"expert": {"push": pushed}}, ["push"])
    assert entry == {"expert": {"successes": [0], "falls": [1]}}
    first = merge_task_record(None, "gap_jump", {"results": entry}, ["push"], [3, 4])
    other = task_record_entry({"expert": {"default": fine, "push": pushed}}, ["default", "push"])
    both = merge_task_record(first, "box_jump", {"results": other}, ["default", "push"], [3, 4])
    assert both["conditions"] == ["push", "default"] and list(both["tasks"]) == ["box_jump", "gap_jump"]
    assert both["tasks"]["gap_jump"]["results"]["expert"]["falls"] == [1, None]  # not run: None
    assert both["tasks"]["box_jump"]["results"]["expert"]["successes"] == [0, 2]  # the record's order
    again = merge_task_record(both, "gap_jump", {"results": other}, ["default", "push"], [3, 4])
    assert again["tasks"]["gap_jump"]["results"]["expert"]["successes"] == [0, 2]  # replaced
    mpc = merge_task_record(again, "gap_jump", {"results": {"mpc": entry["expert"]}}, ["push"], [3, 4])
    assert set(mpc["tasks"]["gap_jump"]["results"]) == {"expert", "mpc"}  # a policy joins, the others stay
    assert mpc["tasks"]["gap_jump"]["results"]["mpc"]["falls"] == [1, None]
    with pytest.raises(ValueError, match="seeds"):
        merge_task_record(both, "gap_jump", {"results": entry}, ["push"], [5, 6])
