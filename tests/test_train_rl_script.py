"""``experiments/train_rl.py``'s options reach :func:`hsddp_gym.learning.sb3.train_sb3` (the training itself is tested
with train_sb3)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest


def test_select_episodes_sizes_the_evaluations_that_pick_the_best_checkpoint(tmp_path, experiment, monkeypatch):
    script = experiment("train_rl")
    calls = []

    def fake(algo, steps, seed, out, **kw):
        calls.append(dict(kw, algo=algo, steps=steps, seed=seed))
        ev = {"mean_return": 1.0, "std_return": 0.0, "falls": 0, "episodes": 1}
        return SimpleNamespace(summary={"steps": steps, "wall_time_s": 1.0, "eval": ev, "eval_best": ev})

    monkeypatch.setattr(script, "train_sb3", fake)
    argv = ["--algos", "ppo", "--seeds", "0", "1", "--steps", "100", "--out", str(tmp_path)]
    assert script.main(argv + ["--select-episodes", "20", "--eval-freq", "50"]) == 0
    assert [c["eval_episodes"] for c in calls] == [20, 20] and calls[0]["eval_freq"] == 50
    assert [c["seed"] for c in calls] == [0, 1]
    assert script.main(argv) == 0 and calls[-1]["eval_episodes"] == 5  # the default
    with pytest.raises(SystemExit):
        script.main(argv + ["--select-episodes", "0"])


def test_env_reaches_train_sb3_and_options_it_does_not_take_are_refused(tmp_path, experiment, monkeypatch):
    script = experiment("train_rl")
    calls = []

    def fake(algo, steps, seed, out, **kw):
        calls.append(kw)
        return SimpleNamespace(summary={"steps": steps, "wall_time_s": 1.0})

    monkeypatch.setattr(script, "train_sb3", fake)
    argv = ["--algos", "sac", "--steps", "100", "--out", str(tmp_path)]
    assert script.main(argv) == 0 and calls[-1]["env_id"] == "hsddp_gym/Bounding-v0"  # the default
    assert script.main(argv + ["--env", "hsddp_gym/Pronking-v0"]) == 0
    assert calls[-1]["env_id"] == "hsddp_gym/Pronking-v0"
    assert script.main(argv + ["--env", "hsddp_gym/Backflip-v0", "--vector-env"]) == 0
    assert calls[-1]["env_id"] == "hsddp_gym/Backflip-v0" and calls[-1]["vector_env"] is True
    assert script.main(argv + ["--env", "hsddp_gym/Backflip-v0", "--train-condition", "push", "--residual", "0.2"]) == 0
    assert calls[-1]["train_condition"] == "push" and calls[-1]["residual_scale"] == 0.2
    for extra in (["--train-condition", "push_x3", "--vector-env"], ["--residual", "3"],
                  ["--residual", "0.2", "--vector-env"]):
        with pytest.raises(SystemExit):
            script.main(argv + ["--env", "hsddp_gym/Pronking-v0", *extra])
    with pytest.raises(SystemExit):
        script.main(argv + ["--env", "hsddp_gym/Nope-v0"])
    assert len(calls) == 4
