"""The command line's parsers and argument types: one-line errors that name the subcommand's help and suggest the
closest valid option or choice, the options a user gave ([`CommandParser`][CommandParser] records them), and the
``type`` functions the subcommands share."""

from __future__ import annotations

import argparse

from hsddp_gym.util.validation import UsageError, did_you_mean, parenthesized


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors, ``error: MESSAGE; see PROG --help`` on stderr and exit code 2: ``--option:
    value (allowed: ...)`` for a bad value, ``--option: invalid choice 'x' (did you mean y?; allowed: ...)`` for a
    mistyped choice (subcommands included)."""

    def error(self, message: str):
        message = message[len("argument "):] if message.startswith("argument ") else message
        self.exit(2, f"error: {message}; see {self.prog} --help\n")

    def _check_value(self, action, value):  # argparse's choice check, with the closest choice suggested
        if action.choices is not None and value not in action.choices:
            choices = [str(c) for c in action.choices]
            raise argparse.ArgumentError(action, f"invalid choice {value!r}" + parenthesized(
                did_you_mean(value, choices), f"allowed: {', '.join(choices)}"))


class CommandParser(Parser):
    """The parser of one subcommand: an argument no option of the subcommand takes is an error naming the closest
    option (``unrecognized argument --polcy (did you mean --policy?)``), and the parsed namespace's ``given`` is
    the set of option destinations the user gave (whatever their value; see [`given_options`][given_options])."""

    def parse_known_args(self, args=None, namespace=None):
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(unrecognized_message(extras, self.option_strings()))
        parsed.given = given_options(self, args)
        return parsed, extras

    def option_strings(self) -> list[str]:
        """Every option string of the subcommand (``--policy``, ``--help``, ...)."""
        return [s for action in self._actions for s in action.option_strings]


def unrecognized_message(extras: list[str], options: list[str]) -> str:
    """``unrecognized argument --polcy (did you mean --policy?)``: the arguments no option takes, each option-like
    one (``--x`` or ``--x=value``) with the closest of ``options``; the values of unknown options are left out."""
    flags = [e.partition("=")[0] for e in extras if e.startswith("-")]
    named = [f + parenthesized(did_you_mean(f, options)) for f in flags] if flags else list(extras)
    return f"unrecognized argument{'s' if len(named) > 1 else ''} {', '.join(named)}"


def given_options(parser: argparse.ArgumentParser, args) -> set[str]:
    """The destinations of the options in ``args`` (a subcommand's arguments, already parsed once): ``args``
    parsed again with every default suppressed, so that an option given at its default value counts as given."""
    actions = [a for a in parser._actions if not isinstance(a, argparse._HelpAction)]
    defaults = [a.default for a in actions]
    for a in actions:
        a.default = argparse.SUPPRESS
    try:
        parsed, _ = argparse.ArgumentParser.parse_known_args(parser, args, None)
    finally:
        for a, d in zip(actions, defaults):
            a.default = d
    dests = {a.dest for a in actions}
    return {k for k in vars(parsed) if k in dests}


def number(kind, low: float, high: float = float("inf"), low_open: bool = False, what: str = ""):
    """An argparse ``type``: a finite ``kind(text)`` within ``[low, high]`` (``(low, high]`` with ``low_open``)."""

    def parse(text: str):
        value = kind(text)
        if not ((value > low if low_open else value >= low) and value <= high):  # NaN fails every comparison
            raise argparse.ArgumentTypeError(f"{text} (allowed: {what})")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its "invalid ... value" message
    return parse


positive_int = number(int, 1, what="an integer >= 1")
positive_float = number(float, 0.0, high=1e300, low_open=True, what="a finite number > 0")
nonnegative_int = number(int, 0, what="an integer >= 0")
nonnegative_float = number(float, 0.0, high=1e300, what="a finite number >= 0")
fraction = number(float, 0.0, 1.0, what="a number in [0, 1]")
finite_float = number(float, -1e300, 1e300, what="a finite number")
seed = number(int, 0, what="an integer >= 0 (a seed)")


def condition(text: str) -> str:
    """An argparse ``type``: a name of ``hsddp_gym.envs.perturbations.CONDITIONS``."""
    from hsddp_gym.envs.perturbations import CONDITIONS

    if text not in CONDITIONS:
        raise argparse.ArgumentTypeError(text + parenthesized(did_you_mean(text, CONDITIONS),
                                                              f"allowed: {', '.join(CONDITIONS)}"))
    return text


def int_list(text: str) -> list[int]:
    """An argparse ``type``: comma-separated positive integers (``128,128``)."""
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"must be comma-separated integers, got {text!r}") from exc
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"must be comma-separated positive integers, got {text!r}")
    return values


def learning_rate(text: str) -> float | str:
    """A learning rate: a number > 0, or ``lin_<number>`` (RL-Zoo's linear decay; ppo/sac only, checked later)."""
    from hsddp_gym.learning.sb3 import parse_learning_rate

    try:
        return parse_learning_rate(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc


def check_conditions(args, flag: str = "--condition") -> None:
    """UsageError when ``args.condition`` and ``--target-speed`` both set the target speed."""
    if not args.condition or args.target_speed is None:
        return
    from hsddp_gym.envs.perturbations import get_condition

    both = [c for c in args.condition if "target_speed" in get_condition(c).env_kwargs]
    if both:
        raise UsageError("--target-speed", f"given with {flag} {' '.join(both)}, which set the target speed",
                         "either --target-speed or speed conditions")


def check_task_condition_names(names, env_id, flag: str = "--condition") -> None:
    """UsageError naming ``flag`` when a condition of ``names`` does not apply to the task of ``env_id``
    ([`hsddp_gym.datasets.collection.check_task_conditions`][hsddp_gym.datasets.collection.check_task_conditions])."""
    from hsddp_gym.datasets.collection import check_task_conditions

    try:
        check_task_conditions(names, env_id, flag)
    except ValueError as exc:
        raise UsageError(flag, str(exc).removeprefix(f"{flag}: "),
                         "conditions that apply to the task (experiments/robustness.py --help)") from None


def print_values(summary: dict, keys, width: int, digits: int = 4) -> None:
    """Print ``  key value`` lines of ``summary``'s ``keys`` present (floats with ``digits`` significant digits)."""
    for k in keys:
        if k in summary:
            v = summary[k]
            print(f"  {k:<{width}} {v:.{digits}g}" if isinstance(v, float) else f"  {k:<{width}} {v}")
