"""Tangent map of the Newmark step, pseudo-arclength continuation, bifurcations, branch switching
(gear_env.analysis.tangent / continuation)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gear_env.analysis import tangent as TG
from gear_env.analysis.continuation import (
    FiniteDifferenceMap,
    OrbitMap,
    continue_map,
    continue_orbits,
    orbit_at,
)
from gear_env.analysis.floquet import PeriodMap, find_periodic_orbit, linear_multipliers
from gear_env.analysis.testsystems import duffing_advance
from gear_env.sim import kernels as K
from gear_env.sim.params import GearParams, model_code
from gear_env.sim.simulator import NEWTON_MAX_ITER, NEWTON_TOL


def _accel(x, phi, omega, c, code):
    a = np.zeros(5)
    ce, se = math.cos(phi + c[10]), math.sin(phi + c[10])  # C_PHI_E = 10
    kk = 1.0 + c[7] * math.cos(phi + c[8])  # C_KAPPA, C_PHI_K
    K.accel(x[:5].copy(), x[5:].copy(), ce, se, omega, kk, c, code, np.zeros(K.GEO_SIZE), a)
    return a


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("target", [1.5, 0.0, -1.5])  # Delta: drive contact, apart, back contact
def test_accel_jacobian_matches_finite_differences_of_the_kernel_force(model, target):
    """The analytic derivative of kernels.accel, one region at a time, against central differences
    of the kernel itself (steps small enough to stay in the region)."""
    p = GearParams()
    c = K.readonly(np.ascontiguousarray(p.consts))
    code = model_code(model)
    rng = np.random.default_rng(3)
    x = np.zeros(10)
    K.static_equilibrium(c, code, 0.0, x)
    x = x + 0.05 * rng.standard_normal(10)
    phi, omega = 0.7, 1.3
    ce, se = math.cos(phi + c[10]), math.sin(phi + c[10])
    delta = K.mesh_state(x[:5].copy(), x[5:].copy(), ce, se, omega, c, code, np.zeros(K.GEO_SIZE))[0]
    x[4] += target - delta
    J = np.zeros((5, 10))
    region = TG.accel_jacobian_array(x, phi, omega, c, code, -9, J)
    assert region == {1.5: 1, 0.0: 0, -1.5: -1}[target]
    fd = np.zeros((5, 10))
    for j in range(10):
        h = 1e-6
        e = np.zeros(10)
        e[j] = h
        fd[:, j] = (_accel(x + e, phi, omega, c, code) - _accel(x - e, phi, omega, c, code)) / (2 * h)
    assert np.max(np.abs(J - fd)) < 1e-7 * (1 + np.max(np.abs(fd)))


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_tangent_map_is_the_period_map_and_its_jacobian_matches_finite_differences(model):
    """Away from grazing (omega = 1.2) the exact Jacobian of the discrete map equals floquet.py's
    central differences to their accuracy, and the map itself is bit-identical."""
    # the independent side: the simulator's fixed-step map and central differences of it
    o = find_periodic_orbit(1.2, model, located=False)
    pm = PeriodMap(1.2, model, located=False)
    for om in (OrbitMap(model, None, 1), OrbitMap(model, None, 1, located=False)):
        y, jac, info, pc = om.tangent(o.state, 1.2, pm.steps)
        assert np.array_equal(y, pm(o.state))  # no contact change: located == unlocated, bit for bit
        assert np.array_equal(pc[0], y)
        assert np.max(np.abs(jac - o.monodromy)) < 1e-6
        mu = np.linalg.eigvals(jac)
        assert max(np.min(np.abs(mu - m)) for m in o.multipliers) < 1e-6
    # no contact change on this orbit: the crossing correction changes nothing
    _, jac_c, info_c, _ = om.tangent(o.state, 1.2, pm.steps, corrected=True)
    assert info[TG.INFO_SWITCHES] == 0 and np.array_equal(jac, jac_c)
    # and the located Floquet map (the default) is the same orbit with the exact Jacobian
    ol = find_periodic_orbit(1.2, model)
    assert np.max(np.abs(ol.state - o.state)) < 1e-10 and np.max(np.abs(ol.monodromy - o.monodromy)) < 1e-6


def test_linear_system_exact_discrete_and_continuous_multipliers():
    """kappa = 0, no TE: a linear system in full contact. The tangent map equals the n-th power of
    the Newmark amplification matrix built here from K and C (taken by differences of the kernel's
    force), to round-off; its eigenvalues converge to exp(lambda T) at O(h^2)."""
    p = GearParams(kappa=0.0, e_m1=0.0)
    c = K.readonly(np.ascontiguousarray(p.consts))
    x0 = np.zeros(10)
    K.static_equilibrium(c, 0, 0.0, x0)
    a_ref = _accel(x0, 0.0, 1.2, c, 0)
    kq = np.zeros((5, 5))
    cv = np.zeros((5, 5))
    for j in range(5):
        e = np.zeros(10)
        e[j] = 1e-3
        kq[:, j] = -(_accel(x0 + e, 0.0, 1.2, c, 0) - a_ref) / 1e-3
        e = np.zeros(10)
        e[5 + j] = 1e-3
        cv[:, j] = -(_accel(x0 + e, 0.0, 1.2, c, 0) - a_ref) / 1e-3
    exact = linear_multipliers(1.2, "constant", p)
    errs = []
    for n in (128, 512):
        h = 2 * math.pi / n / 1.2
        bh2, gh, hh, h1 = h * h / 4, h / 2, h * h / 4, h / 2
        # z = (q, v, a): predictors, then (I + gh C + bh2 K) a1 = -K q~ - C v~
        pred = np.zeros((10, 15))
        pred[:5, :5] = np.eye(5)
        pred[:5, 5:10] = h * np.eye(5)
        pred[:5, 10:] = hh * np.eye(5)
        pred[5:, 5:10] = np.eye(5)
        pred[5:, 10:] = h1 * np.eye(5)
        a1 = np.linalg.solve(np.eye(5) + gh * cv + bh2 * kq, -(kq @ pred[:5] + cv @ pred[5:]))
        step = np.vstack([pred[:5] + bh2 * a1, pred[5:] + gh * a1, a1])
        start = np.vstack([np.eye(10), -np.hstack([kq, cv])])
        mono = (np.linalg.matrix_power(step, n) @ start)[:10]
        om = OrbitMap("constant", p, 1, steps_per_period=n)
        y, jac, _, _ = om.tangent(x0, 1.2, n)
        assert np.max(np.abs(y - x0)) < 1e-12  # the equilibrium is the orbit
        assert np.max(np.abs(jac - mono)) < 1e-10
        mu = np.linalg.eigvals(jac)
        errs.append(max(np.min(np.abs(exact - m)) for m in mu))
    assert errs[0] < 2e-3 and errs[1] < errs[0] / 10  # O(h^2): 16x for 4x the steps


def test_located_and_corrected_multipliers_are_smooth_where_the_unlocated_ones_jump():
    """Constant model near the torus onset: the unlocated discrete map's own |mu|max jumps each time a
    contact change moves to the next step (up to ~0.01 between omega 0.0025 apart); the
    crossing-corrected multipliers (unlocated map) and the located map's exact multipliers (the
    default) grow smoothly, cross 1 once, within 0.006 of the packaged Floquet map's edge, and agree
    with each other to O(h^2)."""
    om_u = OrbitMap("constant", None, 1, located=False)
    ws = np.arange(1.62, 1.6576, 0.0025)
    x = find_periodic_orbit(ws[0], "constant").state
    xl = x.copy()
    raw, cor, loc = [], [], []
    for w in ws:
        x, _, ok = orbit_at(w, "constant", x0=x, located=False)
        assert ok
        raw.append(abs(np.linalg.eigvals(om_u.tangent(x, w, om_u.steps(w))[1])).max())
        cor.append(abs(np.linalg.eigvals(om_u.tangent(x, w, om_u.steps(w), corrected=True)[1])).max())
        xl, mu, ok = orbit_at(w, "constant", x0=xl)
        assert ok
        loc.append(abs(mu).max())
    raw, cor, loc = np.array(raw), np.array(cor), np.array(loc)
    assert np.min(np.diff(raw)) < -0.004  # the sawtooth of the discrete map
    for m in (cor, loc):
        d = np.diff(m)
        assert np.all(d > 0) and np.max(d) < 2 * np.min(d)  # smooth, monotone
        k = int(np.nonzero(m > 1)[0][0])
        edge = ws[k - 1] + (ws[k] - ws[k - 1]) * (1 - m[k - 1]) / (m[k] - m[k - 1])
        assert abs(edge - 1.63698) < 0.006
    assert np.max(np.abs(loc - cor)) < 2e-3


# ------------------------------------------------------------------ known systems
def _duffing_map(delta, alpha, beta, gamma, n_steps=200):
    out = np.empty((0, 2))

    def advance(x, omega):
        y = np.array(x, float)
        duffing_advance(y, 1, n_steps, delta, alpha, beta, gamma, omega, out)
        return y

    return lambda n: FiniteDifferenceMap(advance, n, amplitude=lambda p: float(np.max(np.hypot(p[:, 0], p[:, 1]))))


def test_duffing_fold_pair_matches_harmonic_balance():
    """Hardening Duffing x'' + 0.1 x' + x + 0.1 x^3 = 0.3 cos(omega t): the continuation passes
    both folds of the resonance curve; they agree with the one-harmonic balance
    X (1 - w^2 + 3/4 beta X)^2 + (delta w)^2 X = gamma^2 (X = A^2; three positive roots between
    the folds) to 1 %, and the middle branch is unstable through a real multiplier > 1."""
    d, a, b, g = 0.1, 1.0, 0.1, 0.3
    ws = np.linspace(0.9, 1.4, 5001)
    nroots = []
    for w in ws:
        s, c = a - w * w, 0.75 * b
        r = np.roots([c * c, 2 * s * c, s * s + (d * w) ** 2, -g * g])
        nroots.append(int(np.sum((np.abs(r.imag) < 1e-12) & (r.real > 0))))
    change = np.nonzero(np.diff(nroots))[0]
    assert len(change) == 2
    jump_up, jump_down = (float(0.5 * (ws[i] + ws[i + 1])) for i in change)
    r = continue_map(_duffing_map(d, a, b, g), [0.3, 0.0], 0.7, 1.6, max_switches=0, ds_max=0.05)
    assert r.complete, r.messages
    folds = sorted(bp.omega for bp in r.bifurcations if bp.type == "fold")
    assert len(folds) == 2
    assert abs(folds[0] - jump_up) < 0.01 * jump_up
    assert abs(folds[1] - jump_down) < 0.01 * jump_down
    br = r.branches[0]
    mid = (br.omega > folds[0] + 0.01) & (br.omega < folds[1] - 0.01)
    amp = br.amplitude_u
    unstable = ~br.stable
    # three coexisting orbits inside the fold pair, exactly the middle one unstable (mu > 1 real)
    w = 0.5 * (folds[0] + folds[1])
    cross = np.nonzero((br.omega[:-1] - w) * (br.omega[1:] - w) <= 0)[0]
    assert len(cross) == 3
    assert [bool(unstable[i]) for i in cross] == [False, True, False]
    assert np.all(br.multipliers[unstable & mid, 0].real > 1)
    assert amp[cross[0]] > amp[cross[1]] > amp[cross[2]]  # upper branch first, then saddle, lower


def test_logistic_map_period_doubling_cascade_by_branch_switching():
    """x -> r x (1 - x): period doubling at r = 3 and r = 1 + sqrt(6); the switched period-2
    branch is the analytic ((r + 1) +/- sqrt((r - 3)(r + 1)))/(2 r), and the period-4 branch starts
    at 1 + sqrt(6)."""

    def factory(n):
        return FiniteDifferenceMap(lambda x, r: r * x * (1 - x), n)

    r = continue_map(factory, [0.6], 2.6, 3.5, max_period=4, ds_max=0.05, locate_tol=1e-4)
    pds = [(bp.period, bp.omega) for bp in r.bifurcations if bp.type == "period-doubling"]
    assert any(p == 1 and abs(w - 3.0) < 1e-4 for p, w in pds)
    assert any(p == 2 and abs(w - (1 + math.sqrt(6))) < 1e-4 for p, w in pds)
    b2 = [b for b in r.branches if b.period == 2][0]
    rr = b2.omega
    ana = ((rr + 1) + np.array([-1, 1])[:, None] * np.sqrt(np.maximum((rr - 3) * (rr + 1), 0))) / (2 * rr)
    err = np.min(np.abs(ana - b2.states[:, 0]), axis=0)
    assert np.max(err) < 1e-8
    assert any(b.period == 4 and b.omega[0] > 3.44 for b in r.branches)


# ------------------------------------------------------------------ the gear model
@pytest.mark.parametrize(
    "model, expected",
    [("constant", "pd"), ("dynamic", "stable")],
)
def test_coexisting_period1_orbits_at_0p2(model, expected):
    """Through the fold pair near omega = 0.2 the branch crosses 0.2 three times: two orbits
    an independent integrator also finds (constant: one stable, one period-doubling-unstable with
    mu = -1.11; dynamic: both stable, |mu| 0.26 and 0.39) and the saddle between them (mu > 1)."""
    r = continue_orbits(model, 0.18, 0.22, max_switches=0)
    assert r.complete, r.messages
    br = r.branches[0]
    w = br.omega
    found = []
    for i in np.nonzero((w[:-1] - 0.2) * (w[1:] - 0.2) <= 0)[0]:
        f = (0.2 - w[i]) / (w[i + 1] - w[i])
        x, mu, ok = orbit_at(0.2, model, x0=br.states[i] + f * (br.states[i + 1] - br.states[i]))
        assert ok
        found.append((br.amplitude_u[i], mu[0]))
    found.sort(key=lambda t: t[0].real)
    assert len(found) == 3
    (a_lo, m_lo), (_, m_mid), (a_hi, m_hi) = found
    assert m_mid.real > 1.2 and abs(m_mid.imag) < 1e-9  # the saddle between the folds
    assert abs(m_hi) < 1 and 1.35 < a_hi < 1.45  # the large orbit (U amplitude 1.40)
    folds = [bp.omega for bp in r.bifurcations if bp.type == "fold"]
    assert len(folds) == 2
    if expected == "pd":
        assert abs(m_lo.real + 1.11) < 0.01 and abs(m_lo.imag) < 1e-9
    else:
        assert sorted([abs(m_lo), abs(m_hi)]) == pytest.approx([0.26, 0.39], abs=0.01)


def test_period_two_branch_leaves_the_period_doubling_point():
    """Constant model: the period-2 branch switched onto at the period-doubling point near 0.307
    consists of genuine period-2 orbits, the same as shooting from a simulation finds."""
    r = continue_orbits("constant", 0.29, 0.33, max_switches=1, max_period=2)
    pd = [bp for bp in r.bifurcations if bp.type == "period-doubling" and bp.period == 1]
    assert pd and abs(pd[0].omega - 0.3083) < 0.006
    b2 = [b for b in r.branches if b.period == 2]
    assert b2 and b2[0].parent == 0
    b = b2[0]
    assert abs(b.omega[0] - pd[0].omega) < 0.01
    i = int(np.argmin(np.abs(b.omega - 0.32)))
    ref = find_periodic_orbit(float(b.omega[i]), "constant", period=2, x0=b.states[i])
    assert ref.converged and np.max(np.abs(ref.state - b.states[i])) < 1e-6
    p1 = PeriodMap(float(b.omega[i]), "constant")
    assert np.max(np.abs(p1(b.states[i]) - b.states[i])) > 0.05  # not the period-1 orbit


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_edges_agree_with_the_floquet_map(model):
    """Period-doubling and Neimark-Sacker points of the period-1 branch against the packaged
    stability map's edges (away from the fold near 0.2, where the natural-parameter map jumps)."""
    with open(f"gear_env/data/stability_{model}.json") as fh:
        smap = json.load(fh)
    edges = [(w, b if a == "stable" else a) for w, a, b in smap["bifurcations"] if w > 0.25]
    r = continue_orbits(model, 0.25, 2.6, max_switches=0)
    assert r.complete, r.messages
    found = [(bp.omega, bp.type) for bp in r.bifurcations if bp.type in ("period-doubling", "neimark-sacker")]
    assert len(found) == len(edges)
    for (w, t), (w0, t0) in zip(sorted(found), sorted(edges), strict=True):
        assert t == t0 and abs(w - w0) < 0.002  # both on the located map: bisection vs a 0.01 grid


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="omega_min"):
        continue_orbits("dynamic", -1.0, 2.0)
    with pytest.raises(ValueError, match="omega_min must be < omega_max"):
        continue_orbits("dynamic", 2.0, 1.0)
    with pytest.raises(ValueError, match="model"):
        continue_orbits("rigid", 0.5, 1.0)
    with pytest.raises(ValueError, match="tol"):
        continue_orbits("dynamic", 0.5, 1.0, tol=0.1)
    with pytest.raises(ValueError, match="max_period"):
        continue_orbits("dynamic", 0.5, 1.0, max_period=0)
    with pytest.raises(ValueError, match="ds_min"):
        continue_orbits("dynamic", 0.5, 1.0, ds=0.01, ds_min=0.1)
    with pytest.raises(ValueError, match="period"):
        orbit_at(1.0, "dynamic", period=0)
    for bad in (None, "False", 0):
        with pytest.raises(ValueError, match="located"):
            continue_orbits("dynamic", 0.5, 1.0, located=bad)
        with pytest.raises(ValueError, match="located"):
            orbit_at(1.0, "dynamic", located=bad)
        with pytest.raises(ValueError, match="located"):
            find_periodic_orbit(1.0, "dynamic", located=bad)


def test_a_stopped_continuation_keeps_its_points_and_says_where():
    r = continue_orbits("dynamic", 1.0, 2.0, max_points=5, max_switches=0)
    assert not r.complete
    b = r.branches[0]
    assert len(b.omega) == 5 and not b.complete
    assert "max_points" in b.stop_reason and r.messages
    d = r.to_json_dict()
    json.dumps(d)
    assert len(d["branches"][0]["omega"]) == len(d["branches"][0]["stable"]) == 5


def test_tangent_map_reports_kernel_status_on_divergence():
    c = K.readonly(np.ascontiguousarray(GearParams().consts))
    x = np.full(10, 1e7)
    st = TG.tangent_map(
        x, 1.0, 1, 192, c, 0, NEWTON_MAX_ITER, NEWTON_TOL, np.zeros((10, 10)), np.zeros((1, 10)),
        np.zeros(TG.N_INFO), 0,
    )  # fmt: skip
    assert st != K.OK
