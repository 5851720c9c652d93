"""First run: numba compiles the backward pass (and the other kernels: the rollouts' dynamics, the costs) once,
says so, caches it on disk, and the compile time stays out of the solver's ``solve_time_s``. Each run is a fresh
interpreter with its own empty ``NUMBA_CACHE_DIR``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

SCRIPT = """
import json, time
t0 = time.perf_counter()
from hsddp_gym.planners.tasks import plan_bounding
from hsddp_gym.planners.optimizer import riccati
from hsddp_gym.core import planar_dynamics
riccati.warm_up()
warmed = [len(k.signatures) for k in planar_dynamics.KERNELS]
first = plan_bounding("ddp", cycles=1)
second = plan_bounding("ddp", cycles=1)
stats = riccati.backward_pass.stats
print(json.dumps({"total_s": time.perf_counter() - t0, "solve_s": [first.summary["solve_time_s"],
                  second.summary["solve_time_s"]], "misses": sum(stats.cache_misses.values()),
                  "hits": sum(stats.cache_hits.values()), "signatures": len(riccati.backward_pass.signatures),
                  "dynamics_signatures": [len(k.signatures) for k in planar_dynamics.KERNELS], "warmed": warmed}))
"""


def _run(cache_dir):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    res = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1]), res.stderr


@pytest.mark.slow
def test_first_run_compiles_once_says_so_and_later_runs_load_the_cache(tmp_path):
    first, err = _run(tmp_path / "numba")
    # compiled here, announced once, with the compile time
    assert first["misses"] == 1 and first["hits"] == 0
    assert err.count("numba: compiling the HS-DDP dynamics, backward pass") == 1
    assert err.count("numba: compiled in") == 1
    compile_s = float(err.split("numba: compiled in ")[1].split(" s")[0])
    # the solver reused the warm-up's specialization (no second compile inside a solve) ...
    assert first["signatures"] == 1 and first["dynamics_signatures"] == first["warmed"]
    # ... and the compile is not in solve_time_s: both solves fit in the wall time left after it
    assert sum(first["solve_s"]) <= first["total_s"] - compile_s
    # the cache is on disk and the next process loads it silently
    assert any(p.suffix == ".nbi" for p in (tmp_path / "numba").rglob("*"))
    again, err2 = _run(tmp_path / "numba")
    assert again["misses"] == 0 and again["hits"] == 1 and "numba:" not in err2


def test_warm_up_is_once_per_process():
    from hsddp_gym.planners.optimizer import riccati

    riccati.warm_up(announce=False)
    assert riccati.warm_up() == 0.0
