"""Independent tasks in parallel: serially, in a local process pool, or on a Dask cluster.

:func:`parallel_map` runs ``func`` on each item and returns the results in the order of the
items. Where the work runs:

- ``workers == 1`` (or a single item): in this process, one item after the other;
- ``workers > 1`` without ``scheduler``: a pool of local processes started by ``fork``. A large
  read-only input (the sparse matrices of a model) is passed as ``context``: it is stored in a
  module-level registry *before* the pool starts, so the workers inherit it through ``fork``
  instead of receiving a pickled copy per task. Each worker runs BLAS with one thread, so
  ``workers`` processes use ``workers`` cores (and so does the sparse solver:
  ``PYMOREMBS_SOLVER_THREADS=1`` in the workers). The workers end when their parent ends,
  also when it is killed (:func:`die_with_parent`);
- ``scheduler="local"``: a Dask ``LocalCluster`` of ``workers`` single-threaded processes;
  ``scheduler="tcp://host:port"`` (any address): the Dask cluster there. ``context`` is
  scattered to the workers once.

``func`` must be a module-level function (it is pickled by reference). With a ``context`` it
is called as ``func(context, item)``, else as ``func(item)``.
"""

from __future__ import annotations

import ctypes
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from contextlib import contextmanager
from itertools import pairwise
from typing import Any

from threadpoolctl import threadpool_limits

from pymorembs.errors import UserError
from pymorembs.progress import Progress

_NO_CONTEXT = object()

#: Read-only inputs of running pools, by token; inherited by forked workers.
_REGISTRY: dict[int, Any] = {}
_next_token = 0


def usable_cores() -> int:
    """Number of cores this process may run on (its CPU affinity, not the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def available_memory_bytes() -> float:
    """Memory the system can give this process now: ``MemAvailable`` of ``/proc/meminfo``,
    bytes; infinite where that is not known (not Linux)."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return float("inf")


def dask_available() -> bool:
    """Whether ``dask.distributed`` can be imported (the ``dask`` extra)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def parallel_map(
    func: Callable[..., Any],
    items: Sequence[Any],
    workers: int | None = None,
    scheduler: str | None = None,
    context: Any = _NO_CONTEXT,
    progress: Progress | None = None,
    weights: Sequence[int] | None = None,
) -> list[Any]:
    """``[func(item) for item in items]`` (or ``func(context, item)``), in parallel.

    Parameters
    ----------
    func : callable
        A module-level function.
    items : sequence
        The independent tasks.
    workers : int, optional
        Number of processes; default: the usable cores (:func:`usable_cores`). With a remote
        ``scheduler`` it is ignored (the cluster has its own workers).
    scheduler : str, optional
        None: local processes; ``"local"``: a Dask ``LocalCluster``; else the address of a Dask
        scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    context : object, optional
        A large read-only input passed to every call as the first argument; inherited by
        forked workers, scattered once to Dask workers.
    progress : Progress, optional
        Advanced by ``weights[k]`` (default 1) when item ``k`` is done.
    weights : sequence of int, optional
        Progress units of each item (e.g. the number of frequencies in a chunk).

    Returns
    -------
    list
        The results, in the order of ``items``.

    Raises
    ------
    Exception
        The first exception of a task, re-raised here; the remaining tasks are cancelled.
    """
    items = list(items)
    weights = [1] * len(items) if weights is None else [int(w) for w in weights]
    if len(weights) != len(items):
        raise ValueError("weights must have one entry per item")
    if workers is None:
        workers = usable_cores()
    if workers < 1:
        raise UserError(f"the number of workers must be at least 1, got {workers}")
    args = () if context is _NO_CONTEXT else (context,)
    if scheduler is not None:
        return _dask_map(func, items, workers, scheduler, context, progress, weights)
    # a daemonic process (a Dask or pool worker) may not start processes: run serially there
    if workers == 1 or len(items) <= 1 or multiprocessing.current_process().daemon:
        results = []
        for item, weight in zip(items, weights, strict=True):
            results.append(func(*args, item))
            if progress is not None:
                progress.update(weight)
        return results
    return _pool_map(func, items, min(workers, len(items)), context, progress, weights)


@contextmanager
def _registered(context: Any) -> Iterator[int]:
    global _next_token
    token = _next_token
    _next_token += 1
    _REGISTRY[token] = context
    try:
        yield token
    finally:
        _REGISTRY.pop(token, None)


#: Threads of the sparse solver (PARDISO) in each worker: the workers share the cores.
SOLVER_THREADS_ENV = "PYMOREMBS_SOLVER_THREADS"


#: ``prctl`` option of Linux: the signal a process receives when its parent dies.
PR_SET_PDEATHSIG = 1
#: Seconds between two looks at the parent where ``prctl`` is not available.
PARENT_POLL_S = 1.0


def die_with_parent(parent: int) -> None:
    """End this process when the process ``parent`` ends, even by ``SIGKILL``.

    Forked pool workers would otherwise outlive a killed run (asleep, holding their memory).
    On Linux the kernel sends ``SIGKILL`` when the parent dies (``prctl(PR_SET_PDEATHSIG)``);
    elsewhere a daemon thread looks every :data:`PARENT_POLL_S` seconds whether the parent
    changed (an orphan is adopted by another process). A parent already gone ends it at once.

    Parameters
    ----------
    parent : int
        Process id of the parent (taken in the parent, before the fork).
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
        if armed:
            if os.getppid() != parent:  # died before prctl took effect
                os._exit(1)
            return

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="pymorembs-parent-watch", daemon=True).start()


def _init_worker(parent: int, token: int | None = None, context: Any = _NO_CONTEXT) -> None:
    """Set up a pool worker: it ends with its parent, one BLAS and solver thread; the context
    if it was not inherited.

    A worker leaves SIGINT to its parent (Ctrl-C reaches the whole process group; the parent
    ends the pool, :func:`_pool_map`) and dies by SIGTERM without Python's handlers, which a
    forked worker inherits from its parent: no traceback from a worker when a run is stopped.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent(parent)
    threadpool_limits(limits=1)
    os.environ[SOLVER_THREADS_ENV] = "1"
    if token is not None and context is not _NO_CONTEXT:
        _REGISTRY[token] = context


def _call(func: Callable[..., Any], token: int | None, item: Any) -> Any:
    if token is None:
        return func(item)
    return func(_REGISTRY[token], item)


def _pool_map(
    func: Callable[..., Any],
    items: list[Any],
    workers: int,
    context: Any,
    progress: Progress | None,
    weights: list[int],
) -> list[Any]:
    fork = "fork" in multiprocessing.get_all_start_methods()
    method = "fork" if fork else "spawn"
    with _registered(context) as token:
        use = None if context is _NO_CONTEXT else token
        # with fork the workers inherit the registry; elsewhere the context is pickled once per
        # worker (not per task)
        parent = os.getpid()
        initargs = (parent, use) if fork else (parent, use, context)
        executor = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=multiprocessing.get_context(method),
            initializer=_init_worker,
            initargs=initargs,
        )
        try:
            futures = {executor.submit(_call, func, use, item): k for k, item in enumerate(items)}
            results: list[Any] = [None] * len(items)
            pending = set(futures)
            while pending:
                done, pending = wait(pending, return_when=FIRST_EXCEPTION)
                for future in done:
                    k = futures[future]
                    results[k] = future.result()  # re-raises a task's exception
                    if progress is not None:
                        progress.update(weights[k])
        except BaseException as exc:
            if not isinstance(exc, Exception):  # interrupted (Ctrl-C, SIGTERM): not a task's end
                _end_workers(executor)
            raise
        finally:
            executor.shutdown(wait=True, cancel_futures=True)
    return results


def _end_workers(executor: ProcessPoolExecutor) -> None:
    """Kill the worker processes of ``executor`` at once: an interrupted run does not wait
    for their tasks (which may take minutes) before it ends."""
    processes = list((getattr(executor, "_processes", None) or {}).values())
    for process in processes:
        if process.is_alive():
            process.kill()
    for process in processes:
        process.join(timeout=5)


@contextmanager
def dask_client(scheduler: str, workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: on a new ``LocalCluster`` for ``"local"``, else connected.

    The local cluster has ``workers`` single-threaded worker processes (default: the usable
    cores) and no dashboard; it is closed on exit.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise UserError(
            "--scheduler needs Dask: pip install 'pymorembs[dask]' (dask and distributed)"
        ) from None
    if scheduler == "local":
        with (
            LocalCluster(
                n_workers=workers or usable_cores(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.CRITICAL,  # no heartbeat noise when the cluster closes
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client
        return
    try:
        client = Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise UserError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    try:
        yield client
    finally:
        client.close()


def _limited(func: Callable[..., Any], *args: Any) -> Any:
    """Run ``func`` on a Dask worker with one BLAS and solver thread."""
    previous = os.environ.get(SOLVER_THREADS_ENV)
    os.environ[SOLVER_THREADS_ENV] = "1"
    try:
        with threadpool_limits(limits=1):
            return func(*args)
    finally:
        if previous is None:
            os.environ.pop(SOLVER_THREADS_ENV, None)
        else:
            os.environ[SOLVER_THREADS_ENV] = previous


def _dask_map(
    func: Callable[..., Any],
    items: list[Any],
    workers: int,
    scheduler: str,
    context: Any,
    progress: Progress | None,
    weights: list[int],
) -> list[Any]:
    from distributed import as_completed

    with dask_client(scheduler, workers) as client:
        if context is _NO_CONTEXT:
            futures = [client.submit(_limited, func, item, pure=False) for item in items]
        else:
            [shared] = client.scatter([context], broadcast=True)
            futures = [client.submit(_limited, func, shared, item, pure=False) for item in items]
        index = {future.key: k for k, future in enumerate(futures)}
        results: list[Any] = [None] * len(items)
        try:
            for future in as_completed(futures):
                k = index[future.key]
                results[k] = future.result()  # re-raises a task's exception
                if progress is not None:
                    progress.update(weights[k])
        finally:
            client.cancel([f for f in futures if not f.done()])
    return results


def chunks(n: int, parts: int) -> list[range]:
    """Split ``range(n)`` into ``parts`` contiguous, nearly equal, non-empty ranges."""
    parts = max(1, min(parts, n))
    bounds = [round(k * n / parts) for k in range(parts + 1)]
    return [range(a, b) for a, b in pairwise(bounds) if b > a]


__all__ = [
    "chunks",
    "dask_available",
    "dask_client",
    "die_with_parent",
    "parallel_map",
    "usable_cores",
]
