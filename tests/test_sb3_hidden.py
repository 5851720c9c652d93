"""The SB3 baselines' network sizes (``{"net_arch": [...]}``, ``hsddp-gym train --hidden``, ``train_rl.py
--hidden``): every network of the preset gets them, the loader rebuilds them from ``summary.json``, bad sizes are
refused naming the option."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("stable_baselines3")

from hsddp_gym.learning.sb3 import hyperparameters, load_trained_policy  # noqa: E402


def test_hidden_sizes_reach_every_network_and_the_loader(tmp_path, capsys, experiment):
    from hsddp_gym import cli

    hp = hyperparameters("sac", {"net_arch": [128, 64]})
    assert hp["policy_kwargs"]["net_arch"] == {"pi": [128, 64], "qf": [128, 64]}
    ppo = hyperparameters("ppo", {"net_arch": [32]}, "parallel")
    assert ppo["policy_kwargs"]["net_arch"] == {"pi": [32], "vf": [32]}
    assert ppo["policy_kwargs"]["activation_fn"] == "ELU"  # the preset's other policy settings stay
    for bad in ([], [0], "128", [1.5], [True]):
        with pytest.raises(ValueError, match="net_arch"):
            hyperparameters("sac", {"net_arch": bad})
    # SAC trained with small networks, loaded from summary.json's hyperparameters and the weights alone
    assert cli.main(["train", "--algo", "sac", "--steps", "300", "--learning-starts", "100", "--hidden", "16,8",
                     "--eval-freq", "0", "--eval-episodes", "1", "--max-episode-steps", "40", "--quiet",
                     "--out", str(tmp_path / "sac")]) == 0
    summary = json.loads((tmp_path / "sac" / "summary.json").read_text())
    assert summary["hyperparameters"]["policy_kwargs"]["net_arch"] == {"pi": [16, 8], "qf": [16, 8]}
    policy = load_trained_policy(tmp_path / "sac")
    assert policy is not None
    script = experiment("train_rl")
    with pytest.raises(SystemExit):
        script.main(["--algos", "sac", "--hidden", "128,x", "--out", str(tmp_path / "s")])
    with pytest.raises(SystemExit):
        script.main(["--algos", "sac", "--hidden", "0", "--out", str(tmp_path / "s")])
    assert "--hidden" in capsys.readouterr().err


def test_linear_learning_rate_falls_to_zero_over_the_run(tmp_path, capsys, experiment):
    from hsddp_gym.learning.sb3 import train_sb3
    from hsddp_gym.learning.sb3.presets import model_kwargs

    hp = hyperparameters("ppo", {"learning_rate": "lin_3e-4"}, "parallel")
    schedule = model_kwargs(hp)["learning_rate"]
    assert schedule(1.0) == pytest.approx(3e-4) and schedule(0.25) == pytest.approx(7.5e-5) and schedule(0.0) == 0
    assert model_kwargs(hyperparameters("ppo", {"learning_rate": 1e-4}, "parallel"))["learning_rate"] == 1e-4
    for bad in ("lin_", "lin_x", "lin_-1", "fast", 0, -1e-3, float("nan"), True):
        with pytest.raises(ValueError, match="learning_rate"):
            hyperparameters("ppo", {"learning_rate": bad}, "parallel")
    # a real run: the optimizer's step at the last update is the schedule's at that point, and the run loads
    res = train_sb3("ppo", 256, 0, tmp_path / "ppo", max_episode_steps=30, eval_freq=0, final_eval_episodes=0,
                    preset="parallel", vector_env=True,
                    overrides={"n_envs": 4, "n_steps": 32, "n_epochs": 1, "batch_size": 64,
                               "learning_rate": "lin_1e-3"})
    assert res.summary["hyperparameters"]["learning_rate"] == "lin_1e-3"
    from stable_baselines3 import PPO

    model = PPO.load(tmp_path / "ppo" / "model.zip", device="cpu")
    # SB3 sets the step before each update from the steps collected so far: after two rollouts of 128 steps the
    # last update ran at progress_remaining 1 - 256/256 = 0, the first at 0.5
    assert model.policy.optimizer.param_groups[0]["lr"] == 0.0
    assert model.lr_schedule(0.5) == pytest.approx(5e-4)
    assert load_trained_policy(tmp_path / "ppo") is not None
    script = experiment("train_rl")
    with pytest.raises(SystemExit):
        script.main(["--algos", "ppo", "--learning-rate", "lin_y", "--out", str(tmp_path / "s")])
    assert "--learning-rate" in capsys.readouterr().err
