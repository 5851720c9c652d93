"""The parallel engine (hsddp_gym.util.parallel): the same results on every backend, dead workers' tasks re-run,
task errors raised, bad arguments named; datasets on a local Ray instance equal the local backend's."""

from __future__ import annotations

import dataclasses
import os
import sys
from pathlib import Path

import pytest

from hsddp_gym.datasets.generation import generate_dataset
from hsddp_gym.datasets.recording import NONDETERMINISTIC_INFOS
from hsddp_gym.rollout.policies import PolicySpec
from hsddp_gym.util.parallel import check_backend, run_parallel

TESTS = str(Path(__file__).resolve().parent)


def square(x):
    return x * x


def fails_on_three(x):
    if x == 3:
        raise ValueError("task 3 is bad")
    return x


@dataclasses.dataclass(frozen=True)
class DiesOnce:
    """Kills its worker process (``os._exit``) the first time it is called with ``victim``; then ``fn(x)``."""

    marker: str
    victim: int

    def __call__(self, x):
        if x == self.victim and not os.path.exists(self.marker):
            Path(self.marker).write_text("died once")
            os._exit(1)
        return x * x


@dataclasses.dataclass(frozen=True)
class HeuristicDiesOnce:
    """A dataset policy factory whose first episode with seed ``victim`` kills its worker mid-run."""

    marker: str
    victim: int

    def __call__(self, env, episode_seed: int):
        if episode_seed == self.victim and not os.path.exists(self.marker):
            Path(self.marker).write_text("died once")
            os._exit(1)
        return PolicySpec("heuristic")(env, episode_seed)


def test_local_backend_same_results_for_any_number_of_workers():
    seen = []
    one = run_parallel(square, range(7), workers=1, on_result=lambda i, r: seen.append((i, r)))
    two = run_parallel(square, range(7), workers=2)
    assert one == two == [x * x for x in range(7)]
    assert sorted(seen) == [(i, i * i) for i in range(7)]
    assert run_parallel(square, [], workers=2) == []


def test_a_dead_local_worker_loses_nothing(tmp_path):
    marker = tmp_path / "died"
    out = run_parallel(DiesOnce(str(marker), 4), range(8), workers=2)
    assert marker.exists() and out == [x * x for x in range(8)]


def always_dies(x):
    os._exit(1)


def test_a_worker_that_dies_every_time_fails_after_the_retries():
    with pytest.raises(RuntimeError, match="a worker process died 2 times"):
        run_parallel(always_dies, range(3), workers=2, max_retries=1)


@pytest.mark.parametrize("workers", [1, 2])
def test_task_errors_are_raised_not_retried(workers):
    with pytest.raises(ValueError, match="task 3 is bad"):
        run_parallel(fails_on_three, range(5), workers=workers)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="backend must be one of"):
        run_parallel(square, [1], backend="spark")
    with pytest.raises(ValueError, match="address applies to backend 'ray' only"):
        check_backend("local", "auto")
    with pytest.raises(ValueError, match="workers must be >= 1"):
        run_parallel(square, [1], workers=0)
    with pytest.raises(ValueError, match="max_retries must be >= 0"):
        run_parallel(square, [1], max_retries=-1)
    with pytest.raises(ValueError, match="backend must be one of"):
        generate_dataset("heuristic", 1, "unused", backend="dask")


def test_cli_names_a_bad_backend_and_a_stray_address(tmp_path, capsys):
    from hsddp_gym import cli

    with pytest.raises(SystemExit) as exc:
        cli.main(["dataset", "--policy", "heuristic", "--episodes", "1", "--out", str(tmp_path / "d"),
                  "--backend", "spark"])
    assert exc.value.code == 2 and "--backend" in capsys.readouterr().err
    assert cli.main(["dataset", "--policy", "heuristic", "--episodes", "1", "--out", str(tmp_path / "d"),
                     "--address", "auto"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --address:") and "only with --backend ray" in err and err.count("\n") == 1


# ------------------------------------------------------------------------------------------------ Ray
ray = pytest.importorskip("ray", reason="the ray extra is not installed")


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray instance started by the test (2 CPUs); the test modules importable in its workers."""
    if ray.is_initialized():
        ray.shutdown()
    path = os.pathsep.join([TESTS, *[p for p in sys.path if p]])
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": path, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}})
    yield ray
    ray.shutdown()


def test_ray_backend_same_results_and_a_dead_worker_loses_nothing(local_ray, tmp_path):
    assert run_parallel(square, range(6), workers=2, backend="ray") == [x * x for x in range(6)]
    assert ray.is_initialized()  # an instance it did not start is left running
    marker = tmp_path / "died"
    assert run_parallel(DiesOnce(str(marker), 2), range(5), backend="ray") == [x * x for x in range(5)]
    assert marker.exists()
    with pytest.raises(ValueError, match="task 3 is bad"):
        run_parallel(fails_on_three, range(5), backend="ray")


def test_ray_dataset_equals_the_local_one_even_when_a_worker_is_killed(local_ray, tmp_path, tools):
    steps = 40
    local = generate_dataset("heuristic", 4, tmp_path / "local", seed=5, workers=1, max_episode_steps=steps,
                             progress=False)
    marker = tmp_path / "died"
    remote = generate_dataset(HeuristicDiesOnce(str(marker), 6), 4, tmp_path / "ray", seed=5, workers=2,
                              max_episode_steps=steps, progress=False, backend="ray", policy_name="heuristic")
    assert marker.exists(), "the worker of episode seed 6 was killed once"
    assert remote.metadata["backend"] == "ray" and local.metadata["backend"] == "local"
    tools.assert_same_datasets(tmp_path / "local", tmp_path / "ray", ignore=NONDETERMINISTIC_INFOS)
    assert not (tmp_path / ".ray.partial").exists()  # published atomically, checkpoints removed
