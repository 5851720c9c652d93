"""The ``hsddp-gym`` command line.

Every subcommand writes into ``--out DIR``: a ``summary.json`` with the numbers, plus figures and data.
Run ``hsddp-gym SUBCOMMAND --help`` for the options of each. The subcommands live in one module per group:
[`planning_commands`][hsddp_gym.cli.planning_commands] (``demo``, ``plan``, ``sto``),
[`rollout_command`][hsddp_gym.cli.rollout_command], [`dataset_command`][hsddp_gym.cli.dataset_command] and
[`train_command`][hsddp_gym.cli.train_command]; [`parsing`][hsddp_gym.cli.parsing] holds the parsers and argument types
they share, [`env_choices`][hsddp_gym.cli.env_choices] the envs read from the task registry.
"""

from __future__ import annotations

import argparse
import contextlib
import sys

from hsddp_gym.cli import dataset_command, planning_commands, rollout_command, train_command
from hsddp_gym.cli.parsing import CommandParser, Parser
from hsddp_gym.util.extras import MissingExtraError
from hsddp_gym.util.validation import UsageError


def _version() -> str:
    import hsddp_gym

    return hsddp_gym.__version__


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``hsddp-gym`` and its subcommands (``demo``, ``plan``, ``rollout``, ``sto``, ``dataset``,
    ``train``)."""
    parser = Parser(
        prog="hsddp-gym",
        description="HS-DDP (Li & Wensing, RA-L 2020) for the planar MIT Mini Cheetah: plan bounding gaits, "
                    "optimize switching times, run the planner as MPC in the Gymnasium env.")
    parser.add_argument("--version", action="version", version=f"hsddp-gym {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=CommandParser)
    planning_commands.add_parsers(sub)
    rollout_command.add_parser(sub)
    dataset_command.add_parser(sub)
    train_command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI. A user error (a bad option value, a missing extra) prints one line ``error: ...`` on
    stderr and returns 2; options are checked before any long work starts."""
    with contextlib.suppress(AttributeError, ValueError):  # progress lines as they happen when piped
        sys.stdout.reconfigure(line_buffering=True)
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    args.command_line = " ".join(["hsddp-gym", *argv])  # recorded in summaries (the arguments actually parsed)
    try:
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"error: {exc}; see hsddp-gym {args.command} --help", file=sys.stderr)
        return 2
    except MissingExtraError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
