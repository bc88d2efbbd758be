"""numba kernels of the gear-bearing model: geometry, backlash, mesh force, Newmark-beta steps.

Plain arrays and floats in, arrays out; no Python objects. Everything is dimensionless and in
natural time s = omega_n t (MODEL.md sec. 3b). The state is ``x = [X_p, Y_p, X_g, Y_g, U,
X_p', Y_p', X_g', Y_g', U']`` (b0 units); the mesh phase ``phi`` advances at ``omega``.

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

import numpy as np
from numba import njit

from .params import (
    C_A0,
    C_ALPHA0,
    C_BC,
    C_COS_A0,
    C_E1,
    C_EPS_G,
    C_EPS_P,
    C_FS,
    C_GG,
    C_GP,
    C_KAPPA,
    C_MU,
    C_PHI_E,
    C_PHI_K,
    C_R,
    C_SIG_G,
    C_SIG_P,
    C_SIN_A0,
    C_XI_BG,
    C_XI_BP,
    C_XI_M,
)

kernel = njit(cache=True, error_model="numpy")
"""Decorator of every kernel: compiled once, cached on disk, no Python exceptions inside."""
kernel_inline = njit(cache=True, error_model="numpy", inline="always")
"""Small helpers inlined into their callers at numba IR level."""

NDOF = 5
NSTATE = 10
GAMMA = 0.5
BETA = 0.25
TWO_PI = 2.0 * math.pi

# status codes returned by the integrators
OK = 0
DIVERGED = 1  # non-finite or exploding state
NEWTON_FAILED = 2  # Newton failed even after step splitting

# channels recorded per step by ``integrate_record`` (columns after the 10 states)
REC_S = 10
REC_PHI = 11
REC_OMEGA = 12
REC_DELTA = 13
REC_BD = 14
REC_PSI = 15
REC_FORCE = 16
REC_REGION = 17
N_REC = 18

# per-interval statistics written by ``integrate_stats`` (index into the stats vector)
ST_TIME = 0  # elapsed natural time
ST_SEP_TIME = 1  # time with the teeth apart (|Delta| < B_d)
ST_BACK_TIME = 2  # time in back-side contact
ST_BACK_IMPACTS = 3  # entries into back-side contact
ST_DRIVE_IMPACTS = 4  # re-entries into drive-side contact after a separation
ST_F_SUM = 5  # integral of the mesh force
ST_F_SQ = 6  # integral of the mesh force squared
ST_F_MAX = 7
ST_F_MIN = 8
ST_TR_SQ = 9  # integral of (X_p^2 + Y_p^2 + X_g^2 + Y_g^2)/2 (translational response)
ST_TR_MAX = 10  # max over time of the radial bearing deflection
ST_U_MAX = 11
ST_U_MIN = 12
ST_D_MAX = 13
ST_D_MIN = 14
ST_BD_MAX = 15
ST_BD_MIN = 16
ST_PSI_MAX = 17
ST_PSI_MIN = 18
ST_STEPS = 19  # steps taken
ST_SPLITS = 20  # steps that had to be split
N_STATS = 21

# Poincare sample columns written by ``integrate_stats`` per mesh period
PC_DELTA = 10
PC_BD = 11
PC_PSI = 12
PC_FORCE = 13
N_PC = 14

DIVERGENCE_LIMIT = 1e6  # |state| beyond this (b0 units) counts as divergence


def readonly(a: np.ndarray) -> np.ndarray:
    """``a`` itself if it is read-only, else a read-only view of it (Python helper, not compiled).

    Kernels take their constants (``GearParams.consts``, one row per system for the batch
    kernels) as read-only arrays everywhere: numba compiles a separate copy of a kernel for a
    writable array argument, and a copy of the Newmark loop costs 25-50 s of first-call compile.
    """
    if not a.flags.writeable:
        return a
    v = a.view()
    v.flags.writeable = False
    return v


@njit(cache=True)
def runtime_int(v):
    """``v`` typed as a plain int64 inside a kernel (not a literal; see :func:`runtime_true`)."""
    return np.int64(v)


@njit(cache=True)
def runtime_true():
    """True typed as a plain boolean inside a kernel.

    A kernel that passes a literal (``1``, ``True``) to another kernel makes numba compile a
    copy of the callee specialised to that literal value; passing these instead reuses the
    copy that calls from Python compile.
    """
    return np.int64(0) == np.int64(0)


@kernel_inline
def backlash(delta, bd):
    """Dead-zone function f(Delta; B_d) (eq. 9) and its region (+1 drive, 0 apart, -1 back)."""
    if delta >= bd:
        return delta - bd, 1
    if delta <= -bd:
        return delta + bd, -1
    return 0.0, 0


GEO_SIZE = 14


@kernel
def geometry(q, c, dynamic, out):
    """Mesh geometry at positions q = (X_p, Y_p, X_g, Y_g, ...) (eqs. 5-8), array form.

    Writes ``out[0:14] = [psi, B_d, dB/dq (5), dpsi/dq (5), sin psi, cos psi]``. For the constant
    model psi = alpha0 and B_d = B_c (A8) and the derivative entries are left untouched (the
    caller keeps them zero); for the dynamic model eqs. (5)-(8) (A9) by :func:`geometry_t`.
    """
    if dynamic == 0:
        out[0] = c[C_ALPHA0]
        out[1] = c[C_BC]
        out[12] = c[C_SIN_A0]
        out[13] = c[C_COS_A0]
        return
    db0, db1, dp0, dp1, bd, sp, cp = geometry_t(q[0], q[1], q[2], q[3], step_consts(c))
    out[0] = math.atan2(sp, cp)
    out[1] = bd
    out[2] = db0
    out[3] = db1
    out[4] = -db0
    out[5] = -db1
    out[6] = 0.0
    out[7] = dp0
    out[8] = dp1
    out[9] = -dp0
    out[10] = -dp1
    out[11] = 0.0
    out[12] = sp
    out[13] = cp


@kernel
def mesh_state(q, v, ce, se, omega, c, dynamic, geo):
    """Delta, Delta', B_d, f(Delta), region at one instant (q, v of length 5), array form of
    :func:`mesh_t`; ``geo`` (>= 14, zero-initialised) receives the geometry (see :func:`geometry`).
    ``ce, se`` = cos, sin of (phi + phi_e)."""
    geometry(q, c, dynamic, geo)
    s = (q[0], q[1], q[2], q[3], q[4], v[0], v[1], v[2], v[3], v[4])
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh_t(s, ce, se, omega, step_consts(c), dynamic)
    return delta, ddelta, bd, f, region


FRICTION_SHARPNESS = 10.0


@kernel
def accel(q, v, ce, se, omega, kk, c, dynamic, geo, a):
    """Accelerations a = q'' (natural time) at one instant; returns the mesh force Fhat.

    ``kk`` = 1 + kappa cos(phi + phi_k) is the stiffness factor; psi is left in geo[0].
    """
    k = step_consts(c)
    delta, ddelta, bd, f, region = mesh_state(q, v, ce, se, omega, c, dynamic, geo)
    F = k[8] * ddelta + kk * f
    sp = geo[12]
    cp = geo[13]
    fr = friction_t(ce, se, k)  # [friction extension] 0 unless GearParams.friction > 0
    a[0] = -(k[2] * v[0] + k[4] * q[0] + F * (sp - fr * cp) * k[0])
    a[1] = -(k[2] * v[1] + k[4] * q[1] - F * (cp + fr * sp) * k[0]) + k[6]
    a[2] = -(k[3] * v[2] + k[5] * q[2] - F * (sp - fr * cp) * k[1])
    a[3] = -(k[3] * v[3] + k[5] * q[3] + F * (cp + fr * sp) * k[1]) + k[7]
    a[4] = k[9] - F
    return F


@kernel_inline
def excitation(phi, c):
    """(cos(phi + phi_e), sin(phi + phi_e), 1 + kappa cos(phi + phi_k)) at mesh phase phi."""
    return math.cos(phi + c[C_PHI_E]), math.sin(phi + c[C_PHI_E]), 1.0 + c[C_KAPPA] * math.cos(phi + c[C_PHI_K])


@kernel_inline
def step_consts(c):
    """The constants one Newmark step needs, as a tuple of scalars (kept in registers).

    (1/eps_p, 1/eps_g, pinion and gear bearing damping and stiffness (natural time), the weights
    per unit mass, 2 xi_m, F_s, E1, A0, R, 1/R, B_c, sin and cos alpha0, mu, cos and sin phi_e).
    """
    sgp = c[C_SIG_P]
    sgg = c[C_SIG_G]
    iep = 1.0 / c[C_EPS_P]
    ieg = 1.0 / c[C_EPS_G]
    return (
        iep,
        ieg,
        2.0 * c[C_XI_BP] * sgp,
        2.0 * c[C_XI_BG] * sgg,
        sgp * sgp,
        sgg * sgg,
        -c[C_GP] * iep,
        -c[C_GG] * ieg,
        2.0 * c[C_XI_M],
        c[C_FS],
        c[C_E1],
        c[C_A0],
        c[C_R],
        1.0 / c[C_R],
        c[C_BC],
        c[C_SIN_A0],
        c[C_COS_A0],
        c[C_MU],
        math.cos(c[C_PHI_E]),
        math.sin(c[C_PHI_E]),
    )


@kernel_inline
def step_coeffs(h, k):
    """Newmark coefficients of a step of length h (natural time): (h, beta h^2, gamma h,
    (1/2 - beta) h^2, (1 - gamma) h, inverse diagonal of the Newton matrix for the pinion and the
    gear bearings). Loop-invariant while omega is constant."""
    bh2 = BETA * h * h
    gh = GAMMA * h
    d0 = 1.0 + gh * k[2] + bh2 * k[4]
    d2 = 1.0 + gh * k[3] + bh2 * k[5]
    q = 1.0 / (d0 * d2)  # one division for both inverses (recomputed every step of a ramp)
    return h, bh2, gh, h * h * (0.5 - BETA), h * (1.0 - GAMMA), q * d2, q * d0


@kernel_inline
def geometry_t(q0, q1, q2, q3, k):
    """Dynamic-model geometry (eqs. 5-8) at positions (X_p, Y_p, X_g, Y_g), no trigonometric call.

    Returns (dB/dX_p, dB/dY_p, dpsi/dX_p, dpsi/dY_p, B_d, sin psi, cos psi); the derivatives
    with respect to (X_g, Y_g) are their negatives and those with respect to U are zero. With
    ca = R/A_d, sa = sqrt(1 - ca^2) = sqrt(A_d^2 - R^2)/A_d (alpha_d), cz = d1/A_d and
    z = -d2/A_d (the arcsin term): sin psi = sa cz + ca z and cos psi = ca cz - sa z. Two square
    roots and one division (divisions and roots are the dearest operations of a step).
    """
    A0 = k[11]
    R = k[12]
    d1 = A0 - q0 + q2
    d2 = q1 - q3
    ad2 = d1 * d1 + d2 * d2
    ad = math.sqrt(ad2)
    r2 = ad2 - R * R  # A_d^2 sin^2(alpha_d)
    if r2 < 1e-30 * ad2:
        r2 = 1e-30 * ad2
    rs = math.sqrt(r2)  # A_d sin(alpha_d)
    rd = rs * d1
    pinv = 1.0 / (ad * rd)  # the one division: 1/A_d = pinv rd, 1/(sa cz) = pinv A_d A_d^2
    iad = pinv * rd
    inv = pinv * ad * ad2
    ca = R * iad
    sa = rs * iad
    ta = rs * k[13]
    cz = d1 * iad
    z = -d2 * iad
    sp = sa * cz + ca * z
    cp = ca * cz - sa * z
    bd = k[14] + (ad - A0) * ta
    dalpha_dad = ca * iad * cz * inv  # ca / (A_d sa)
    icz = sa * inv
    db_dad = ta + (ad - A0) * (1.0 + ta * ta) * dalpha_dad
    d2a = d2 * iad * iad
    return (
        -db_dad * cz,
        -db_dad * z,
        -dalpha_dad * cz - d2a,
        -dalpha_dad * z - (d2a * z + iad) * icz,
        bd,
        sp,
        cp,
    )


@kernel_inline
def mesh_t(s, ce, se, omega, k, dynamic):
    """Mesh quantities of a state tuple s = (q0..q4, v0..v4, ...) at one instant.

    Returns (Delta, Delta', B_d, f(Delta), region, sin psi, cos psi, dB/dX_p, dB/dY_p, dpsi/dX_p,
    dpsi/dY_p).
    """
    q0, q1, q2, q3, q4 = s[0], s[1], s[2], s[3], s[4]
    v0, v1, v2, v3, v4 = s[5], s[6], s[7], s[8], s[9]
    dx = q0 - q2
    dy = q1 - q3
    e1 = k[10]
    if dynamic == 0:
        sp = k[15]
        cp = k[16]
        bd = k[14]
        db0 = 0.0
        db1 = 0.0
        dp0 = 0.0
        dp1 = 0.0
        delta = dx * sp - dy * cp + q4 - e1 * ce
        ddelta = (v0 - v2) * sp - (v1 - v3) * cp + v4 + e1 * omega * se
    else:
        db0, db1, dp0, dp1, bd, sp, cp = geometry_t(q0, q1, q2, q3, k)
        delta = dx * sp - dy * cp + q4 - e1 * ce
        psid = dp0 * (v0 - v2) + dp1 * (v1 - v3)
        ddelta = (v0 - v2) * sp - (v1 - v3) * cp + v4 + e1 * omega * se + psid * (dx * cp + dy * sp)
    f, region = backlash(delta, bd)
    return delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1


@kernel_inline
def friction_t(ce, se, k):
    """[friction extension, GearParams.friction] mu s(phi), s = tanh(10 sin phi): the tangential
    (off line-of-action) tooth friction force per unit mesh force. ``ce, se`` = cos, sin(phi + phi_e).
    The friction force mu s F acts on the pinion along (cos psi, sin psi) and on the gear opposite;
    its moment on the gears is neglected. Returns 0 when friction is off (the paper's model)."""
    mu = k[17]
    if mu == 0.0:
        return 0.0
    return mu * math.tanh(FRICTION_SHARPNESS * (se * k[18] - ce * k[19]))


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


NEWTON_MORE = 0  # newton_iter_t: iterate again
NEWTON_DONE = 1  # newton_iter_t: converged, (t, a) is the new state
NEWTON_BAD = 2  # newton_iter_t: non-finite update


@kernel_inline
def newton_start_t(s, g, ce, se, w_b, hc, k, dynamic):
    """Predictors and the first corrector of a Newmark step from the state tuple s = (q, v, a)
    with the guess g of the end-of-step acceleration. Returns (predictors pv = (q~, v~), corrected
    (q, v) t at g, :func:`mesh_t` at t)."""
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
    pv = (qp0, qp1, qp2, qp3, qp4, vp0, vp1, vp2, vp3, vp4)
    t = corrector_t(pv, g[0], g[1], g[2], g[3], g[4], bh2, gh)
    return pv, t, mesh_t(t, ce, se, w_b, k, dynamic)


@kernel_inline
def newton_iter_t(pv, a, t, mesh, ce, se, kk, w_b, hc, k, dynamic, tol, taylor_only=False, friction=True):
    """One semismooth Newton iteration of a Newmark step (no loop inside, so a batch of them
    vectorises across systems, see ``batch_kernels``).

    ``a`` is the current iterate of the end-of-step acceleration, ``t`` = corrector at a and
    ``mesh`` = :func:`mesh_t` at t. Returns (code, a, t, mesh, fin) with code NEWTON_MORE,
    NEWTON_DONE (then (t, a) is the new state and fin = (F, region, Delta, B_d, sin psi,
    cos psi) at its end) or NEWTON_BAD (non-finite update). With ``taylor_only`` (dynamic model)
    an iteration that the Taylor update does not finish returns NEWTON_MORE without evaluating
    the geometry again (the batch kernel redoes such steps with the scalar path). With
    ``friction=False`` the friction extension is ignored (no tanh call; the batch kernel redoes
    the steps of systems with friction).
    """
    iep, ieg, c0, c2, k0, k2, ext1, ext3, xim2, Fs = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8], k[9]
    h, bh2, gh, hh, h1, idd0, idd2 = hc
    a0, a1, a2, a3, a4 = a
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    F = xim2 * ddelta + kk * f
    fr = friction_t(ce, se, k) if friction else 0.0  # [friction extension] tilts the force off the LOA
    cd = gh * xim2
    w0 = (sp - fr * cp) * iep
    w1 = -(cp + fr * sp) * iep
    w2 = -(sp - fr * cp) * ieg
    w3 = (cp + fr * sp) * ieg
    # residual r = a + C v + K q + w F - ext
    r0 = a0 + c0 * t[5] + k0 * t[0] + w0 * F
    r1 = a1 + c0 * t[6] + k0 * t[1] + w1 * F - ext1
    r2 = a2 + c2 * t[7] + k2 * t[2] + w2 * F
    r3 = a3 + c2 * t[8] + k2 * t[3] + w3 * F - ext3
    r4 = a4 + F - Fs
    # u = dF/da = bh2 kk df/dq + gh 2 xi_m g, g = dDelta/dq (force direction frozen)
    cs = bh2 * kk if region != 0 else 0.0
    rr = cs * float(region)
    cg = cd + cs
    u0 = cg * sp - rr * db0
    u1 = -cg * cp - rr * db1
    u2 = -cg * sp + rr * db0
    u3 = cg * cp + rr * db1
    u4 = cg
    # Sherman-Morrison: (D + w u^T) d = -r, D = diag(dd0, dd0, dd2, dd2, 1)
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
    e0 = y0 - fac * z0
    e1 = y1 - fac * z1
    e2 = y2 - fac * z2
    e3 = y3 - fac * z3
    e4 = y4 - fac
    a0 += e0
    a1 += e1
    a2 += e2
    a3 += e3
    a4 += e4
    an = (a0, a1, a2, a3, a4)
    dmax = max(abs(e0), abs(e1), abs(e2), abs(e3), abs(e4))
    if not math.isfinite(dmax):
        return NEWTON_BAD, an, t, mesh, (F, region, delta, bd, sp, cp)
    t = corrector_t(pv, a0, a1, a2, a3, a4, bh2, gh)
    if dynamic != 0 and bh2 * dmax <= DQ_LINEAR:
        # Final update of the dynamic model: the geometry at the new positions is the
        # first-order Taylor expansion of eqs. (5)-(8) about the previous iterate (the
        # remainder, curvature of B_d(q) ~1e-3 per b0 times |dq|^2 <= 1e-8, is below 1e-11),
        # which saves the square roots and divisions of a second geometry evaluation.
        dpsi = bh2 * (dp0 * (e0 - e2) + dp1 * (e1 - e3))
        bd1 = bd + bh2 * (db0 * (e0 - e2) + db1 * (e1 - e3))
        sp1 = sp + cp * dpsi
        cp1 = cp - sp * dpsi
        dx = t[0] - t[2]
        dy = t[1] - t[3]
        delta1 = dx * sp1 - dy * cp1 + t[4] - k[10] * ce
        psid = dp0 * (t[5] - t[7]) + dp1 * (t[6] - t[8])
        ddelta1 = (t[5] - t[7]) * sp1 - (t[6] - t[8]) * cp1 + t[9] + k[10] * w_b * se + psid * (dx * cp1 + dy * sp1)
        f1, region1 = backlash(delta1, bd1)
        if region1 == region:
            return NEWTON_DONE, an, t, mesh, (xim2 * ddelta1 + kk * f1, region1, delta1, bd1, sp1, cp1)
    if dynamic != 0 and taylor_only:
        return NEWTON_MORE, an, t, mesh, (F, region, delta, bd, sp, cp)
    old_region = region
    mesh = mesh_t(t, ce, se, w_b, k, dynamic)
    delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1 = mesh
    F = xim2 * ddelta + kk * f
    # The backlash force is piecewise linear: for the constant model the update is exact
    # once the region it assumed is the region it lands in. The dynamic model's geometry is
    # mildly nonlinear: its update is accepted when small (tol) or when the position change
    # of the last Newton update, bh2 * dmax, is below DQ_LINEAR, where the neglected
    # quadratic term (curvature of B_d(q) ~ 1e-3 per b0 times DQ_LINEAR^2) is below 1e-11.
    if region == old_region and (
        dynamic == 0
        or bh2 * dmax <= DQ_LINEAR
        or dmax <= tol * (1.0 + max(abs(a0), abs(a1), abs(a2), abs(a3), abs(a4)))
    ):
        return NEWTON_DONE, an, t, mesh, (F, region, delta, bd, sp, cp)
    return NEWTON_MORE, an, t, mesh, (F, region, delta, bd, sp, cp)


@kernel_inline
def newmark_try_t(s, g, ce, se, kk, w_b, hc, k, dynamic, max_iter, tol):
    """Attempt one Newmark step on the state tuple s = (q (5), v (5), a (5)).

    ``hc`` = :func:`step_coeffs` of the step, ``(ce, se, kk)`` the excitation, ``w_b`` the
    meshing frequency at its end and ``g`` Newton's starting guess of the end-of-step
    acceleration. Returns (converged, new state tuple, F, region, Delta, B_d, sin psi, cos psi);
    on failure the state tuple returned is the input one.
    """
    pv, t, mesh = newton_start_t(s, g, ce, se, w_b, hc, k, dynamic)
    a = (g[0], g[1], g[2], g[3], g[4])
    fin = (0.0, 0, 0.0, 0.0, 0.0, 0.0)
    for _it in range(max_iter):
        code, a, t, mesh, fin = newton_iter_t(pv, a, t, mesh, ce, se, kk, w_b, hc, k, dynamic, tol)
        if code == NEWTON_DONE:
            s1 = (t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], a[0], a[1], a[2], a[3], a[4])
            return True, s1, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]
        if code == NEWTON_BAD:
            break
    return False, s, fin[0], fin[1], fin[2], fin[3], fin[4], fin[5]


DQ_LINEAR = 1e-4
"""Dynamic model: a Newton update that moves the positions by less than this (b0) is final."""

MAX_SPLIT_LEVEL = 6
WORK_SIZE = 80


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
            ok, ss, F, region, delta, bd, sp, cp = newmark_try_t(
                ss, ga, cek, sek, kkk, wk, hc, k, dynamic, max_iter, tol
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
def psi_t(sp, cp, c, dynamic):
    """Meshing angle psi [rad] from sin and cos psi (alpha0 exactly for the constant model)."""
    if dynamic == 0:
        return c[C_ALPHA0]
    return math.atan2(sp, cp)


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


@kernel_inline
def _diverged_t(s):
    """True if a state tuple holds a non-finite value or |q|_1 + |v|_1 > DIVERGENCE_LIMIT."""
    m = abs(s[0]) + abs(s[1]) + abs(s[2]) + abs(s[3]) + abs(s[4])
    m += abs(s[5]) + abs(s[6]) + abs(s[7]) + abs(s[8]) + abs(s[9])
    return not (m <= DIVERGENCE_LIMIT)


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

    Fills ``a``; returns (F, region, delta, bd) at the start; psi is left in work[0].
    """
    geo = work
    ce, se, kk = excitation(phi0, c)
    F = accel(x[0:5], x[5:10], ce, se, w0, kk, c, dynamic, geo, a)
    delta, ddelta, bd, f, region = mesh_state(x[0:5], x[5:10], ce, se, w0, c, dynamic, geo)
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
                ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(
                    s, g, tab[m, 0], tab[m, 1], tab[m, 2], wb, hc, k, dynamic, max_iter, tol
                )
                if not ok:
                    break
            el += hc[0]
            g = guess_t(s, s1, dynamic == 0 or split != 0.0)
            s = s1
            if _diverged_t(s):
                store_t(s, x, a)
                return DIVERGED, j + 1, el
            _record_row_t(out, j + 1, s, el, phi0 + dphi * (j + 1), wb, delta, bd, sp, cp, F, region, c, dynamic)
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
def _stats_init(stats):
    for i in range(N_STATS):
        stats[i] = 0.0
    for i in (ST_F_MAX, ST_U_MAX, ST_D_MAX, ST_BD_MAX, ST_PSI_MAX, ST_TR_MAX):
        stats[i] = -np.inf
    for i in (ST_F_MIN, ST_U_MIN, ST_D_MIN, ST_BD_MIN, ST_PSI_MIN):
        stats[i] = np.inf


@kernel
def integrate_stats(x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats):
    """Integrate n_periods mesh periods and accumulate interval statistics (no time series).

    ``poincare`` (n_periods, N_PC) receives, at the end of each mesh period, the 10 states and
    Delta, B_d, psi, F. ``stats`` (N_STATS) accumulates the ``ST_*`` quantities (reset first if
    ``reset_stats``). Time integrals use the trapezoidal rule. omega goes linearly in time from
    w0 to w1 over the interval. Returns (status, periods completed, natural time elapsed).
    ``phi0`` should be a multiple of 2 pi for the samples to lie on the Poincare section.

    The state and the statistics live in local variables (registers) during the loop and are
    written back at the end, also when the run stops early. psi enters the statistics through
    sin psi (monotonic in psi, |psi| < pi/2), so no atan2 is evaluated per step.
    """
    return integrate_stats_tab(
        x, a, phi0, w0, w1, n_periods, n_steps, c, dynamic, poincare, stats, max_iter, tol, reset_stats,
        _excitation_table(phi0, n_steps, c),
    )  # fmt: skip


@kernel_inline
def _acc_init():
    """Interval accumulators of :func:`integrate_stats_tab` (sums 0, maxima -inf, minima +inf):
    (time, steps, split steps, separated time, back-contact time, back impacts, drive impacts,
    integral of F, of F^2, of the translational response; max radial deflection^2, F max/min,
    U max/min, Delta max/min, B_d max/min, sin psi max/min)."""
    ni = -np.inf
    pi = np.inf
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ni, ni, pi, ni, pi, ni, pi, ni, pi, ni, pi)


@kernel_inline
def _acc_step(acc, h, s, F, region, delta, bd, sp, split, F_prev, reg_prev, tr_prev):
    """The accumulators after a step of length h that ended in state s with mesh force F, contact
    ``region``, Delta, B_d and sin psi (``F_prev``, ``reg_prev``, ``tr_prev``: the same at the
    start of the step). Returns (accumulators, translational response at the end of the step)."""
    (t_sum, n_ok, n_split, sep_t, back_t, back_imp, drive_imp, f_sum, f_sq, tr_sq,
     rp_max, f_max, f_min, u_max, u_min, d_max, d_min, bd_max, bd_min, sp_max, sp_min) = acc  # fmt: skip
    t_sum += h
    n_ok += 1.0
    n_split += split
    if region == 0:
        sep_t += h
    elif region < 0:
        back_t += h
        if reg_prev >= 0:
            back_imp += 1.0
    elif reg_prev == 0:
        drive_imp += 1.0
    f_sum += 0.5 * h * (F + F_prev)
    f_sq += 0.5 * h * (F * F + F_prev * F_prev)
    rpp = s[0] * s[0] + s[1] * s[1]
    rpg = s[2] * s[2] + s[3] * s[3]
    tr = 0.5 * (rpp + rpg)
    tr_sq += 0.5 * h * (tr + tr_prev)
    acc = (
        t_sum, n_ok, n_split, sep_t, back_t, back_imp, drive_imp, f_sum, f_sq, tr_sq,
        max(rp_max, max(rpp, rpg)), max(f_max, F), min(f_min, F), max(u_max, s[4]), min(u_min, s[4]),
        max(d_max, delta), min(d_min, delta), max(bd_max, bd), min(bd_min, bd), max(sp_max, sp), min(sp_min, sp),
    )  # fmt: skip
    return acc, tr


@kernel_inline
def _acc_store(acc, stats, c, dynamic):
    """Add the accumulators to ``stats`` (sums) and merge them into it (extrema)."""
    (t_sum, n_ok, n_split, sep_t, back_t, back_imp, drive_imp, f_sum, f_sq, tr_sq,
     rp_max, f_max, f_min, u_max, u_min, d_max, d_min, bd_max, bd_min, sp_max, sp_min) = acc  # fmt: skip
    stats[ST_TIME] += t_sum
    stats[ST_STEPS] += n_ok
    stats[ST_SPLITS] += n_split
    stats[ST_SEP_TIME] += sep_t
    stats[ST_BACK_TIME] += back_t
    stats[ST_BACK_IMPACTS] += back_imp
    stats[ST_DRIVE_IMPACTS] += drive_imp
    stats[ST_F_SUM] += f_sum
    stats[ST_F_SQ] += f_sq
    stats[ST_TR_SQ] += tr_sq
    if n_ok > 0.0:
        stats[ST_TR_MAX] = max(stats[ST_TR_MAX], math.sqrt(rp_max))
        stats[ST_F_MAX] = max(stats[ST_F_MAX], f_max)
        stats[ST_F_MIN] = min(stats[ST_F_MIN], f_min)
        stats[ST_U_MAX] = max(stats[ST_U_MAX], u_max)
        stats[ST_U_MIN] = min(stats[ST_U_MIN], u_min)
        stats[ST_D_MAX] = max(stats[ST_D_MAX], d_max)
        stats[ST_D_MIN] = min(stats[ST_D_MIN], d_min)
        stats[ST_BD_MAX] = max(stats[ST_BD_MAX], bd_max)
        stats[ST_BD_MIN] = min(stats[ST_BD_MIN], bd_min)
        if dynamic == 0:
            stats[ST_PSI_MAX] = max(stats[ST_PSI_MAX], c[C_ALPHA0])
            stats[ST_PSI_MIN] = min(stats[ST_PSI_MIN], c[C_ALPHA0])
        else:
            stats[ST_PSI_MAX] = max(stats[ST_PSI_MAX], math.asin(sp_max))
            stats[ST_PSI_MIN] = min(stats[ST_PSI_MIN], math.asin(sp_min))


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

    Two nested loops: the inner one takes the steps and calls no function; a step whose Newton
    iteration does not converge leaves it for the outer loop, which takes the step again with
    :func:`split_step_t` and re-enters the inner loop with the result (``split = 1``), so the
    same code records every step. With the call inside the hot loop, as before, the compiler
    keeps the ~60 live values of a step ready to be saved around it (on x86-64 every
    floating-point register is caller-saved): 5-17 % slower in interleaved A/B runs, with
    bit-identical results.
    """
    work = np.zeros(WORK_SIZE)
    k = step_consts(c)
    if reset_stats:
        _stats_init(stats)
    total = n_periods * n_steps
    dphi = TWO_PI / n_steps
    ww = (w1 * w1 - w0 * w0) / total
    F_prev, reg_prev, delta, bd = start_step(x, a, phi0, w0, c, dynamic, work)
    s = load_t(x, a)
    g = (a[0], a[1], a[2], a[3], a[4])
    tr_prev = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    acc = _acc_init()  # local accumulators (merged into ``stats`` at the end)
    el = 0.0
    wa = w0
    hc = step_coeffs(dphi / w0, k)
    status = OK
    done = n_periods
    split = 0.0  # 1.0: step j was just taken by split_step_t
    j = 0
    while j < total:
        while j < total:  # the hot loop: no calls
            wb, hc = omega_step_t(j, wa, hc, w0, ww, dphi, k)
            m = (j + 1) % n_steps
            if split == 0.0:
                ok, s1, F, region, delta, bd, sp, cp = newmark_try_t(
                    s, g, tab[m, 0], tab[m, 1], tab[m, 2], wb, hc, k, dynamic, max_iter, tol
                )
                if not ok:
                    break
            h = hc[0]
            el += h
            g = guess_t(s, s1, dynamic == 0 or split != 0.0)
            s = s1
            if _diverged_t(s):
                status = DIVERGED
                done = j // n_steps
                break
            acc, tr_prev = _acc_step(acc, h, s, F, region, delta, bd, sp, split, F_prev, reg_prev, tr_prev)
            F_prev = F
            reg_prev = region
            if m == 0:
                _poincare_store_t(poincare, (j + 1) // n_steps - 1, s, F, delta, bd, sp, cp, c, dynamic)
            wa = wb
            split = 0.0
            j += 1
        if j == total or status != OK:
            break
        # step j again, split into sub-steps (rare: Newton cycled between contact regions); the
        # hot loop then takes its result
        st, s1, F, region, delta, bd, sp, cp, _split = split_step_t(
            s, phi0 + dphi * j, dphi, wa, wb, c, k, runtime_int(dynamic), max_iter, tol
        )
        if st != OK:
            el += hc[0]
            status = st
            done = j // n_steps
            break
        split = 1.0
    store_t(s, x, a)
    _acc_store(acc, stats, c, dynamic)
    return status, done, el


def integrate_stats_batch(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter,
                          tol):  # fmt: skip
    """Advance a batch of independent systems by n_periods each (one call for a vector env).

    Python entry of :func:`_integrate_stats_batch` (same arguments): passes C read-only, so that
    every caller shares one compiled copy (see :func:`readonly`).
    """
    _integrate_stats_batch(
        X, A, W0, W1, n_periods, n_steps, readonly(C), dynamic, poincare, stats, status, elapsed, max_iter, tol
    )


@kernel
def _integrate_stats_batch(
    X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol
):
    """Advance a batch of independent systems by n_periods each (one call for a vector env).

    X (n, 10), A (n, 5), W0/W1 (n,), C (n, N_CONSTS) constants per system, dynamic (n,) model
    codes, poincare (n, n_periods, N_PC), stats (n, N_STATS), status (n,) int64 and elapsed (n,)
    outputs. Each system starts at mesh phase 0 (a Poincare section). A system whose status is
    not OK is left in an unspecified state; the caller resets it.
    """
    n = X.shape[0]
    reset = runtime_true()  # not the literal True: see runtime_true
    for j in range(n):
        st, done, s = integrate_stats(
            X[j],
            A[j],
            0.0,
            W0[j],
            W1[j],
            n_periods,
            n_steps,
            C[j],
            dynamic[j],
            poincare[j],
            stats[j],
            max_iter,
            tol,
            reset,
        )
        status[j] = st
        elapsed[j] = s


@kernel
def static_equilibrium(c, dynamic, phi0, out):
    """Drive-side static equilibrium with kappa = 0 and the TE frozen at phase phi0 (A10).

    Writes positions and zero velocities into ``out`` (10). Bearings deflect by the static mesh
    force F_s along the line of action (and by gravity, if set); U closes Delta = B_d + F_s.
    """
    geo = np.zeros(GEO_SIZE)
    q = np.zeros(5)
    Fs = c[C_FS]
    lam_p = c[C_EPS_P] * c[C_SIG_P] ** 2
    lam_g = c[C_EPS_G] * c[C_SIG_G] ** 2
    psi = c[C_ALPHA0]
    bd = c[C_BC]
    for _it in range(100):
        sp = math.sin(psi)
        cp = math.cos(psi)
        q[0] = -sp * Fs / lam_p
        q[1] = cp * Fs / lam_p - c[C_GP] / lam_p
        q[2] = sp * Fs / lam_g
        q[3] = -cp * Fs / lam_g - c[C_GG] / lam_g
        trans = (q[0] - q[2]) * sp - (q[1] - q[3]) * cp
        q[4] = bd + Fs + c[C_E1] * math.cos(phi0 + c[C_PHI_E]) - trans
        geometry(q, c, dynamic, geo)
        if abs(geo[0] - psi) < 1e-15 and abs(geo[1] - bd) < 1e-15:
            break
        psi = geo[0]
        bd = geo[1]
    for i in range(5):
        out[i] = q[i]
        out[5 + i] = 0.0
