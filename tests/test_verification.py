"""Verification against known answers: linear natural frequencies (MODEL.md sec. 5), the linear
frequency response in full contact, the independent solve_ivp reference (gear_env.sim.reference) in
periodic regimes, and second-order convergence on impacting motion."""

import math

import numpy as np
import pytest

from gear_env import GearParams, GearSimulator, default_steps_per_period
from gear_env.sim.linear import linear_frequency_response, matrices, natural_frequencies
from gear_env.sim.reference import reference_initial_state, reference_poincare


def test_natural_frequencies_constant_model():
    w = natural_frequencies(GearParams(), "constant")
    expected = [0.32004, 0.81887, 0.94374, 1.14856, 3.11400]
    assert np.allclose(w, expected, atol=6e-6)
    d = GearParams().dimensionless()
    # modes 2 and 4 are the uncoupled perpendicular bearing modes
    assert abs(w[1] - d["sigma_g"]) < 1e-12 and abs(w[3] - d["sigma_p"]) < 1e-12


def test_natural_frequencies_dynamic_model():
    w = natural_frequencies(GearParams(), "dynamic")
    expected = [0.30519, 0.81887, 0.94366, 1.14856, 3.26573]
    assert np.allclose(w, expected, atol=6e-6)
    _, _, K = matrices(GearParams(), "dynamic")
    assert not np.allclose(K, K.T)  # dB_d/dq makes K non-symmetric


def test_linear_matrices_match_model_md():
    p = GearParams()
    d = p.dimensionless()
    M, C, K = matrices(p)
    assert np.allclose(np.diag(M), [d["eps_p"], d["eps_p"], d["eps_g"], d["eps_g"], 1.0])
    a = p.alpha0
    g = np.array([math.sin(a), -math.cos(a), -math.sin(a), math.cos(a), 1.0])
    assert np.allclose(K - np.outer(g, g), np.diag([d["lam_p"]] * 2 + [d["lam_g"]] * 2 + [0.0]))
    assert np.allclose(C, C.T)


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("omega", [0.6, 1.2, 2.0])
def test_full_contact_small_excitation_matches_linear_response(model, omega):
    """kappa = 0 and a small TE keep the teeth in contact: the response is the linear one."""
    p = GearParams(kappa=0.0, e_m1=2e-7)  # E1 = 0.01 << F_s = 0.0275
    lr = linear_frequency_response(p, omega, model)
    sim = GearSimulator(p, model, 256, omega, lr.state(0.0))
    tr = sim.record(60)
    assert np.all(tr["region"] == 1)
    last = tr.poincare_rows[-5:, :10]
    err = np.max(np.abs(last - lr.state(0.0)))
    amp = lr.amplitude("delta")
    if model == "constant":
        # exact equations are linear here: only the O(h^2) Newmark error remains
        assert err < 2e-3 * amp, (err, amp)
    else:
        # the dynamic B_d(q) is mildly nonlinear (static bearing deflection ~0.1 b0): ~4e-6 b0
        assert err < 1e-5, (err, amp)
    tail = tr.data[-3 * 256 :]
    u = tail[:, 4]
    assert abs(0.5 * (u.max() - u.min()) / lr.amplitude("U") - 1.0) < 3e-3
    assert abs(lr.delta_static - (1.0 + p.dimensionless()["F_s"])) < 1e-12 or model == "dynamic"


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_initial_state_a10_matches_reference(model):
    from gear_env import default_initial_state

    p = GearParams()
    assert np.max(np.abs(default_initial_state(p, model) - reference_initial_state(p, model))) < 1e-12


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("omega", [0.2, 0.45, 0.8, 1.2, 1.5, 2.8])
def test_agrees_with_solve_ivp_in_periodic_regimes(model, omega):
    """Newmark at the default step count vs DOP853 (rtol 1e-11, contact changes located by events).

    Both start from the same state on the attractor (after 300 transient periods) and run 15
    mesh periods; all 10 states at every Poincare point agree to 1e-3 (b0 units). The omegas
    include the hardest periodic cases of the convergence study: 0.2 (low omega: long natural-time
    steps, impacts) and 1.5 (one violent impact per mesh period).
    """
    p = GearParams()
    sim = GearSimulator(p, model, None, omega)
    assert sim.steps_per_period == default_steps_per_period(omega)
    sim.advance(300)
    start = sim.state
    st = sim.advance(15)
    ref = reference_poincare(omega, model, p, transient=0, periods=15, initial_state=start)
    err = np.max(np.abs(st.poincare[:, :10] - ref.states))
    assert err < 1e-3, err
    assert np.max(np.abs(st.poincare[:, 10] - ref.delta)) < 1e-3
    if omega == 2.8:
        assert ref.events >= 15  # contact loss and re-impact every mesh period


def test_agrees_with_solve_ivp_from_a10_transient():
    """The transient from the default initial state (contact loss at omega = 2.8) also agrees."""
    p = GearParams()
    sim = GearSimulator(p, "dynamic", None, 2.8)
    st = sim.advance(20)
    ref = reference_poincare(2.8, "dynamic", p, transient=0, periods=20)
    assert np.max(np.abs(st.poincare[:, :10] - ref.states)) < 1e-3


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("omega", [1.5, 3.0])
def test_second_order_convergence_with_impacts(model, omega):
    """Errors vs N = 2048 over 10 impacting mesh periods fall as N^-2 (fit over N = 32..512)."""
    p = GearParams()
    sim = GearSimulator(p, model, 128, omega)
    sim.advance(300)
    start = sim.state
    runs = {}
    for n in (32, 64, 128, 256, 512, 2048):
        runs[n] = GearSimulator(p, model, n, omega, start).advance(10)
    assert runs[2048].drive_impacts >= 10 and runs[2048].separation_fraction > 0.5
    ns = np.array([32, 64, 128, 256, 512])
    errs = np.array([np.max(np.abs(runs[n].poincare[:, :10] - runs[2048].poincare[:, :10])) for n in ns])
    order = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert 1.75 < order < 2.3, (order, errs)
    assert np.all(np.diff(errs) < 0)
