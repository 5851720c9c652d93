"""A regular (non-editable) install puts one import package, ``hsddp_gym``, into site-packages, and works from a
user's project that has its own ``envs/`` and ``planners/`` packages (a common layout in RL code)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

USER_CHECK = """
import envs, planners
assert envs.WHOSE == "user" and planners.WHOSE == "user", "the user's own packages must win"
import gymnasium as gym
import hsddp_gym
import hsddp_gym.envs.bounding, hsddp_gym.planners.policies.mpc
assert hsddp_gym.__file__.startswith(SITE), hsddp_gym.__file__
assert hsddp_gym.envs.bounding.__file__.startswith(SITE), hsddp_gym.envs.bounding.__file__
env = gym.make("hsddp_gym/Bounding-v0")
obs, _ = env.reset(seed=0)
for _ in range(5):
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0)
print("stepped", obs.shape, float(reward))
"""


def _copy_source(dest: Path) -> Path:
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.split()
    for f in files:
        if (ROOT / f).is_file():
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / f, dest / f)
    return dest


def _dependency_paths() -> list[str]:
    """This interpreter's import paths (site-packages and what their .pth files added), without the checkout."""
    skip = {str(ROOT), str(ROOT / "tests"), ""}
    return [p for p in sys.path if p not in skip and Path(p).is_dir()]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout to copy the sources")
    tmp = tmp_path_factory.mktemp("install")
    src = _copy_source(tmp / "src")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    # the dependencies come from this interpreter's paths (no downloads); the editable install of the
    # checkout is a meta-path finder registered by a .pth of our site-packages, which is not processed there
    Path(site, "deps.pth").write_text("\n".join(_dependency_paths()) + "\n")
    res = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps",
                          "--no-build-isolation", "--no-index", "-q", str(src)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    return {"python": py, "bin": venv / "bin", "site": Path(site), "tmp": tmp}


def _run(installed, args, cwd, **kw):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, env=env, timeout=600, **kw)


def test_one_top_level_package_is_installed(installed):
    site = installed["site"]
    assert (site / "hsddp_gym" / "planners" / "optimizer" / "hsddp.py").is_file()
    assert (site / "hsddp_gym" / "envs" / "bounding.py").is_file()
    assert not (site / "planners").exists() and not (site / "envs").exists()
    top = next(site.glob("hsddp_gym-*.dist-info")) / "top_level.txt"
    if top.exists():
        assert top.read_text().split() == ["hsddp_gym"]


def test_env_and_cli_work_beside_a_users_own_envs_and_planners(installed):
    user = installed["tmp"] / "user_project"
    for pkg in ("envs", "planners"):
        (user / pkg).mkdir(parents=True)
        (user / pkg / "__init__.py").write_text('WHOSE = "user"\n')
    res = _run(installed, [str(installed["python"]), "-c", f"SITE = {str(installed['site'])!r}\n" + USER_CHECK],
               cwd=user)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "stepped (17,)" in res.stdout
    out = user / "runs" / "heuristic"
    res = _run(installed, [str(installed["bin"] / "hsddp-gym"), "rollout", "--policy", "heuristic", "--episodes",
                           "1", "--out", str(out), "--quiet"], cwd=user)
    assert res.returncode == 0, res.stdout + res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["policy"] == "heuristic" and summary["falls"] == 0


def test_planners_and_envs_are_not_importable_names(installed):
    empty = installed["tmp"] / "empty"
    empty.mkdir()
    for name in ("planners", "envs"):
        res = _run(installed, [str(installed["python"]), "-c", f"import {name}"], cwd=empty)
        assert res.returncode != 0 and f"No module named '{name}'" in res.stderr, res.stderr
    res = _run(installed, [str(installed["python"]), "-c", "import hsddp_gym.planners, hsddp_gym.envs"], cwd=empty)
    assert res.returncode == 0, res.stderr

