"""Independent tasks in parallel: in this process, in spawn-started local processes, or on a Ray cluster.

[`run_parallel`][run_parallel] is the one engine behind dataset generation and the robustness / push sweeps. Each task
is ``fn(task)`` with a picklable module-level ``fn`` and a picklable ``task``; results come back in this process as
they finish (``on_result``) and in task order at the end, so a caller that makes every task depend only on
its own inputs (an episode only on its seed) gets the same results for any backend and any number of workers.

Backends (`BACKENDS`):

* ``"local"``: ``workers == 1`` runs the tasks here, one after the other; more workers are ``spawn``-started
  processes of `concurrent.futures.ProcessPoolExecutor`, each limited to one BLAS/OpenMP/numba thread.
  A worker that dies (killed, out of memory) breaks the pool: the pool is restarted and the tasks that had not
  finished are run again, at most ``max_retries`` times.
* ``"ray"``: every task is a Ray task (``num_cpus=1``, one BLAS thread each). With ``address=None`` a local Ray
  instance with ``workers`` CPUs is started for the call and shut down after it; with an address (``"auto"``,
  ``"ray://host:10001"``, ``"host:6379"``) the call joins that running cluster, whose nodes must have this
  package installed. A task whose worker dies is re-run by Ray (``max_retries``). Ray is an optional extra
  (``pip install -e ".[ray]"``); nothing else needs it.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
from collections.abc import Callable, Sequence

from hsddp_gym.util.extras import require

BACKENDS = ("local", "ray")
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")
DEFAULT_RETRIES = 3
"""Times a task whose worker died is run again before the run fails."""


def check_backend(backend: str, address: str | None = None) -> None:
    """Validate ``backend`` (one of `BACKENDS`) and ``address`` (a non-empty string, Ray only); for
    ``"ray"`` check that Ray is installed ([`MissingExtraError`][hsddp_gym.util.extras.MissingExtraError] naming the
    extra)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if address is not None:
        if backend != "ray":
            raise ValueError(f"address applies to backend 'ray' only, got backend {backend!r}")
        if not isinstance(address, str) or not address.strip():
            raise ValueError(f"address must be a non-empty string such as 'auto' or 'ray://host:10001', "
                             f"got {address!r}")
    if backend == "ray":
        require(["ray"], "backend 'ray'")


@contextlib.contextmanager
def child_threads(threads: int):
    """Set the BLAS/OpenMP/numba thread counts in ``os.environ`` while worker processes are started.

    A spawned worker imports NumPy (hence OpenBLAS) while it unpickles its first task -- before any pool
    initializer runs -- so the limit must already be in the environment it inherits. Values the user set are
    kept; the parent's own (already loaded) libraries are unaffected.
    """
    old = {v: os.environ.get(v) for v in THREAD_VARS}
    for v in THREAD_VARS:
        os.environ.setdefault(v, str(int(threads)))
    try:
        yield
    finally:
        for v, value in old.items():
            if value is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = value


def add_backend_arguments(parser, what: str = "the episodes") -> None:
    """``--backend {local,ray}`` and ``--address ADDR`` on an argparse ``parser`` (the CLI and the sweeps)."""
    parser.add_argument("--backend", choices=BACKENDS, default="local",
                        help=f"where {what} run: 'local' (this process or local worker processes) or 'ray' (a local "
                             "Ray instance, or the cluster at --address; needs the ray extra). Same results either "
                             "way; a task whose worker dies is run again (default: %(default)s)")
    parser.add_argument("--address", default=None,
                        help="with --backend ray: the address of a running Ray cluster ('auto', 'ray://host:10001', "
                             "'host:6379'); its nodes need hsddp_gym installed (default: start a local Ray instance)")


def run_parallel(fn: Callable, tasks: Sequence, workers: int = 1, backend: str = "local", address: str | None = None,
                 on_result: Callable[[int, object], None] | None = None, max_retries: int = DEFAULT_RETRIES) -> list:
    """``[fn(t) for t in tasks]``, computed by ``backend`` with ``workers`` workers (see the module docstring).

    Args:
        fn: a picklable (module-level) function of one task.
        tasks: picklable tasks.
        workers: local processes, or the CPUs of a local Ray instance (ignored when joining a cluster).
        backend: ``"local"`` or ``"ray"``.
        address: Ray cluster address (None: start a local instance for this call).
        on_result: ``on_result(index, result)``, called in this process as each task finishes (any order).
        max_retries: re-runs of a task whose worker died (a task that raises is not re-run: its error is raised).
    Returns:
        The results in task order.
    """
    check_backend(backend, address)
    workers, max_retries = int(workers), int(max_retries)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if max_retries < 0:
        raise ValueError(f"max_retries must be >= 0, got {max_retries}")
    tasks = list(tasks)
    results: list = [None] * len(tasks)

    def finished(i: int, result) -> None:
        results[i] = result
        if on_result is not None:
            on_result(i, result)

    if not tasks:
        return results
    if backend == "ray":
        _run_ray(fn, tasks, workers, address, finished, max_retries)
    elif workers == 1:
        for i, t in enumerate(tasks):
            finished(i, fn(t))
    else:
        _run_pool(fn, tasks, workers, finished, max_retries)
    return results


def _run_pool(fn, tasks, workers, finished, max_retries) -> None:
    todo = list(range(len(tasks)))
    ctx = multiprocessing.get_context("spawn")
    for attempt in range(max_retries + 1):
        pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=ctx)
        try:
            with child_threads(1):  # the workers are started by the submits
                futures = {pool.submit(fn, tasks[i]): i for i in todo}
            for fut in cf.as_completed(futures):
                i = futures[fut]
                finished(i, fut.result())
                todo.remove(i)
        except cf.process.BrokenProcessPool:
            pool.shutdown(wait=False, cancel_futures=True)
            if attempt == max_retries:
                raise RuntimeError(f"a worker process died {max_retries + 1} times; {len(todo)} task(s) unfinished "
                                   f"(max_retries={max_retries}). Killed or out of memory, or it could not import "
                                   f"the task: spawn-started workers import fn by its module name, so a function "
                                   f"of a script loaded by path must be importable from sys.path") from None
            continue
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
        return


def _call(fn, task):
    return fn(task)


def _run_ray(fn, tasks, workers, address, finished, max_retries) -> None:
    import ray

    started = False
    if not ray.is_initialized():
        env = {"env_vars": {v: os.environ.get(v, "1") for v in THREAD_VARS}}
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, runtime_env=env,
                     configure_logging=False)
        else:
            ray.init(address=address, log_to_driver=False, runtime_env=env, configure_logging=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=False)(_call)
        fn_ref = ray.put(fn)
        pending = {remote.remote(fn_ref, t): i for i, t in enumerate(tasks)}
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    i = pending.pop(ref)
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:  # the task raised: re-raise its own error
                        raise exc.as_instanceof_cause() from None
                    finished(i, result)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
    finally:
        if started:
            ray.shutdown()
