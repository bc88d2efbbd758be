"""Attractor census with basin fractions (gear_env.analysis.census)."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env.analysis.census import attractor_census, start_grid
from gear_env.analysis.continuation import orbit_at
from gear_env.sim.params import GearParams


def test_census_finds_the_two_stable_period1_orbits_at_0p2():
    """Dynamic model, omega = 0.2: the continuation's two stable period-1 orbits (U amplitude 0.88
    and 1.40) are both reached from a 6 x 6 grid; every start is accounted for and the orbit
    points are the shooting solutions."""
    c = attractor_census(0.2, "dynamic", n_u=6, n_v=6)
    assert len(c.starts) == 36 and sum(a.count for a in c.attractors) == 36
    assert sum(a.fraction for a in c.attractors) == pytest.approx(1.0)
    labels = sorted((a.label, round(a.amplitude_u, 2)) for a in c.attractors)
    assert labels == [("period-1", 0.88), ("period-1", 1.4)]
    assert c.attractors[0].fraction >= c.attractors[1].fraction
    for a in c.attractors:
        x, mu, ok = orbit_at(0.2, "dynamic", x0=a.points[-1])
        assert ok and np.max(np.abs(mu)) < 1
        assert np.max(np.abs(x - a.points[-1])) < 1e-3
        assert set(np.flatnonzero(c.assignment == c.attractors.index(a))) == set(a.members)


def test_single_attractor_gets_the_whole_basin():
    c = attractor_census(1.2, "constant", n_u=3, n_v=2, transient=300, periods=16)
    assert len(c.attractors) == 1
    a = c.attractors[0]
    assert a.label == "period-1" and a.fraction == 1.0 and a.count == 6
    assert c.to_json_dict()["attractors"][0]["fraction"] == 1.0


def test_start_grid_and_bad_input():
    g = start_grid(GearParams(), "dynamic", 0.5, 3, 2, 1.0, 0.4)
    assert g.shape == (6, 10)
    assert np.allclose(sorted(set(np.round(g[:, 9], 12))), [-0.4, 0.4])
    assert np.ptp(g[:, 4]) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="n_u"):
        attractor_census(0.5, n_u=0)
    with pytest.raises(ValueError, match="span_u"):
        attractor_census(0.5, span_u=-1.0)
    with pytest.raises(ValueError, match="periods"):
        attractor_census(0.5, periods=2)
    with pytest.raises(ValueError, match="omega"):
        attractor_census(-0.5)
    with pytest.raises(ValueError, match="starts"):
        attractor_census(0.5, starts=np.zeros((3, 4)))
