"""The front-ends of Algorithm 2: ``hsddp-gym sto`` writes its summary keys, takes duration bounds and the task-2
variants (recorded, and refused naming the option when wrong), and the experiment scripts
(``paper_task2_sto``, ``al_iterations``) validate their options."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.sto import STOOptions

STO_SUMMARY_KEYS = {"initial_total_time", "total_time", "reduction", "mode_durations", "iterations", "final_cost",
                    "switching_violation"}
"""The keys ``hsddp-gym sto`` writes to summary.json."""


@pytest.mark.parametrize("method", ["hsddp", "open-loop"])
def test_sto_cli_writes_the_summary_keys(method, tmp_path):
    from hsddp_gym.cli import main

    out = tmp_path / method
    assert main(["sto", "--method", method, "--iterations", "2", "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert STO_SUMMARY_KEYS <= set(s), STO_SUMMARY_KEYS - set(s)
    assert s["initial_total_time"] == pytest.approx(0.296, rel=1e-12)
    assert s["total_time"] == pytest.approx(sum(s["mode_durations"]), rel=1e-12)
    assert s["reduction"] == pytest.approx(1.0 - s["total_time"] / s["initial_total_time"], rel=1e-12)
    assert len(s["mode_durations"]) == 4 and s["iterations"] == 2 and s["switching_violation"] <= 1e-4
    assert (out / "solution.npz").exists()


def test_sto_cli_duration_bounds(tmp_path):
    """``--min-duration`` reaches the optimization: HS-DDP shortens back stance and the second flight the most
    (to about 22 ms unbounded), so a 60 ms minimum becomes active and is recorded."""
    from hsddp_gym.cli import main

    out = tmp_path / "bounded"
    assert main(["sto", "--iterations", "30", "--min-duration", "0.06", "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["min_duration"] == 0.06 and s["max_duration"] == STOOptions().max_duration
    d = np.array(s["mode_durations"])
    assert np.all(d >= 0.06 - 1e-12) and np.isclose(d.min(), 0.06), d
    assert s["switching_violation"] <= 1e-4


def test_sto_cli_variants_are_recorded_and_validated(tmp_path, capsys):
    from hsddp_gym.cli import main

    out = tmp_path / "v"
    assert main(["sto", "--iterations", "1", "--z-velocity", "code", "--grf-tracking", "off", "--terminal-half",
                 "off", "--max-touchdown-error", "0.001", "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert (s["z_velocity"], s["grf_tracking"], s["terminal_half"], s["periodic"]) == ("code", False, False, False)
    assert s["al_max_abs_tolerance"] == 0.001 and s["max_touchdown_error"] <= 0.001
    assert len(s["touchdown_heights"]) == 2
    for argv, name in ((["--z-velocity", "zero"], "--z-velocity"), (["--grf-tracking", "yes"], "--grf-tracking"),
                       (["--terminal-half", "1"], "--terminal-half"), (["--max-touchdown-error", "0"],
                                                                       "--max-touchdown-error"),
                       (["--periodic-weight", "-2"], "--periodic-weight")):
        with pytest.raises(SystemExit):
            main(["sto", *argv, "--out", str(tmp_path / "bad")])
        assert name in capsys.readouterr().err, argv
    for argv, name in ((["--periodic", "--cycles", "2"], "--cycles"), (["--periodic-weight", "10"], "--periodic")):
        assert main(["sto", *argv, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: {name}") and err.count("\n") == 1, err


def test_experiment_scripts_validate_their_options(experiment, capsys):
    task2 = experiment("paper_task2_sto")
    for argv, name in ((["--workers", "0"], "--workers"), (["--iterations", "-1"], "--iterations"),
                       (["--max-touchdown-error", "0"], "--max-touchdown-error"),
                       (["--z-velocity", "up"], "--z-velocity"), (["--terminal-half", "yes"], "--terminal-half")):
        with pytest.raises(SystemExit):
            task2.main(argv)
        assert name in capsys.readouterr().err, argv
    al = experiment("al_iterations")
    for argv, name in ((["--set", "sigma=3"], "--set"), (["--set", "beta=big"], "--set beta"),
                       (["--cycles", "0"], "--cycles")):
        with pytest.raises(SystemExit):
            al.main(argv)
        assert name in capsys.readouterr().err, argv
    assert al.parse_set("max_ddp_iterations=30") == ("max_ddp_iterations", 30)
    assert al.parse_set("sigma0=35.355") == ("sigma0", 35.355)
