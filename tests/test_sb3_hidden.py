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
