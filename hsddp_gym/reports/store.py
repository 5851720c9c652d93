"""The results store: small JSON records by topic, each with the command that made it.

A record is one file ``results/<topic>/<name>.json``; its id is the path under ``results/`` without the suffix
(``"speed/env"``). Every record has the same envelope::

    {
      "record": "speed/env",                       # its id
      "description": "what it is, one sentence",
      "command": "python experiments/bench_env.py --seconds 3 --record results/speed/env.json",
      "version": "0.2.0",                          # hsddp_gym.__version__ of the run
      "machine": {"cpus": 2, "load_average_before": [...], "load_average_after": [...], ...},
      "data": {...}                                # what the script measured (its own layout)
    }

``command`` is a string or a list of strings (several commands, in order). Records are written atomically and read
as plain JSON (nothing is unpickled). Tables and figures are made from records only
([`hsddp_gym.reports.tables`][hsddp_gym.reports.tables], [`hsddp_gym.reports.figures`][hsddp_gym.reports.figures]).
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

from hsddp_gym.util.io import atomic_path, json_default

ENVELOPE_KEYS = ("record", "description", "command", "version", "machine", "data")
RESULTS_DIR = "results"


def _load_average() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):  # pragma: no cover - not on POSIX
        return None


def machine_info() -> dict:
    """What a speed figure needs to be read: cores, the load average now, the interpreter and platform."""
    return {"cpus": os.cpu_count(), "load_average_before": _load_average(), "python": platform.python_version(),
            "platform": platform.platform(terse=True), "processor": platform.machine()}


def without_option(argv: list[str] | None, option: str) -> list[str]:
    """``argv`` (default ``sys.argv[1:]``) less ``option`` and the values that follow it (up to the next ``--``
    option): e.g. ``--made-with`` (the commands that made a record's inputs) is not part of the command that makes
    the record."""
    out, skip = [], False
    for a in (sys.argv[1:] if argv is None else list(argv)):
        if a == option:
            skip = True
        elif skip and a.startswith("--"):
            skip = False
        if not skip:
            out.append(a)
    return out


def invoked_command(argv: list[str] | None = None) -> str:
    """The command line of this process as a user would type it (``python experiments/x.py ...``).

    Args:
        argv: the arguments after the program (default ``sys.argv[1:]``).
    """
    prog = Path(sys.argv[0])
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        prog_text = str(prog.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        prog_text = str(prog)
    head = f"python {prog_text}" if prog.suffix == ".py" else prog.name
    return " ".join([head, *(shlex.quote(str(a)) for a in args)])


def record_id(path) -> str:
    """The id of the record at ``path`` (``.../results/speed/env.json`` -> ``"speed/env"``)."""
    path = Path(path)
    if path.suffix != ".json":
        raise ValueError(f"record path must end in .json, got {str(path)!r}")
    parts = path.with_suffix("").parts
    if RESULTS_DIR in parts:
        parts = parts[len(parts) - parts[::-1].index(RESULTS_DIR):]
    else:
        parts = parts[-2:]
    return "/".join(parts)


def write_record(path, data: dict, description: str, command: str | list[str] | None = None,
                 machine: dict | None = None) -> Path:
    """Write a record atomically.

    Args:
        path: ``results/<topic>/<name>.json``.
        data: the measurements (JSON-serializable; NumPy arrays and scalars are converted).
        description: what the record is, one sentence.
        command: the command(s) that made it (default: this process's command line).
        machine: [`machine_info`][machine_info] taken before the measurement (``load_average_after`` is added now).
    """
    from hsddp_gym import __version__

    if not isinstance(data, dict):
        raise TypeError(f"data must be a dict, got {type(data).__name__}")
    if not isinstance(description, str) or not description.strip():
        raise ValueError(f"description must be a non-empty string, got {description!r}")
    machine = dict(machine_info() if machine is None else machine)
    machine["load_average_after"] = _load_average()
    payload = {"record": record_id(path), "description": description,
               "command": invoked_command() if command is None else command, "version": __version__,
               "machine": machine, "data": data}
    with atomic_path(path) as tmp:
        tmp.write_text(dumps(payload) + "\n")
    return Path(path)


SIGNIFICANT_DIGITS = 8
"""Significant digits a record keeps of a float (no measurement here is finer; the rest is noise that costs bytes)."""


def _rounded(value):
    if isinstance(value, float):
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}")
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return value


def _is_leaf(value) -> bool:
    """An object of scalars or a list of non-string scalars (goes on one line; a list of strings, such as commands,
    keeps one per line)."""
    if isinstance(value, dict):
        return all(not isinstance(v, (list, dict)) for v in value.values())
    return all(not isinstance(v, (list, dict, str)) for v in value)


SHORT_LINE = 180
"""A list or object (no list of strings) whose JSON takes at most this many characters goes on one line."""


def _layout(value, depth: int) -> str:
    if isinstance(value, (list, dict)):
        line = json.dumps(value, allow_nan=False, separators=(", ", ": "))
        strings = isinstance(value, list) and any(isinstance(v, str) for v in value)
        if not value or _is_leaf(value) or (len(line) <= SHORT_LINE and not strings):
            return line
    pad, inner = " " * depth, " " * (depth + 1)
    if isinstance(value, list):
        body = ",\n".join(inner + _layout(v, depth + 1) for v in value)
        return "[\n" + body + "\n" + pad + "]"
    if isinstance(value, dict):
        body = ",\n".join(f"{inner}{json.dumps(k)}: {_layout(v, depth + 1)}" for k, v in value.items())
        return "{\n" + body + "\n" + pad + "}"
    return json.dumps(value, allow_nan=False)


def dumps(payload) -> str:
    """JSON with one key per line, except that an object of scalars (one episode's fields), a list of numbers and a
    short list or object ([`SHORT_LINE`][SHORT_LINE] characters; no list of strings) go on one line; floats to
    [`SIGNIFICANT_DIGITS`][SIGNIFICANT_DIGITS] (records stay small and diffable)."""
    plain = json.loads(json.dumps(payload, default=json_default, allow_nan=False))
    return _layout(_rounded(plain), 0)


@dataclass(frozen=True)
class Record:
    """One record of the store (the envelope's fields)."""

    id: str
    description: str
    command: str | list
    version: str
    machine: dict
    data: dict
    path: Path

    @property
    def commands(self) -> list[str]:
        """``command`` as a list of command lines."""
        return [self.command] if isinstance(self.command, str) else list(self.command)


def read_record(path) -> Record:
    """Read and check one record (a missing envelope key or a wrong id is an error naming the file)."""
    path = Path(path)
    try:
        payload = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(payload, dict):
        raise ValueError(f"{path}: a record is a JSON object, got {type(payload).__name__}")
    missing = [k for k in ENVELOPE_KEYS if k not in payload]
    if missing:
        raise ValueError(f"{path}: record misses {missing}")
    if payload["record"] != record_id(path):
        raise ValueError(f"{path}: record id {payload['record']!r} does not match its path ({record_id(path)!r})")
    command = payload["command"]
    if not (isinstance(command, str) and command.strip()) and not (
            isinstance(command, list) and command and all(isinstance(c, str) and c.strip() for c in command)):
        raise ValueError(f"{path}: 'command' must be a non-empty string or list of strings")
    return Record(id=payload["record"], description=payload["description"], command=command,
                  version=payload["version"], machine=payload["machine"], data=payload["data"], path=path)


class Store:
    """The records under ``root/results`` (read lazily, each once).

    Args:
        root: the repository's top folder (the one holding ``results/``).
    """

    def __init__(self, root) -> None:
        self.root = Path(root)
        self.dir = self.root / RESULTS_DIR
        if not self.dir.is_dir():
            raise FileNotFoundError(f"no results store at {self.dir}")
        self._cache: dict[str, Record] = {}

    def ids(self) -> list[str]:
        """Every record id, sorted."""
        return sorted(record_id(p) for p in self.dir.rglob("*.json"))

    def __getitem__(self, rid: str) -> Record:
        if rid not in self._cache:
            path = self.dir / f"{rid}.json"
            if not path.is_file():
                raise KeyError(f"no record {rid!r} in {self.dir} (have: {', '.join(self.ids())})")
            self._cache[rid] = read_record(path)
        return self._cache[rid]

    def data(self, rid: str) -> dict:
        """The ``data`` of record ``rid``."""
        return self[rid].data


def compact(values, digits: int = 4):
    """``values`` (an array or nested lists of numbers) as nested lists rounded to ``digits`` significant digits:
    figure data small enough for the store."""
    import numpy as np

    arr = np.asarray(values)
    if arr.dtype.kind in "biu":
        return arr.tolist()
    flat = [float(f"{v:.{digits}g}") for v in arr.astype(float).ravel()]
    return np.array(flat).reshape(arr.shape).tolist()
