"""Amplitude spectra in multiples of the mesh frequency (gear_env.analysis.spectrum)."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env.analysis.floquet import find_periodic_orbit
from gear_env.analysis.spectrum import amplitude_spectrum, waterfall
from gear_env.sim.simulator import GearSimulator

N = 64  # samples per mesh period


def _phase(periods: int) -> np.ndarray:
    return 2 * np.pi * np.arange(periods * N) / N  # mesh phase of each sample


def test_pure_harmonic_amplitude_at_its_multiple():
    ph = _phase(32)
    x = 0.7 * np.cos(3 * ph + 0.4) + 5.0  # third mesh harmonic plus an offset
    s = amplitude_spectrum(x, steps_per_period=N)
    assert s.amplitude_at(3.0) == pytest.approx(0.7, rel=1e-12)
    assert s.frequency[np.argmax(s.amplitude)] == pytest.approx(3.0)
    assert s.amplitude_at(0.0) == 0.0  # mean removed
    assert s.amplitude_at(1.0) < 1e-12
    # no window: all energy in the single bin
    r = amplitude_spectrum(x, steps_per_period=N, window="rect")
    assert r.amplitude_at(3.0) == pytest.approx(0.7, rel=1e-12)
    assert np.sort(r.amplitude)[-2] < 1e-12


def test_period2_signal_has_half_multiple():
    ph = _phase(40)
    x = np.cos(ph) + 0.25 * np.sin(0.5 * ph) + 0.1 * np.cos(1.5 * ph)
    s = amplitude_spectrum(x, steps_per_period=N, max_multiple=3)
    assert s.amplitude_at(0.5) == pytest.approx(0.25, rel=1e-9)
    assert s.amplitude_at(1.0) == pytest.approx(1.0, rel=1e-9)
    assert s.amplitude_at(1.5) == pytest.approx(0.1, rel=1e-9)
    assert s.frequency[-1] <= 3.0


def test_partial_period_is_dropped():
    ph = 2 * np.pi * np.arange(10 * N + 17) / N
    s = amplitude_spectrum(np.cos(2 * ph), steps_per_period=N)
    assert s.periods == 10
    assert s.amplitude_at(2.0) == pytest.approx(1.0, rel=1e-12)


def test_gear_period2_orbit_shows_half_multiple():
    """At omega = 0.45 the period-1 orbit has flipped (multiplier < -1): the response is period-2."""
    # the fixed-step simulator's own period-2 orbit (located=False), so that the record is periodic to round-off
    o2 = find_periodic_orbit(0.45, "constant", period=2, steps_per_period=N, located=False)
    assert o2.converged
    sim = GearSimulator(model="constant", omega=0.45, steps_per_period=N, initial_state=o2.state)
    s = amplitude_spectrum(sim.record(32), "delta")
    assert s.amplitude_at(0.5) > 0.05 * s.amplitude_at(1.0)
    # a period-2 response has no other sub-harmonic content
    assert s.amplitude_at(0.25) < 1e-3 * s.amplitude_at(0.5)


def test_gear_period1_has_only_harmonics():
    o = find_periodic_orbit(1.2, "dynamic", steps_per_period=N)
    sim = GearSimulator(model="dynamic", omega=1.2, steps_per_period=N, initial_state=o.state)
    s = amplitude_spectrum(sim.record(16), "delta")
    assert s.amplitude_at(0.5) < 1e-6 * s.amplitude_at(1.0)


def test_waterfall_shape_and_content():
    wf = waterfall([1.0, 1.2], model="dynamic", periods=16, transient=50, steps_per_period=32, max_multiple=3)
    assert wf.amplitude.shape == (2, len(wf.frequency))
    assert wf.frequency[-1] == pytest.approx(3.0)
    k1 = np.argmin(np.abs(wf.frequency - 1.0))
    assert np.all(wf.amplitude.argmax(axis=1) == k1)  # dominated by the mesh frequency


def test_spectrum_errors():
    with pytest.raises(ValueError, match="steps_per_period"):
        amplitude_spectrum(np.zeros(100))
    with pytest.raises(ValueError, match="periods"):
        amplitude_spectrum(np.zeros(10), steps_per_period=N)
    with pytest.raises(ValueError, match="window"):
        amplitude_spectrum(np.zeros(4 * N), steps_per_period=N, window="kaiser")
    with pytest.raises(ValueError, match="finite"):
        amplitude_spectrum(np.full(4 * N, np.nan), steps_per_period=N)
    with pytest.raises(ValueError, match="omegas"):
        waterfall([])
