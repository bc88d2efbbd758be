"""Motion classification and Lyapunov exponents on systems with known answers, then the gear model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gear_env.analysis import Classification, classify_motion, largest_lyapunov
from gear_env.analysis.classify import count_clusters, lyapunov_tolerance, recurrence_residuals, same_orbit
from gear_env.analysis.lyapunov import lyapunov_map
from gear_env.analysis.testsystems import Duffing, linear_oscillator
from gear_env.sim.simulator import GearSimulator


# --- synthetic point sets ---------------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 3, 5, 7, 11, 16, 24])
def test_period_n_orbit_is_recognised(n):
    rng = np.random.default_rng(n)
    orbit = rng.uniform(-1.0, 1.0, size=(n, 4))
    pts = np.tile(orbit, (200 // n + 1, 1))[:200] + 1e-7 * rng.standard_normal((200, 4))
    c = classify_motion(pts, lyapunov=-0.01)
    assert isinstance(c, Classification)
    assert (c.label, c.period, c.n_clusters, c.converged) == (f"period-{n}", n, n, True)


def test_torus_is_quasi_periodic_with_or_without_exponent():
    k = np.arange(300)
    theta = 2 * math.pi * k * (math.sqrt(5) - 1) / 2  # golden rotation number: never recurs
    pts = np.c_[np.cos(theta), 0.5 * np.sin(theta), 0.2 * np.cos(theta) ** 2]
    assert classify_motion(pts, lyapunov=1e-5).label == "quasi-periodic"
    c = classify_motion(pts)  # data-only fallback: a rotation keeps neighbours together
    assert c.label == "quasi-periodic" and abs(c.divergence) < 0.02


def test_sign_of_exponent_decides_non_periodic_points():
    pts = np.random.default_rng(0).uniform(size=(100, 3))
    assert classify_motion(pts, lyapunov=0.05).label == "chaotic"
    assert classify_motion(pts, lyapunov=0.0).label == "quasi-periodic"
    conv = classify_motion(pts, lyapunov=-0.05)  # attracted, but not yet periodic: run longer
    assert conv.converged is False and conv.period >= 1


def test_recurrence_clusters_and_same_orbit():
    orbit = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]])
    pts = np.tile(orbit, (10, 1))
    r = recurrence_residuals(pts, 6)
    assert r[2] == 0.0 and r[5] == 0.0 and r[0] > 0.1
    assert count_clusters(pts) == 3
    assert same_orbit(pts, np.roll(pts, 1, axis=0), 3)
    assert not same_orbit(pts, pts * 0.9, 3)  # a spiral that still contracts is not confirmed


def test_lyapunov_tolerance_shrinks_with_time():
    assert lyapunov_tolerance(100.0) == pytest.approx(0.02)  # 2/T
    assert lyapunov_tolerance(1e6) == pytest.approx(5e-4)  # the floor


def test_resolved_positive_exponent_is_chaos_even_when_points_recur():
    """Rule 0: the exponent decides before the recurrence test when it is above the zero band."""
    orbit = np.tile(np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]]), (20, 1))
    assert classify_motion(orbit).label == "period-3"
    assert classify_motion(orbit, lyapunov=-0.01).label == "period-3"
    assert classify_motion(orbit, lyapunov=4e-4).label == "period-3"  # within the band: periodic
    c = classify_motion(orbit, lyapunov=2e-3)
    assert c.label == "chaotic" and c.period == 0 and c.best_period == 3
    assert classify_motion(orbit, lyapunov=2e-3, lyap_tol=5e-3).label == "period-3"


def test_dynamic_0p45_is_chaotic():
    """Dynamic model, omega = 0.45: its Poincare points recur after 32 periods within 1e-3, but
    the exponent (+0.001 per unit time, +0.013 per mesh period) is resolved: chaotic. The
    neighbours 0.44 (period-8) and 0.455 (period-16, negative exponent) stay periodic."""
    from gear_env.analysis import sweep

    r = sweep([0.44, 0.445, 0.45, 0.455], model="dynamic", progress=False)
    assert r.regime[2] == "chaotic" and r.lyapunov[2] > 5e-4
    assert r.regime[0] == "period-8" and r.regime[3] == "period-16"
    assert r.lyapunov[0] < 0 and r.lyapunov[3] < 0


@pytest.mark.parametrize(
    "points, kwargs, word",
    [
        (np.empty((0, 3)), {}, "poincare_points"),
        (np.array([[1.0, np.nan], [0.0, 1.0]]), {}, "finite"),
        (np.ones((5, 2)), {"tol": 0.0}, "tol"),
        (np.ones((5, 2)), {"max_period": 0}, "max_period"),
        (np.ones((5, 2)), {"lyapunov": float("nan")}, "lyapunov"),
    ],
)
def test_invalid_input_is_rejected(points, kwargs, word):
    with pytest.raises(ValueError, match=word):
        classify_motion(points, **kwargs)


# --- forced Duffing oscillator: period-doubling cascade and chaos (independent RK4) -------------
@pytest.mark.parametrize(
    "gamma, label",
    [(0.20, "period-1"), (0.27, "period-2"), (0.29, "period-4"), (0.37, "period-5"), (0.50, "chaotic")],
)
def test_duffing_cascade(gamma, label):
    d = Duffing(gamma)
    pts, x = d.poincare((1.0, 0.0), transient=1000, periods=256)
    lam = d.lyapunov(x, periods=300)
    c = classify_motion(pts, lam)
    assert c.label == label
    if label == "chaotic":
        assert lam > 0.05  # literature: ~0.1-0.15 per unit time for this attractor
        assert classify_motion(pts).label == "chaotic"  # the geometric fallback agrees
    else:
        assert lam < -0.01


@pytest.mark.parametrize("xi", [0.02, 0.1])
def test_linear_oscillator_exponent_is_minus_xi(xi):
    osc = linear_oscillator(xi)
    pts, x = osc.poincare((0.3, 0.0), transient=400, periods=50)
    assert classify_motion(pts).label == "period-1"
    assert osc.lyapunov(x, periods=150) == pytest.approx(-xi, rel=2e-3)


# --- the gear model ------------------------------------------------------------------------------
def test_gear_lyapunov_recorder_matches_generic_algorithm():
    """The sweep's batch-kernel recorder gives the same number as the generic one-period-map loop."""
    w = 2.0
    sim = GearSimulator(None, "dynamic", 64, w)
    sim.advance(100)
    x0 = sim.state

    def advance(x):
        s = GearSimulator(None, "dynamic", 64, w, x.copy())
        iv = s.advance(1)
        x[:] = s.state
        return iv.duration

    ref = lyapunov_map(advance, x0, 40)
    batch = largest_lyapunov(w, "dynamic", state=x0, periods=40, steps_per_period=64)
    assert batch == pytest.approx(ref, rel=1e-6, abs=1e-9)


def test_gear_period_one_at_1p2_and_torus_near_2():
    sim = GearSimulator(None, "dynamic", 128, 1.2)
    sim.advance(400)
    lam = largest_lyapunov(1.2, "dynamic", state=sim.state, periods=200)
    c = classify_motion(sim.advance(200).poincare[:, :10], lam)
    assert c.label == "period-1" and lam < -0.005
    sim = GearSimulator(None, "dynamic", 128, 2.0)
    sim.advance(400)
    lam = largest_lyapunov(2.0, "dynamic", state=sim.state, periods=400)
    c = classify_motion(sim.advance(200).poincare[:, :10], lam, lyap_tol=lyapunov_tolerance(400 * 2 * math.pi / 2))
    assert not c.periodic and c.label == "quasi-periodic"
    assert abs(lam) < 3e-3


def test_largest_lyapunov_rejects_bad_arguments():
    with pytest.raises(ValueError, match="d0"):
        largest_lyapunov(1.0, d0=0.0)
    with pytest.raises(ValueError, match="periods"):
        largest_lyapunov(1.0, periods=1)
    with pytest.raises(ValueError, match="omega"):
        largest_lyapunov(float("nan"))


def test_gear_sweep_band_around_2_is_not_periodic():
    from gear_env.analysis import sweep

    r = sweep([1.95, 2.0, 2.05], model="dynamic", transient=300, periods=200, progress=False)
    assert all(g in ("quasi-periodic", "chaotic") for g in r.regime), r.regime
    assert np.all(np.abs(r.lyapunov) < 5e-3)  # a torus: exponent near zero, not clearly chaotic
    assert np.all(r.n_clusters > 32)


def test_lyapunov_recorder_statistics_match_a_plain_record():
    from gear_env.analysis.lyapunov import lyapunov_record
    from gear_env.sim import kernels as K
    from gear_env.sim.params import GearParams, model_code
    from gear_env.sim.simulator import IntervalStats

    sim = GearSimulator(None, "dynamic", 64, 0.4)  # impacting motion: contact loss > 0
    sim.advance(100)
    x = sim.state
    plain = sim.advance(30)
    _, pc, stats, t_all, _, _ = lyapunov_record(x, 0.4, 30, 64, GearParams().consts, model_code("dynamic"), 1e-8)
    rec = IntervalStats(0.4, 0.4, 30, t_all, pc, stats)
    np.testing.assert_allclose(pc, plain.poincare, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(x, sim.state, rtol=1e-6, atol=1e-8)
    for name in ("U", "delta", "bd", "psi", "force"):
        assert rec.amplitude(name) == pytest.approx(plain.amplitude(name), rel=1e-6)
    assert rec.separation_fraction == pytest.approx(plain.separation_fraction, abs=1e-3)
    assert rec.separation_fraction > 0.1
    assert stats[K.ST_TIME] == pytest.approx(plain.stats[K.ST_TIME], rel=1e-12)


def test_lyapunov_record_reports_a_blow_up_and_leaves_the_state():
    """A diverging reference trajectory raises SimulationDivergedError naming the period (from the
    compiled pair kernel), never returns NaN, and leaves the caller's state array untouched."""
    from gear_env.analysis.lyapunov import lyapunov_record
    from gear_env.errors import SimulationDivergedError
    from gear_env.sim.params import GearParams, model_code

    x = np.r_[np.zeros(4), 5e5, np.zeros(4), 1e6]  # |q| + |v| beyond the divergence limit
    before = x.copy()
    with pytest.raises(SimulationDivergedError, match="Lyapunov record") as exc:
        lyapunov_record(x, 1.0, 10, 16, GearParams().consts, model_code("constant"), 1e-8)
    assert exc.value.period == 0
    assert np.array_equal(x, before)
