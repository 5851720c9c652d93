"""gSDE exploration for the PPO baseline (``{"sde": True}``, ``train_rl.py --sde``): the settings it sets, its
refusals, and a real short run whose policy loads and whose own draws follow gSDE (noise weights held for
``sde_sample_freq`` steps, reproducible per noise seed)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from hsddp_gym.learning.sb3 import SDE_HYPERPARAMS, hyperparameters, load_trained_policy, train_sb3  # noqa: E402


def test_sde_sets_gsde_and_is_refused_where_it_does_not_apply(tmp_path, capsys, experiment):
    hp = hyperparameters("ppo", {"sde": True}, "parallel")
    assert hp["use_sde"] is True and hp["sde_sample_freq"] == SDE_HYPERPARAMS["sde_sample_freq"]
    assert hp["policy_kwargs"]["log_std_init"] == -2.0 and hp["policy_kwargs"]["activation_fn"] == "ELU"
    assert "use_sde" not in hyperparameters("ppo", {"sde": False}, "parallel")
    with pytest.raises(ValueError, match="ppo only"):
        hyperparameters("sac", {"sde": True})
    with pytest.raises(ValueError, match="sde must be"):
        hyperparameters("ppo", {"sde": "yes"})
    # an explicit initial log std wins over gSDE's -2 whatever the order of the overrides
    for overrides in ({"log_std_init": -3, "sde": True}, {"sde": True, "log_std_init": -3}):
        assert hyperparameters("ppo", overrides, "parallel")["policy_kwargs"]["log_std_init"] == -3.0
    assert hyperparameters("ppo", {"log_std_init": -1.5})["policy_kwargs"]["log_std_init"] == -1.5
    for algo, bad in (("ppo", float("nan")), ("ppo", "low"), ("ppo", True), ("sac", -3.0)):
        with pytest.raises(ValueError, match="log_std_init"):
            hyperparameters(algo, {"log_std_init": bad})
    with pytest.raises(SystemExit):
        experiment("train_rl").main(["--algos", "sac", "--log-std-init", "-3", "--out", str(tmp_path / "s")])
    assert "--log-std-init" in capsys.readouterr().err
    script = experiment("train_rl")
    with pytest.raises(SystemExit):
        script.main(["--algos", "sac", "--sde", "--out", str(tmp_path / "s")])
    assert "--sde" in capsys.readouterr().err
    from hsddp_gym import cli

    assert cli.main(["train", "--algo", "sac", "--sde", "--steps", "5", "--out", str(tmp_path / "c")]) == 2
    assert capsys.readouterr().err.startswith("error: --sde: given with --algo sac")


def test_a_gsde_run_loads_and_its_draws_hold_the_noise_weights(tmp_path):
    res = train_sb3("ppo", 256, 0, tmp_path / "ppo", max_episode_steps=30, eval_freq=0, final_eval_episodes=2,
                    preset="parallel", vector_env=True,
                    overrides={"n_envs": 4, "n_steps": 32, "n_epochs": 1, "batch_size": 64, "sde": True,
                               "net_arch": [16]})
    assert res.summary["hyperparameters"]["use_sde"] is True
    assert res.summary["eval"]["episodes"] == 2 and res.summary["eval_stochastic"]["episodes"] == 2
    obs = np.zeros(17, dtype=np.float32)
    draws = load_trained_policy(tmp_path / "ppo", deterministic=False, noise_seed=3)
    mean = load_trained_policy(tmp_path / "ppo")
    m = mean.act(obs)
    run = [draws.act(obs) for _ in range(9)]
    # the same observation: the same draw while the weights are held (4 steps), another after each redraw
    assert all(np.array_equal(run[k], run[0]) for k in range(4))
    assert not np.array_equal(run[4], run[0]) and all(np.array_equal(run[k], run[4]) for k in range(5, 8))
    assert not np.array_equal(run[0], m)
    draws.reset()
    assert np.array_equal(draws.act(obs), run[0])  # reseeded at every reset


def test_noise_scale_sweep_reads_the_runs_and_scale_zero_is_the_mean_action(tmp_path, experiment):
    import json

    from hsddp_gym.learning.reporting import evaluate_policy_episodes

    train_sb3("ppo", 128, 0, tmp_path / "ppo", max_episode_steps=30, eval_freq=0, final_eval_episodes=0,
              preset="parallel", vector_env=True, overrides={"n_envs": 4, "n_steps": 32, "n_epochs": 1,
                                                             "batch_size": 64, "net_arch": [16]})
    script = experiment("rl_noise_scale")
    out = tmp_path / "sweep"
    assert script.main(["--runs", str(tmp_path / "ppo"), "--out", str(out), "--scales", "0", "0.5", "1",
                        "--episodes", "2", "--max-episode-steps", "25"]) == 0
    rows = json.loads((out / "noise_scale.json").read_text())["rows"]
    assert [r["scale"] for r in rows] == [0.0, 0.5, 1.0] and all(r["episodes"] == 2 for r in rows)
    mean = evaluate_policy_episodes(load_trained_policy(tmp_path / "ppo"), 2, 0, max_episode_steps=25)
    assert rows[0]["returns"] == mean["returns"] and rows[2]["returns"] != rows[0]["returns"]
    assert "| 0 (mean action) |" in (out / "noise_scale.md").read_text()
    with pytest.raises(ValueError, match="noise_scale"):
        load_trained_policy(tmp_path / "ppo", noise_scale=0.5)  # scales draws only
    with pytest.raises(ValueError, match="noise_scale"):
        load_trained_policy(tmp_path / "ppo", deterministic=False, noise_scale=-1.0)
    with pytest.raises(SystemExit):
        script.main(["--runs", str(tmp_path / "nothing"), "--out", str(out)])


def test_the_cli_sets_the_learning_rate_and_the_initial_noise_of_rl_runs(tmp_path, capsys):
    """``hsddp-gym train --lr`` (a number or lin_<number>) and ``--log-std-init``, as train_rl.py's options; bad
    values stop before training with the option named."""
    import json

    from hsddp_gym import cli
    from hsddp_gym.learning.sb3 import parse_learning_rate

    assert parse_learning_rate("3e-4") == 3e-4 and parse_learning_rate("lin_3e-4") == "lin_3e-4"
    for bad in ("fast", "lin_x", "0", "-1e-3", "nan"):
        with pytest.raises(ValueError, match="learning_rate"):
            parse_learning_rate(bad)
    with pytest.raises(TypeError, match="str"):
        parse_learning_rate(3e-4)
    out = tmp_path / "ppo"
    assert cli.main(["train", "--algo", "ppo", "--steps", "64", "--lr", "lin_2e-4", "--log-std-init", "-1.5",
                     "--hidden", "8", "--eval-freq", "0", "--eval-episodes", "1", "--max-episode-steps", "10",
                     "--out", str(out), "--quiet"]) == 0
    hp = json.loads((out / "summary.json").read_text())["hyperparameters"]
    assert hp["learning_rate"] == "lin_2e-4" and hp["policy_kwargs"]["log_std_init"] == -1.5
    bc = cli.build_parser().parse_args(["train", "--algo", "bc", "--dataset", "d", "--out", "x", "--lr", "5e-4"])
    default = cli.build_parser().parse_args(["train", "--algo", "bc", "--out", "x"])
    assert bc.lr == 5e-4 and cli.train_command._bc_lr(default) == 1e-3
    for argv, message in ((["--algo", "ppo", "--steps", "5", "--log-std-init", "nan"], "error: --log-std-init: "),
                          (["--algo", "sac", "--steps", "5", "--log-std-init", "-1"], "error: --log-std-init: given"),
                          (["--algo", "bc", "--dataset", "d", "--lr", "lin_1e-3"], "error: --lr: lin_1e-3"),
                          (["--algo", "ppo", "--steps", "5", "--lr", "fast"], "--lr")):
        code = None
        try:
            code = cli.main(["train", *argv, "--out", str(tmp_path / "bad")])
        except SystemExit as exc:  # argparse's own refusal of a bad --lr
            code = exc.code
        assert code == 2 and message in capsys.readouterr().err, argv
        assert not (tmp_path / "bad").exists()
