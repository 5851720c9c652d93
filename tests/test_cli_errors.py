"""A new user's mistakes on the command line: each is one line ``error: OPTION: ... (allowed: ...)`` on stderr,
exit code 2, no traceback, and is caught before any long work starts (the long jobs are replaced by functions
that fail the test if reached). Also: ``--version``, line-buffered stdout, trained policies from the CLI, the
Python API's dataset paths."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hsddp_gym import cli
from hsddp_gym.datasets.generation import generate_dataset, partial_dir
from hsddp_gym.datasets.storage import load_minari, load_npz, read_metadata, resolve_dataset_dir
from hsddp_gym.registry import ENV_TASKS
from hsddp_gym.util.validation import UsageError

EPISODES = 2


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "heur"
    generate_dataset("heuristic", EPISODES, out, seed=0, max_episode_steps=20, progress=False)
    return out


@pytest.fixture
def no_long_work(monkeypatch):
    """The jobs behind the commands: reaching one fails the test (the error must come before)."""
    import hsddp_gym.datasets.generation as generation
    import hsddp_gym.learning.bc as bc
    import hsddp_gym.learning.dagger as dagger
    import hsddp_gym.learning.sb3 as sb3
    import hsddp_gym.planners.tasks as tasks
    import hsddp_gym.workflows as workflows
    from hsddp_gym.cli import rollout_command

    def reached(*args, **kwargs):
        raise AssertionError("long work started before the options were checked")

    for module, name in ((tasks, "plan_bounding"), (tasks, "run_sto"), (generation, "generate_dataset"),
                         (bc, "run_bc"), (dagger, "run_dagger"), (sb3, "train_sb3"), (workflows, "run_demo"),
                         (rollout_command, "run_rollouts"), (workflows, "run_rollouts")):
        monkeypatch.setattr(module, name, reached)


def run(argv, capsys) -> tuple[int, str]:
    try:
        rc = cli.main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    captured = capsys.readouterr()
    return rc, captured.err


def assert_one_line_error(rc, err, option):
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith(f"error: {option}"), err
    assert "Traceback" not in err and "allowed" in err


def _cases(tmp: Path, ds: Path) -> list[tuple[list[str], str]]:
    f = tmp / "a_file"
    f.write_text("x")
    out = str(tmp / "out")
    return [
        # --out naming an existing file, or a path through one
        (["rollout", "--out", str(f)], "--out"),
        (["rollout", "--out", str(f / "sub")], "--out"),
        (["plan", "--out", str(f)], "--out"),
        (["sto", "--out", str(f)], "--out"),
        (["demo", "--out", str(f)], "--out"),
        (["dataset", "--out", str(f)], "--out"),
        (["train", "--algo", "bc", "--dataset", str(ds), "--out", str(f)], "--out"),
        (["train", "--algo", "sac", "--steps", "10", "--out", str(f / "x")], "--out"),
        # an existing dataset without --overwrite
        (["dataset", "--out", str(ds)], "--out"),
        # numbers
        (["rollout", "--seed", "-5", "--out", out], "--seed"),
        (["dataset", "--seed", "-5", "--out", out], "--seed"),
        (["train", "--algo", "bc", "--seed", "-5", "--out", out], "--seed"),
        (["train", "--algo", "bc", "--action-queue", "-1", "--out", out], "--action-queue"),
        (["train", "--algo", "ppo", "--steps", "10", "--action-queue", "2", "--out", out], "--action-queue"),
        (["rollout", "--target-speed", "nan", "--out", out], "--target-speed"),
        (["rollout", "--target-speed", "inf", "--out", out], "--target-speed"),
        (["dataset", "--target-speed", "nan", "--out", out], "--target-speed"),
        (["rollout", "--push", "-1", "0", "0", "0", "--out", out], "--push"),
        (["rollout", "--push", "nan", "0", "0", "0", "--out", out], "--push"),
        (["rollout", "--push", "1", "0", "nan", "0", "--out", out], "--push"),
        (["rollout", "--push", "6", "0", "0", "0", "--out", out], "--push"),  # after the 5 s episode
        (["rollout", "--push", "1", "0", "0", "0", "--max-episode-steps", "100", "--out", out], "--push"),
        (["rollout", "--episodes", "0", "--out", out], "--episodes"),
        (["plan", "--speed", "inf", "--out", out], "--speed"),
        (["dataset", "--out", ""], "--out"),
        (["sto", "--min-duration", "0.3", "--max-duration", "0.1", "--out", out], "--min-duration"),
        (["sto", "--min-duration", "0.3", "--out", out], "--min-duration"),  # above the default max 0.2
        (["sto", "--max-duration", "0.01", "--out", out], "--max-duration"),  # below the default min 0.02
        (["sto", "--min-duration", "0.1", "--out", out], "--min-duration"),  # above the initial 72 ms
        (["sto", "--max-duration", "0.05", "--out", out], "--max-duration"),  # below the initial 80 ms
        # datasets
        (["dataset", "--dataset-id", "no version", "--out", out], "--dataset-id"),
        (["dataset", "--dataset-id", "hsddp_gym/bounding/mpc", "--out", out], "--dataset-id"),
        (["train", "--algo", "bc", "--dataset", str(tmp / "missing"), "--out", out], "--dataset"),
        (["train", "--algo", "bc", "--dataset", str(tmp), "--out", out], "--dataset"),
        (["train", "--algo", "bc", "--out", out], "--dataset"),
        (["train", "--algo", "bc", "--dataset", str(ds / "minari"), "--demos", "10", "--out", out], "--demos"),
        (["train", "--algo", "bc", "--dataset", str(ds), "--curve", "1,2,8", "--out", out], "--curve"),
        (["train", "--algo", "dagger", "--dataset", str(ds), "--demos", "3", "--out", out], "--demos"),
        (["train", "--algo", "dagger", "--curve", "1", "--out", out], "--curve"),
        (["train", "--algo", "bc", "--dataset", str(ds), "--demos", "1", "--curve", "2", "--out", out], "--curve"),
        (["train", "--algo", "ppo", "--out", out], "--steps"),
        (["train", "--algo", "ppo", "--steps", "10", "--learning-starts", "5", "--out", out], "--learning-starts"),
        (["train", "--algo", "sac", "--steps", "10", "--preset", "parallel", "--out", out], "--preset"),
        # policies
        (["rollout", "--policy", "foo", "--out", out], "--policy"),
        (["rollout", "--policy", "bc:" + str(tmp / "missing"), "--out", out], "--policy"),
        (["rollout", "--policy", "sb3:" + str(ds), "--out", out], "--policy"),
        (["rollout", "--env", "hsddp_gym/Terrain-v0", "--policy", "expert", "--out", out], "--policy"),
        (["dataset", "--env", "hsddp_gym/Terrain-v0", "--policy", "expert", "--out", out], "--policy"),
        (["rollout", "--transfer", "--out", out], "--transfer"),
        # envs
        (["rollout", "--env", "hsddp_gym/Terrain-v0", "--simulator", "mujoco", "--out", out], "--simulator"),
        (["rollout", "--env", "hsddp_gym/BoundingKKT-v0", "--simulator", "mujoco", "--out", out], "--simulator"),
        (["rollout", "--env", "hsddp_gym/StandToBound-v0", "--target-speed", "1.5", "--out", out], "--target-speed"),
        (["rollout", "--env", "hsddp_gym/Pronking-v0", "--target-speed", "3", "--out", out], "--target-speed"),
        (["rollout", "--env", "hsddp_gym/Backflip-v0", "--push", "3", "0", "0", "0", "--out", out], "--push"),
        (["train", "--algo", "ppo", "--steps", "10", "--env", "hsddp_gym/Terrain-v0", "--out", out], "--env"),
    ]


def test_every_user_error_is_one_line_with_exit_code_2_before_any_work(tmp_path, dataset, no_long_work, capsys):
    cases = _cases(tmp_path, dataset)
    for argv, option in cases:
        rc, err = run(argv, capsys)
        assert_one_line_error(rc, err, option)
    assert not (tmp_path / "out").exists() and not partial_dir(tmp_path / "out").exists()


def test_the_error_line_names_the_value_and_what_is_allowed(tmp_path, dataset, no_long_work, capsys):
    rc, err = run(["sto", "--min-duration", "0.3", "--max-duration", "0.1", "--out", str(tmp_path / "o")], capsys)
    assert "0.3" in err and "0.1" in err and "--min-duration < --max-duration" in err
    rc, err = run(["train", "--algo", "bc", "--dataset", str(dataset), "--demos", "10", "--out", str(tmp_path)],
                  capsys)
    assert f"1 .. {EPISODES}" in err and "10" in err
    rc, err = run(["rollout", "--push", "nan", "0", "0", "0", "--out", str(tmp_path / "o")], capsys)
    assert "nan" in err and "options[" not in err


def test_errors_from_a_real_process_have_no_traceback(tmp_path):
    """The installed entry point, as a user runs it (an invalid dataset id and a negative seed)."""
    exe = Path(sys.executable).with_name("hsddp-gym")
    for argv in (["dataset", "--dataset-id", "bad id", "--episodes", "1", "--out", str(tmp_path / "d")],
                 ["rollout", "--seed", "-5", "--out", str(tmp_path / "r")]):
        res = subprocess.run([str(exe), *argv], capture_output=True, text=True, timeout=120)
        assert res.returncode == 2 and "Traceback" not in res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and res.stderr.startswith("error: ")
    assert not (tmp_path / "d").exists() and not partial_dir(tmp_path / "d").exists()


def test_version_and_line_buffered_stdout(tmp_path):
    exe = Path(sys.executable).with_name("hsddp-gym")
    res = subprocess.run([str(exe), "--version"], capture_output=True, text=True, timeout=60)
    import hsddp_gym

    assert res.returncode == 0 and res.stdout.strip() == f"hsddp-gym {hsddp_gym.__version__}"
    helped = subprocess.run([str(exe), "rollout", "--help"], capture_output=True, text=True, timeout=60)
    assert "bc:DIR" in helped.stdout and "sb3:DIR" in helped.stdout
    # piped (as here), Python block-buffers stdout and progress lines would all arrive at exit; main() switches
    # to line buffering
    buffering = subprocess.run([sys.executable, "-c",
                                "import sys; from hsddp_gym import cli\n"
                                "try:\n    cli.main(['rollout', '--seed', '-1'])\nexcept SystemExit:\n    pass\n"
                                "print(sys.stdout.line_buffering)"], capture_output=True, text=True, timeout=60)
    assert buffering.stdout.strip().splitlines()[-1] == "True"


# ------------------------------------------------------------------------------------------ suggestions
@pytest.mark.parametrize("argv,line", [
    (["rollout", "--polcy", "mpc"], "error: unrecognized argument --polcy (did you mean --policy?); "
                                    "see hsddp-gym rollout --help"),
    (["rollout", "--qiet", "--zzzzzz=1"], "error: unrecognized arguments --qiet (did you mean --quiet?), --zzzzzz; "
                                          "see hsddp-gym rollout --help"),
    (["rolout"], "error: COMMAND: invalid choice 'rolout' (did you mean rollout?; allowed: "),
    (["dataset", "--policy", "mcp", "--out", "x"], "error: --policy: invalid choice 'mcp' (did you mean mpc?; "
                                                   "allowed: mpc, expert, heuristic, random); "
                                                   "see hsddp-gym dataset --help"),
    (["rollout", "--env", "Backflip-v0"], "error: --env: invalid choice 'Backflip-v0' (did you mean "
                                          "hsddp_gym/Backflip-v0?; allowed: hsddp_gym/Bounding-v0, "),
    (["train", "--algo", "bcc", "--out", "x"], "error: --algo: invalid choice 'bcc' (did you mean bc?; "),
    (["dataset", "--condition", "pushh", "--out", "x"], "error: --condition: pushh (did you mean push?; allowed: "),
    (["rollout", "--policy", "mcp"], "error: --policy: unknown policy 'mcp' (did you mean mpc?) (allowed: "),
    (["rollout", "--policy", "bcc:runs/bc"], "error: --policy: unknown policy 'bcc:runs/bc' (did you mean "
                                             "bc:runs/bc?) (allowed: "),
])
def test_mistakes_name_the_subcommands_help_and_the_closest_valid_word(argv, line, no_long_work, capsys):
    rc, err = run(argv, capsys)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith(line), err
    help_of = "hsddp-gym --help" if argv[0] == "rolout" else f"hsddp-gym {argv[0]} --help"
    assert err.rstrip().endswith(f"; see {help_of}"), err


def test_the_parsing_mechanisms():
    """The suggestion, the unrecognized-argument line and the options a user gave, each built directly."""
    from hsddp_gym.cli.parsing import CommandParser, given_options, unrecognized_message
    from hsddp_gym.util.validation import did_you_mean, parenthesized

    assert did_you_mean("mcp", ["mpc", "expert"]) == "did you mean mpc?"
    assert did_you_mean("zzzz", ["mpc", "expert"]) == ""
    assert parenthesized("", "b") == " (b)" and parenthesized("", "") == ""
    assert unrecognized_message(["--polcy", "mpc"], ["--policy"]) == "unrecognized argument --polcy (did you mean " \
                                                                    "--policy?)"
    assert unrecognized_message(["stray"], ["--policy"]) == "unrecognized argument stray"
    p = CommandParser(prog="hsddp-gym x")
    p.add_argument("--epochs", type=int, default=50)
    p.add_argument("--flag", action="store_true")
    p.add_argument("--name", default="a")
    assert given_options(p, ["--epochs", "50"]) == {"epochs"}  # given at its default value: still given
    assert given_options(p, ["--flag", "--name=b"]) == {"flag", "name"}
    args = p.parse_args(["--epochs", "50"])
    assert args.given == {"epochs"} and args.epochs == 50 and args.name == "a"  # the defaults are restored


def test_train_refuses_every_option_an_algorithm_does_not_use(tmp_path, no_long_work, capsys):
    """Each option of ``train`` given with each --algo that does not use it (even at its default value): one line
    naming the option and the algorithms that use it."""
    import argparse

    from hsddp_gym.cli.train_command import ALGOS, OPTION_ALGOS

    parser = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices["train"]
    actions = {a.option_strings[0]: a for a in parser._actions}
    values = {"--condition": ["push"], "--hidden": ["8"], "--curve": ["1"], "--gain-noise": ["0.01", "0.1"],
              "--input-noise": ["0.01", "0.1"]}
    checked = 0
    for option, algos in OPTION_ALGOS.items():
        action = actions[option]
        value = [] if action.nargs == 0 else values.get(option, [str(action.choices[0])] if action.choices
                                                        else [str(action.default or 1)])
        for algo in sorted(set(ALGOS) - set(algos)):
            rc, err = run(["train", "--algo", algo, option, *value, "--out", str(tmp_path / "o")], capsys)
            assert_one_line_error(rc, err, f"{option}: given with --algo {algo}")
            assert f"--algo {algos[0]}" in err
            checked += 1
    assert checked >= 60


# ------------------------------------------------------------------------------------------ every env
@pytest.mark.parametrize("env_id", ENV_TASKS)
def test_rollout_runs_in_every_registered_env(env_id, tmp_path, capsys):
    out = tmp_path / "r"
    assert cli.main(["rollout", "--env", env_id, "--policy", "random", "--episodes", "1", "--max-episode-steps", "5",
                     "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["env_id"] == env_id and s["mean_episode_length"] == 5 and "transfer" not in s
    capsys.readouterr()


def test_rollout_episodes_start_where_the_expert_says(tmp_path):
    """The expert of Bounding-v0 run in its MuJoCo twin: built by the one factory, its episode starts at its
    ``reset_options`` (its plan's first state)."""
    import gymnasium as gym

    from hsddp_gym.rollout.policies import make_policy

    out = tmp_path / "expert"
    twin = "hsddp_gym/BoundingMuJoCo-v0"
    assert cli.main(["rollout", "--env", twin, "--policy", "expert", "--episodes", "1", "--max-episode-steps", "3",
                     "--out", str(out), "--quiet"]) == 0
    env = gym.make(twin)
    start = make_policy("expert", env).reset_options["state"]
    np.testing.assert_array_equal(np.load(out / "episode0.npz")["states"][0], start)
    env.close()


def _fake_run(tmp: Path, env_id: str) -> Path:
    """A finished-looking bc run trained in ``env_id`` (its weights are never read: the env check comes first)."""
    run_dir = tmp / f"bc_{env_id.split('/')[-1]}"
    run_dir.mkdir()
    (run_dir / "summary.json").write_text(json.dumps({"algo": "bc", "env_id": env_id}))
    (run_dir / "policy.npz").write_bytes(b"")
    return run_dir


def test_a_trained_policy_is_refused_in_another_env(tmp_path, no_long_work, capsys):
    run_dir = _fake_run(tmp_path, "hsddp_gym/Backflip-v0")
    out = str(tmp_path / "o")
    rc, err = run(["rollout", "--policy", f"bc:{run_dir}", "--env", "hsddp_gym/Bounding-v0", "--out", out], capsys)
    assert_one_line_error(rc, err, "--env: hsddp_gym/Bounding-v0, but --policy bc:")
    assert "trained in hsddp_gym/Backflip-v0" in err and "--transfer" in err
    rc, err = run(["rollout", "--policy", f"bc:{run_dir}", "--simulator", "mujoco", "--out", out], capsys)
    assert_one_line_error(rc, err, "--simulator: hsddp_gym/BackflipMuJoCo-v0, but --policy bc:")
    assert "its MuJoCo twin" in err
    from hsddp_gym.cli.env_choices import relation, trained_env_id

    assert trained_env_id(run_dir) == "hsddp_gym/Backflip-v0"
    (run_dir / "summary.json").write_text(json.dumps({"algo": "bc"}))  # a run from before the field
    assert trained_env_id(run_dir) == "hsddp_gym/Bounding-v0"
    assert relation("hsddp_gym/Bounding-v0", "hsddp_gym/BoundingKKT-v0") == "its KKT twin"
    assert relation("hsddp_gym/Bounding-v0", "hsddp_gym/Pronking-v0") == "the env of another task (pronking)"


# ------------------------------------------------------------------------------------------ Python API
def test_dataset_paths_resolve_to_the_dataset_directory(dataset, tmp_path):
    for inner in (dataset / "minari", dataset / "episodes.npz", dataset / "metadata.json",
                  next((dataset / "minari").iterdir())):
        assert resolve_dataset_dir(inner) == dataset
    ds = load_minari(dataset / "minari")  # the folder MINARI_DATASETS_PATH points at
    assert ds.total_episodes == EPISODES
    assert read_metadata(dataset / "minari")["episodes"] == EPISODES
    assert load_npz(dataset / "minari").n_episodes == EPISODES
    with pytest.raises(UsageError, match="does not exist"):
        resolve_dataset_dir(tmp_path / "nothing", "dataset")
    (tmp_path / "other").mkdir()
    with pytest.raises(ValueError, match="not a dataset directory"):
        load_minari(tmp_path / "other")


def test_the_dataset_loaders_fail_alike(tmp_path):
    """A missing path or a folder without a dataset: load_npz and load_minari raise the same UsageError, naming the
    argument, the path, the files a dataset folder holds and the command that writes one."""
    (tmp_path / "other").mkdir()
    for path in (tmp_path / "nope", tmp_path / "other"):
        errors = []
        for load in (load_npz, load_minari):
            with pytest.raises(UsageError) as caught:
                load(path)
            errors.append(str(caught.value))
        assert errors[0] == errors[1], errors
        assert errors[0].startswith(f"path: {str(path)!r}")
        assert "metadata.json, episodes.npz and minari/" in errors[0] and "hsddp-gym dataset --out DIR" in errors[0]


def test_generate_dataset_refuses_a_bad_id_before_recording(tmp_path, monkeypatch):
    import hsddp_gym.datasets.generation as generation

    monkeypatch.setattr(generation, "collect_episodes", lambda *a, **k: pytest.fail("episodes were recorded"))
    with pytest.raises(ValueError, match="dataset_id"):
        generate_dataset("heuristic", 1, tmp_path / "d", dataset_id="no-version", progress=False)


def test_run_bc_refuses_more_demos_or_curve_points_than_the_dataset_has(dataset, tmp_path):
    from hsddp_gym.learning.bc import run_bc

    with pytest.raises(ValueError, match="demos"):
        run_bc(dataset, tmp_path / "bc", demos=EPISODES + 1, eval_episodes=0, progress=False)
    with pytest.raises(ValueError, match="curve"):
        run_bc(dataset, tmp_path / "bc", curve=[1, EPISODES + 5], eval_episodes=0, progress=False)
    from hsddp_gym.learning.demonstrations import load_demonstrations

    for fmt in ("npz", "minari"):  # DAgger's --demos goes through here
        with pytest.raises(ValueError, match=f"episodes must be in 1 .. {EPISODES}"):
            load_demonstrations(dataset, episodes=EPISODES + 1, fmt=fmt)


def test_dataset_reports_the_wall_time_with_the_reference_episodes(tmp_path, capsys):
    out = tmp_path / "dart"
    assert cli.main(["dataset", "--policy", "heuristic", "--episodes", "2", "--max-episode-steps", "10",
                     "--action-noise", "0.05", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    meta = read_metadata(out)
    assert meta["reference_time_s"] > 0 and "reference-score episodes" in printed and "in all" in printed


# ------------------------------------------------------------------------------------------ trained policies
def test_rollout_of_a_trained_bc_policy(dataset, tmp_path, capsys):
    """`hsddp-gym train --algo bc` then `rollout --policy bc:DIR`: the same actions as the policy loaded in
    Python, and a rerun without --video removes the GIF of an earlier run."""
    pytest.importorskip("torch")
    from hsddp_gym.learning.bc import MLPPolicy
    from hsddp_gym.workflows import load_policy

    run_dir = tmp_path / "bc"
    assert cli.main(["train", "--algo", "bc", "--dataset", str(dataset), "--epochs", "2", "--eval-episodes", "0",
                     "--out", str(run_dir), "--quiet"]) == 0
    out = tmp_path / "roll"
    argv = ["rollout", "--policy", f"bc:{run_dir}", "--episodes", "1", "--max-episode-steps", "8", "--out", str(out),
            "--quiet"]
    assert cli.main([*argv, "--video"]) == 0 and (out / "episode0.gif").exists()
    assert cli.main(argv) == 0
    assert not (out / "episode0.gif").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["policy"] == f"bc:{run_dir}" and "video" not in summary
    # the CLI's episode is the loaded policy's
    import gymnasium as gym

    env = gym.make("hsddp_gym/Bounding-v0", max_episode_steps=8)
    policy = load_policy(f"bc:{run_dir}", env)
    assert isinstance(policy, MLPPolicy)
    from hsddp_gym.rollout.episodes import run_episode

    ep = run_episode(env, policy, 0)
    np.testing.assert_array_equal(np.load(out / "episode0.npz")["actions"], ep.actions)
    env.close()
    capsys.readouterr()
    assert summary["env_id"] == "hsddp_gym/Bounding-v0"  # the env it was trained in
    # another env: refused, or transferred on purpose (a note on stderr, a record in the summary)
    twin = ["--env", "hsddp_gym/BoundingMuJoCo-v0"]
    rc, err = run([*argv, *twin], capsys)
    assert_one_line_error(rc, err, "--env: hsddp_gym/BoundingMuJoCo-v0, but --policy bc:")
    assert cli.main([*argv, *twin, "--transfer"]) == 0
    err = capsys.readouterr().err
    assert "note: --transfer: " in err and "trained in hsddp_gym/Bounding-v0" in err and "its MuJoCo twin" in err
    assert json.loads((out / "summary.json").read_text())["transfer"] == {
        "trained_env_id": "hsddp_gym/Bounding-v0", "env_id": "hsddp_gym/BoundingMuJoCo-v0",
        "relation": "its MuJoCo twin"}
    # without --env a trained policy runs in its own env
    summary_file = run_dir / "summary.json"
    summary_file.write_text(json.dumps({**json.loads(summary_file.read_text()), "env_id": "hsddp_gym/Pronking-v0"}))
    assert cli.main(argv) == 0
    assert json.loads((out / "summary.json").read_text())["env_id"] == "hsddp_gym/Pronking-v0"
    capsys.readouterr()
    # dagger:DIR accepts a BC run (both are MLP policies); sb3:DIR refuses it
    assert load_policy(f"dagger:{run_dir}").__class__ is MLPPolicy
    with pytest.raises(UsageError, match="'bc' run"):
        load_policy(f"sb3:{run_dir}")
    with pytest.raises(ValueError, match="trained policy"):
        load_policy("mpc")


def test_rollout_of_a_trained_sb3_policy(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    run_dir = tmp_path / "sac"
    assert cli.main(["train", "--algo", "sac", "--steps", "64", "--learning-starts", "32", "--eval-freq", "0",
                     "--eval-episodes", "0", "--max-episode-steps", "32", "--out", str(run_dir), "--quiet"]) == 0
    out = tmp_path / "roll"
    assert cli.main(["rollout", "--policy", f"sb3:{run_dir}", "--episodes", "1", "--max-episode-steps", "6",
                     "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["mean_episode_length"] > 0
    rc, err = run(["rollout", "--policy", f"ppo:{run_dir}", "--out", str(out)], capsys)
    assert_one_line_error(rc, err, "--policy")
    assert "'sac' run" in err


def test_check_output_dir_refuses_an_unwritable_parent(tmp_path):
    from hsddp_gym.util.validation import check_output_dir

    if os.geteuid() == 0:
        pytest.skip("root can write anywhere")
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    with pytest.raises(UsageError, match="not writable"):
        check_output_dir(locked / "x", "--out")


def test_train_says_when_curve_png_cannot_be_drawn(monkeypatch, tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    import hsddp_gym.learning.sb3 as sb3
    import hsddp_gym.util.extras as extras

    real = extras.is_installed
    monkeypatch.setattr(extras, "is_installed", lambda m: m != "matplotlib" and real(m))

    def stop(*args, **kwargs):
        raise RuntimeError("stopped before training")

    monkeypatch.setattr(sb3, "train_sb3", stop)
    with pytest.raises(RuntimeError, match="stopped before training"):
        cli.main(["train", "--algo", "sac", "--steps", "10", "--out", str(tmp_path / "t"), "--quiet"])
    err = capsys.readouterr().err
    assert "matplotlib is not installed, so curve.png will not be drawn" in err and "'viz'" not in err
    assert "hsddp_gym[viz]" in err


@pytest.mark.parametrize("command", [["dataset", "--policy", "expert", "--episodes", "1"],
                                     ["train", "--algo", "dagger"]])
def test_a_target_speed_for_a_task_that_fixes_its_own_is_one_line_naming_it(command, tmp_path, capsys):
    argv = [*command, "--env", "hsddp_gym/StandToBound-v0", "--target-speed", "1.2", "--out", str(tmp_path / "x")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --target-speed") and "takes no target speed" in err and not (tmp_path / "x").exists()
