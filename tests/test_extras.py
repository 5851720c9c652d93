"""With the core dependencies only (no minari, h5py, torch, stable-baselines3, matplotlib, Pillow, imageio),
every command that needs an extra says so -- one ``error:`` line naming the package and the extra, exit code 2
-- before it starts (nothing is written), and the core jobs still run.

The core-only venv is simulated in a subprocess by a meta-path finder that refuses the extras' imports; the
subprocess first checks that ``import minari`` / ``import torch`` / ``import matplotlib`` really fail there.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hsddp_gym.datasets.generation import generate_dataset
from hsddp_gym.util.extras import MissingExtraError, missing, require

BLOCKED = ("minari", "h5py", "torch", "stable_baselines3", "matplotlib", "PIL", "imageio")

SCRIPT = textwrap.dedent('''
    import contextlib, importlib.abc, io, json, sys
    BLOCKED = set(sys.argv[1].split(","))

    class Blocker(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, Blocker())
    result = {"imports": {}}
    for mod in sorted(BLOCKED):
        try:
            __import__(mod)
            result["imports"][mod] = "imported"
        except ImportError:
            result["imports"][mod] = "missing"
    from hsddp_gym import cli
    result["runs"] = []
    for argv in json.loads(sys.argv[2]):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                rc = cli.main(argv)
            except SystemExit as exc:
                rc = exc.code
            except BaseException as exc:  # reported, so the test shows what escaped
                rc, err = "raised", io.StringIO(f"{type(exc).__name__}: {exc}")
        result["runs"].append({"argv": argv, "rc": rc, "err": err.getvalue()})
    print(json.dumps(result))
''')


@pytest.fixture(scope="module")
def core_only(tmp_path_factory):
    """Run CLI commands in a subprocess where the extras cannot be imported; ``{argv[0] + tag: run}``."""
    from hsddp_gym.learning.bc import BCConfig, MLPPolicy
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.util.io import write_json

    tmp = tmp_path_factory.mktemp("core")
    ds = tmp / "ds"
    generate_dataset("heuristic", 1, ds, max_episode_steps=10, progress=False)
    # a BC run directory written without torch: a random 2-layer MLP in the policy.npz format
    rng = np.random.default_rng(0)
    n_in = EnvInterface().layout.size
    weights = [(rng.normal(size=(8, n_in)) * 0.1, np.zeros(8)), (rng.normal(size=(4, 8)) * 0.1, np.zeros(4))]
    bc = tmp / "bc"
    MLPPolicy(weights=weights, obs_mean=np.zeros(n_in), obs_std=np.ones(n_in),
              config=BCConfig(hidden=(8,))).save(bc / "policy.npz")
    write_json(bc / "summary.json", {"algo": "bc"})
    sac = tmp / "sac"  # a SAC run directory's layout (its weights are never read: the check comes first)
    write_json(sac / "summary.json", {"algo": "sac"})
    (sac / "model.zip").write_bytes(b"")
    cases = {
        "dataset": ["dataset", "--policy", "heuristic", "--episodes", "1", "--out", str(tmp / "d")],
        "train-bc": ["train", "--algo", "bc", "--dataset", str(ds), "--out", str(tmp / "t")],
        "train-bc-npz": ["train", "--algo", "bc", "--format", "npz", "--dataset", str(ds), "--out", str(tmp / "t")],
        "train-ppo": ["train", "--algo", "ppo", "--steps", "10", "--out", str(tmp / "t")],
        "demo": ["demo", "--out", str(tmp / "demo")],
        "demo-no-video": ["demo", "--no-video", "--out", str(tmp / "demo")],
        "plan": ["plan", "--method", "heuristic", "--cycles", "1", "--out", str(tmp / "plan")],
        "rollout-video": ["rollout", "--policy", "heuristic", "--video", "--out", str(tmp / "rv")],
        "rollout-sb3": ["rollout", "--policy", f"sb3:{sac}", "--out", str(tmp / "rs")],
        "plan-no-plots": ["plan", "--method", "heuristic", "--cycles", "1", "--no-plots", "--quiet", "--out",
                          str(tmp / "plan_ok")],
        "rollout": ["rollout", "--policy", "heuristic", "--episodes", "1", "--max-episode-steps", "5", "--quiet",
                    "--out", str(tmp / "r")],
        "rollout-bc": ["rollout", "--policy", f"bc:{bc}", "--episodes", "1", "--max-episode-steps", "5", "--quiet",
                       "--out", str(tmp / "rbc")],
    }
    res = subprocess.run([sys.executable, "-c", SCRIPT, ",".join(BLOCKED), json.dumps(list(cases.values()))],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    return out["imports"], dict(zip(cases, out["runs"])), tmp


def test_the_blocker_really_removes_the_extras(core_only):
    imports, _, _ = core_only
    assert imports == {m: "missing" for m in BLOCKED}


@pytest.mark.parametrize("case, names, extra", [
    ("dataset", ["minari", "h5py"], "'data' extra"),
    ("train-bc", ["torch", "minari"], "torch"),
    ("train-bc-npz", ["torch"], "torch==2.13.0"),
    ("train-ppo", ["stable-baselines3", "torch"], "'rl' extra"),
    ("demo", ["matplotlib", "pillow"], "'viz' extra"),
    ("demo-no-video", ["matplotlib"], "'viz' extra"),
    ("plan", ["matplotlib"], "--no-plots"),
    ("rollout-video", ["pillow"], "'viz' extra"),
    ("rollout-sb3", ["stable-baselines3", "torch"], "'rl' extra"),
])
def test_a_missing_extra_is_named_before_the_command_starts(core_only, case, names, extra):
    _, runs, tmp = core_only
    run = runs[case]
    err = run["err"]
    assert run["rc"] == 2, run
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ") and "Traceback" not in err
    assert all(n in err for n in names) and extra in err and "pip install" in err
    if case == "train-bc-npz":
        assert "minari" not in err
    # nothing was written: no half-finished output (plan used to leave trajectory.npz behind)
    for name in ("d", "t", "demo", "plan", "rv", "rs"):
        assert not (tmp / name).exists(), name
    assert not (tmp / ".d.partial").exists()


def test_core_jobs_run_without_the_extras(core_only):
    _, runs, tmp = core_only
    for case in ("plan-no-plots", "rollout", "rollout-bc"):
        assert runs[case]["rc"] == 0, runs[case]
    assert (tmp / "plan_ok" / "trajectory.npz").exists()
    assert json.loads((tmp / "rbc" / "summary.json").read_text())["mean_episode_length"] > 0


def test_require_names_the_package_and_the_extra():
    require(["numpy"], "x")  # installed: nothing happens
    assert missing(["numpy", "no_such_module_xyz"]) == ["no_such_module_xyz"]
    with pytest.raises(MissingExtraError, match="job needs no_such_module_xyz"):
        require(["no_such_module_xyz"], "job")
    with pytest.raises(ImportError, match="'data' extra"):
        import hsddp_gym.util.extras as extras

        orig = extras.is_installed
        try:
            extras.is_installed = lambda m: m != "minari"
            generate_dataset("heuristic", 1, "/nonexistent/never", progress=False)
        finally:
            extras.is_installed = orig
