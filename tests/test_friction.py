"""The optional tooth-friction extension (GearParams.friction) that makes the meshing angle fluctuate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gear_env.analysis.floquet import find_periodic_orbit
from gear_env.sim import kernels as K
from gear_env.sim.params import GearParams, model_code
from gear_env.sim.simulator import GearSimulator, simulate


def test_friction_force_is_tangential_and_opposite():
    """Independent evaluation of the translational equations with friction at a random state."""
    p = GearParams(friction=0.08)
    c = p.consts
    rng = np.random.default_rng(1)
    q = rng.normal(0, 0.3, 5)
    v = rng.normal(0, 0.3, 5)
    phi = 0.7
    ce, se, kk = K.excitation(phi, c)
    geo = np.zeros(K.WORK_SIZE)
    a = np.zeros(5)
    F = K.accel(q, v, ce, se, 1.3, kk, c, model_code("dynamic"), geo, a)
    psi = geo[0]
    n_p = np.array([-math.sin(psi), math.cos(psi)])  # normal force direction on the pinion
    t_p = np.array([math.cos(psi), math.sin(psi)])  # tangential (off line of action)
    fr = 0.08 * math.tanh(10 * math.sin(phi))
    d = p.dimensionless()
    f_p = F * (n_p + fr * t_p)
    ap = -(2 * 0.07 * d["sigma_p"] * v[:2] + d["sigma_p"] ** 2 * q[:2]) + f_p / d["eps_p"]
    ag = -(2 * 0.07 * d["sigma_g"] * v[2:4] + d["sigma_g"] ** 2 * q[2:4]) - f_p / d["eps_g"]
    assert np.allclose(a[:2], ap, rtol=1e-12, atol=1e-14)
    assert np.allclose(a[2:4], ag, rtol=1e-12, atol=1e-14)
    assert a[4] == pytest.approx(d["F_s"] - F)


def test_friction_off_keeps_psi_constant_and_on_makes_it_fluctuate():
    base = simulate(1.0, "dynamic", periods=20, transient=200)
    assert base.amplitude("psi") < 1e-14  # MODEL.md sec. 6: psi cannot move without off-LOA forces
    grav = simulate(1.0, "dynamic", periods=20, transient=200, params=GearParams(gravity=9.81))
    assert grav.amplitude("psi") < 1e-14  # gravity only shifts psi statically
    amps = []
    for mu in (0.05, 0.1):
        tr = simulate(1.0, "dynamic", periods=20, transient=200, params=GearParams(friction=mu))
        amps.append(tr.amplitude("psi"))
    assert amps[0] > 1e-6  # ~8.6e-6 rad (4.9e-4 deg)
    assert amps[1] / amps[0] == pytest.approx(2.0, rel=0.05)  # small-mu response is linear in mu


def test_friction_periodic_orbit_and_psi_period():
    p = GearParams(friction=0.1)
    o = find_periodic_orbit(1.2, "dynamic", p)
    assert o.converged and o.stable
    sim = GearSimulator(p, "dynamic", omega=1.2, initial_state=o.state)
    tr = sim.record(4)
    psi = tr["psi"]
    n = tr.steps_per_period
    assert np.max(np.abs(psi[n:] - psi[:-n])) < 1e-12  # psi is mesh-periodic on the orbit
    assert np.ptp(psi) > 1e-6
