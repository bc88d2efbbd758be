"""Contact changes located inside the Newmark step (``tangent_map(..., corrected=2)``,
``kernels.crossing_t``): the Jacobian is the exact derivative of the located map, the multipliers
are smooth in omega where the unlocated map's jump, the located map converges at order 2 on
impacting motion, and the crossing lies on the contact boundary."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gear_env import GearParams, GearSimulator
from gear_env.analysis import tangent as TG
from gear_env.sim import kernels as K
from gear_env.sim.params import model_code
from gear_env.sim.reference import reference_poincare

C = K.readonly(np.ascontiguousarray(GearParams().consts))


def _map(x, omega, model, mode, n=192, periods=1):
    y = np.array(x, float)
    jac = np.zeros((10, 10))
    pc = np.zeros((periods, 10))
    info = np.zeros(TG.N_INFO)
    assert TG.tangent_map(y, omega, periods, n, C, model_code(model), 12, 1e-10, jac, pc, info, mode) == K.OK
    return y, jac, pc, info


def _start(model, omega, n=192, periods=300):
    sim = GearSimulator(GearParams(), model, n, omega)
    sim.advance(periods)
    return sim.state


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_located_jacobian_is_the_derivative_of_the_located_map(model):
    """Central differences of the located map equal its tangent (including the dependence of the
    crossing on the start state) on an orbit with two contact changes per period."""
    x = _start(model, 1.64)
    _, jac, _, info = _map(x, 1.64, model, 2)
    assert info[TG.INFO_LOCATED] >= 2
    fd = np.zeros((10, 10))
    for j in range(10):
        e = np.zeros(10)
        e[j] = 1e-6 * (1 + abs(x[j]))
        fd[:, j] = (_map(x + e, 1.64, model, 2)[0] - _map(x - e, 1.64, model, 2)[0]) / (2 * e[j])
    assert np.max(np.abs(jac - fd)) < 1e-6 * np.max(np.abs(jac))
    # without the located split the exact discrete Jacobian differs at O(h) (the contact changes
    # inside steps), far more than the finite-difference error above
    _, jac0, _, _ = _map(x, 1.64, model, 0)
    assert np.max(np.abs(jac0 - jac)) > 1e-4


def test_multipliers_are_smooth_in_omega_when_contact_changes_are_located():
    """The largest |mu| of the period-1 orbit on omega 1.630-1.650 (constant model, N = 192; the
    unlocated map's exact multipliers jump by ~0.006 there): the located one has no jump above 1e-4
    (measured: 3.6e-5) and its Newton converges in <= 3 iterations (exact Jacobian)."""
    x = _start("constant", 1.63)
    saw = {}
    for mode in (0, 2):
        xs = x.copy()
        mus = []
        for w in np.linspace(1.63, 1.65, 41):
            it = 0
            for it in range(30):  # noqa: B007 (it is checked after the loop)
                y, jac, _, _ = _map(xs, w, "constant", mode)
                r = y - xs
                if np.max(np.abs(r)) < 1e-11:
                    break
                xs = xs - np.linalg.solve(jac - np.eye(10), r)
            if mode == 2:
                assert it <= 3
            mus.append(np.max(np.abs(np.linalg.eigvals(jac))))
        mu = np.array(mus)
        saw[mode] = float(np.max(np.abs(mu[1:-1] - 0.5 * (mu[:-2] + mu[2:]))))
    assert saw[2] < 1e-4
    assert saw[0] > 1e-3  # the sawtooth the location removes


def test_located_map_converges_at_second_order_with_impacts():
    """Constant model, omega 1.5 (one impact per mesh period, two contact changes): the Poincare
    error of the located map against the event-located reference falls by 4 per halving of the step
    (3.97, 3.97 measured for 64 -> 128 -> 256)."""
    x0 = _start("constant", 1.5, 512)
    ref = reference_poincare(1.5, "constant", None, 0, 4, initial_state=x0)
    assert ref.events >= 8
    errs = [float(np.max(np.abs(_map(x0, 1.5, "constant", 2, n, 4)[2] - ref.states))) for n in (64, 128, 256)]
    for e0, e1 in zip(errs, errs[1:]):
        assert 3.6 < e0 / e1 < 4.4, errs


def test_crossing_lies_on_the_contact_boundary():
    """kernels.crossing_t puts the end of the step's first part on Delta = B_d (to 1e-12 b0)."""
    x = _start("constant", 1.5)
    k = K.step_consts(C)
    a = np.zeros(5)
    work = np.zeros(K.WORK_SIZE)
    n = 192
    dphi = 2 * math.pi / n
    _F, reg, d, bd = K.start_step(x, a, 0.0, 1.5, C, 0, work)
    s = K.load_t(x, a)
    found = 0
    for j in range(n):
        ce, se, kk = K.excitation(dphi * (j + 1), C)
        ok, s1, F, reg1, d1, bd1, sp, cp = K.newmark_try_t(s, s[10:15], ce, se, kk, 1.5,
                                                           K.step_coeffs(dphi / 1.5, k), k, 0, 12, 1e-10)  # fmt: skip
        assert ok
        if reg1 != reg:
            side = K.crossing_side_t(reg, reg1)
            loc, th, sm, wm, Fm, dm, bdm, spm, cpm = K.crossing_t(
                s, s1[10:15], reg, side, d - side * bd, dphi * j, dphi, 1.5, 1.5, C, k, 0, 12, 1e-10
            )
            assert loc and 0.0 < th < 1.0
            assert abs(dm - side * bdm) < 1e-12
            found += 1
        s, reg, d, bd = s1, reg1, d1, bd1
    assert found >= 2


@pytest.mark.parametrize(("model", "omega"), [("constant", 1.5), ("dynamic", 1.0), ("dynamic", 2.6)])
def test_fast_crossing_agrees_with_the_illinois_search(model, omega):
    """kernels.crossing_fast_t (the drivers' search: cubic Hermite guess, secant refinement) finds every
    crossing of a coarse run (27 steps per period) that crossing_t finds, at the same theta to within
    LOCATE_TOL_STEP, and with the gap there correspondingly small; a step whose ends do not straddle the
    boundary is handed back (status 0) instead of guessed."""
    x = _start(model, omega)
    dyn = model_code(model)
    k = K.step_consts(C)
    a = np.zeros(5)
    work = np.zeros(K.WORK_SIZE)
    n = 27
    dphi = 2 * math.pi / n
    _F, reg, d, bd = K.start_step(x, a, 0.0, omega, C, dyn, work)
    s = K.load_t(x, a)
    found = 0
    for _p in range(3):
        for j in range(n):
            ce0, se0, _kk0 = K.excitation(dphi * j, C)
            ce, se, kk = K.excitation(dphi * (j + 1), C)
            hc = K.step_coeffs(dphi / omega, k)
            ok, s1, F, reg1, d1, bd1, sp, cp = K.newmark_try_t(s, s[10:15], ce, se, kk, omega, hc, k, dyn, 12, 1e-10)
            assert ok
            if reg1 != reg:
                side = K.crossing_side_t(reg, reg1)
                loc, th, sm, wm, Fm, dm, bdm, spm, cpm = K.crossing_t(
                    s, s1[10:15], reg, side, d - side * bd, dphi * j, dphi, omega, omega, C, k, dyn, 12, 1e-10
                )
                st, thf, smf, wmf, Fmf, dmf, bdmf, spmf, cpmf = K.crossing_fast_t(
                    s, s1, ce0, se0, ce, se, reg, side, dphi * j, dphi, omega, omega, C, k, dyn, 12, 1e-10,
                    K.LOCATE_TOL_STEP,
                )  # fmt: skip
                assert loc and st == 1
                assert abs(thf - th) <= K.LOCATE_TOL_STEP, (thf, th)
                g, rate = K.gap_rate_t(smf, *K.excitation(dphi * (j + thf), C)[:2], omega, k, dyn, side)
                assert abs(g) <= 2 * K.LOCATE_TOL_STEP * abs(rate) * dphi / omega
                # the same call with an end that does not cross: handed back
                st0 = K.crossing_fast_t(s, s, ce0, se0, ce0, se0, reg, side, dphi * j, dphi, omega, omega, C, k, dyn,
                                        12, 1e-10, K.LOCATE_TOL_STEP)[0]  # fmt: skip
                assert st0 == 0
                found += 1
            s, reg, d, bd = s1, reg1, d1, bd1
    assert found >= 4
