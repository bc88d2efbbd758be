"""Parallel sweeps: chunking, local process pool, a real Dask LocalCluster on loopback, resume."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from gear_env.analysis import sweep
from gear_env.analysis.sweep import _split_cost

FAST = dict(model="constant", transient=40, periods=24, progress=False, steps_per_period=64)
GRID = np.linspace(0.8, 1.3, 6)  # period-1 everywhere for this model


def test_split_cost_gives_contiguous_balanced_chunks():
    cost = np.r_[np.full(10, 10.0), np.ones(30)]
    ranges = _split_cost(cost, 4)
    assert ranges[0][0] == 0 and ranges[-1][1] == 40
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
    loads = [cost[a:b].sum() for a, b in ranges]
    assert max(loads) <= 1.5 * cost.sum() / 4
    assert _split_cost(np.ones(3), 10) == [(0, 1), (1, 2), (2, 3)]


@pytest.fixture(scope="module")
def threaded():
    with ThreadPoolExecutor(2) as ex:
        return sweep(GRID, executor=ex, chunks=3, **FAST)


def test_chunked_sweep_agrees_with_serial(threaded):
    serial = sweep(GRID, **FAST)
    assert threaded.regime == serial.regime == ["period-1"] * 6
    # chunk heads start from the coarse ramp, not from the previous point: same orbit all the same
    np.testing.assert_allclose(threaded.poincare[:, -1, :10], serial.poincare[:, -1, :10], atol=1e-3)
    assert threaded.meta["parallel"] and not serial.meta["parallel"]


def test_local_process_pool_gives_identical_results(threaded):
    r = sweep(GRID, workers=2, chunks=3, **FAST)
    assert r.regime == threaded.regime
    np.testing.assert_array_equal(r.poincare, threaded.poincare)
    np.testing.assert_array_equal(r.lyapunov, threaded.lyapunov)


def test_dask_local_cluster_on_loopback(threaded):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp",
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        r = sweep(GRID, executor="dask", scheduler=cluster.scheduler_address, chunks=3, **FAST)
    assert r.regime == threaded.regime
    np.testing.assert_array_equal(r.poincare, threaded.poincare)


def test_parallel_sweep_resumes_after_interruption(tmp_path, threaded):
    ck = tmp_path / "p.ckpt.npz"

    def stop(done):
        if done >= 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        with ThreadPoolExecutor(1) as ex:
            sweep(GRID, executor=ex, chunks=3, checkpoint=str(ck), _on_point=stop, **FAST)
    with np.load(ck) as z:
        saved = list(z["index"])
    assert 2 <= len(saved) < 6
    calls = []
    with ThreadPoolExecutor(2) as ex:
        r = sweep(GRID, executor=ex, chunks=3, checkpoint=str(ck), _on_point=calls.append, **FAST)
    assert len(calls) == 6 - len(saved)
    np.testing.assert_array_equal(r.poincare, threaded.poincare)


def test_executor_argument_errors():
    with pytest.raises(ValueError, match="scheduler"):
        sweep(GRID, executor="dask", **FAST)
    with pytest.raises(ValueError, match="executor"):
        sweep(GRID, executor="slurm", **FAST)
    with pytest.raises(ValueError, match="chunks"):
        sweep(GRID, workers=2, chunks=0, **FAST)
