"""Every command-line entry point explains itself: ``--help`` of every ``experiments/`` script and of every
``hsddp-gym`` subcommand prints its usage and exits 0 (a stray ``%`` in a help text makes argparse's ``--help`` raise,
which nothing else would notice), and the shell commands a script's help quotes keep their line continuations (a
single backslash at a line's end in a docstring joins the lines)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SCRIPTS = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "experiments").glob("*.py"))


def _subcommands() -> list[str]:
    import argparse

    from hsddp_gym.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return sorted(sub.choices)


SUBCOMMANDS = _subcommands()


def test_the_lists_are_not_empty():
    assert len(SCRIPTS) >= 10 and "robustness" in SCRIPTS
    assert {"demo", "rollout", "dataset", "train"} <= set(SUBCOMMANDS)


@pytest.mark.parametrize("name", SCRIPTS)
def test_every_experiment_script_prints_its_help(name, experiment, capsys):
    script = experiment(name)
    with pytest.raises(SystemExit) as exit_:
        script.main(["--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage:") and "--help" in out
    joined = re.findall(r"\S {4,}--[a-z]", script.__doc__ or "")  # "... --seed 1000         --action-noise ..."
    assert not joined, f"a command in experiments/{name}.py's docstring lost its line continuation: {joined}"


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_every_cli_subcommand_prints_its_help(command, capsys):
    from hsddp_gym import cli

    with pytest.raises(SystemExit) as exit_:
        cli.main([command, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: hsddp-gym " + command)


def _subparsers():
    import argparse

    from hsddp_gym.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return sub.choices


def test_every_cli_option_has_a_help_text():
    import argparse

    for command, p in _subparsers().items():
        assert p.description, command
        for action in p._actions:
            if not isinstance(action, argparse._HelpAction):
                assert action.help and len(action.help) > 10, (command, action.option_strings)


def test_train_options_are_grouped_by_the_algorithms_that_use_them(capsys):
    """Every ``train`` option belongs to the algorithms of :data:`OPTION_ALGOS` (no more, no fewer options), sits in
    its group of ``train --help`` and its help starts with those algorithms."""
    from hsddp_gym.cli import train_command

    p = _subparsers()["train"]
    options = {a.option_strings[0]: a for a in p._actions if a.option_strings != ["-h", "--help"]}
    assert set(options) == set(train_command.OPTION_ALGOS)
    titles = {g.title: g for g in p._action_groups}
    for title, algo_of in train_command.GROUPS.values():
        assert {a.option_strings[0] for a in titles[title]._group_actions} == set(algo_of)
    for option, algos in train_command.OPTION_ALGOS.items():
        tag = "all algos" if algos == train_command.ALGOS else ", ".join(algos)
        assert options[option].help.startswith(f"[{tag}] "), option


def test_the_dataset_id_help_names_the_default_id_of_every_env():
    from hsddp_gym.datasets.storage import default_dataset_id
    from hsddp_gym.registry import DATASET_ENVS

    (action,) = [a for a in _subparsers()["dataset"]._actions if "--dataset-id" in a.option_strings]
    ids = [default_dataset_id("POLICY", env) for env in DATASET_ENVS]
    assert len(set(ids)) == len(DATASET_ENVS)
    assert default_dataset_id("mpc") == "hsddp_gym/bounding/mpc-v0"
    assert default_dataset_id("expert", "hsddp_gym/GapJump-v0") == "hsddp_gym/gap_jump/expert-v0"
    for env, dataset_id in zip(DATASET_ENVS, ids):
        assert f"{env}: {dataset_id}" in action.help


def test_rollout_help_lists_every_registered_env():
    from hsddp_gym.registry import ENV_TASKS

    (action,) = [a for a in _subparsers()["rollout"]._actions if "--env" in a.option_strings]
    assert tuple(action.choices) == tuple(ENV_TASKS)
    assert all(env in action.help for env in ENV_TASKS)
