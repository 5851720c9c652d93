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
