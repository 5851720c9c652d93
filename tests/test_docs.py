"""The README's and the documentation site's code blocks: every ```python block runs as written, every command line
of a ```bash block parses with its program's own argument parser, and the two set-up commands install every extra a
command can ask for.

The Python blocks read files that the CLI writes (a dataset, a BC run, a SAC run); the test writes them with the same
commands at tiny settings into a scratch working directory, then runs each block unchanged in a fresh interpreter
there.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import runpy
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

from hsddp_gym.reports.markers import markdown_files

ROOT = Path(__file__).resolve().parents[1]
PAGES = {str(p.relative_to(ROOT)): p.read_text() for p in markdown_files(ROOT)}
README = PAGES["README.md"]


def fenced_blocks(text: str, language: str) -> list[str]:
    """The bodies of the ```language blocks of a Markdown text."""
    return re.findall(rf"^```{language}\n(.*?)^```", text, flags=re.S | re.M)


PYTHON_BLOCKS = [(name, i, code) for name, text in PAGES.items()
                 for i, code in enumerate(fenced_blocks(text, "python"))]


def command_lines(block: str) -> list[str]:
    """The ``hsddp-gym ...``, ``python experiments/...`` and ``python -m hsddp_gym...`` commands of a shell block
    (continuation lines joined, comments dropped, split at ``&&``, ``;`` and ``|``; loop variables read as 0)."""
    text = re.sub(r"\\\n", " ", block)
    text = re.sub(r"\$\([^)]*\)", "", text)              # command substitutions
    text = re.sub(r"\$\{?[A-Za-z_][A-Za-z_0-9]*\}?", "0", text)  # shell variables
    out = []
    for line in text.splitlines():
        try:
            tokens = shlex.split(line, comments=True)
        except ValueError as exc:
            raise AssertionError(f"unparsable shell line: {line!r} ({exc})") from None
        cmd: list[str] = []
        for tok in [*tokens, ";"]:
            if tok in ("&&", ";", "|", "||", "&", "do", "done", "then", "fi"):
                if cmd:
                    out.append(cmd)
                cmd = []
            else:
                cmd.append(tok)
    return [c for c in out if c and (c[0] == "hsddp-gym" or (c[0] in ("python", "python3") and len(c) > 1 and (
        c[1].startswith("experiments/") or (c[1] == "-m" and len(c) > 2 and c[2].startswith("hsddp_gym")))))]


COMMANDS = [(name, " ".join(cmd), cmd) for name, text in PAGES.items() for block in fenced_blocks(text, "bash")
            for cmd in command_lines(block)]


class _Parsed(Exception):
    """Raised by the patched ``parse_args`` once the arguments have parsed."""


@contextlib.contextmanager
def _parse_only():
    original = argparse.ArgumentParser.parse_args

    def parse_args(self, args=None, namespace=None):
        original(self, args, namespace)
        raise _Parsed

    argparse.ArgumentParser.parse_args = parse_args
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_args = original


def parse(cmd: list[str]) -> str | None:
    """None if ``cmd`` parses with its program's parser, else the parser's message."""
    err = io.StringIO()
    if cmd[0] == "hsddp-gym":
        from hsddp_gym.cli import main as run
        argv = cmd[1:]
    elif cmd[1] == "-m":
        module = runpy.run_module(cmd[2] + ("" if cmd[2].endswith("__main__") else ".__main__"), run_name="docs")
        run, argv = module["main"], cmd[3:]
    else:
        script = ROOT / cmd[1]
        if not script.is_file():
            return f"no such script {cmd[1]}"
        module = runpy.run_path(str(script), run_name="docs")
        run, argv = module["main"], cmd[2:]
    with _parse_only(), contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            run(argv)
        except _Parsed:
            return None
        except SystemExit as exc:
            if exc.code in (0, None):
                return None  # --help
            return err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else f"exit {exc.code}"
    return "the program finished without parsing its arguments"


def test_the_pages_have_the_blocks_users_need():
    joined = "\n".join(code for _, _, code in PYTHON_BLOCKS)
    readme = "\n".join(fenced_blocks(README, "python"))
    for needle in ('gym.make("hsddp_gym/Bounding-v0"', "minari.load_dataset(", "MPCPolicy"):
        assert needle in readme, f"README quickstart lacks {needle}"
    for needle in ("load_minari(", "load_policy(", "sol.control("):
        assert needle in joined, needle
    assert len(COMMANDS) >= 20


@pytest.mark.parametrize("page,line,cmd", COMMANDS, ids=[f"{n}:{c[:60]}" for n, c, _ in COMMANDS])
def test_every_documented_command_parses(page, line, cmd):
    problem = parse(cmd)
    assert problem is None, f"{page}: `{line}`: {problem}"


def test_a_wrong_documented_command_is_caught():
    assert parse(["hsddp-gym", "rollout", "--no-such-option"]) is not None
    assert parse(["python", "experiments/robustness.py", "--conditions", "no_such_condition"]) is not None
    assert parse(["python", "experiments/no_such_script.py"]) == "no such script experiments/no_such_script.py"
    assert parse(["hsddp-gym", "rollout", "--policy", "mpc", "--episodes", "2"]) is None


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A working directory with the files the snippets load, written by the CLI at tiny settings."""
    cwd = tmp_path_factory.mktemp("docs")
    exe = str(Path(sys.executable).with_name("hsddp-gym"))
    commands = [
        [exe, "dataset", "--policy", "mpc", "--episodes", "1", "--max-episode-steps", "10", "--quiet",
         "--out", "runs/demo_dataset"],
        [exe, "train", "--algo", "bc", "--dataset", "runs/demo_dataset", "--epochs", "2", "--eval-episodes", "0",
         "--quiet", "--out", "runs/bc"],
        [exe, "train", "--algo", "sac", "--steps", "64", "--learning-starts", "32", "--eval-freq", "0",
         "--eval-episodes", "0", "--max-episode-steps", "32", "--quiet", "--out", "runs/sac"],
    ]
    for cmd in commands:
        res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-2000:]
    return cwd


@pytest.mark.slow
@pytest.mark.parametrize("page,index,code", PYTHON_BLOCKS, ids=[f"{n}[{i}]" for n, i, _ in PYTHON_BLOCKS])
def test_every_python_block_runs_as_written(workdir, page, index, code):
    env = {k: v for k, v in os.environ.items() if k != "MINARI_DATASETS_PATH"}
    env["MPLBACKEND"] = "Agg"
    res = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True, timeout=600,
                         env=env)
    assert res.returncode == 0, f"{page}, python block {index}:\n{code}\n--- stderr:\n{res.stderr[-3000:]}"


def test_the_two_setup_commands_install_every_extra_a_command_asks_for():
    """`pip install "torch==2.13.0" && pip install -e ".[all]"` must cover every package that
    :mod:`hsddp_gym.util.extras` can ask for, so the README's commands stay the whole set-up."""
    from hsddp_gym.util.extras import _PIP_NAMES, EXTRAS

    setup = re.findall(r"^python3 -m venv .*$", README, flags=re.M)
    assert len(setup) == 2 and all('pip install "torch==2.13.0" && pip install -e ".[all]"' in c for c in setup)
    assert setup[0].endswith("hsddp-gym demo") and setup[1].endswith("python -m pytest -q")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    optional = project["optional-dependencies"]
    assert set(re.findall(r"\[(.*)\]", optional["all"][0])[0].split(",")) >= {"rl", "data", "viz"}

    def names(reqs):
        return {re.split(r"[\[<>=; ]", r, maxsplit=1)[0].lower() for r in reqs}

    for module, (extra, _) in EXTRAS.items():
        pip_name = _PIP_NAMES.get(module, module).lower()
        if extra == "torch":
            continue  # installed by the first half of the command
        listed = names(optional[extra])
        implied = {"h5py": "minari", "imageio": "imageio"}  # minari[hdf5] brings h5py
        assert pip_name in listed or implied.get(pip_name) in listed, (module, extra)


def test_the_site_builds_strict(tmp_path):
    """``mkdocs build --strict``: no broken link, no missing page or reference, no docstring warning."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-4000:]
    assert (tmp_path / "site" / "api" / "policies" / "index.html").is_file()
