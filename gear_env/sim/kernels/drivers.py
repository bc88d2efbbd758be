"""Integration drivers: many Newmark steps per call, from one state (``integrate_record``,
``integrate_stats``) or a batch one system after the other (``integrate_stats_batch``).

Python code reaches them through :func:`gear_env.sim.integration.integrate`. The hot loops call no
function (every step helper is inlined); see :func:`integrate_stats_tab` for why.
"""

from __future__ import annotations

import math

import numpy as np

from ..params import CONTACTS_CORRECTED
from .jit import kernel, kernel_inline, readonly, runtime_int, runtime_true
from .layout import (
    DIVERGED,
    K_LOC,
    K_MU,
    K_VC,
    N_LOOP_ACC,
    NDOF,
    NSTATE,
    OK,
    PC_BD,
    PC_DELTA,
    PC_FORCE,
    PC_PSI,
    REC_BD,
    REC_DELTA,
    REC_FORCE,
    REC_OMEGA,
    REC_PHI,
    REC_PSI,
    REC_REGION,
    REC_S,
    RS_ACC,
    RS_BD_PREV,
    RS_D_PREV,
    RS_EL,
    RS_F_PREV,
    RS_G,
    RS_HC,
    RS_J,
    RS_REG_PREV,
    RS_S,
    RS_SIZE,
    RS_TR_PREV,
    RS_WA,
    RS_WB,
    SPLIT_PENDING,
    TWO_PI,
    WORK_SIZE,
)
from .mesh import (
    eom_residual_t,
    excitation,
    force_t,
    friction_t,
    load_table,
    mesh_direction_t,
    mesh_t,
    psi_t,
    step_consts,
    step_consts_at,
    torque_fluctuates_t,
    with_load_t,
)
from .newmark import (
    DQ_LINEAR,
    LOCATE_TOL_FIXED,
    LOCATE_TOL_STEP,
    _diverged_t,
    crossing_fast_t,
    crossing_side_t,
    crossing_t,
    guess_t,
    kink_correct_t,
    load_t,
    newmark_try_t,
    omega_step_t,
    output_t,
    split_step_t,
    step_coeffs,
    store_t,
)
from .stats import _acc_init, _acc_step, _acc_store, _stats_init, _stats_merge


@kernel
def _excitation_table(phi0, n_steps, c):
    """Excitation (cos, sin of phi + phi_e; stiffness factor) at the n_steps phases of a period."""
    tab = np.empty((n_steps, 3))
    dphi = TWO_PI / n_steps
    for k in range(n_steps):
        ce, se, kk = excitation(phi0 + dphi * k, c)
        tab[k, 0] = ce
        tab[k, 1] = se
        tab[k, 2] = kk
    return tab


@kernel
def start_step(x, a, phi0, w0, c, dynamic, work):
    """Consistent initial acceleration and mesh quantities at the start of an interval.

    Fills ``a``; returns (F, region, delta, bd) at the start; psi is left in work[0]. The
    arithmetic of :func:`~gear_env.sim.kernels.mesh.accel` (a = -r(0, q, v)) from the inline leaves,
    so that a driver's first call compiles no array-form kernel (accel, mesh_state, geometry).
    """
    k = step_consts_at(step_consts(c), phi0, c, torque_fluctuates_t(c))
    ce, se, kk = excitation(phi0, c)
    s = (x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9])
    delta, ddelta, bd, f, region, sp, cp, _db0, _db1, _dp0, _dp1 = mesh_t(s, ce, se, w0, k, dynamic)
    F = force_t(ddelta, f, kk, k)
    fr = friction_t(ce, se, k)  # [friction extension] 0 unless GearParams.friction > 0
    w = mesh_direction_t(sp, cp, fr, k, dynamic, region, _db0, _db1, _dp0, _dp1, x[0] - x[2], x[1] - x[3])
    r = eom_residual_t((0.0, 0.0, 0.0, 0.0, 0.0), s, F, w, k)  # a = -r(0, q, v)
    for i in range(NDOF):
        a[i] = -r[i]
    work[0] = psi_t(sp, cp, c, dynamic)
    return F, region, delta, bd


@kernel
def integrate_record(x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, out, max_iter, tol):
    """Integrate n_periods mesh periods, recording every step.

    ``x`` (10) and ``a`` (5) are updated in place; omega goes linearly in time from w0 to w1 over
    the whole interval. ``out`` has shape (n_periods*n_steps + 1, N_REC): row 0 is the start.
    Returns (status, rows_written, natural time elapsed).
    """
    work = np.zeros(WORK_SIZE)
    tab = _excitation_table(phi0, n_steps, c)
    k = step_consts(c)
    total = n_periods * n_steps
    dphi = TWO_PI / n_steps
    ww = (w1 * w1 - w0 * w0) / total
    tq = torque_fluctuates_t(c)  # read once: the loop's steps then take k untouched when it is False
    ld = load_table(phi0, dphi, total, c)  # a fluctuating torque's load per step (empty if constant)
    F0, region, delta, bd = start_step(x, a, phi0, w0, c, dynamic, work)
    for i in range(NSTATE):
        out[0, i] = x[i]
    out[0, REC_S] = 0.0
    out[0, REC_PHI] = phi0
    out[0, REC_OMEGA] = w0
    out[0, REC_DELTA] = delta
    out[0, REC_BD] = bd
    out[0, REC_PSI] = work[0]
    out[0, REC_FORCE] = F0
    out[0, REC_REGION] = region
    s = load_t(x, a)
    g = (a[0], a[1], a[2], a[3], a[4])
    el = 0.0
    wa = w0
    hc = step_coeffs(dphi / w0, k)
    split = 0.0
    j = 0
    while j < total:  # two loops, as in integrate_stats_tab: the inner one calls no function
        while j < total:
            wb, hc = omega_step_t(j, wa, hc, w0, ww, dphi, k)
            m = (j + 1) % n_steps
            if split == 0.0:
                kq = with_load_t(k, ld[j], tq)  # k itself unless the torque fluctuates
                ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(
                    s, g, tab[m, 0], tab[m, 1], tab[m, 2], wb, hc, kq, dynamic, max_iter, tol
                )
                if not ok:
                    break
            el += hc[0]
            g = guess_t(s, s1, dynamic == 0 or split != 0.0)
            so = output_t(s, s1, k[K_VC] * hc[0] * (1.0 - split))  # a split step's: Newmark's velocity
            s = s1
            if _diverged_t(s):
                store_t(s, x, a)
                return DIVERGED, j + 1, el
            _record_row_t(out, j + 1, so, el, phi0 + dphi * (j + 1), wb, delta, bd, sp, cp, F, region, c, dynamic)
            wa = wb
            split = 0.0
            j += 1
        if j == total:
            break
        st, s1, F, region, delta, bd, sp, cp, _split = split_step_t(
            s, phi0 + dphi * j, dphi, wa, wb, c, k, runtime_int(dynamic), max_iter, tol
        )
        if st != OK:
            store_t(s, x, a)
            return st, j + 1, el + hc[0]
        split = 1.0
    store_t(s, x, a)
    return OK, total + 1, el


@kernel_inline
def _record_row_t(out, r, s, el, phi, w, delta, bd, sp, cp, F, region, c, dynamic):
    """Row r of a recorded time series (:func:`integrate_record`)."""
    for i in range(NSTATE):
        out[r, i] = s[i]
    out[r, REC_S] = el
    out[r, REC_PHI] = phi
    out[r, REC_OMEGA] = w
    out[r, REC_DELTA] = delta
    out[r, REC_BD] = bd
    out[r, REC_PSI] = psi_t(sp, cp, c, dynamic)
    out[r, REC_FORCE] = F
    out[r, REC_REGION] = region


@kernel
def integrate_stats(x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats):
    """Integrate n_periods mesh periods and accumulate interval statistics (no time series).

    ``poincare`` (n_periods, N_PC) receives, at the end of each mesh period, the 10 states and
    Delta, B_d, psi, F. ``stats`` (N_STATS) accumulates the ``ST_*`` quantities (reset first if
    ``reset_stats``). Time integrals use the trapezoidal rule. omega goes linearly in time from
    w0 to w1 over the interval. Returns (status, periods completed, natural time elapsed).
    ``phi0`` should be a multiple of 2 pi for the samples to lie on the Poincare section.
    The loop is :func:`stats_segment`'s; Python calls :func:`integrate_stats_lazy`, the same.
    """
    return integrate_stats_tab(
        x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats,
        _excitation_table(phi0, n_steps, c),
    )  # fmt: skip


@kernel_inline
def _poincare_store_t(poincare, p, s, F, delta, bd, sp, cp, c, dynamic):
    """Row p of the Poincare samples: the 10 states, Delta, B_d, psi and F."""
    for i in range(NSTATE):
        poincare[p, i] = s[i]
    poincare[p, PC_DELTA] = delta
    poincare[p, PC_BD] = bd
    poincare[p, PC_PSI] = psi_t(sp, cp, c, dynamic)
    poincare[p, PC_FORCE] = F


@kernel
def integrate_stats_tab(
    x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab
):
    """:func:`integrate_stats` with the excitation table of the period given
    (``_excitation_table(phi0, n_steps, c)``), for callers that run many short intervals.

    The steps are taken by :func:`stats_segment`, which stops before a step whose Newton
    iteration does not converge; :func:`split_resume` takes that step in sub-steps and the
    segment goes on. :func:`integrate_stats_lazy` is the same loop in Python.
    """
    rs = np.empty(RS_SIZE)
    rs[RS_J] = -1.0
    st, done, el = stats_segment(
        x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab, rs
    )
    while st == SPLIT_PENDING:
        st, done, el = split_resume(x, a, phi0, n_steps, c, dynamic, poincare, stats, max_iter, tol, rs)
        if st == OK:
            st, done, el = stats_segment(
                x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab,
                rs,
            )  # fmt: skip
    return st, done, el


def integrate_stats_lazy(x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol,
                         reset_stats, tab=None):  # fmt: skip
    """:func:`integrate_stats` (same arguments and results, bit for bit) as a Python loop over
    :func:`stats_segment` and :func:`split_resume`: the step-splitting fallback, a second copy of
    the Newmark step (~5 s of first-call compile), is compiled only when a step first needs it.
    The entry of :func:`gear_env.sim.integration.integrate` for one system (simulator, single env).

    It runs :func:`integrate_stats_tab`'s own Python source (``py_func``), so the loop is written once:
    in Python the two kernels it calls are numba dispatchers, each compiled on its first call.

    ``tab``: the excitation table ``_excitation_table(phi0, n_steps, c)`` if the caller keeps it (computed here
    otherwise; :func:`gear_env.sim.integration.integrate` keeps one per step count and constants)."""
    if tab is None:
        tab = _excitation_table(phi0, n_steps, c)
    return integrate_stats_tab.py_func(
        x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab
    )


@kernel_inline
def _rs_tuple15(rs, o):
    """The 15 floats rs[o:o+15] as a tuple (a state tuple of ``kernels.newmark``)."""
    return (rs[o], rs[o + 1], rs[o + 2], rs[o + 3], rs[o + 4], rs[o + 5], rs[o + 6], rs[o + 7], rs[o + 8],
            rs[o + 9], rs[o + 10], rs[o + 11], rs[o + 12], rs[o + 13], rs[o + 14])  # fmt: skip


@kernel_inline
def _rs_acc(rs):
    """The accumulators (``stats._acc_init``) saved in rs."""
    o = RS_ACC
    return (rs[o], rs[o + 1], rs[o + 2], rs[o + 3], rs[o + 4], rs[o + 5], rs[o + 6], rs[o + 7], rs[o + 8],
            rs[o + 9], rs[o + 10], rs[o + 11], rs[o + 12], rs[o + 13], rs[o + 14], rs[o + 15], rs[o + 16],
            rs[o + 17], rs[o + 18], rs[o + 19], rs[o + 20])  # fmt: skip


@kernel_inline
def _rs_hc(rs):
    """The step coefficients (``newmark.step_coeffs``, 7 floats) saved in rs."""
    o = RS_HC
    return (rs[o], rs[o + 1], rs[o + 2], rs[o + 3], rs[o + 4], rs[o + 5], rs[o + 6])


@kernel_inline
def _rs_save_t(rs, j, s, g, acc, tr_prev, F_prev, reg_prev, el, wa, wb, hc, d_prev, bd_prev):
    """Write the loop's locals into rs (layout ``RS_*``)."""
    rs[RS_D_PREV] = d_prev
    rs[RS_BD_PREV] = bd_prev
    rs[RS_J] = j
    for i in range(NSTATE + NDOF):
        rs[RS_S + i] = s[i]
    for i in range(NDOF):
        rs[RS_G + i] = g[i]
    for i in range(N_LOOP_ACC):
        rs[RS_ACC + i] = acc[i]
    rs[RS_TR_PREV] = tr_prev
    rs[RS_F_PREV] = F_prev
    rs[RS_REG_PREV] = reg_prev
    rs[RS_EL] = el
    rs[RS_WA] = wa
    rs[RS_WB] = wb
    for i in range(7):
        rs[RS_HC + i] = hc[i]


@kernel
def stats_segment(
    x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab, rs
):
    """The loop of :func:`integrate_stats_tab` (same arguments, plus ``rs``), up to the first step
    that Newton does not finish.

    ``rs[RS_J] = -1`` starts the interval. At a step that needs splitting the loop's locals go to
    ``rs`` (``kernels.layout``, ``RS_*``) and SPLIT_PENDING is returned (x, a and stats not yet
    updated); :func:`split_resume` takes that step and puts them back, and a call with the same
    arguments and ``rs`` continues (a call of the fallback from here would make every caller
    compile a second copy of the Newmark step). Returns (status, periods completed, natural time
    elapsed) at the end of the interval.

    The state and the statistics live in local variables (registers) during the loop and are
    written back at the end, also when the run stops early. psi enters the statistics through
    sin psi (monotonic in psi, |psi| < pi/2), so no atan2 is evaluated per step. The hot loop
    calls no function: with a call inside it the compiler keeps the ~60 live values of a step
    ready to be saved around it (on x86-64 every floating-point register is caller-saved): 5-17 %
    slower in interleaved A/B runs, with bit-identical results.
    """
    k = step_consts(c)
    total = n_periods * n_steps
    dphi = TWO_PI / n_steps
    ww = (w1 * w1 - w0 * w0) / total
    tq = torque_fluctuates_t(c)  # read once: the loop's steps then take k untouched when it is False
    ld = load_table(phi0, dphi, total, c)  # a fluctuating torque's load per step (empty if constant)
    status = OK
    done = n_periods
    if rs[RS_J] >= 0.0:  # continue after split_resume took step j - 1
        j = np.int64(rs[RS_J])
        s = _rs_tuple15(rs, RS_S)
        g = (rs[RS_G], rs[RS_G + 1], rs[RS_G + 2], rs[RS_G + 3], rs[RS_G + 4])
        acc = _rs_acc(rs)
        tr_prev = rs[RS_TR_PREV]
        F_prev = rs[RS_F_PREV]
        reg_prev = np.int64(rs[RS_REG_PREV])
        el = rs[RS_EL]
        wa = rs[RS_WA]
        hc = _rs_hc(rs)
        d_prev = rs[RS_D_PREV]
        bd_prev = rs[RS_BD_PREV]
    else:
        work = np.zeros(WORK_SIZE)
        if reset_stats:
            _stats_init(stats)
        F_prev, reg_prev, d_prev, bd_prev = start_step(x, a, phi0, w0, c, dynamic, work)
        s = load_t(x, a)
        g = (a[0], a[1], a[2], a[3], a[4])
        tr_prev = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
        acc = _acc_init()  # local accumulators (merged into ``stats`` at the end)
        el = 0.0
        wa = w0
        hc = step_coeffs(dphi / w0, k)
        j = 0
    # a copy of the table allocated here: its row length (3) is then known to the compiler, which
    # indexes it with a constant stride (with the argument's: +1.5 % time per step, constant model)
    # (a loop: a slice assignment would compile numba's shape-mismatch error message, ~3 s)
    tf = np.empty((n_steps, 3))
    for i in range(n_steps):
        tf[i, 0] = tab[i, 0]
        tf[i, 1] = tab[i, 1]
        tf[i, 2] = tab[i, 2]
    locate = k[K_LOC] != 0.0
    # the step that the hot loop hands over to be located (its unlocated result)
    wb = wa
    m = 0
    kq = k
    s1 = s
    F = 0.0
    region = reg_prev
    delta = d_prev
    bd = bd_prev
    sp = 0.0
    cp = 1.0
    while True:
        pending = False
        while j < total:  # the hot loop: no calls
            wb, hc = omega_step_t(j, wa, hc, w0, ww, dphi, k)
            m = (j + 1) % n_steps
            kq = with_load_t(k, ld[j], tq)  # k itself unless the torque fluctuates
            ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(
                s, g, tf[m, 0], tf[m, 1], tf[m, 2], wb, hc, kq, dynamic, max_iter, tol
            )
            if not ok:
                break
            if locate and region != reg_prev:
                pending = True
                break
            h = hc[0]
            el += h
            g = guess_t(s, s1, dynamic == 0)
            s0 = s
            s = s1
            if _diverged_t(s):
                status = DIVERGED
                done = j // n_steps
                break
            acc, tr_prev = _acc_step(acc, h, s, F, region, delta, bd, sp, 0.0, F_prev, reg_prev, tr_prev)
            F_prev = F
            reg_prev = region
            d_prev = delta
            bd_prev = bd
            if m == 0:  # the velocity the forces felt (newmark.output_t; Newmark's own without the correction)
                so = output_t(s0, s, k[K_VC] * h)
                _poincare_store_t(poincare, (j + 1) // n_steps - 1, so, F, delta, bd, sp, cp, c, dynamic)
            wa = wb
            j += 1
        if not pending:
            break
        # step j changed the contact region and contact changes are located or corrected (K_LOC): take it again
        # split at the crossing, or correct its kink (out of the hot loop, which stays free of calls)
        nloc = 0
        if corrects_kink(k, reg_prev, region):
            s1, F, region, delta, bd, sp, cp = corrected_fixed_step(
                s, s1, reg_prev, tf[j % n_steps, 0], tf[j % n_steps, 1], wa, tf[m, 0], tf[m, 1], tf[m, 2], wb, hc, kq,
                dynamic,
            )  # fmt: skip
        else:
            s1, F, region, delta, bd, sp, cp, h, nloc, sa, hl = located_fixed_step(
                s, s1, F, region, delta, bd, sp, cp, reg_prev, d_prev, bd_prev, phi0 + dphi * j, dphi, wa, wb,
                tf[m, 0], tf[m, 1], tf[m, 2], c, kq, dynamic, max_iter, tol, tf[j % n_steps, 0], tf[j % n_steps, 1],
            )  # fmt: skip
        split = 1.0 if nloc > 0 else 0.0
        if nloc == 0:  # corrected, or no crossing found: the whole step
            h = hc[0]
            sa = s
            hl = h
        el += h
        g = guess_t(s, s1, dynamic == 0 or nloc > 0)
        s = s1
        if _diverged_t(s):
            status = DIVERGED
            done = j // n_steps
            break
        acc, tr_prev = _acc_step(acc, h, s, F, region, delta, bd, sp, split, F_prev, reg_prev, tr_prev)
        F_prev = F
        reg_prev = region
        d_prev = delta
        bd_prev = bd
        if m == 0:  # the corrected velocity of the step's last part
            so = output_t(sa, s, k[K_VC] * hl)
            _poincare_store_t(poincare, (j + 1) // n_steps - 1, so, F, delta, bd, sp, cp, c, dynamic)
        wa = wb
        j += 1
    if j < total and status == OK:
        # step j needs sub-steps (rare: Newton cycled between contact regions): split_resume
        _rs_save_t(rs, j, s, g, acc, tr_prev, F_prev, reg_prev, el, wa, wb, hc, d_prev, bd_prev)
        return SPLIT_PENDING, 0, el
    store_t(s, x, a)
    _acc_store(acc, stats, c, dynamic)
    return status, done, el


@kernel
def split_resume(x, a, phi0, n_steps, c, dynamic, poincare, stats, max_iter, tol, rs):
    """Take the step :func:`stats_segment` stopped at (SPLIT_PENDING) in sub-steps
    (:func:`split_step_t`) and do with its result what the segment's loop does with a step; the
    loop's locals go back into ``rs``. Returns (OK, 0, 0.0) for the segment to go on; if the step
    fails even in sub-steps, or diverges, ends the interval as the segment would (state into x
    and a, statistics into ``stats``) and returns (status, periods completed, time elapsed)."""
    j = np.int64(rs[RS_J])
    dphi = TWO_PI / n_steps
    k = step_consts(c)
    s = _rs_tuple15(rs, RS_S)
    acc = _rs_acc(rs)
    wb = rs[RS_WB]
    hc = _rs_hc(rs)
    el = rs[RS_EL]
    st, s1, F, region, delta, bd, sp, cp, _split = split_step_t(
        s, phi0 + dphi * j, dphi, rs[RS_WA], wb, c, k, dynamic, max_iter, tol
    )
    if st != OK:
        store_t(s, x, a)
        _acc_store(acc, stats, c, dynamic)
        return st, j // n_steps, el + hc[0]
    # the segment's loop body with split = 1 (Newton's next guess: the split step's acceleration)
    h = hc[0]
    el += h
    g = guess_t(s, s1, True)
    if _diverged_t(s1):
        store_t(s1, x, a)
        _acc_store(acc, stats, c, dynamic)
        return DIVERGED, j // n_steps, el
    acc, tr_prev = _acc_step(
        acc, h, s1, F, region, delta, bd, sp, 1.0, rs[RS_F_PREV], np.int64(rs[RS_REG_PREV]), rs[RS_TR_PREV]
    )
    m = (j + 1) % n_steps
    if m == 0:
        _poincare_store_t(poincare, (j + 1) // n_steps - 1, s1, F, delta, bd, sp, cp, c, dynamic)
    _rs_save_t(rs, j + 1, s1, g, acc, tr_prev, F, region, el, wb, wb, hc, delta, bd)
    return OK, 0, 0.0


def integrate_stats_batch(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter,
                          tol):  # fmt: skip
    """Advance a batch of independent systems by n_periods each (one call for a vector env).

    X (n, 10), A (n, 5), W0/W1 (n,), C (n, N_CONSTS) constants per system, dynamic (n,) model
    codes, poincare (n, n_periods, N_PC), stats (n, N_STATS), status (n,) int64 and elapsed (n,)
    outputs. Each system starts at mesh phase 0 (a Poincare section). A system whose status is
    not OK is left in an unspecified state; the caller resets it.

    A Python loop over :func:`_integrate_stats_batch` (the systems one after the other through
    :func:`stats_segment`) and :func:`split_resume` for a step that needs splitting, as
    :func:`integrate_stats_lazy` does for one system: the same numbers as calling
    :func:`integrate_stats` per system, and the fallback is compiled only when first needed. C
    is passed read-only, so that every caller shares one compiled copy (see :func:`readonly`).
    """
    C = readonly(C)
    rs = np.empty(RS_SIZE)
    rs[RS_J] = -1.0
    row = np.zeros(1, np.int64)
    args = (X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol, rs, row)
    while _integrate_stats_batch(*args) == SPLIT_PENDING:
        j = int(row[0])
        st, _done, el = split_resume(
            X[j], A[j], 0.0, n_steps, C[j], int(dynamic[j]), poincare[j], stats[j], max_iter, tol, rs
        )
        if st != OK:  # the system's interval ended in the split step
            status[j] = st
            elapsed[j] = el
            rs[RS_J] = -1.0
            row[0] = j + 1


@kernel
def _integrate_stats_batch(
    X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol, rs, row
):
    """The loop of :func:`integrate_stats_batch` from system row[0] on (``rs`` as
    :func:`stats_segment` left it, or rs[RS_J] = -1 for a new interval). Returns OK at the end, or
    SPLIT_PENDING with row[0] = the system whose step needs splitting."""
    n = X.shape[0]
    reset = runtime_true()  # not the literal True: see runtime_true
    for j in range(row[0], n):
        st, done, s = stats_segment(
            X[j], A[j], 0.0, W0[j], W1[j], n_periods, n_steps, C[j], dynamic[j], poincare[j], stats[j], max_iter, tol,
            reset, _excitation_table(0.0, n_steps, C[j]), rs,
        )  # fmt: skip
        if st == SPLIT_PENDING:
            row[0] = j
            return SPLIT_PENDING
        status[j] = st
        elapsed[j] = s
        rs[RS_J] = -1.0
    return OK


# ---- contact changes located, and the error-controlled driver (issue 24) ------------------------
MAX_CROSSINGS = 4
"""Contact changes located per step at most (:func:`located_step_t`); more stay inside the step."""


@kernel_inline
def located_step_t(s, s1, F, region, delta, bd, sp, cp, reg0, d0, bd0, phi_a, dphi, w_a, w_b, ce, se, kk, c, k,
                   dynamic, max_iter, tol, ce_a, se_a, dq_lin, theta_tol):  # fmt: skip
    """A Newmark step from s (contact region ``reg0``, Delta ``d0``, B_d ``bd0`` there) whose
    unlocated result (s1, F, region, delta, bd, sp, cp) ends in another region, taken again split at
    its contact changes (``newmark.crossing_fast_t``, falling back to ``newmark.crossing_t``; up to
    :data:`MAX_CROSSINGS`): each part before a crossing with the force on its branch, the rest from the
    crossing. ``ce, se, kk``: the excitation at the end of the step, ``ce_a, se_a`` at its start;
    ``dq_lin`` as in ``newmark.newton_iter_t``; ``theta_tol``: the crossing tolerance (``newmark.LOCATE_TOL_STEP``,
    or ``LOCATE_TOL_FIXED`` for the fixed-step drivers). Returns
    (state, F, region, Delta, B_d, sin psi, cos psi, natural time of the step, crossings located, the state
    at the start of the step's last part, that part's natural time: what ``newmark.output_t`` takes); the
    unlocated result if no crossing is found."""
    h_sum = 0.0
    n = 0
    sa = s
    ra = reg0
    ga = d0
    gb = bd0
    pa = phi_a
    dp = dphi
    wa = w_a
    cea = ce_a
    sea = se_a
    while region != ra and n < MAX_CROSSINGS:
        side = crossing_side_t(ra, region)
        a1 = (s1[10], s1[11], s1[12], s1[13], s1[14])
        if n > 0:
            cea, sea, _kka = excitation(pa, c)
        fast, th, sm, wm, _Fm, dm, bdm, _spm, _cpm = crossing_fast_t(
            sa, s1, cea, sea, ce, se, ra, side, pa, dp, wa, w_b, c, k, dynamic, max_iter, tol, theta_tol
        )
        if fast == 0:
            located, th, sm, wm, _Fm, dm, bdm, _spm, _cpm = crossing_t(
                sa, a1, ra, side, ga - side * gb, pa, dp, wa, w_b, c, k, dynamic, max_iter, tol, theta_tol
            )
            if not located:
                break
        hc2 = step_coeffs(2.0 * (1.0 - th) * dp / (wm + w_b), k)
        ok2, s2, F2, region2, delta2, bd2, sp2, cp2 = newmark_try_t(sm, a1, ce, se, kk, w_b, hc2, k, dynamic,
                                                                    max_iter, tol, dq_lin)  # fmt: skip
        if not ok2:
            break
        h_sum += 2.0 * th * dp / (wa + wm)
        n += 1
        ra = side if ra == 0 else 0  # the region entered at the crossing
        sa, ga, gb, pa, dp, wa = sm, dm, bdm, pa + th * dp, (1.0 - th) * dp, wm
        s1, F, region, delta, bd, sp, cp = s2, F2, region2, delta2, bd2, sp2, cp2
    h_last = 2.0 * dp / (wa + w_b)
    return s1, F, region, delta, bd, sp, cp, h_sum + h_last, n, sa, h_last


@kernel
def located_fixed_step(s, s1, F, region, delta, bd, sp, cp, reg0, d0, bd0, phi_a, dphi, w_a, w_b, ce, se, kk, c, k,
                       dynamic, max_iter, tol, ce_a, se_a):  # fmt: skip
    """:func:`located_step_t` of the fixed-step drivers that locate contact changes (``K_LOC``: :func:`stats_segment`
    and the SIMD lanes' ``batch_kernels._locate_lane``), at ``DQ_LINEAR`` and the crossing tolerance
    ``LOCATE_TOL_FIXED``. Not inlined: one compiled copy for both (so they agree bit for bit), and the one-system
    loop keeps its registers (it calls this only after its hot loop). Units as there: states in b0 and b0 per unit
    of natural time, times (returned: the step's and its last part's) in natural time (omega_n t), phases in rad."""
    return located_step_t(s, s1, F, region, delta, bd, sp, cp, reg0, d0, bd0, phi_a, dphi, w_a, w_b, ce, se, kk, c, k,
                          dynamic, max_iter, tol, ce_a, se_a, DQ_LINEAR, LOCATE_TOL_FIXED)  # fmt: skip


@kernel_inline
def corrects_kink(k, reg0, region):
    """Whether the fixed-step drivers correct the kink of a step from contact region ``reg0`` into ``region``
    (:func:`corrected_fixed_step`) rather than locate it (:func:`located_fixed_step`): with ``K_LOC`` =
    ``params.CONTACTS_CORRECTED``, across one contact edge (a step from one flank to the other is located), without the
    friction extension (whose tilted force the correction does not model)."""
    return k[K_LOC] == CONTACTS_CORRECTED and (reg0 == 0 or region == 0) and k[K_MU] == 0.0


@kernel
def corrected_fixed_step(s, s1, reg0, ce0, se0, w_a, ce, se, kk, w_b, hc, k, dynamic):
    """``newmark.kink_correct_t`` for the one-system loop (:func:`stats_segment`). Not inlined, as
    :func:`located_fixed_step`, so that the loop keeps its registers; the SIMD lanes (``batch_kernels._correct_lane``)
    inline ``kink_correct_t`` itself, with the same arithmetic (bit for bit, tested). Units as there (b0, natural
    time)."""
    return kink_correct_t(s, s1, reg0, ce0, se0, w_a, ce, se, kk, w_b, hc, k, dynamic)


@kernel
def integrate_located(x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats,
                      theta_tol=LOCATE_TOL_STEP):  # fmt: skip
    """:func:`integrate_located_tab` with the excitation table of the period computed here."""
    return integrate_located_tab(
        x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats,
        _excitation_table(phi0, n_steps, c), DQ_LINEAR, theta_tol,
    )  # fmt: skip


@kernel
def integrate_located_tab(
    x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats, tab, dq_lin,
    theta_tol=LOCATE_TOL_STEP,
):  # fmt: skip
    """:func:`integrate_stats` (same arguments and results) with every contact change located and
    the step split there (:func:`located_step_t`), so that no contact change lies inside a step: the
    Poincare map is then smooth in the state and omega, and its error has the expansion in h^2,
    h^4, ... of a smooth problem (what :func:`integrate_tol` extrapolates). ``stats[ST_SPLITS]``
    counts the steps split at a contact change (and any split by the Newton fallback). ``dq_lin``: as in
    ``newmark.newton_iter_t`` (:data:`newmark.DQ_LINEAR` for the exact Newmark solution); ``theta_tol``: the
    crossing tolerance (:data:`newmark.LOCATE_TOL_STEP`; the fixed-step drivers' flag ``K_LOC`` uses
    ``LOCATE_TOL_FIXED``)."""
    k = step_consts(c)
    total = n_periods * n_steps
    dphi = TWO_PI / n_steps
    ww = (w1 * w1 - w0 * w0) / total
    work = np.zeros(WORK_SIZE)
    if reset_stats:
        _stats_init(stats)
    F_prev, reg_prev, d_prev, bd_prev = start_step(x, a, phi0, w0, c, dynamic, work)
    s = load_t(x, a)
    g = (a[0], a[1], a[2], a[3], a[4])
    tr_prev = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    acc = _acc_init()
    el = 0.0
    wa = w0
    hc = step_coeffs(dphi / w0, k)
    for j in range(total):
        wb, hc = omega_step_t(j, wa, hc, w0, ww, dphi, k)
        m = (j + 1) % n_steps
        ce, se, kk = tab[m, 0], tab[m, 1], tab[m, 2]
        ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(s, g, ce, se, kk, wb, hc, k, dynamic, max_iter, tol,
                                                             dq_lin)  # fmt: skip
        split = 0.0
        if not ok:
            st, s1, F, region, delta, bd, sp, cp, _sp = split_step_t(s, phi0 + dphi * j, dphi, wa, wb, c, k, dynamic,
                                                                    max_iter, tol)  # fmt: skip
            if st != OK:
                store_t(s, x, a)
                _acc_store(acc, stats, c, dynamic)
                return st, j // n_steps, el
            split = 1.0
        h = hc[0]
        sa = s  # the start of the step's last part and its time, for the corrected velocity (output_t)
        hl = 0.0 if split != 0.0 else h  # a split step's samples: Newmark's velocity
        if region != reg_prev:
            s1, F, region, delta, bd, sp, cp, h_loc, nloc, sa_loc, hl_loc = located_step_t(
                s, s1, F, region, delta, bd, sp, cp, reg_prev, d_prev, bd_prev, phi0 + dphi * j, dphi, wa, wb, ce,
                se, kk, c, k, dynamic, max_iter, tol, tab[j % n_steps, 0], tab[j % n_steps, 1], dq_lin, theta_tol,
            )  # fmt: skip
            if nloc > 0:
                split = 1.0
                h, sa, hl = h_loc, sa_loc, hl_loc
        el += h
        g = guess_t(s, s1, dynamic == 0 or split != 0.0)
        s = s1
        if _diverged_t(s):
            store_t(s, x, a)
            _acc_store(acc, stats, c, dynamic)
            return DIVERGED, j // n_steps, el
        acc, tr_prev = _acc_step(acc, h, s, F, region, delta, bd, sp, split, F_prev, reg_prev, tr_prev)
        F_prev = F
        reg_prev = region
        d_prev = delta
        bd_prev = bd
        if m == 0:
            so = output_t(sa, s, k[K_VC] * hl)
            _poincare_store_t(poincare, (j + 1) // n_steps - 1, so, F, delta, bd, sp, cp, c, dynamic)
        wa = wb
    store_t(s, x, a)
    _acc_store(acc, stats, c, dynamic)
    return OK, n_periods, el


TOL_N_MIN = 8
"""Fewest steps per mesh period of the coarse run of :func:`integrate_tol`."""
TOL_N_MAX = 8192
"""Most steps per mesh period of the coarse run of :func:`integrate_tol`."""
TOL_SAFETY = 0.5
""":func:`integrate_tol` aims the next period's estimate at TOL_SAFETY * err_tol."""
TOL_DQ_SCALE = 1.0
"""Default ``dq_scale`` of :func:`integrate_tol` (0: the Newton iteration of the fixed-step drivers)."""


@kernel_inline
def tol_dq_linear(err_tol, n, scale):
    """``dq_lin`` (b0) of a run of :func:`integrate_tol` with N steps per mesh period at error ``err_tol``:
    ``scale`` sqrt(err_tol / N), at least :data:`newmark.DQ_LINEAR`.

    Why it is safe: the dynamic model's Newton iteration ends with a first-order Taylor update of the
    geometry (``newmark.newton_iter_t``), whose neglected term is about 1e-3 dq^2 per step (curvature of
    B_d(q) ~ 1e-3 per b0); at dq = sqrt(err_tol / N) that is 1e-3 err_tol / N per step, 1e-3 err_tol per
    period at most. Measured (N = 27, err_tol = 3e-3, dynamic omega 0.3-2.6): the period's result moves by
    <= 5e-9 b0 against a discretisation error of 2e-3 to 8e-3, and the coarse run takes 1.2-1.4x less time
    (at large steps the first update moves the positions by more than DQ_LINEAR, so the strict rule
    evaluates the geometry a second time)."""
    return max(DQ_LINEAR, scale * math.sqrt(err_tol / n))


@kernel
def integrate_tol(x, a, w0, w1, n_periods, n_start, c, dynamic, poincare, stats, max_iter, tol, err_tol, cost,
                  dq_scale):  # fmt: skip
    """Integrate ``n_periods`` mesh periods from mesh phase 0 (omega linear in time from w0 to w1
    over the interval) with the error per mesh period controlled: ``err_tol`` (b0 units; the 10
    states, velocities per unit natural time).

    Every mesh period is integrated twice with contact changes located (:func:`integrate_located`),
    with N and 2N steps. Their difference estimates the error of the 2N result,
    err = max|x_2N - x_N| / 3 (the located map's error is c h^2 + O(h^4)); a period with
    err > err_tol is repeated with more steps. The period's result is the Richardson value
    (4 x_2N - x_N) / 3, whose error is O(h^4) and in practice far below err (local
    extrapolation). The next period starts with N scaled by sqrt(TOL_SAFETY err_tol / err).
    Poincare samples are the extrapolated states at phase 2 pi k (the other columns from the 2N
    run); ``stats`` those of the 2N runs. ``cost`` (n_periods,) receives the Newmark steps of each
    period (both runs and repeats). ``dq_scale``: the Newton iteration's final-update rule of the runs
    (:func:`tol_dq_linear`; :data:`TOL_DQ_SCALE` by default, 0 for the strict rule of the fixed-step
    drivers). Returns (status, periods done, natural time elapsed, N last).
    """
    n = max(TOL_N_MIN, n_start)
    _stats_init(stats)
    dw2 = w1 * w1 - w0 * w0
    x1 = np.empty(NSTATE)
    x2 = np.empty(NSTATE)
    a1 = np.empty(NDOF)
    a2 = np.empty(NDOF)
    pc1 = np.empty((1, poincare.shape[1]))
    pc2 = np.empty((1, poincare.shape[1]))
    st1 = np.empty(stats.shape[0])
    st2 = np.empty(stats.shape[0])
    el = 0.0
    n_tab = n  # the excitation tables of the two runs, recomputed when N changes (rarely)
    tab1 = _excitation_table(0.0, n, c)
    tab2 = _excitation_table(0.0, 2 * n, c)
    for p in range(n_periods):
        wa = math.sqrt(w0 * w0 + dw2 * p / n_periods)
        wb = math.sqrt(w0 * w0 + dw2 * (p + 1.0) / n_periods)
        spent = 0.0
        while True:
            for i in range(NSTATE):
                x1[i] = x[i]
                x2[i] = x[i]
            if n != n_tab:
                tab1 = _excitation_table(0.0, n, c)
                tab2 = _excitation_table(0.0, 2 * n, c)
                n_tab = n
            st, _d, _e = integrate_located_tab(
                x1,
                a1,
                0.0,
                wa,
                wb,
                1,
                n,
                c,
                dynamic,
                pc1,
                st1,
                max_iter,
                tol,
                True,
                tab1,
                tol_dq_linear(err_tol, n, dq_scale),
            )
            if st != OK:
                return st, p, el, n
            st, _d, el2 = integrate_located_tab(
                x2,
                a2,
                0.0,
                wa,
                wb,
                1,
                2 * n,
                c,
                dynamic,
                pc2,
                st2,
                max_iter,
                tol,
                True,
                tab2,
                tol_dq_linear(err_tol, 2 * n, dq_scale),
            )
            if st != OK:
                return st, p, el, n
            spent += 3.0 * n
            err = 0.0
            for i in range(NSTATE):
                err = max(err, abs(x2[i] - x1[i]))
            err /= 3.0
            if err <= err_tol or n >= TOL_N_MAX:
                break
            n = min(TOL_N_MAX, max(2 * n, int(math.ceil(n * math.sqrt(err / (TOL_SAFETY * err_tol))))))
        for i in range(NSTATE):
            x[i] = (4.0 * x2[i] - x1[i]) / 3.0
            poincare[p, i] = x[i]
        for i in range(NSTATE, poincare.shape[1]):
            poincare[p, i] = pc2[0, i]
        for i in range(NDOF):
            a[i] = a2[i]
        _stats_merge(stats, st2)
        el += el2
        cost[p] = spent
        grow = math.sqrt(max(err, 1e-300) / (TOL_SAFETY * err_tol))
        n = int(math.ceil(n * min(2.0, max(0.5, grow))))
        n = min(TOL_N_MAX, max(TOL_N_MIN, n))
    return OK, n_periods, el, n
