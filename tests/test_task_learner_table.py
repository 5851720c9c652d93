"""The task x learner evaluation: every policy of a task record also played under a push, observation noise and in the
MuJoCo twin (``experiments/tasks.py --conditions ... --mujoco``), and the README's table made from those counts."""

from __future__ import annotations

import pytest

from hsddp_gym.benchmarks.tasks import TWIN, condition_counts, task_evaluation_main
from hsddp_gym.registry import TASKS
from hsddp_gym.reports.store import Store, write_record
from hsddp_gym.reports.tables.tasks import TWIN_KEY, success_cell, tasks_summary


def test_the_counts_play_each_condition_and_the_twin_on_the_same_seeds():
    task = TASKS["stand_to_bound"]
    counts = condition_counts(task, "expert", [9700, 9701], ("push", "obs_noise"), twin=True)
    assert list(counts) == ["push", "obs_noise", TWIN]
    for c in counts.values():
        assert c["episodes"] == 2 and 0 <= c["successes"] <= 2 and 0 <= c["falls"] <= 2
    assert condition_counts(task, "expert", [9700], ()) == {}


def test_a_condition_that_cannot_apply_or_is_unknown_is_refused_naming_it(capsys):
    with pytest.raises(ValueError, match="speed_0.5.*does not apply"):
        condition_counts(TASKS["backflip"], "expert", [9600], ("speed_0.5",))
    with pytest.raises(ValueError, match="unknown condition"):
        condition_counts(TASKS["backflip"], "expert", [9600], ("sideways",))
    with pytest.raises(ValueError, match="a non-empty list of condition names, got 'push'"):
        condition_counts(TASKS["backflip"], "expert", [9600], "push")  # a name, not a list of names
    for bad, said in (("speed_0.5", "does not apply"), ("sideways", "unknown condition")):
        with pytest.raises(SystemExit):
            task_evaluation_main(["--task", "backflip", "--conditions", bad], "d")
        err = capsys.readouterr().err
        assert "--conditions" in err and said in err and bad in err


def _row(label, env_id, successes, conditions=None, **fields):
    row = {"label": label, "env_id": env_id, "episodes": 20, "successes": successes, "falls": 20 - successes,
           "mean_return": 1.0, "std_return": 0.0, **fields}
    if conditions is not None:
        row["conditions"] = {k: {"successes": v, "falls": 20 - v, "episodes": 20} for k, v in conditions.items()}
    return row


def test_the_table_sums_training_seeds_with_their_interval_and_each_condition(tmp_path):
    env = "hsddp_gym/StandToBound-v0"
    dagger = dict(rounds=8, episodes_per_round=8, labeller="mpc", train_wall_time_s=100.0)
    data = {"env_id": env, "seeds": list(range(9700, 9720)), "success_rule": "r",
            "rows": [_row("expert", env, 20, {"push": 19, "obs_noise": 18}),
                     _row("expert", "hsddp_gym/StandToBoundMuJoCo-v0", 17)],
            "bc": [_row("BC", env, s, transitions=100, demonstrations=4, train_wall_time_s=3.0) for s in (0, 10)],
            "dagger": [_row("DAgger", env, s, {"push": p, "obs_noise": 20, TWIN_KEY: 16}, transitions=1000 + s,
                            expert_labels=900, **dagger) for s, p in ((20, 15), (18, 16), (19, 17))],
            "ppo": [_row("PPO", env, s, algo="ppo", residual=None, checkpoint="final", env_steps=5000 + s,
                         total_env_steps=5000, train_wall_time_s=120.0) for s in (0, 2)],
            "sac": [_row("SAC", env, 5, {TWIN_KEY: 4}, algo="sac", residual={"base": "expert", "scale": 0.2},
                         checkpoint="best", env_steps=3000, total_env_steps=4000, train_wall_time_s=60.0)]}
    write_record(tmp_path / "results" / "tasks" / "stand_to_bound.json", data, "a test record",
                 command="python experiments/tasks.py --task stand_to_bound --record results/tasks/x.json")
    text = tasks_summary(Store(tmp_path))
    rows = {c[1]: c for c in ([x.strip() for x in line.split("|")[1:-1]] for line in text.splitlines()
                              if line.startswith("| ") and not line.startswith("| task"))}
    assert rows["expert (plan tracking)"][2:6] == ["20/20", "19/20", "18/20", "17/20"]
    assert rows["BC"][2:6] == ["10/40 (0-100 %)", "–", "–", "–"]  # no condition runs: dashes
    mpc = rows["DAgger, 8 iterations, MPC labels"]
    assert mpc[0] == "" and mpc[2].startswith("57/60 (") and mpc[3:6] == ["48/60", "60/60", "48/60"]
    assert mpc[6:] == ["900", "1,019", "100 s", "3"]
    assert rows["PPO (final weights)"][2:] == ["2/40 (0-69 %)", "–", "–", "–", "0", "5,001", "120 s", "2"]
    residual = rows["SAC, residual on the expert (scale 0.2) (best checkpoint)"]
    assert residual[2] == "5/20" and residual[5] == "4/20" and residual[7] == "3,000"


def test_the_success_interval_is_the_t_interval_of_the_seed_rates():
    rows = [{"successes": s, "episodes": 20} for s in (20, 18, 19)]
    # rates 1.0, 0.9, 0.95: mean 0.95, std 0.05, t(2) 4.303 -> half 0.1242
    assert success_cell(rows) == "57/60 (83-100 %)"
    assert success_cell(rows[:1]) == "20/20"
    assert success_cell([{"successes": 20, "episodes": 20}] * 3) == "60/60 (100 % every seed)"


def test_a_tiny_bc_and_ppo_of_a_task_go_through_the_evaluation_into_the_table(tmp_path):
    """The task table's path end to end at toy size: a dataset of the task's expert, BC on it and PPO from scratch in
    the task's env (``hsddp-gym``), evaluated on 2 seeds, under a push and in the twin, recorded and tabulated."""
    pytest.importorskip("stable_baselines3")
    from hsddp_gym import cli
    from hsddp_gym.reports.store import read_record

    env = TASKS["stand_to_bound"].env_id
    data, bc, ppo = tmp_path / "ds", tmp_path / "bc", tmp_path / "ppo"
    assert cli.main(["dataset", "--env", env, "--policy", "expert", "--episodes", "2", "--max-episode-steps", "40",
                     "--seed", "5", "--out", str(data), "--quiet"]) == 0
    assert cli.main(["train", "--algo", "bc", "--dataset", str(data), "--epochs", "2", "--eval-episodes", "1",
                     "--max-episode-steps", "20", "--out", str(bc), "--quiet"]) == 0
    assert cli.main(["train", "--algo", "ppo", "--env", env, "--steps", "200", "--eval-freq", "0", "--eval-episodes",
                     "1", "--max-episode-steps", "20", "--out", str(ppo), "--quiet"]) == 0
    record = tmp_path / "results" / "tasks" / "stand_to_bound.json"
    assert task_evaluation_main(["--task", "stand_to_bound", "--episodes", "2", "--bc", str(bc), "--ppo", str(ppo),
                                 "--conditions", "push", "--mujoco", "--record", str(record), "--quiet"], "d") == 0
    rec = read_record(record).data
    assert [r["label"] for r in rec["ppo"]] == ["PPO (training seed 0, final weights)"]  # no best checkpoint: none
    for row in rec["bc"] + rec["ppo"]:
        assert set(row["conditions"]) == {"push", TWIN} and row["episodes"] == 2 and "per_episode" not in row
        assert set(row["failed_seeds"]) <= {9700, 9701} and set(row["fell_seeds"]) <= set(row["failed_seeds"])
    assert rec["ppo"][0]["hyperparameters"]["n_steps"] == 512
    text = tasks_summary(Store(tmp_path))
    assert "| PPO (final weights) |" in text and "| BC |" in text
