"""Executors for parallel sweeps: local process pools and Dask, behind ``concurrent.futures``.

* ``local`` - ``ProcessPoolExecutor`` with the ``forkserver`` start method (``spawn`` where
  forkserver is unavailable): no fork of a process holding threads or numba state. Before the
  pool starts, the caller's ``warm`` function (for sweeps
  :func:`gear_env.analysis.sweep.warm_numba_cache`) compiles (or loads) every kernel the tasks use
  in the parent, so the workers only *read* the on-disk numba cache and never race to write it;
  each worker runs ``warm`` once as its initializer, loading the kernels, and ends itself when the
  main process is gone (also after a kill -9; :mod:`.lifeline`).
* ``dask`` - ``dask.distributed.Client(address).get_executor()``; the workers must be able to
  import ``gear_env`` (same installation). The client is closed afterwards, the cluster is not.
* an ``Executor`` instance - used as given and not shut down.

This module knows nothing of what runs in the pool (it imports no other module of the package),
so :mod:`gear_env.analysis.sweep` can use it without an import cycle.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager


def _noop(x: int) -> int:
    return x


def _worker_init(main_pid: int, warm: Callable[[], None] | None) -> None:
    """Worker initializer: end with the main process (also after SIGKILL), then preload."""
    from .lifeline import exit_with_parent

    exit_with_parent(main_pid)
    if warm is not None:
        warm()


def local_pool(workers: int, warm: Callable[[], None] | None = None) -> ProcessPoolExecutor:
    """A process pool of ``workers`` (forkserver/spawn).

    Args:
        workers: processes (>= 1).
        warm: a module-level function (picklable) run once in this process before the pool
            starts and once in each worker as its initializer, e.g.
            :func:`gear_env.analysis.sweep.warm_numba_cache`; None: nothing is preloaded.
    """
    if warm is not None:
        warm()
    methods = mp.get_all_start_methods()
    ctx = mp.get_context("forkserver" if "forkserver" in methods else "spawn")
    return ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(), warm)
    )


def start_workers(ex: Executor, workers: int) -> None:
    """Make sure the pool's workers are running and warmed (keeps start-up out of timings)."""
    list(ex.map(_noop, range(4 * workers)))


@contextmanager
def get_executor(
    executor: Executor | str | None,
    workers: int,
    scheduler: str | None = None,
    warm: Callable[[], None] | None = None,
) -> Iterator[Executor]:
    """Context manager yielding the executor a parallel sweep submits its chunks to.

    Args:
        executor: None or ``"local"`` (process pool), ``"dask"`` (needs ``scheduler``) or an
            ``Executor`` instance (yielded as is, not shut down).
        workers: processes of a local pool (>= 1).
        scheduler: Dask scheduler address such as ``tcp://127.0.0.1:8786``.
        warm: the local pool's preloading function (see :func:`local_pool`); unused otherwise.
    """
    if isinstance(executor, Executor):
        yield executor
        return
    if executor in (None, "local"):
        if scheduler is not None:
            raise ValueError("scheduler is only used with executor='dask'")
        ex = local_pool(workers, warm)
        try:
            yield ex
        finally:
            ex.shutdown(wait=True, cancel_futures=True)
        return
    if executor == "dask":
        if not scheduler:
            raise ValueError("executor='dask' needs a scheduler address (scheduler='tcp://host:port')")
        try:
            from distributed import Client
        except ImportError as exc:  # pragma: no cover - dask is in the analysis extra
            raise ValueError("executor='dask' needs dask[distributed] (pip install 'gear-env[analysis]')") from exc
        client = Client(scheduler, timeout=30)
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    raise ValueError(f"executor must be None, 'local', 'dask' or a concurrent.futures.Executor, got {executor!r}")
