"""The one Python-side way into the kernels (gear_env.sim.integration.integrate): every path gives the
same numbers bit for bit, outputs go where the caller asks, and bad combinations are refused."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env import GearParams, default_initial_state
from gear_env.sim import kernels as K
from gear_env.sim.integration import integrate


def _starts(n: int, model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = GearParams()
    x0 = default_initial_state(p, model)
    X = np.stack([x0 + 0.01 * i for i in range(n)])
    return X, np.zeros((n, K.NDOF)), np.stack([p.consts] * n)


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_single_batch_and_simd_paths_agree_bit_for_bit(model):
    code = 0 if model == "constant" else 1
    n, periods, nsp = 3, 4, 32
    X, A, C = _starts(n, model)
    w0 = np.array([0.9, 1.2, 1.5])
    w1 = np.array([0.9, 1.3, 1.4])  # held, ramp up, ramp down
    runs = {}
    for simd in (True, False):
        Xs, As = X.copy(), A.copy()
        runs[simd] = (integrate(Xs, As, C, code, w0, w1, periods, nsp, simd=simd), Xs, As)
    for i in range(n):
        x, a = X[i].copy(), A[i].copy()
        r = integrate(x, a, C[i], code, float(w0[i]), float(w1[i]), periods, nsp)
        assert r.status == K.OK and r.done == periods
        for rb, Xb, Ab in runs.values():
            assert rb.status[i] == K.OK
            np.testing.assert_array_equal(Xb[i], x)
            np.testing.assert_array_equal(Ab[i], a)
            np.testing.assert_array_equal(rb.poincare[i], r.poincare)
            np.testing.assert_array_equal(rb.stats[i], r.stats)
            assert rb.elapsed[i] == r.elapsed
    assert list(runs[True][0].done) == [periods] * n and runs[False][0].done is None


def test_record_matches_stats_and_buffers_are_filled_in_place():
    X, A, C = _starts(1, "dynamic")
    x1, a1, x2, a2 = X[0].copy(), A[0].copy(), X[0].copy(), A[0].copy()
    pc = np.full((3, K.N_PC), np.nan)
    st = np.full(K.N_STATS, np.nan)
    r = integrate(x1, a1, C[0], 1, 1.1, 1.1, 3, 32, poincare=pc, stats=st)
    assert r.poincare is pc and r.stats is st and np.isfinite(pc).all() and np.isfinite(st).all()
    rec = integrate(x2, a2, C[0], 1, 1.1, 1.1, 3, 32, record=True)
    assert rec.status == K.OK and rec.done == 3 * 32 + 1 and rec.record.shape == (3 * 32 + 1, K.N_REC)
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(rec.record[32::32, : K.NSTATE], pc[:, : K.NSTATE])  # the Poincare rows
    assert rec.elapsed == r.elapsed


def test_constants_are_passed_read_only_and_record_of_a_batch_is_refused(monkeypatch):
    X, A, C = _starts(2, "constant")
    seen = []
    real = K.integrate_stats_lazy

    def spy(*args):
        seen.append(args[7].flags.writeable)
        return real(*args)

    monkeypatch.setattr(K, "integrate_stats_lazy", spy)
    assert C.flags.writeable
    integrate(X[0].copy(), A[0].copy(), C[0], 0, 1.0, 1.0, 1, 16)
    assert seen == [False]  # the kernel got a read-only view (one compiled copy, kernels.readonly)
    assert C.flags.writeable  # the caller's array is unchanged
    with pytest.raises(ValueError, match="record=True"):
        integrate(X, A, C, 0, np.ones(2), np.ones(2), 1, 16, record=True)
