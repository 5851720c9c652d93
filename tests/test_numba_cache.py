"""First run: numba compiles the backward pass (and the other kernels: the rollouts' dynamics, the costs) once,
says so, caches it on disk, and the compile time stays out of the solver's ``solve_time_s``; the contact kernel's
step is cached whole, keyed by every module it is compiled from. Each run is a fresh interpreter with its own empty
``NUMBA_CACHE_DIR``."""

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


CONTACT_SCRIPT = """
import json
from hsddp_gym.core import batch_contact, batch_model
existed = batch_contact._cache_index_exists()
batch_contact.warm_up()
stats = batch_contact.step_batch.stats
print(json.dumps({"existed": existed, "misses": sum(stats.cache_misses.values()),
                  "hits": sum(stats.cache_hits.values()), "helper_signatures": len(batch_model.kinematics.signatures)}))
"""


def _run(cache_dir, script=SCRIPT):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
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


@pytest.mark.slow
def test_the_contact_kernel_compiles_once_and_later_runs_load_it_whole(tmp_path):
    first, err = _run(tmp_path / "numba", CONTACT_SCRIPT)
    assert not first["existed"] and first["misses"] == 1 and first["hits"] == 0
    assert first["helper_signatures"] == 1  # compiled into the step
    assert err.count("numba: compiling the batched contact kernel") == 1 and err.count("numba: compiled in") == 1
    again, err2 = _run(tmp_path / "numba", CONTACT_SCRIPT)
    assert again["existed"] and again["misses"] == 0 and again["hits"] == 1 and "numba:" not in err2
    assert again["helper_signatures"] == 0  # the cached step holds the functions it calls: none compiled again


def test_the_contact_kernels_cache_key_covers_every_module_it_is_compiled_from():
    """numba checks only a cached function's own source file; the step's key also holds the digest of
    KERNEL_MODULES (a closure constant), which must name every module of the compiled functions the steps call."""
    from numba.core.registry import CPUDispatcher

    from hsddp_gym.core import batch_contact

    allowed = {m.__name__ for m in batch_contact.KERNEL_MODULES} | {batch_contact.__name__}
    steps = (batch_contact.step_batch, batch_contact.step_batch_terrain)
    todo, seen, modules = [step.py_func for step in steps], set(), set()
    while todo:
        func = todo.pop()
        if func in seen:
            continue
        seen.add(func)
        modules.add(func.__module__)
        todo += [value.py_func for value in map(func.__globals__.get, func.__code__.co_names)
                 if isinstance(value, CPUDispatcher)]
    assert {"hsddp_gym.core.batch_model", "hsddp_gym.core.batch_terrain", "hsddp_gym.core.batch_lcp"} <= modules
    assert modules <= allowed
    for step in steps:
        assert batch_contact.KERNEL_SOURCES in [cell.cell_contents for cell in step.py_func.__closure__]


def test_compile_step_checks_its_arguments():
    from hsddp_gym.core.batch_contact import compile_step

    with pytest.raises(TypeError, match="on_terrain must be a bool, got int"):
        compile_step(1, "step")
    with pytest.raises(ValueError, match="name must be a Python identifier, got 'a step'"):
        compile_step(False, "a step")
