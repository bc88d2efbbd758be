"""The Newmark-beta step and its Newton iteration (one step, and the split-step fallback).

Time stepping
-------------
Newmark-beta, average acceleration (gamma = 1/2, beta = 1/4), with the step uniform in *mesh
phase*: a mesh period is always ``n`` steps of ``dphi = 2 pi / n``. Inside a control interval
omega varies linearly in time from ``w0`` to ``w1``; then omega^2 is linear in phase, so omega is
known exactly at every step boundary and the step length is ``h = 2 dphi / (w_a + w_b)``.
Poincare samples (phase = 2 pi k) fall exactly on step boundaries, also while omega ramps.

Each step solves the nonlinear equilibrium at the end of the step for the new acceleration with
Newton's method. The Newton matrix is diagonal (mass, damping, bearing stiffness) plus one rank-one
term (the mesh force acts along g and is felt along w = M^-1 g), so it is solved in O(n) with the
Sherman-Morrison formula. The Jacobian is the exact one for the active contact region (semismooth
Newton on the piecewise-linear backlash); only the tiny dependence of the force direction on psi
is frozen within a step.

Contact changes inside a step
-----------------------------
The dead-zone force f(Delta) is continuous (and so is the viscous mesh term, A6), so the
acceleration stays continuous and only its derivative jumps at a contact change. A step that
contains one therefore keeps an O(h^3) local error, and the global error stays O(h^2) with a
fixed step (shown by the convergence tests on impacting motion). The contact change is not
located; the semismooth Newton iteration finds the end-of-step region. If Newton does not converge
(it can cycle between two regions when the end of the step sits on a kink) the step is split in
halves, recursively up to 2^6 sub-steps, before a failure is reported.
"""

from __future__ import annotations

import math

from .jit import kernel, kernel_inline, runtime_int
from .layout import DIVERGENCE_LIMIT, GAMMA, K_BETA, K_VC, NDOF, NEWTON_FAILED, NSTATE, OK
from .mesh import (
    backlash,
    backlash_branch,
    bearing_t,
    deflection_gradient_t,
    deflection_t,
    eom_residual_t,
    excitation,
    force_gradient_t,
    force_t,
    friction_t,
    geometry_taylor_t,
    mesh_direction_t,
    mesh_t,
    psi_t,
    step_consts,
    step_consts_at,
    torque_fluctuates_t,
)


@kernel_inline
def step_coeffs(h, k):
    """Newmark coefficients of a step of length h (natural time): (h, beta h^2, gamma_f h,
    (1/2 - beta) h^2, (1 - gamma_f) h, inverse diagonal of the Newton matrix for the pinion and the
    gear bearings). Loop-invariant while omega is constant. beta is ``k[K_BETA]``
    (``GearParams.newmark_beta``), gamma = 1/2.

    gamma_f = 1/2 - w, w = ``k[K_VC]`` (0 unless ``GearParams.velocity_correction``): the velocity the
    forces feel, v_f = v_n + h ((1 - gamma_f) a_n + gamma_f a_{n+1}) = v_{n+1} - w h (a_{n+1} - a_n), is
    what the predictor and corrector below produce (:func:`newton_start_t`, :func:`corrector_t`); the
    state keeps Newmark's v_{n+1} = v_f + w h (a_{n+1} - a_n) (:func:`state_t`). With w = 0 every
    coefficient is the plain scheme's, bit for bit."""
    beta = k[K_BETA]
    bh2 = beta * h * h
    gf = GAMMA - k[K_VC]
    gh = gf * h
    c_p, c_g, k_p, k_g = bearing_t(k)  # dr/da = I + gh dr/dv + bh2 dr/dq: its diagonal
    d0 = 1.0 + gh * c_p + bh2 * k_p
    d2 = 1.0 + gh * c_g + bh2 * k_g
    q = 1.0 / (d0 * d2)  # one division for both inverses (recomputed every step of a ramp)
    return h, bh2, gh, h * h * (0.5 - beta), h * (1.0 - gf), q * d2, q * d0


@kernel_inline
def state_t(t, a0, a1, a2, a3, a4, s, wh):
    """The new state tuple (q, v, a) of a step from the corrected (q, v_f) ``t``, the new acceleration
    (a0..a4) and the step's start state ``s``: v = v_f + wh (a - a_old), wh = ``k[K_VC]`` h (0: v_f).

    The scalar paths' version: without the velocity correction (wh = 0) it returns v_f with no arithmetic. The
    one-system loop is bound by instruction throughput, and the ten operations of :func:`state_vc_t` cost it 3 % of
    its time at wh = 0 (interleaved timing of captured GearSpeedDemand-v0 calls); the result is the same but for
    the sign of a zero velocity."""
    if wh == 0.0:
        return (t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], a0, a1, a2, a3, a4)
    return state_vc_t(t, a0, a1, a2, a3, a4, s, wh)


@kernel_inline
def state_vc_t(t, a0, a1, a2, a3, a4, s, wh):
    """:func:`state_t` without a branch, for the SIMD lanes (``batch_kernels``), whose loop over lanes a branch
    could keep from vectorising."""
    return (
        t[0], t[1], t[2], t[3], t[4],
        t[5] + wh * (a0 - s[10]),
        t[6] + wh * (a1 - s[11]),
        t[7] + wh * (a2 - s[12]),
        t[8] + wh * (a3 - s[13]),
        t[9] + wh * (a4 - s[14]),
        a0, a1, a2, a3, a4,
    )  # fmt: skip


@kernel_inline
def output_t(s0, s1, wh):
    """The state tuple s1 of a step from s0 with the velocity the forces felt (:func:`step_coeffs`):
    v - wh (a - a_old), wh = ``k[K_VC]`` h: what Poincare samples and records hold (s1 itself when wh = 0)."""
    return (
        s1[0], s1[1], s1[2], s1[3], s1[4],
        s1[5] - wh * (s1[10] - s0[10]),
        s1[6] - wh * (s1[11] - s0[11]),
        s1[7] - wh * (s1[12] - s0[12]),
        s1[8] - wh * (s1[13] - s0[13]),
        s1[9] - wh * (s1[14] - s0[14]),
        s1[10], s1[11], s1[12], s1[13], s1[14],
    )  # fmt: skip


@kernel_inline
def corrector_t(p, a0, a1, a2, a3, a4, bh2, gh):
    """Newmark corrector: (q, v) = predictors p = (q~, v~) + (beta h^2, gamma h) x acceleration."""
    return (
        p[0] + bh2 * a0,
        p[1] + bh2 * a1,
        p[2] + bh2 * a2,
        p[3] + bh2 * a3,
        p[4] + bh2 * a4,
        p[5] + gh * a0,
        p[6] + gh * a1,
        p[7] + gh * a2,
        p[8] + gh * a3,
        p[9] + gh * a4,
    )


@kernel_inline
def rank_one_solve_t(r0, r1, r2, r3, r4, w0, w1, w2, w3, u0, u1, u2, u3, u4, idd0, idd2):
    """Newton update d of a step: (D + w u^T) d = -r by the Sherman-Morrison formula, with
    D = diag(dd0, dd0, dd2, dd2, 1) given by its inverses idd0, idd2 (``step_coeffs``) and w_4 = 1."""
    y0 = -r0 * idd0
    y1 = -r1 * idd0
    y2 = -r2 * idd2
    y3 = -r3 * idd2
    y4 = -r4
    z0 = w0 * idd0
    z1 = w1 * idd0
    z2 = w2 * idd2
    z3 = w3 * idd2
    fac = (u0 * y0 + u1 * y1 + u2 * y2 + u3 * y3 + u4 * y4) / (1.0 + u0 * z0 + u1 * z1 + u2 * z2 + u3 * z3 + u4)
    return y0 - fac * z0, y1 - fac * z1, y2 - fac * z2, y3 - fac * z3, y4 - fac


@kernel_inline
def newton_delta_t(a, t, mesh, ce, se, kk, hc, k, dynamic, friction=True):
    """The Newton update of a step's end-of-step acceleration: the residual r of the equations of
    motion at the corrected state t (acceleration iterate a, ``mesh`` = :func:`mesh_t` at t, whose
    backlash value f and region are used as given) and d = -(dr/da)^-1 r. Returns (d_0..d_4, F)."""
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    F = force_t(ddelta, f, kk, k)
    fr = friction_t(ce, se, k) if friction else 0.0  # [friction extension] tilts the force off the LOA
    w = mesh_direction_t(sp, cp, fr, k, dynamic, region, db0, db1, dp0, dp1, t[0] - t[2], t[1] - t[3])
    w0, w1, w2, w3 = w
    # the residual of the equations of motion at the corrected state t (kernels.mesh)
    r0, r1, r2, r3, r4 = eom_residual_t(a, t, F, w, k)
    # Jacobian dr/da = D + w u^T: D = I + gh C + bh2 K (step_coeffs), and u = dF/da = gh dF/dv +
    # bh2 dF/dq, with dF/dv = dF/dDelta' g and dF/dq = dF/dDelta g + dF/dB_d dB_d/dq (g = dDelta/dq,
    # force direction and psi frozen within the step; dB_d/dU = 0)
    dF_ddd, dF_dd, dF_dbd = force_gradient_t(delta, bd, region, kk, k)
    g0, g1, g2, g3, g4 = deflection_gradient_t(sp, cp)
    cg = gh * dF_ddd + bh2 * dF_dd
    cb = bh2 * dF_dbd
    u0 = cg * g0 + cb * db0
    u1 = cg * g1 + cb * db1
    u2 = cg * g2 - cb * db0
    u3 = cg * g3 - cb * db1
    u4 = cg * g4
    return rank_one_solve_t(r0, r1, r2, r3, r4, w0, w1, w2, w3, u0, u1, u2, u3, u4, idd0, idd2) + (F,)


DQ_LINEAR = 1e-4
"""Dynamic model: a Newton update that moves the positions by less than this (b0) is final (the
default of :func:`newton_iter_t`'s ``dq_lin``; the fixed-step drivers use it)."""

NEWTON_MORE = 0  # newton_iter_t: iterate again
NEWTON_DONE = 1  # newton_iter_t: converged, (t, a) is the new state
NEWTON_BAD = 2  # newton_iter_t: non-finite update


@kernel_inline
def predictors_t(s, hc):
    """Newmark's predictors pv = (q~, v~) of a step from the state tuple s = (q, v, a) (``hc``: :func:`step_coeffs`)."""
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    qp0 = s[0] + h * s[5] + hh * s[10]
    qp1 = s[1] + h * s[6] + hh * s[11]
    qp2 = s[2] + h * s[7] + hh * s[12]
    qp3 = s[3] + h * s[8] + hh * s[13]
    qp4 = s[4] + h * s[9] + hh * s[14]
    vp0 = s[5] + h1 * s[10]
    vp1 = s[6] + h1 * s[11]
    vp2 = s[7] + h1 * s[12]
    vp3 = s[8] + h1 * s[13]
    vp4 = s[9] + h1 * s[14]
    return (qp0, qp1, qp2, qp3, qp4, vp0, vp1, vp2, vp3, vp4)


@kernel_inline
def newton_start_t(s, g, ce, se, w_b, hc, k, dynamic):
    """Predictors and the first corrector of a Newmark step from the state tuple s = (q, v, a)
    with the guess g of the end-of-step acceleration. Returns (predictors pv = (q~, v~), corrected
    (q, v) t at g, :func:`mesh_t` at t)."""
    pv = predictors_t(s, hc)
    t = corrector_t(pv, g[0], g[1], g[2], g[3], g[4], hc[1], hc[2])
    return pv, t, mesh_t(t, ce, se, w_b, k, dynamic)


@kernel_inline
def newton_iter_t(
    pv, a, t, mesh, ce, se, kk, w_b, hc, k, dynamic, tol, taylor_only=False, friction=True, dq_lin=DQ_LINEAR
):
    """One semismooth Newton iteration of a Newmark step (no loop inside, so a batch of them
    vectorises across systems, see ``batch_kernels``).

    ``a`` is the current iterate of the end-of-step acceleration, ``t`` = corrector at a and
    ``mesh`` = :func:`mesh_t` at t. Returns (code, a, t, mesh, fin, dmax) with code NEWTON_MORE,
    NEWTON_DONE (then (t, a) is the new state and fin = (F, region, Delta, B_d, sin psi,
    cos psi) at its end) or NEWTON_BAD (non-finite update), and dmax the largest |update| of a (the batch kernel
    keeps it to resume the iteration, :func:`newmark_resume_t`). With ``taylor_only`` (dynamic model)
    an iteration that the Taylor update does not finish returns NEWTON_MORE without evaluating
    the geometry again (the batch kernel redoes such steps with the scalar path). With
    ``friction=False`` the friction extension is ignored (no tanh call; the batch kernel redoes
    the steps of systems with friction). ``dq_lin`` (b0): a dynamic-model update that moves the
    positions by less than this is final (:data:`DQ_LINEAR`; the error-controlled driver passes a
    larger one at coarse steps, ``drivers.tol_dq_linear``).
    """
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    a0, a1, a2, a3, a4 = a
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    e0, e1, e2, e3, e4, F = newton_delta_t(a, t, mesh, ce, se, kk, hc, k, dynamic, friction)
    a0 += e0
    a1 += e1
    a2 += e2
    a3 += e3
    a4 += e4
    an = (a0, a1, a2, a3, a4)
    dmax = max(abs(e0), abs(e1), abs(e2), abs(e3), abs(e4))
    if not math.isfinite(dmax):
        return NEWTON_BAD, an, t, mesh, (F, region, delta, bd, sp, cp), dmax
    t = corrector_t(pv, a0, a1, a2, a3, a4, bh2, gh)
    if dynamic != 0 and bh2 * dmax <= dq_lin:
        # Final update of the dynamic model: the geometry at the new positions is the
        # first-order Taylor expansion of eqs. (5)-(8) about the previous iterate (the
        # remainder, curvature of B_d(q) ~1e-3 per b0 times |dq|^2 <= 1e-8, is below 1e-11),
        # which saves the square roots and divisions of a second geometry evaluation.
        bd1, sp1, cp1 = geometry_taylor_t(bd, sp, cp, db0, db1, dp0, dp1, e0 - e2, e1 - e3, bh2)
        delta1, ddelta1 = deflection_t(t, sp1, cp1, dp0, dp1, ce, se, w_b, k, dynamic)
        f1, region1 = backlash(delta1, bd1)
        if region1 == region:
            return NEWTON_DONE, an, t, mesh, (force_t(ddelta1, f1, kk, k), region1, delta1, bd1, sp1, cp1), dmax
    if dynamic != 0 and taylor_only:
        return NEWTON_MORE, an, t, mesh, (F, region, delta, bd, sp, cp), dmax
    old_region = region
    mesh = mesh_t(t, ce, se, w_b, k, dynamic)
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    F = force_t(ddelta, f, kk, k)
    # The backlash force is piecewise linear: for the constant model the update is exact
    # once the region it assumed is the region it lands in. The dynamic model's geometry is
    # mildly nonlinear: its update is accepted when small (tol) or when the position change
    # of the last Newton update, bh2 * dmax, is below DQ_LINEAR, where the neglected
    # quadratic term (curvature of B_d(q) ~ 1e-3 per b0 times DQ_LINEAR^2) is below 1e-11.
    if region == old_region and (
        dynamic == 0 or bh2 * dmax <= dq_lin or dmax <= tol * (1.0 + max(abs(a0), abs(a1), abs(a2), abs(a3), abs(a4)))
    ):
        return NEWTON_DONE, an, t, mesh, (F, region, delta, bd, sp, cp), dmax
    return NEWTON_MORE, an, t, mesh, (F, region, delta, bd, sp, cp), dmax


@kernel_inline
def newmark_try_t(s, g, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol, dq_lin=DQ_LINEAR):
    """Attempt one Newmark step on the state tuple s = (q (5), v (5), a (5)).

    ``hc`` = :func:`step_coeffs` of the step, ``(ce, se, kk)`` the excitation, ``w_b`` the
    meshing frequency at its end and ``g`` Newton's starting guess of the end-of-step
    acceleration; ``dq_lin`` as in :func:`newton_iter_t`. Returns (converged, new state tuple, F,
    region, Delta, B_d, sin psi, cos psi); on failure the state tuple returned is the input one.
    """
    pv, t, mesh = newton_start_t(s, g, ce, se, w_b, hc, k, dynamic)
    a = (g[0], g[1], g[2], g[3], g[4])
    fin = (0.0, 0, 0.0, 0.0, 0.0, 0.0)
    for _it in range(max_iter):
        code, a, t, mesh, fin, _dm = newton_iter_t(pv, a, t, mesh, ce, se, kk, w_b, hc, k, dynamic, tol, False, True,
                                                   dq_lin)  # fmt: skip
        if code == NEWTON_DONE:
            s1 = state_t(t, a[0], a[1], a[2], a[3], a[4], s, k[K_VC] * hc[0])
            return True, s1, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]
        if code == NEWTON_BAD:
            break
    return False, s, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]


@kernel_inline
def newmark_resume_t(s, a, dmax, old_region, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol):
    """:func:`newmark_try_t` from its first Newton iterate on: the SIMD lanes (``batch_kernels``) took the first
    iteration (:func:`newton_iter_t` with ``taylor_only``, no friction) and it returned NEWTON_MORE with the iterate
    ``a``, its largest update ``dmax`` and (dynamic model) the region ``old_region`` of the mesh it started from. The
    corrector at ``a`` is rebuilt from s's predictors and the first iteration's remaining checks are made as
    :func:`newton_iter_t` makes them without ``taylor_only``, so the result is :func:`newmark_try_t`'s bit for bit
    (friction off) at one Newton iteration and one mesh evaluation less. Returns as :func:`newmark_try_t`."""
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    pv = predictors_t(s, hc)
    a0, a1, a2, a3, a4 = a
    t = corrector_t(pv, a0, a1, a2, a3, a4, bh2, gh)
    mesh = mesh_t(t, ce, se, w_b, k, dynamic)
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    F = force_t(ddelta, f, kk, k)
    fin = (F, region, delta, bd, sp, cp)
    # the end of newton_iter_t's first iteration (the constant model's returned NEWTON_MORE only on a region change)
    if (
        dynamic != 0
        and region == old_region
        and (bh2 * dmax <= DQ_LINEAR or dmax <= tol * (1.0 + max(abs(a0), abs(a1), abs(a2), abs(a3), abs(a4))))
    ):
        return True, state_t(t, a0, a1, a2, a3, a4, s, k[K_VC] * h), F, region, delta, bd, sp, cp
    for _it in range(max_iter - 1):
        code, a, t, mesh, fin, _dm = newton_iter_t(pv, a, t, mesh, ce, se, kk, w_b, hc, k, dynamic, tol, False, True)
        if code == NEWTON_DONE:
            s1 = state_t(t, a[0], a[1], a[2], a[3], a[4], s, k[K_VC] * h)
            return True, s1, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]
        if code == NEWTON_BAD:
            break
    return False, s, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]


@kernel_inline
def mesh_branch_t(s, ce, se, omega, k, dynamic, region):
    """:func:`mesh_t` with the backlash force taken on the branch ``region`` whatever Delta is
    (:func:`backlash_branch`, the one-sided continuation), and ``region`` reported."""
    delta, ddelta, bd, _f, _reg, sp, cp, db0, db1, dp0, dp1 = mesh_t(s, ce, se, omega, k, dynamic)
    return delta, ddelta, bd, backlash_branch(delta, bd, region), region, sp, cp, db0, db1, dp0, dp1


@kernel_inline
def newmark_branch_try_t(s, g, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol, region):
    """A Newmark step (:func:`newmark_try_t`, same arguments plus ``region``) with the backlash
    force held on the branch ``region``: the part of a step before a located contact change.
    Newton iterates until the update is below tol (1 + max|a|); for the constant model the force
    is then linear and one update is exact. Returns (converged, new state tuple, F, Delta, B_d,
    sin psi, cos psi); on failure the state returned is the input one."""
    bh2 = hc[1]
    gh = hc[2]
    pv, t, mesh = newton_start_t(s, g, ce, se, w_b, hc, k, dynamic)
    mesh = mesh_branch_t(t, ce, se, w_b, k, dynamic, region)
    a0, a1, a2, a3, a4 = g[0], g[1], g[2], g[3], g[4]
    for _it in range(max_iter):
        e0, e1, e2, e3, e4, F = newton_delta_t((a0, a1, a2, a3, a4), t, mesh, ce, se, kk, hc, k, dynamic)
        a0 += e0
        a1 += e1
        a2 += e2
        a3 += e3
        a4 += e4
        dmax = max(abs(e0), abs(e1), abs(e2), abs(e3), abs(e4))
        if not math.isfinite(dmax):
            break
        t = corrector_t(pv, a0, a1, a2, a3, a4, bh2, gh)
        mesh = mesh_branch_t(t, ce, se, w_b, k, dynamic, region)
        if dynamic == 0 or dmax <= tol * (1.0 + max(abs(a0), abs(a1), abs(a2), abs(a3), abs(a4))):
            delta, ddelta, bd, f, _r, sp, cp, _b0, _b1, _p0, _p1 = mesh
            s1 = state_t(t, a0, a1, a2, a3, a4, s, k[K_VC] * hc[0])
            return True, s1, force_t(ddelta, f, kk, k), delta, bd, sp, cp
    return False, s, 0.0, 0.0, 0.0, 0.0, 0.0


LOCATE_MAX_ITER = 60
"""Iterations of the crossing search of :func:`crossing_t` (Illinois; it needs 5-12)."""
LOCATE_TOL_STEP = 1e-4
"""Crossing tolerance of the integration drivers (``drivers.located_step_t``): a split point off by
d theta changes the step's end by ~ (jump of the jerk) h^3 d theta, far below the step's error."""
LOCATE_TOL_FIXED = 1e-2
"""Crossing tolerance of the fixed-step drivers that locate contact changes (the kernels' ``K_LOC``, the environments'
``locate_contacts``): the first secant step of ``crossing_fast_t`` from the cubic interpolant's root then usually
ends the search, one solve per crossing instead of 2-3 at LOCATE_TOL_STEP, for no change of the orbits' error
(``benchmarks/contact_steps.py``)."""
LOCATE_TOL = 1e-13
"""The crossing search stops when the bracket of the crossing is below this fraction of the step
or the gap function is below LOCATE_TOL * 1e-2 b0."""


@kernel_inline
def crossing_side_t(reg0, region1):
    """The contact boundary a step from region ``reg0`` into ``region1`` crosses first: +1 the
    drive side (gap function Delta - B_d), -1 the back side (Delta + B_d)."""
    if reg0 == 0:
        return region1
    return reg0


KINK_THETA_TOL = 1e-6
"""The Newton iteration of :func:`kink_correct_t` for the crossing theta (fraction of the step) stops at an update
below this: the theta after it is good to ~1e-12, and the correction's integrals of the gap, which vanishes at the
crossing, change by ~(error of theta)^2. It takes 2-3 iterations (a tolerance of 1e-12 took 3-20: rounding noise)."""


@kernel_inline
def kink_correct_t(s, s1, reg0, ce0, se0, w_a, ce, se, kk, w_b, hc, k, dynamic):
    """The Newmark step from s (contact region ``reg0``) to s1 that stepped over one contact edge, corrected for the
    kink of the backlash force inside it, without a solve. ``ce0, se0``: the excitation at its start (omega ``w_a``),
    ``ce, se, kk`` at its end (``w_b``); ``hc``: its :func:`step_coeffs`. Returns (state, F, region, Delta, B_d,
    sin psi, cos psi) at its end.

    The gap function G (Delta - side B_d) over the step is the cubic Hermite interpolant of its values and rates at
    both ends (tau in [0, 1]); its root theta is the crossing. After it the force on the new branch differs from the
    old branch's by sg G (sg = +-kk), so the accelerations by D(tau) = -w sg G(tau) (w: :func:`mesh_direction_t`,
    1 on U). Newmark's step took D as if it were smooth, with a(1) holding D(1): v by h D(1) / 2 and q by beta h^2
    D(1), where the exact increments are h int_theta^1 D and h^2 int_theta^1 (1 - tau) D. Newmark's velocity of a
    smooth solution also carries the bias (1/6 - beta) h^2 a' (what makes Fox-Goodwin's positions fourth order), so
    after the kink it should carry that of the new branch's D' too. The predictors of the step are shifted by these
    differences, and the accelerations answer by one linear Newton solve at the end's mesh (exact for the constant
    model's piecewise-linear force; the dynamic model's geometry held). F, Delta, B_d and the region at the end are
    updated to first order (psi held). The local error of the step drops from O(h^2 D') to O(h^3): measured in
    docs/SIMULATOR.md ("Contact changes corrected inside the fixed steps")."""
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    beta = k[K_BETA]
    wh = k[K_VC] * h
    # the end: positions and the velocity the forces felt (output_t), and its mesh
    tf = (s1[0], s1[1], s1[2], s1[3], s1[4], s1[5] - wh * (s1[10] - s[10]), s1[6] - wh * (s1[11] - s[11]),
          s1[7] - wh * (s1[12] - s[12]), s1[8] - wh * (s1[13] - s[13]), s1[9] - wh * (s1[14] - s[14]))  # fmt: skip
    delta, ddelta, bd, _f, region, sp, cp, db0, db1, dp0, dp1 = mesh_t(tf, ce, se, w_b, k, dynamic)
    side = crossing_side_t(reg0, region)
    g0, r0 = gap_rate_t(s, ce0, se0, w_a, k, dynamic, side)
    g1 = delta - side * bd
    r1 = ddelta - side * (db0 * (tf[5] - tf[7]) + db1 * (tf[6] - tf[8]))
    # G(tau) = g0 + m0 tau + c2 tau^2 + c3 tau^3, and its root th in [0, 1] (Newton safeguarded by bisection)
    m0 = h * r0
    m1 = h * r1
    c3 = 2.0 * g0 + m0 - 2.0 * g1 + m1
    c2 = -3.0 * g0 - 2.0 * m0 + 3.0 * g1 - m1
    lo = 0.0
    hi = 1.0
    plo = g0
    th = g0 / (g0 - g1) if g0 != g1 else 0.5
    for _it in range(20):
        p = ((c3 * th + c2) * th + m0) * th + g0
        dp = (3.0 * c3 * th + 2.0 * c2) * th + m0
        if p * plo > 0.0:
            lo = th
            plo = p
        else:
            hi = th
        nt = th - p / dp if dp != 0.0 else -1.0
        if not lo < nt < hi:
            nt = 0.5 * (lo + hi)
        done = abs(nt - th) <= KINK_THETA_TOL
        th = nt
        if done:
            break
    t2 = th * th
    t3 = t2 * th
    # int_theta^1 G and int_theta^1 tau G
    iv = (g0 + 0.5 * m0 + c2 / 3.0 + 0.25 * c3) - th * (g0 + 0.5 * m0 * th + c2 * t2 / 3.0 + 0.25 * c3 * t3)
    it = (0.5 * g0 + m0 / 3.0 + 0.25 * c2 + 0.2 * c3) - t2 * (0.5 * g0 + m0 * th / 3.0 + 0.25 * c2 * t2 + 0.2 * c3 * t3)
    sg = kk if reg0 == 0 else -kk
    w0, w1, w2, w3 = mesh_direction_t(sp, cp, 0.0, k, dynamic, region, db0, db1, dp0, dp1, tf[0] - tf[2],
                                      tf[1] - tf[3])  # fmt: skip
    # (exact - Newmark) of D's part of the step, per unit of -w: velocity (with the new bias) and positions
    cv = -sg * h * (iv + (1.0 / 6.0 - beta) * m1 - 0.5 * g1)
    cq = -sg * h * h * (iv - it - beta * g1)
    dq0, dq1, dq2, dq3, dq4 = cq * w0, cq * w1, cq * w2, cq * w3, cq
    dv0, dv1, dv2, dv3, dv4 = cv * w0, cv * w1, cv * w2, cv * w3, cv
    # the accelerations' answer to the shifted predictors: the Newton matrix of newton_delta_t at the end's mesh
    c_p, c_g, k_p, k_g = bearing_t(k)
    gg0, gg1, gg2, gg3, gg4 = deflection_gradient_t(sp, cp)
    dF_ddd, dF_dd, dF_dbd = force_gradient_t(delta, bd, region, kk, k)
    dFs = (dF_ddd * (gg0 * dv0 + gg1 * dv1 + gg2 * dv2 + gg3 * dv3 + gg4 * dv4)
           + dF_dd * (gg0 * dq0 + gg1 * dq1 + gg2 * dq2 + gg3 * dq3 + gg4 * dq4)
           + dF_dbd * (db0 * (dq0 - dq2) + db1 * (dq1 - dq3)))  # fmt: skip
    cg = gh * dF_ddd + bh2 * dF_dd
    cb = bh2 * dF_dbd
    e0, e1, e2, e3, e4 = rank_one_solve_t(
        c_p * dv0 + k_p * dq0 + w0 * dFs, c_p * dv1 + k_p * dq1 + w1 * dFs, c_g * dv2 + k_g * dq2 + w2 * dFs,
        c_g * dv3 + k_g * dq3 + w3 * dFs, dFs, w0, w1, w2, w3, cg * gg0 + cb * db0, cg * gg1 + cb * db1,
        cg * gg2 - cb * db0, cg * gg3 - cb * db1, cg * gg4, idd0, idd2,
    )  # fmt: skip
    dq0 += bh2 * e0
    dq1 += bh2 * e1
    dq2 += bh2 * e2
    dq3 += bh2 * e3
    dq4 += bh2 * e4
    dv0 += gh * e0
    dv1 += gh * e1
    dv2 += gh * e2
    dv3 += gh * e3
    dv4 += gh * e4
    t = (tf[0] + dq0, tf[1] + dq1, tf[2] + dq2, tf[3] + dq3, tf[4] + dq4,
         tf[5] + dv0, tf[6] + dv1, tf[7] + dv2, tf[8] + dv3, tf[9] + dv4)  # fmt: skip
    # the end's mesh to first order in the shift (psi held)
    delta += gg0 * dq0 + gg1 * dq1 + gg2 * dq2 + gg3 * dq3 + gg4 * dq4
    ddelta += gg0 * dv0 + gg1 * dv1 + gg2 * dv2 + gg3 * dv3 + gg4 * dv4
    bd += db0 * (dq0 - dq2) + db1 * (dq1 - dq3)
    f, region = backlash(delta, bd)
    s2 = state_t(t, s1[10] + e0, s1[11] + e1, s1[12] + e2, s1[13] + e3, s1[14] + e4, s, wh)
    return s2, force_t(ddelta, f, kk, k), region, delta, bd, sp, cp


@kernel_inline
def branch_part_t(s, g1, theta, reg0, phi_a, dphi, w_a, w_b, c, k, dynamic, max_iter, tol):
    """The first part, theta of its phase increment dphi, of a step from s with the force held on
    the branch ``reg0`` (omega^2 linear in phase; Newton guess: the accelerations interpolated
    towards g1). Returns (converged, state, omega at its end, F, Delta, B_d, sin psi, cos psi)."""
    wt = math.sqrt(w_a * w_a + (w_b * w_b - w_a * w_a) * theta)
    hc = step_coeffs(2.0 * theta * dphi / (w_a + wt), k)
    ce, se, kk = excitation(phi_a + theta * dphi, c)
    gs = (
        s[10] + theta * (g1[0] - s[10]),
        s[11] + theta * (g1[1] - s[11]),
        s[12] + theta * (g1[2] - s[12]),
        s[13] + theta * (g1[3] - s[13]),
        s[14] + theta * (g1[4] - s[14]),
    )
    ok, sm, F, delta, bd, sp, cp = newmark_branch_try_t(s, gs, ce, se, kk, wt, hc, k, dynamic, max_iter, tol, reg0)
    return ok, sm, wt, F, delta, bd, sp, cp


@kernel
def crossing_t(s, g1, reg0, side, gap0, phi_a, dphi, w_a, w_b, c, k, dynamic, max_iter, tol, theta_tol=LOCATE_TOL):
    """Locate the contact change inside a Newmark step from the state tuple s (contact region
    ``reg0``, gap function ``gap0`` = Delta - side B_d at s) across the boundary ``side``
    (:func:`crossing_side_t`).

    The gap function at the end of the first part of the step, theta of its phase increment, with
    the force held on the branch ``reg0`` (:func:`branch_part_t`), is driven to zero by the
    Illinois (modified regula falsi) method on theta in [0, 1] (to ``theta_tol``: the default
    LOCATE_TOL for a smooth map and its Jacobian; the drivers use LOCATE_TOL_STEP). ``g1`` is a guess of the
    end-of-step accelerations. Returns (located, theta, state at the crossing, omega there, F,
    Delta, B_d, sin psi, cos psi); located is False if the whole step held on ``reg0`` does not
    cross (then the step is taken unlocated) or a part's Newton iteration fails.
    """
    ok, sb, wb_, Fb, db_, bdb, spb, cpb = branch_part_t(s, g1, 1.0, reg0, phi_a, dphi, w_a, w_b, c, k, dynamic,
                                                        max_iter, tol)  # fmt: skip
    gb = db_ - side * bdb
    if not ok or gap0 == 0.0 or gb * gap0 > 0.0:
        return False, 1.0, sb, wb_, Fb, db_, bdb, spb, cpb
    ta = 0.0
    ga = gap0
    tb = 1.0
    scale = 1.0 + abs(db_)
    tc, sc, wc, Fc, dc, bdc, spc, cpc = tb, sb, wb_, Fb, db_, bdb, spb, cpb
    for _it in range(LOCATE_MAX_ITER):
        tc = (ta * gb - tb * ga) / (gb - ga)
        tc = min(max(tc, min(ta, tb)), max(ta, tb))
        ok, sc, wc, Fc, dc, bdc, spc, cpc = branch_part_t(s, g1, tc, reg0, phi_a, dphi, w_a, w_b, c, k, dynamic,
                                                          max_iter, tol)  # fmt: skip
        if not ok:
            return False, tc, sc, wc, Fc, dc, bdc, spc, cpc
        gc = dc - side * bdc
        if abs(gc) <= 1e-2 * theta_tol * scale or abs(tb - ta) <= theta_tol:
            break
        if gc * gb < 0.0:
            ta, ga = tb, gb
        else:
            ga *= 0.5
        tb, gb = tc, gc
    return True, tc, sc, wc, Fc, dc, bdc, spc, cpc


@kernel_inline
def gap_rate_t(s, ce, se, omega, k, dynamic, side):
    """The gap function Delta - side B_d of the state tuple s (excitation ``ce, se``, :func:`excitation`) and its
    rate in natural time (Delta' - side dB_d/ds, dB_d/ds = dB/dX_p (X_p' - X_g') + dB/dY_p (Y_p' - Y_g'))."""
    delta, ddelta, bd, _f, _r, _sp, _cp, db0, db1, _dp0, _dp1 = mesh_t(s, ce, se, omega, k, dynamic)
    return delta - side * bd, ddelta - side * (db0 * (s[5] - s[7]) + db1 * (s[6] - s[8]))


LOCATE_FAST_ITER = 6
"""Solves of :func:`crossing_fast_t` before it hands the crossing to :func:`crossing_t` (it needs 2-3)."""


@kernel_inline
def crossing_fast_t(s, s1, ce0, se0, ce1, se1, reg0, side, phi_a, dphi, w_a, w_b, c, k, dynamic, max_iter, tol,
                    theta_tol):  # fmt: skip
    """:func:`crossing_t` of the drivers, with fewer solves: the first guess of theta is the root of the
    cubic Hermite interpolant of the gap function between the step's start s and its unlocated end s1 (values
    and rates at both ends, :func:`gap_rate_t`; ``ce0, se0`` and ``ce1, se1``: the excitation there), refined
    by secant steps on the branch parts
    (:func:`branch_part_t`; the first step with the interpolant's slope) inside the bracket they build, until
    theta moves by less than ``theta_tol``. Each refinement is one Newmark solve; the Illinois search of
    :func:`crossing_t` takes 6-8 (the whole step on the branch first, then 5-7 parts). Returns
    (status, theta, state at the crossing, omega there, F, Delta, B_d, sin psi, cos psi): status 1 located,
    0 use :func:`crossing_t` (no sign change of the interpolated gap, a step outside the bracket, a failed
    solve or no convergence in :data:`LOCATE_FAST_ITER` solves)."""
    h = 2.0 * dphi / (w_a + w_b)
    g0, r0 = gap_rate_t(s, ce0, se0, w_a, k, dynamic, side)
    g1, r1 = gap_rate_t(s1, ce1, se1, w_b, k, dynamic, side)
    if g0 == 0.0 or g0 * g1 > 0.0:
        return 0, 1.0, s, w_a, 0.0, 0.0, 0.0, 0.0, 0.0
    # the cubic Hermite p(t) = g0 (2t^3-3t^2+1) + m0 (t^3-2t^2+t) + g1 (-2t^3+3t^2) + m1 (t^3-t^2): its root in
    # [0, 1] by Newton's method safeguarded with bisection (no solve)
    m0 = h * r0
    m1 = h * r1
    c3 = 2.0 * g0 + m0 - 2.0 * g1 + m1
    c2 = -3.0 * g0 - 2.0 * m0 + 3.0 * g1 - m1
    lo = 0.0
    hi = 1.0
    plo = g0
    th = g0 / (g0 - g1)
    slope = g1 - g0
    for _it in range(12):
        p = ((c3 * th + c2) * th + m0) * th + g0
        dp = (3.0 * c3 * th + 2.0 * c2) * th + m0
        if p * plo > 0.0:
            lo = th
            plo = p
        else:
            hi = th
        slope = dp
        nt = th - p / dp if dp != 0.0 else -1.0
        if not lo < nt < hi:
            nt = 0.5 * (lo + hi)
        done = abs(nt - th) <= 1e-12
        th = nt
        if done:
            break
    a1 = (s1[10], s1[11], s1[12], s1[13], s1[14])
    ta = 0.0  # bracket of the branch-held gap: ga at ta (theta 0: g0); tb the first part past the crossing
    ga = g0
    tb = 2.0
    tp = -1.0  # the previous part, for the secant
    gp = 0.0
    for _it in range(LOCATE_FAST_ITER):
        ok, sc, wc, Fc, dc, bdc, spc, cpc = branch_part_t(s, a1, th, reg0, phi_a, dphi, w_a, w_b, c, k, dynamic,
                                                          max_iter, tol)  # fmt: skip
        if not ok:
            return 0, th, sc, wc, Fc, dc, bdc, spc, cpc
        gc = dc - side * bdc
        if gc * ga > 0.0:
            ta, ga = th, gc
        else:
            tb = th
        if tp >= 0.0 and gc != gp:
            slope = (gc - gp) / (th - tp)
        tp, gp = th, gc
        nt = th - gc / slope if slope != 0.0 else -1.0
        if abs(nt - th) <= theta_tol:
            return 1, th, sc, wc, Fc, dc, bdc, spc, cpc
        if not ta < nt < min(tb, 1.0):
            if tb > 1.0:
                return 0, th, sc, wc, Fc, dc, bdc, spc, cpc
            nt = 0.5 * (ta + tb)
        th = nt
    return 0, th, s, w_a, 0.0, 0.0, 0.0, 0.0, 0.0


@kernel_inline
def split_at_t(s, g1, theta, reg0, phi_a, dphi, w_a, w_b, ce, se, kk, c, k, dynamic, max_iter, tol):
    """A Newmark step from s split at the fraction theta of its phase increment: the first part
    with the force held on the branch ``reg0`` (:func:`branch_part_t`), the rest from there to the
    end as a normal step (``ce, se, kk``: the excitation at the end). Returns (converged, state at
    the split, omega there, state at the end, F, region, Delta, B_d, sin psi, cos psi) at the end."""
    ok, sm, wm, _F, _d, _bd, _sp, _cp = branch_part_t(s, g1, theta, reg0, phi_a, dphi, w_a, w_b, c, k, dynamic,
                                                      max_iter, tol)  # fmt: skip
    if not ok:
        return False, sm, wm, sm, 0.0, 0, 0.0, 0.0, 0.0, 0.0
    hc = step_coeffs(2.0 * (1.0 - theta) * dphi / (wm + w_b), k)
    ok, s2, F, region, delta, bd, sp, cp = newmark_try_t(sm, g1, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol)
    return ok, sm, wm, s2, F, region, delta, bd, sp, cp


MAX_SPLIT_LEVEL = 6


@kernel
def split_step_t(s, phi_a, dphi, w_a, w_b, c, k, dynamic, max_iter, tol):
    """Fallback of :func:`newmark_step_t`: the step divided into 2, 4, ... 2^6 sub-steps (omega^2
    linear in phase inside it) until Newton converges in every sub-step. Same return as
    :func:`newmark_step_t`."""
    F = 0.0
    region = 0
    delta = 0.0
    bd = 0.0
    sp = 0.0
    cp = 0.0
    tq = torque_fluctuates_t(c)
    for level in range(1, MAX_SPLIT_LEVEL + 1):
        nsub = 1 << level
        ss = s
        good = True
        sub = dphi / nsub
        wprev = w_a
        for j in range(nsub):
            frac = (j + 1.0) / nsub
            wk = math.sqrt(w_a * w_a + (w_b * w_b - w_a * w_a) * frac)
            hc = step_coeffs(2.0 * sub / (wprev + wk), k)
            cek, sek, kkk = excitation(phi_a + sub * (j + 1.0), c)
            ga = (ss[10], ss[11], ss[12], ss[13], ss[14])
            kq = step_consts_at(k, phi_a + sub * (j + 1.0), c, tq)  # k itself unless the torque fluctuates
            ok, ss, F, region, delta, bd, sp, cp = newmark_try_t(
                ss, ga, cek, sek, kkk, wk, hc, kq, dynamic, max_iter, tol
            )
            if not ok:
                good = False
                break
            wprev = wk
        if good:
            return OK, ss, F, region, delta, bd, sp, cp, 1
    return NEWTON_FAILED, s, F, region, delta, bd, sp, cp, 1


@kernel_inline
def newmark_step_t(s, g, phi_a, dphi, ce, se, kk, w_a, w_b, hc, c, k, dynamic, max_iter, tol):
    """Advance the state tuple s = (q, v, a) by a phase increment dphi (omega: w_a -> w_b).

    ``(ce, se, kk)`` is the excitation at the end phase phi_a + dphi and ``hc`` the step
    coefficients (:func:`step_coeffs` of h = 2 dphi / (w_a + w_b)). Returns (status, new state
    tuple, F, region, Delta, B_d, sin psi, cos psi, split), split = 1 if Newton needed sub-steps.
    """
    ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(s, g, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol)
    if ok:
        return OK, s1, F, region, delta, bd, sp, cp, 0
    # runtime_int: the SIMD kernels pass the model as a literal; the rare fallback is compiled once
    return split_step_t(s, phi_a, dphi, w_a, w_b, c, k, runtime_int(dynamic), max_iter, tol)


@kernel_inline
def guess_t(s0, s1, last):
    """Newton's starting guess for the next step's acceleration: linear extrapolation
    2 a_{n+1} - a_n from the last two steps, or a_{n+1} itself if ``last`` (after a split step,
    and for the constant model, whose piecewise-linear Newton does not depend on the guess)."""
    if last:
        return (s1[10], s1[11], s1[12], s1[13], s1[14])
    return (
        2.0 * s1[10] - s0[10],
        2.0 * s1[11] - s0[11],
        2.0 * s1[12] - s0[12],
        2.0 * s1[13] - s0[13],
        2.0 * s1[14] - s0[14],
    )


@kernel_inline
def omega_step_t(j, wa, hc, w0, ww, dphi, k):
    """Meshing frequency at the end of step j of an interval in which omega goes linearly in time
    from w0 (omega^2 linear in the step index; ``ww`` = (w1^2 - w0^2)/total, its increment per
    step), and the coefficients of the step from ``wa``: ``hc`` (those of the previous step) is
    reused while omega is constant. Returns (omega at the end of the step, step coefficients)."""
    if ww == 0.0:
        return w0, hc
    wb = math.sqrt(w0 * w0 + ww * (j + 1.0))
    return wb, step_coeffs(2.0 * dphi / (wa + wb), k)


@kernel_inline
def load_t(x, a):
    """State tuple (q, v, a) from the arrays x (10) and a (5)."""
    return (x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9], a[0], a[1], a[2], a[3], a[4])


@kernel_inline
def store_t(s, x, a):
    """Write the state tuple back into x (10) and a (5)."""
    for i in range(NSTATE):
        x[i] = s[i]
    for i in range(NDOF):
        a[i] = s[NSTATE + i]


@kernel_inline
def _diverged_t(s):
    """True if a state tuple holds a non-finite value or |q|_1 + |v|_1 > DIVERGENCE_LIMIT."""
    m = abs(s[0]) + abs(s[1]) + abs(s[2]) + abs(s[3]) + abs(s[4])
    m += abs(s[5]) + abs(s[6]) + abs(s[7]) + abs(s[8]) + abs(s[9])
    return not (m <= DIVERGENCE_LIMIT)


@kernel
def newmark_step(x, a, phi_a, dphi, ce, se, kk, w_a, w_b, c, dynamic, work, max_iter, tol):
    """Array form of one step: advance (x, a) in place by a phase increment dphi while omega goes
    linearly in time w_a -> w_b; ``ce, se, kk`` is the excitation at the end phase.

    Returns (status, F, region, delta, bd, split) with the mesh quantities at the end of the
    step; psi at the end of the step is written to work[0].
    """
    k = step_consts(c)
    hc = step_coeffs(2.0 * dphi / (w_a + w_b), k)
    s0 = load_t(x, a)
    st, s, F, region, delta, bd, sp, cp, split = newmark_step_t(
        s0, (a[0], a[1], a[2], a[3], a[4]), phi_a, dphi, ce, se, kk, w_a, w_b, hc, c, k, dynamic, max_iter, tol
    )
    if st == OK:
        store_t(s, x, a)
        work[0] = psi_t(sp, cp, c, dynamic)
    return st, F, region, delta, bd, split
