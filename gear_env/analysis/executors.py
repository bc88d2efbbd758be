"""Executors for parallel sweeps: local process pools and Dask, behind ``concurrent.futures``.

* ``local`` - ``ProcessPoolExecutor`` with the ``forkserver`` start method (``spawn`` where
  forkserver is unavailable): no fork of a process holding threads or numba state. Before the
  pool starts, :func:`warm_numba_cache` compiles (or loads) every kernel a sweep uses in the
  parent, so the workers only *read* the on-disk numba cache and never race to write it; each
  worker loads the kernels once in its initializer, and ends itself when the main process is gone
  (also after a kill -9; :mod:`.lifeline`).
* ``dask`` - ``dask.distributed.Client(address).get_executor()``; the workers must be able to
  import ``gear_env`` (same installation). The client is closed afterwards, the cluster is not.
* an ``Executor`` instance - used as given and not shut down.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager

_WARM = False


def warm_numba_cache() -> None:
    """Compile/load every kernel a sweep uses (tiny inputs); idempotent per process."""
    global _WARM
    if _WARM:
        return
    import numpy as np

    from ..params import GearParams, model_code
    from .lyapunov import lyapunov_record
    from .sweep import SweepConfig, run_point

    p = GearParams()
    for model in ("constant", "dynamic"):
        x = np.zeros(10)
        from .. import kernels as K

        K.static_equilibrium(p.consts, model_code(model), 0.0, x)
        lyapunov_record(x, 1.0, 4, 8, p.consts, model_code(model), 1e-8)
        run_point(SweepConfig(model, "forward", 1, 4, p, 8, False, False, max_extend=0), 1.0, None)
    _WARM = True


def _worker_init(main_pid: int | None = None) -> None:
    if main_pid is not None:  # end with the main process, also when it is killed with SIGKILL
        from .lifeline import exit_with_parent

        exit_with_parent(main_pid)
    warm_numba_cache()


def _noop(x: int) -> int:
    return x


def local_pool(workers: int) -> ProcessPoolExecutor:
    """A process pool of ``workers`` (forkserver/spawn) whose workers preload the kernels."""
    warm_numba_cache()
    methods = mp.get_all_start_methods()
    ctx = mp.get_context("forkserver" if "forkserver" in methods else "spawn")
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),))


def start_workers(ex: Executor, workers: int) -> None:
    """Make sure the pool's workers are running and warmed (keeps start-up out of timings)."""
    list(ex.map(_noop, range(4 * workers)))


@contextmanager
def get_executor(executor: Executor | str | None, workers: int, scheduler: str | None = None) -> Iterator[Executor]:
    """Context manager yielding the executor a parallel sweep submits its chunks to.

    Args:
        executor: None or ``"local"`` (process pool), ``"dask"`` (needs ``scheduler``) or an
            ``Executor`` instance (yielded as is, not shut down).
        workers: processes of a local pool (>= 1).
        scheduler: Dask scheduler address such as ``tcp://127.0.0.1:8786``.
    """
    if isinstance(executor, Executor):
        yield executor
        return
    if executor in (None, "local"):
        if scheduler is not None:
            raise ValueError("scheduler is only used with executor='dask'")
        ex = local_pool(workers)
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
