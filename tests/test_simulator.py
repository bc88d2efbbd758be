"""Simulator API: initial state A10, constant vs dynamic backlash, state continuity, argument
validation, divergence handling and determinism."""

import math

import numpy as np
import pytest

from gear_env import GearParams, GearSimulator, SimulationDivergedError, default_initial_state, simulate
from gear_env.sim.reference import RefConsts, mesh_quantities, rhs


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_initial_state_a10(model):
    """Delta(0) = B_d + F_s, zero velocities, static equilibrium of the kappa = 0 model."""
    p = GearParams()
    x0 = default_initial_state(p, model)
    k = RefConsts.from_params(p)
    y = np.concatenate([x0, [0.0]])
    delta, ddelta, bd, psi = mesh_quantities(y, 1.0, k, model)
    assert abs(delta - (bd + k.F_s)) < 1e-12
    assert np.all(x0[5:] == 0.0)
    k0 = RefConsts.from_params(p.replace(kappa=0.0))
    acc = rhs(0.0, y, 1.0, k0, model)[5:10]
    assert np.max(np.abs(acc)) < 1e-11
    # the trajectory's first row is this state
    tr = simulate(1.0, model, periods=1, transient=0)
    assert np.array_equal(tr.states[0], x0)
    assert abs(tr["delta"][0] - (tr["bd"][0] + k.F_s)) < 1e-12


def test_constant_vs_dynamic_backlash():
    """MODEL.md sec. 6: b_d varies in the dynamic model while psi stays at alpha0 (1e-12)."""
    p = GearParams()
    a0 = p.alpha0
    dyn = simulate(1.5, "dynamic", periods=20, transient=100)
    con = simulate(1.5, "constant", periods=20, transient=100)
    assert dyn.amplitude("bd") > 0.02  # b_d differs from b_c by a few percent
    assert np.max(np.abs(dyn["bd"] - 1.0)) > 0.04
    assert np.max(np.abs(dyn["psi"] - a0)) < 1e-12
    assert np.all(con["bd"] == 1.0)
    assert np.all(con["psi"] == a0)
    # the two models give different trajectories
    assert np.max(np.abs(dyn["U"] - con["U"])) > 1e-3


def test_poincare_samples_are_every_period():
    tr = simulate(1.2, "dynamic", periods=7, transient=0, steps_per_period=64)
    assert tr.poincare("U").shape == (7,)
    phase = tr.poincare("phase")
    assert np.allclose(phase, 2 * np.pi * np.arange(1, 8), atol=1e-9)
    s = tr.poincare("s")
    assert np.allclose(np.diff(s), 2 * np.pi / 1.2, rtol=1e-12)


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_advance_in_pieces_equals_one_call(model):
    a = GearSimulator(model=model, omega=2.8)
    b = GearSimulator(model=model, omega=2.8)
    st1 = a.advance(25)
    st2 = a.advance(15)
    st = b.advance(40)
    assert np.allclose(np.vstack([st1.poincare, st2.poincare]), st.poincare, rtol=0, atol=1e-12)
    # record() continues the same trajectory as advance()
    c = GearSimulator(model=model, omega=2.8)
    c.advance(25)
    tr = c.record(15)
    assert np.allclose(tr.poincare_rows[:, :10], st2.poincare[:, :10], rtol=0, atol=1e-12)


def test_omega_ramp_ends_at_target_and_on_section():
    sim = GearSimulator(omega=1.0)
    st = sim.advance(50, omega_end=1.3)
    assert sim.omega == 1.3 and st.omega_start == 1.0
    # omega linear in time: elapsed natural time = periods * 2 pi / mean(omega)
    assert math.isclose(st.duration, 50 * 2 * np.pi / 1.15, rel_tol=1e-4)
    tr = sim.record(2, omega_end=1.0)
    assert math.isclose(tr.omega[0], 1.3) and math.isclose(tr.omega[-1], 1.0)


def test_determinism():
    a = simulate(2.1, "dynamic", periods=30, transient=50)
    b = simulate(2.1, "dynamic", periods=30, transient=50)
    assert np.array_equal(a.data, b.data)
    s1 = GearSimulator(omega=0.45).advance(40)
    s2 = GearSimulator(omega=0.45).advance(40)
    assert np.array_equal(s1.poincare, s2.poincare) and np.array_equal(s1.stats, s2.stats)


@pytest.mark.parametrize("omega", [float("nan"), float("inf"), -1.0, 0.0, "1.2", None, True])
def test_bad_omega(omega):
    with pytest.raises(ValueError, match="omega"):
        simulate(omega, periods=1, transient=0)


@pytest.mark.parametrize("periods", [0, -3, 1.5])
def test_bad_periods(periods):
    with pytest.raises(ValueError, match="periods"):
        simulate(1.0, periods=periods, transient=0)
    with pytest.raises(ValueError, match="periods"):
        GearSimulator().advance(periods)


def test_bad_transient_model_steps_state():
    with pytest.raises(ValueError, match="transient"):
        simulate(1.0, periods=1, transient=-1)
    with pytest.raises(ValueError, match="model"):
        simulate(1.0, model="elastic", periods=1, transient=0)
    with pytest.raises(ValueError, match="steps_per_period"):
        simulate(1.0, periods=1, transient=0, steps_per_period=2)
    for bad in (np.zeros(9), np.zeros((2, 10)), np.zeros(11), [np.nan] * 10):
        with pytest.raises(ValueError, match="initial_state"):
            simulate(1.0, periods=1, transient=0, initial_state=bad)
    with pytest.raises(ValueError, match="omega_end"):
        GearSimulator().advance(2, omega_end=-1.0)


def test_divergence_raises_with_period():
    x = np.full(10, 1e7)
    with pytest.raises(SimulationDivergedError) as ei:
        simulate(1.0, periods=5, transient=0, initial_state=x)
    assert ei.value.period == 0
    assert "diverged" in str(ei.value) and "mesh period 0" in str(ei.value)
    # a state that grows past the limit later: absurd negative-damping-like kick
    x = default_initial_state(GearParams(), "dynamic")
    x[9] = 5e5
    sim = GearSimulator(omega=1.0, initial_state=x)
    with pytest.raises(SimulationDivergedError) as ei:
        sim.advance(10)
    assert ei.value.omega == 1.0 and ei.value.period >= 0
    # the failed interval is discarded: state unchanged
    assert np.array_equal(sim.state, x)


def test_no_nan_ever_returned():
    tr = simulate(2.0, "dynamic", periods=20, transient=20)
    assert np.all(np.isfinite(tr.data))


def test_default_steps_per_period_rule_and_ramps():
    """192 steps per mesh period, more below omega ~ 0.27 (natural-time step <= 0.12)."""
    from gear_env import default_steps_per_period
    from gear_env.sim.simulator import MAX_NATURAL_STEP

    assert default_steps_per_period(1.2) == 192 and default_steps_per_period(0.3) == 192
    assert default_steps_per_period(0.2) == 262
    for w in (1e-3, 0.05, 0.1, 0.2, 0.27, 0.5, 3.0, 100.0):
        n = default_steps_per_period(w)
        assert 2 * np.pi / (w * n) <= MAX_NATURAL_STEP + 1e-15 and 192 <= n <= 100_000
    with pytest.raises(ValueError, match="omega"):
        default_steps_per_period(0.0)
    # automatic: chosen per interval from its lower omega; an explicit value is kept
    sim = GearSimulator(None, "constant", None, 1.0)
    assert sim.steps_per_period == 192
    sim.advance(2, omega_end=0.2)
    assert sim.steps_per_period == 262
    tr = sim.record(1)
    assert tr.steps_per_period == 262 and len(tr.data) == 263
    fixed = GearSimulator(None, "constant", 64, 1.0)
    fixed.advance(2, omega_end=0.2)
    assert fixed.steps_per_period == 64


def test_complex_initial_state_is_refused():
    from gear_env import simulate

    with pytest.raises(ValueError, match="initial_state must be real numbers"):
        simulate(1.0, periods=1, transient=0, initial_state=np.zeros(10) + 1j)
