"""The README's Python blocks run as written, and its two set-up commands install every extra a command can ask
for.

The blocks read files that the README's own commands write (a dataset, a BC run, a SAC run); the test writes
them with the same commands at small settings into a scratch working directory, then runs each ```python block
unchanged in a fresh interpreter there.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A working directory with the files the snippets load, written by the README's commands (shortened)."""
    cwd = tmp_path_factory.mktemp("readme")
    exe = str(Path(sys.executable).with_name("hsddp-gym"))
    commands = [
        [exe, "dataset", "--policy", "mpc", "--episodes", "1", "--max-episode-steps", "10", "--quiet",
         "--out", "runs/issue7/mpc50_dart"],
        [exe, "train", "--algo", "bc", "--dataset", "runs/issue7/mpc50_dart", "--epochs", "2", "--eval-episodes", "0",
         "--quiet", "--out", "runs/issue7/bc"],
        [exe, "train", "--algo", "sac", "--steps", "64", "--learning-starts", "32", "--eval-freq", "0",
         "--eval-episodes", "0", "--max-episode-steps", "32", "--quiet", "--out", "runs/rl1h/sac/seed0"],
    ]
    for cmd in commands:
        res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-2000:]
    return cwd


def test_the_readme_has_the_python_blocks_we_run():
    blocks = python_blocks(README)
    assert len(blocks) >= 4
    joined = "\n".join(blocks)
    for needle in ("gym.make(\"hsddp_gym/Bounding-v0\"", "load_minari(", "minari.load_dataset(", "load_policy(",
                   "sol.control(k, x)"):
        assert needle in joined, needle


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(python_blocks(README))))
def test_readme_python_block_runs_as_written(workdir, index):
    code = python_blocks(README)[index]
    res = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True, timeout=600,
                         env={k: v for k, v in __import__("os").environ.items() if k != "MINARI_DATASETS_PATH"})
    assert res.returncode == 0, f"README block {index}:\n{code}\n--- stderr:\n{res.stderr[-3000:]}"


def test_the_two_setup_commands_install_every_extra_a_command_asks_for():
    """`pip install "torch==2.13.0" && pip install -e ".[all]"` must cover every package that
    :mod:`hsddp_gym.util.extras` can ask for, so the README's commands stay the whole set-up."""
    from hsddp_gym.util.extras import _PIP_NAMES, EXTRAS

    setup = re.findall(r"^python3 -m venv .*$", README, flags=re.M)
    assert len(setup) == 2 and all('pip install "torch==2.13.0" && pip install -e ".[all]"' in c for c in setup)
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
