"""A regular (non-editable) install puts one import package, ``hsddp_gym``, into site-packages, and works from a
user's project that has its own ``envs/`` and ``planners/`` packages (a common layout in RL code); with the core
dependencies only, the core runs and every command that needs an extra names it before it starts."""

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
def wheel(tmp_path_factory):
    """A wheel of the checkout, built once (a regular, non-editable build)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout to copy the sources")
    tmp = tmp_path_factory.mktemp("wheel")
    src = _copy_source(tmp / "src")
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                          "-q", "-w", str(tmp / "dist"), str(src)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    return next((tmp / "dist").glob("hsddp_gym-*.whl"))


def _venv_with(wheel, tmp: Path, dependency_paths: list[str]) -> dict:
    """A venv (no pip) whose dependencies are importable from ``dependency_paths`` (a .pth: no downloads, and
    the checkout's editable install, a meta-path finder registered by a .pth of our site-packages, is not
    registered there), with ``wheel`` installed into it."""
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    Path(site, "deps.pth").write_text("\n".join(dependency_paths) + "\n")
    res = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index",
                          "-q", str(wheel)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    return {"python": py, "bin": venv / "bin", "site": Path(site), "tmp": tmp}


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory):
    return _venv_with(wheel, tmp_path_factory.mktemp("install"), _dependency_paths())


def core_distributions() -> dict:
    """The installed distributions the core install needs: ``hsddp_gym``'s requirements without extras, and
    theirs, transitively (``{normalized name: Distribution}``)."""
    import importlib.metadata as md

    from packaging.markers import default_environment
    from packaging.requirements import Requirement

    env = {**default_environment(), "extra": ""}
    found: dict = {}

    def visit(name: str) -> None:
        key = name.lower().replace("_", "-")
        if key in found:
            return
        found[key] = md.distribution(name)
        for text in found[key].requires or []:
            req = Requirement(text)
            if req.marker is None or req.marker.evaluate(env):
                visit(req.name)

    visit("hsddp_gym")
    found.pop("hsddp-gym")
    return found


@pytest.fixture(scope="module")
def core_only(wheel, tmp_path_factory):
    """A venv with the core dependencies only: their top-level entries of our site-packages symlinked into a
    directory of their own (numpy, gymnasium, pin and its cmeel prefix, numba, tqdm, ...), nothing else."""
    pytest.importorskip("packaging")
    tmp = tmp_path_factory.mktemp("core_only")
    deps = tmp / "core_site"
    deps.mkdir()
    for dist in core_distributions().values():
        base = Path(dist.locate_file(""))
        for entry in {str(f).split("/")[0] for f in dist.files or []} - {"..", "__pycache__"}:
            if (base / entry).exists() and not (deps / entry).exists():
                (deps / entry).symlink_to(base / entry)
    cmeel = deps / "cmeel.prefix" / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    return _venv_with(wheel, tmp, [str(deps)] + ([str(cmeel)] if cmeel.is_dir() else []))


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



CORE_CHECK = """
import importlib.util
absent = [m for m in ("minari", "h5py", "torch", "stable_baselines3", "matplotlib", "PIL", "imageio", "ray", "mujoco")
          if importlib.util.find_spec(m) is not None]
assert not absent, f"not a core-only environment: {absent}"
import numpy, gymnasium, pinocchio, numba, tqdm, hsddp_gym
print("core ok")
"""


def test_a_core_only_install_runs_the_core_and_names_the_missing_extras(core_only):
    work = core_only["tmp"] / "work"
    work.mkdir()
    res = _run(core_only, [str(core_only["python"]), "-c", CORE_CHECK], cwd=work)
    assert res.returncode == 0 and "core ok" in res.stdout, res.stdout + res.stderr
    cli = str(core_only["bin"] / "hsddp-gym")
    res = _run(core_only, [cli, "rollout", "--policy", "heuristic", "--episodes", "1", "--max-episode-steps", "50",
                           "--out", str(work / "rollout"), "--quiet"], cwd=work)
    assert res.returncode == 0, res.stdout + res.stderr
    for argv, extra in ((["dataset", "--policy", "heuristic", "--episodes", "1"], "data"),
                        (["train", "--algo", "ppo", "--steps", "10"], "rl"),
                        (["demo"], "viz")):
        out = work / argv[0]
        res = _run(core_only, [cli, *argv, "--out", str(out)], cwd=work)
        assert res.returncode == 2, (argv, res.stdout, res.stderr)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in res.stderr, res.stderr
        assert f"the '{extra}' extra" in lines[0] and f"hsddp_gym[{extra}]" in lines[0], lines[0]
        assert not out.exists(), f"{argv[0]} wrote {out} before failing"
