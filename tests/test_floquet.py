"""Shooting, Floquet multipliers and the stability map (gear_env.analysis.floquet / stability)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gear_env.analysis.floquet import classify_multipliers, find_periodic_orbit, linear_multipliers
from gear_env.analysis.stability import StabilityMap, default_stability_map, stability_map
from gear_env.sim.params import GearParams
from gear_env.sim.simulator import GearSimulator


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance from each multiplier in a to its nearest one in b (conjugate order free)."""
    return float(max(np.min(np.abs(b - x)) for x in a))


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_period1_orbit_equals_long_simulation(model):
    orbit = find_periodic_orbit(1.2, model)
    assert orbit.converged and orbit.period == 1
    assert orbit.residual < 1e-10
    # |mu|max = 0.961: 3000 periods shrink the transient to ~1e-52
    sim = GearSimulator(model=model, omega=1.2)
    sim.advance(3000)
    assert np.max(np.abs(sim.state - orbit.state)) < 1e-8
    assert np.all(np.abs(orbit.multipliers) < 1.0)
    assert orbit.stable and orbit.bifurcation == "stable"


# |mu|max of the grazing period-1 orbits by the event-located SciPy reference (DOP853, rtol 1e-11; Newton
# with a central-difference Jacobian): ``python benchmarks/located_crossings.py --part grazing``
GRAZING_REFERENCE = {("constant", 0.25): 0.38802, ("dynamic", 0.20): 0.26082}


@pytest.mark.parametrize("case", sorted(GRAZING_REFERENCE))
def test_grazing_multipliers_match_the_event_located_reference(case):
    """At an orbit that touches a contact boundary the located map's exact multipliers (the default)
    are within 0.005 of the reference at the default step count; the unlocated map's finite-difference
    multipliers are not (0.02-0.03 off), which is what the located map fixes."""
    model, w = case
    ref = GRAZING_REFERENCE[case]
    o = find_periodic_orbit(w, model, transient=600)
    assert o.converged and abs(o.max_multiplier - ref) < 0.005
    u = find_periodic_orbit(w, model, x0=o.state, located=False)
    assert u.converged and abs(u.max_multiplier - ref) > 0.01


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_linear_multipliers_match_exp_lambda_T(model):
    """kappa = 0 and no TE: the orbit is the static equilibrium in full contact and the monodromy
    eigenvalues are exp(lambda_i T) of the linear system (Newmark error O(h^2))."""
    p = GearParams(kappa=0.0, e_m1=0.0)
    exact = linear_multipliers(1.2, model, p)
    # modal damping: |mu| = exp(-zeta w T); the slowest decaying pair is mode 1 (zeta 0.024)
    assert np.all(np.abs(exact) < 1.0)
    errs = []
    for n in (128, 512):
        o = find_periodic_orbit(1.2, model, p, steps_per_period=n)
        assert o.converged
        errs.append(_match(o.multipliers, exact))
        assert np.allclose(np.sort(np.abs(o.multipliers)), np.sort(np.abs(exact)), atol=3e-3)
    assert errs[0] < 2e-3
    assert errs[1] < errs[0] / 4  # second-order convergence of the discretised map


def test_linear_multiplier_moduli_are_modal_decay():
    """|mu| of the uncoupled perpendicular bearing modes is exactly exp(-xi_b sigma T)."""
    p = GearParams(kappa=0.0, e_m1=0.0)
    mu = linear_multipliers(1.0, "constant", p)
    T = 2 * np.pi / 1.0
    sig_g = p.dimensionless()["sigma_g"]
    assert np.min(np.abs(np.abs(mu) - np.exp(-0.07 * sig_g * T))) < 1e-12


def test_neimark_sacker_between_1_6_and_1_7():
    """A complex pair of multipliers leaves the unit circle in [1.6, 1.7] (torus bifurcation)."""
    for model in ("constant", "dynamic"):
        below = find_periodic_orbit(1.6, model)
        above = find_periodic_orbit(1.7, model, x0=below.state)
        assert below.converged and above.converged
        assert below.max_multiplier < 1.0 < above.max_multiplier
        assert above.bifurcation == "neimark-sacker"
        mu = above.multipliers[0]
        assert abs(mu.imag) > 0.5  # complex pair, not +/-1


def test_period_doubling_at_low_speed_and_period2_orbit():
    o1 = find_periodic_orbit(0.45, "constant")
    assert o1.converged and o1.bifurcation == "period-doubling"
    assert o1.multipliers[0].real < -1.0 and abs(o1.multipliers[0].imag) < 1e-9
    o2 = find_periodic_orbit(0.45, "constant", period=2)
    assert o2.converged and o2.period == 2
    # a genuine period-2 orbit, not the period-1 orbit counted twice
    assert np.max(np.abs(o2.state - o1.state)) > 1e-3


def test_classify_multipliers():
    assert classify_multipliers(np.array([0.9, 0.5j])) == "stable"
    assert classify_multipliers(np.array([-1.1, 0.5])) == "period-doubling"
    assert classify_multipliers(np.array([1.1, 0.5])) == "fold"
    assert classify_multipliers(np.array([0.6 + 0.9j, 0.6 - 0.9j])) == "neimark-sacker"


def test_find_orbit_rejects_bad_arguments():
    with pytest.raises(ValueError, match="omega"):
        find_periodic_orbit(-1.0)
    with pytest.raises(ValueError, match="period"):
        find_periodic_orbit(1.0, period=0)
    with pytest.raises(ValueError, match="x0"):
        find_periodic_orbit(1.0, x0=np.zeros(3))
    with pytest.raises(ValueError, match="model"):
        find_periodic_orbit(1.0, model="rigid")


# ------------------------------------------------------------------------ stability map
def test_stability_map_cache_roundtrip_and_corruption(tmp_path, monkeypatch):
    monkeypatch.setenv("GEAR_ENV_CACHE", str(tmp_path))
    m = stability_map("constant", omega_min=1.5, omega_max=1.8, points=7)
    files = list(tmp_path.glob("stability-constant-*.json"))
    assert len(files) == 1
    assert m.is_stable(1.5) and not m.is_stable(1.8)
    (lo, hi) = m.stable_intervals()[0]
    assert lo == 1.5 and 1.6 < hi < 1.7
    assert m.bifurcations()[0][2] == "neimark-sacker"
    # cached: same result without recomputation (a hit returns an equal map)
    m2 = stability_map("constant", omega_min=1.5, omega_max=1.8, points=7)
    assert np.allclose(m2.max_multiplier, m.max_multiplier)
    # a corrupt cache file is recomputed, not trusted
    files[0].write_text('{"format": "gear-env-stability-map", "version": 1, "omega": [1, 2')
    m3 = stability_map("constant", omega_min=1.5, omega_max=1.8, points=7)
    assert np.allclose(m3.max_multiplier, m.max_multiplier)
    json.loads(files[0].read_text())  # rewritten completely
    # a tampered (valid JSON, wrong content) file is not trusted either
    d = json.loads(files[0].read_text())
    d["max_multiplier"] = [0.0] * 7
    d["labels"] = ["stable"] * 7
    d["omega"] = [9.0] * 7
    files[0].write_text(json.dumps(d))
    m4 = stability_map("constant", omega_min=1.5, omega_max=1.8, points=7)
    assert not m4.is_stable(1.8)


def test_stability_map_errors(tmp_path, monkeypatch):
    monkeypatch.setenv("GEAR_ENV_CACHE", str(tmp_path))
    with pytest.raises(ValueError, match="omega_max"):
        stability_map("dynamic", omega_min=2.0, omega_max=1.0, points=5)
    with pytest.raises(ValueError, match="points"):
        stability_map("dynamic", points=1)
    m = stability_map("dynamic", omega_min=1.0, omega_max=1.2, points=3)
    with pytest.raises(ValueError, match="omega"):
        m.is_stable(2.0)
    with pytest.raises(ValueError):
        StabilityMap.from_dict({"format": "gear-env-stability-map", "version": 99})


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_packaged_default_maps(model):
    m = default_stability_map(model)
    assert m.model == model and m.converged.all()
    assert m.omega[0] == pytest.approx(0.05) and m.omega[-1] == pytest.approx(3.0)
    assert m.is_stable(1.0) and m.is_stable(1.2)
    assert not m.is_stable(2.0) and m.label_at(2.0) == "neimark-sacker"
    assert m.label_at(0.45) == "period-doubling"
    # the map is what stability_map returns for the default configuration (no computation)
    assert stability_map(model) is not None


@pytest.mark.slow
@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_packaged_maps_are_reproducible(model, tmp_path, monkeypatch):
    from gear_env.analysis.stability import DEFAULT_POINTS, _grid, compute_stability_map

    m = compute_stability_map(_grid(0.05, 3.0, DEFAULT_POINTS), model)
    d = default_stability_map(model)
    assert list(m.labels) == list(d.labels)
    assert np.allclose(m.max_multiplier, d.max_multiplier, atol=1e-6)


@pytest.mark.parametrize("omega", [0.8, 1.2])
def test_lyapunov_equals_log_multiplier_over_period(omega):
    """Independent cross-check of two methods: on a stable period-1 orbit the largest Lyapunov
    exponent (two trajectories, renormalised every period) is ln|mu_max| / T, T = 2 pi / omega."""
    from gear_env.analysis import largest_lyapunov

    o = find_periodic_orbit(omega, "dynamic")
    lam = largest_lyapunov(omega, "dynamic", state=o.state, periods=1000)
    assert lam == pytest.approx(np.log(o.max_multiplier) * omega / (2 * np.pi), abs=3e-4)


def test_period_map_reuses_its_last_result_only_for_the_same_map_and_state():
    """The located map keeps its last (P(x), Jacobian) for the Newton loop; a changed state or a changed
    public attribute (omega) recomputes, so the cache cannot hand back another map's result."""
    from gear_env.analysis.floquet import PeriodMap

    pm = PeriodMap(1.2, "dynamic")
    x = find_periodic_orbit(1.2, "dynamic").state
    y1, n1 = pm(x), pm.evaluations
    assert np.array_equal(pm(x), y1) and np.array_equal(pm.jacobian(x), pm.jacobian(x.copy()))
    assert pm.evaluations == n1  # the same x: no new evaluation
    pm.omega = 1.25
    y2 = pm(x)
    assert pm.evaluations == n1 + 1 and not np.array_equal(y1, y2)
    assert np.array_equal(y2, PeriodMap(1.25, "dynamic", steps_per_period=pm.steps)(x))
