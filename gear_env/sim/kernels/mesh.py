"""The gear-bearing model, written once: mesh geometry, backlash, excitation, friction, mesh
force and the equations of motion (MODEL.md sec. 3b), as inline numba leaf functions plus their
array forms.

This is the one file to open to change a physics term. Every path takes its arithmetic from the
leaves here, inlined by numba: the explicit accelerations (:func:`accel`), the Newton residual,
its Jacobian and the dynamic model's Taylor update (``kernels.newmark``), the SIMD lanes
(``gear_env.sim.batch_kernels``, which run the same Newton iteration), the static equilibrium
(:func:`static_equilibrium`) and the tangent map of continuation (``analysis/tangent.py``).

=============================  ======================================================================
term                           leaves (change them together)
=============================  ======================================================================
backlash law (eq. 9)           :func:`backlash`, :func:`backlash_branch`, :func:`backlash_slopes`,
                               :func:`backlash_inverse`
dynamic backlash B_d (eq. 8)   :func:`dynamic_backlash_t` (the paper's law or Yi et al.'s involute law,
                               whose arctangent is the call-free :func:`atan_small_t`)
dynamic geometry (eqs. 5-8)    :func:`geometry_t`, its first-order update :func:`geometry_taylor_t`
torque fluctuation             :func:`external_load_t` (the U row's load), :func:`step_consts_at`;
                               in the loops :func:`load_table` and :func:`with_load_t`
excitation (TE, stiffness)     :func:`excitation`
mesh deflection and rate       :func:`deflection_t`, its gradient :func:`deflection_gradient_t`
mesh force                     :func:`force_t`, its partial derivatives :func:`force_gradient_t`
friction extension             :func:`friction_t`, the tilt in :func:`force_direction_t`
force along the gradient       :func:`mesh_direction_t` (``GearParams.mesh_force_direction``)
bearings, weights, inertia     :func:`bearing_t`, :func:`eom_residual_t`
equations of motion            :func:`eom_residual_t`: r = a + C v + K q + w F - ext (accel = -r(0))
=============================  ======================================================================

``tests/test_physics_once.py`` reads the package's source and fails if a constant of the
equations of motion (``K_IEP`` ... ``K_FS``) is named outside this file or the step constants are
indexed by position, and checks every path against the reference on random states.

``gear_env/sim/reference.py`` states the same equations in readable NumPy (a right-hand side for
SciPy's ``solve_ivp``), written independently from MODEL.md; read it first. ``tests/test_kernels.py``
compares the geometry and the accelerations term by term and ``tests/test_verification.py`` whole
trajectories, so a change made here and not there (or the reverse) fails a test.

Plain arrays and floats in, arrays out; everything dimensionless, in natural time
s = omega_n t; the state is ``x = [X_p, Y_p, X_g, Y_g, U, X_p', Y_p', X_g', Y_g', U']``
(b0 units) and the mesh phase ``phi`` advances at ``omega``.
"""

from __future__ import annotations

import math

import numpy as np
from numba.cpython.unsafe.tuple import tuple_setitem

from ..params import (
    C_A0,
    C_ALPHA0,
    C_BC,
    C_BETA,
    C_COS_A0,
    C_E1,
    C_EPS_G,
    C_EPS_P,
    C_FS,
    C_GG,
    C_GP,
    C_KAPPA,
    C_LOC,
    C_MU,
    C_NE,
    C_NK,
    C_NT,
    C_NU_G,
    C_NU_P,
    C_PH_TG,
    C_PH_TP,
    C_PHI_E,
    C_PHI_K,
    C_R,
    C_SIG_G,
    C_SIG_P,
    C_SIN_A0,
    C_TAIL,
    C_TG1,
    C_TP1,
    C_VC,
    C_XI_BG,
    C_XI_BP,
    C_XI_M,
    FORCE_GRADIENT,
    FOX_GOODWIN_BETA,
    LAW_INVOLUTE,
)
from .jit import kernel, kernel_inline
from .layout import (
    K_A0,
    K_BC,
    K_C_G,
    K_C_P,
    K_COS_A0,
    K_COS_PHI_E,
    K_E1,
    K_EXT_G,
    K_EXT_P,
    K_FS,
    K_IEG,
    K_IEP,
    K_INV_R,
    K_K_G,
    K_K_P,
    K_MU,
    K_R,
    K_SIN_A0,
    K_SIN_PHI_E,
    K_XIM2,
    VC_WEIGHT,
)


@kernel_inline
def step_consts(c):
    """The constants one Newmark step needs, as a tuple of N_K scalars (kept in registers),
    indexed by the ``K_*`` names of ``kernels.layout`` (``k[K_XIM2]`` = 2 xi_m, ...), in this order.

    (1/eps_p, 1/eps_g, pinion and gear bearing damping and stiffness (natural time), the weights
    per unit mass, 2 xi_m, F_s, E1, A0, R, 1/R, B_c, sin and cos alpha0, mu, cos and sin phi_e, Newmark beta).
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
        c[C_BETA],
        c[C_VC] * VC_WEIGHT if c[C_BETA] == FOX_GOODWIN_BETA else 0.0,
        c[C_LOC],
    )


@kernel_inline
def external_load_t(phi, c):
    """The U row's external load (per unit k_m0 b0) at mesh phase ``phi`` of the interval: F_s,
    plus with a fluctuating torque (``GearParams.T_p1``, ``T_g1``; ``c[C_NT]`` = 1)
    A_p sin(nu_p phi + ph_p) + A_g sin(nu_g phi + ph_g), A_j = m_e r_bj T_j1 / (J_j k_m0 b0):
    m_e (r_bp T_p(t)/J_p + r_bg T_g(t)/J_g) / (k_m0 b0), the torques' share of the relative
    acceleration (MODEL.md sec. 3, F_s). nu_j = torque order / z_j (cycles per mesh period); the
    phases ph_j are those at the interval's phase 0 (``GearParams.consts_at_period``)."""
    if c[C_NT] == 0.0:
        return c[C_FS]
    return (
        c[C_FS] + c[C_TP1] * math.sin(c[C_NU_P] * phi + c[C_PH_TP]) + c[C_TG1] * math.sin(c[C_NU_G] * phi + c[C_PH_TG])
    )


@kernel_inline
def torque_fluctuates_t(c):
    """True if the constants ``c`` carry a torque fluctuation (``GearParams.T_p1`` or ``T_g1`` > 0)."""
    return c[C_NT] != 0.0


@kernel_inline
def step_consts_at(k, phi, c, fluctuates):
    """The step constants ``k`` (:func:`step_consts`) for a step ending at mesh phase ``phi``:
    ``k`` itself, unless ``fluctuates`` (:func:`torque_fluctuates_t` (c), read once before a loop of
    steps), then ``k`` with k[K_FS] replaced by :func:`external_load_t` (phi) (the equations of motion
    read the load there, :func:`eom_residual_t`)."""
    if not fluctuates:
        return k
    return tuple_setitem(k, K_FS, external_load_t(phi, c))


@kernel_inline
def with_load_t(k, load, fluctuates):
    """:func:`step_consts_at` with the load given (a row of :func:`load_table`): what the Newmark loops
    use, so that no sine (a library call) sits in a loop of steps (a call there slows every model,
    also with the torque constant, by keeping the loop's registers saved around it)."""
    if not fluctuates:
        return k
    return tuple_setitem(k, K_FS, load)


@kernel
def load_table(phi0, dphi, total, c):
    """:func:`external_load_t` at the ends of ``total`` steps of ``dphi`` from mesh phase ``phi0`` (an
    empty array when the torque is constant: the loops then never read it)."""
    if not torque_fluctuates_t(c):
        return np.empty(0)
    out = np.empty(total)
    for j in range(total):
        out[j] = external_load_t(phi0 + dphi * (j + 1), c)
    return out


@kernel_inline
def excitation(phi, c):
    """The periodic excitation at mesh phase phi: (ce, se, kk).

    The TE enters the deflection as E1 ce and its rate as E1 omega se (:func:`deflection_t`), the
    stiffness factor kk multiplies f(Delta) (:func:`force_t`). Single cosines (the paper's model,
    ``c[C_NK] = c[C_NE] = 0``): ce, se = cos, sin(phi + phi_e) and kk = 1 + kappa cos(phi + phi_k),
    exactly as before the series existed. Fourier series (``GearParams.stiffness_harmonics`` /
    ``te_harmonics``, packed after ``C_TAIL`` as (a_n, b_n) = amplitude (cos, sin) of the phase):
    kk = 1 + sum_n kappa_n cos(n phi + phi_kn) and, with E1 = 1, ce = e(phi)/b0 = sum_n E_n
    cos(n phi + phi_en), se = -de/dphi / b0. cos(n phi), sin(n phi) come from one cos and one sin
    by the angle-addition recurrence, so N harmonics cost two trigonometric calls, not N.
    """
    nk = int(c[C_NK])
    ne = int(c[C_NE])
    if nk == 0 and ne == 0:
        return math.cos(phi + c[C_PHI_E]), math.sin(phi + c[C_PHI_E]), 1.0 + c[C_KAPPA] * math.cos(phi + c[C_PHI_K])
    c1 = math.cos(phi)
    s1 = math.sin(phi)
    cn = 1.0
    sn = 0.0
    kv = 0.0
    ce = 0.0
    se = 0.0
    j = C_TAIL + 2 * nk
    for n in range(1, max(nk, ne) + 1):
        cn, sn = cn * c1 - sn * s1, sn * c1 + cn * s1  # cos, sin(n phi)
        if n <= nk:
            kv += c[C_TAIL + 2 * n - 2] * cn - c[C_TAIL + 2 * n - 1] * sn
        if n <= ne:
            a = c[j + 2 * n - 2]
            b = c[j + 2 * n - 1]
            ce += a * cn - b * sn
            se += n * (a * sn + b * cn)
    if ne == 0:
        ce = math.cos(phi + c[C_PHI_E])
        se = math.sin(phi + c[C_PHI_E])
    if nk == 0:
        kv = c[C_KAPPA] * math.cos(phi + c[C_PHI_K])
    return ce, se, 1.0 + kv


@kernel_inline
def backlash(delta, bd):
    """Dead-zone function f(Delta; B_d) (eq. 9) and its region (+1 drive, 0 apart, -1 back).

    The backlash law is these four functions: this one, :func:`backlash_branch` (f on a given
    branch), :func:`backlash_slopes` (its derivatives, for the Newton and tangent Jacobians) and
    :func:`backlash_inverse` (for the static equilibrium); change them together
    (``tests/test_physics_once.py`` checks that they agree). The branches are written out here
    rather than taken from :func:`backlash_branch`: this function is inlined into every Newton
    iteration, and three nested inlines per copy made the first compile ~20 % longer.
    """
    if delta >= bd:
        return delta - bd, 1
    if delta <= -bd:
        return delta + bd, -1
    return 0.0, 0


@kernel_inline
def backlash_branch(delta, bd, region):
    """f(Delta; B_d) on the branch ``region`` (+1: Delta - B_d, -1: Delta + B_d, 0: 0), also
    outside that branch's range of Delta (the one-sided continuation the tangent map needs)."""
    if region == 0:
        return 0.0
    return delta - region * bd


@kernel_inline
def backlash_slopes(delta, bd, region):
    """Partial derivatives (df/dDelta, df/dB_d) of the dead-zone function :func:`backlash` on the
    branch ``region`` (what the Newton Jacobian differentiates; its one-sided derivative at a kink)."""
    if region == 0:
        return 0.0, 0.0
    return 1.0, -float(region)


@kernel_inline
def backlash_inverse(f, bd):
    """The drive-side deflection Delta >= B_d at which :func:`backlash` gives f >= 0 (used by
    :func:`static_equilibrium`)."""
    return bd + f


@kernel_inline
def atan_small_t(x):
    """atan(x) without a library call: three half-angle reductions atan(x) = 2 atan(x / (1 + sqrt(1 + x^2)))
    bring |x| below tan(pi/16) = 0.199, where 16 terms of the Taylor series are exact to round-off (the
    first omitted term is below 2e-25 of the value)."""
    y = x / (1.0 + math.sqrt(1.0 + x * x))  # written out, no loop: this sits inside the Newmark loops
    y = y / (1.0 + math.sqrt(1.0 + y * y))
    y = y / (1.0 + math.sqrt(1.0 + y * y))
    y2 = y * y
    # sum_{n odd <= 31} (-1)^((n-1)/2) y^(n-1) / n by Horner in y^2, written out
    s = -1.0 / 31.0
    s = 1.0 / 29.0 + y2 * s
    s = -1.0 / 27.0 + y2 * s
    s = 1.0 / 25.0 + y2 * s
    s = -1.0 / 23.0 + y2 * s
    s = 1.0 / 21.0 + y2 * s
    s = -1.0 / 19.0 + y2 * s
    s = 1.0 / 17.0 + y2 * s
    s = -1.0 / 15.0 + y2 * s
    s = 1.0 / 13.0 + y2 * s
    s = -1.0 / 11.0 + y2 * s
    s = 1.0 / 9.0 + y2 * s
    s = -1.0 / 7.0 + y2 * s
    s = 1.0 / 5.0 + y2 * s
    s = -1.0 / 3.0 + y2 * s
    s = 1.0 / 1.0 + y2 * s
    return 8.0 * y * s


@kernel_inline
def dynamic_backlash_t(ad, ta, dalpha_dad, k, law):
    """The dynamic half backlash B_d and dB_d/dA_d at centre distance A_d (b0 units), given
    ta = tan(alpha_d) and dalpha_d/dA_d.

    The paper's law (eq. 8; ``law``, the kernels' model code, without the bit LAW_INVOLUTE):
    B_d = B_c + (A_d - A0) tan(alpha_d). With the bit LAW_INVOLUTE (``GearParams.backlash_law =
    "involute"``), Yi et al. (2019) as in
    ROSS's ``multi_rotor/mesh.py``: B_d = B_c + R (inv alpha_d - inv alpha0), inv a = tan a - a,
    R = (r_bp + r_bg)/b0; dB_d/dA_d = R tan^2(alpha_d) dalpha_d/dA_d. To first order in A_d - A0
    the involute law is (A_d - A0) sin(alpha0) where eq. (8) has tan(alpha0).
    """
    if law & LAW_INVOLUTE:
        R = k[K_R]
        ta0 = k[K_SIN_A0] / k[K_COS_A0]
        # alpha_d - alpha0 = atan(x), x = (ta - ta0) / (1 + ta ta0), by atan_small_t: no libm call in the
        # Newmark loop (a call there costs the constant model too, docs/SIMULATOR.md "Benchmark")
        x = (ta - ta0) / (1.0 + ta * ta0)
        bd = k[K_BC] + R * ((ta - ta0) - atan_small_t(x))
        return bd, R * ta * ta * dalpha_dad
    d = ad - k[K_A0]
    return k[K_BC] + d * ta, ta + d * (1.0 + ta * ta) * dalpha_dad


@kernel_inline
def geometry_t(q0, q1, q2, q3, k, law):
    """Dynamic-model geometry (eqs. 5-8) at positions (X_p, Y_p, X_g, Y_g), no trigonometric call
    (the involute backlash law, bit LAW_INVOLUTE of ``law``, adds two arctangents; :func:`dynamic_backlash_t`).

    Returns (dB/dX_p, dB/dY_p, dpsi/dX_p, dpsi/dY_p, B_d, sin psi, cos psi); the derivatives
    with respect to (X_g, Y_g) are their negatives and those with respect to U are zero. With
    ca = R/A_d, sa = sqrt(1 - ca^2) = sqrt(A_d^2 - R^2)/A_d (alpha_d), cz = d1/A_d and
    z = -d2/A_d (the arcsin term): sin psi = sa cz + ca z and cos psi = ca cz - sa z. Two square
    roots and one division (divisions and roots are the dearest operations of a step).
    """
    A0 = k[K_A0]
    R = k[K_R]
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
    ta = rs * k[K_INV_R]
    cz = d1 * iad
    z = -d2 * iad
    sp = sa * cz + ca * z
    cp = ca * cz - sa * z
    dalpha_dad = ca * iad * cz * inv  # ca / (A_d sa)
    icz = sa * inv
    bd, db_dad = dynamic_backlash_t(ad, ta, dalpha_dad, k, law)
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
def geometry_taylor_t(bd, sp, cp, db0, db1, dp0, dp1, ex, ey, scale):
    """First-order update of the dynamic geometry (:func:`geometry_t`) when the pinion moves by
    scale (ex, ey) relative to the gear: returns (B_d, sin psi, cos psi) at the new positions
    from those and the derivatives (dB/dX_p, dB/dY_p, dpsi/dX_p, dpsi/dY_p) at the old ones."""
    dpsi = scale * (dp0 * ex + dp1 * ey)
    bd1 = bd + scale * (db0 * ex + db1 * ey)
    return bd1, sp + cp * dpsi, cp - sp * dpsi


@kernel_inline
def mesh_t(s, ce, se, omega, k, dynamic):
    """Mesh quantities of a state tuple s = (q0..q4, v0..v4, ...) at one instant.

    Returns (Delta, Delta', B_d, f(Delta), region, sin psi, cos psi, dB/dX_p, dB/dY_p, dpsi/dX_p,
    dpsi/dY_p).
    """
    if dynamic == 0:
        sp = k[K_SIN_A0]
        cp = k[K_COS_A0]
        bd = k[K_BC]
        db0 = 0.0
        db1 = 0.0
        dp0 = 0.0
        dp1 = 0.0
    else:
        db0, db1, dp0, dp1, bd, sp, cp = geometry_t(s[0], s[1], s[2], s[3], k, dynamic)
    delta, ddelta = deflection_t(s, sp, cp, dp0, dp1, ce, se, omega, k, dynamic)
    f, region = backlash(delta, bd)
    return delta, ddelta, bd, f, region, sp, cp, db0, db1, dp0, dp1


@kernel_inline
def deflection_t(s, sp, cp, dp0, dp1, ce, se, omega, k, dynamic):
    """Mesh deflection Delta along the line of action and its rate Delta' (MODEL.md sec. 3) at a state tuple
    s = (q0..q4, v0..v4, ...), given sin and cos psi and (dynamic model) dpsi/dX_p, dpsi/dY_p; the
    dynamic model adds the psi' term psi' (dx cos psi + dy sin psi). Returns (Delta, Delta')."""
    dx = s[0] - s[2]
    dy = s[1] - s[3]
    e1 = k[K_E1]
    delta = dx * sp - dy * cp + s[4] - e1 * ce
    ddelta = (s[5] - s[7]) * sp - (s[6] - s[8]) * cp + s[9] + e1 * omega * se
    if dynamic != 0:
        psid = dp0 * (s[5] - s[7]) + dp1 * (s[6] - s[8])
        ddelta += psid * (dx * cp + dy * sp)
    return delta, ddelta


@kernel_inline
def deflection_gradient_t(sp, cp):
    """g = dDelta/dq = dDelta'/dv on (X_p, Y_p, X_g, Y_g, U) of :func:`deflection_t` with psi
    frozen (the line of action; the psi-dependence is left to ``analysis/tangent.py``)."""
    return sp, -cp, -sp, cp, 1.0


@kernel_inline
def force_t(ddelta, f, kk, k):
    """Mesh force Fhat = 2 xi_m Delta' + (1 + kappa cos(phi + phi_k)) f(Delta) (MODEL.md sec. 3, natural
    time); ``kk`` is the stiffness factor, ``f`` the dead-zone function :func:`backlash`."""
    return k[K_XIM2] * ddelta + kk * f


@kernel_inline
def force_gradient_t(delta, bd, region, kk, k):
    """Partial derivatives of the mesh force :func:`force_t` on the backlash branch ``region``:
    (dF/dDelta', dF/dDelta, dF/dB_d), from :func:`backlash_slopes`."""
    sd, sb = backlash_slopes(delta, bd, region)
    return k[K_XIM2], kk * sd, kk * sb


FRICTION_SHARPNESS = 10.0


@kernel_inline
def friction_t(ce, se, k):
    """[friction extension, GearParams.friction] mu s(phi), s = tanh(10 sin phi): the tangential
    (off line-of-action) tooth friction force per unit mesh force. ``ce, se`` = cos, sin(phi + phi_e).
    The friction force mu s F acts on the pinion along (cos psi, sin psi) and on the gear opposite;
    its moment on the gears is neglected. Returns 0 when friction is off (the paper's model)."""
    mu = k[K_MU]
    if mu == 0.0:
        return 0.0
    return mu * math.tanh(FRICTION_SHARPNESS * (se * k[K_COS_PHI_E] - ce * k[K_SIN_PHI_E]))


# ---- the equations of motion -----------------------------------------------------------------
# Written once, in residual form r(a, q, v) = a + C v + K q + w F - ext = 0 (per unit mass, natural
# time): :func:`accel` is a = -r(0, q, v), the Newton iteration of ``kernels.newmark`` drives r to
# zero with the Jacobian assembled from :func:`bearing_t`, :func:`deflection_gradient_t`,
# :func:`force_gradient_t` and :func:`force_direction_t`, and :func:`static_equilibrium` solves
# r(0, q, 0) = 0. The SIMD path (``gear_env.sim.batch_kernels``) runs the same Newton iteration.


@kernel_inline
def bearing_t(k):
    """Bearing damping and stiffness per unit mass (the diagonal C and K of the equations of
    motion, natural time): (pinion damping, gear damping, pinion stiffness, gear stiffness),
    each acting on X and Y; U has none."""
    return k[K_C_P], k[K_C_G], k[K_K_P], k[K_K_G]


@kernel_inline
def force_direction_t(sp, cp, fr, k):
    """w = M^-1 g_F: the generalised force of a unit mesh force on (X_p, Y_p, X_g, Y_g) per unit
    mass (on U it is 1). Along the line of action (sin psi, -cos psi) on the pinion and opposite
    on the gear, tilted by the friction extension's fr = mu s(phi) (:func:`friction_t`)."""
    iep = k[K_IEP]
    ieg = k[K_IEG]
    return (
        (sp - fr * cp) * iep,
        -(cp + fr * sp) * iep,
        -(sp - fr * cp) * ieg,
        (cp + fr * sp) * ieg,
    )


@kernel_inline
def mesh_direction_t(sp, cp, fr, k, dynamic, region, db0, db1, dp0, dp1, dx, dy):
    """w of the equations of motion for the kernels' model code ``dynamic``: :func:`force_direction_t`
    (eq. 10: along the line of action, psi frozen), unless the code has the bit FORCE_GRADIENT
    (``GearParams.mesh_force_direction = "gradient"``, ROSS's force): then the mesh force acts along
    the gradient of Delta - region B_d, so w also has d(Delta)/dpsi dpsi/dq = (dx cos psi + dy sin psi)
    dpsi/dq and -region dB_d/dq on (X_p, Y_p), their negatives on (X_g, Y_g) (dx, dy = X_p - X_g,
    Y_p - Y_g; dB_d/dq, dpsi/dq from :func:`geometry_t`; region 0, the teeth apart, keeps the psi term
    for the damping force). With the gradient the mesh force derives from the potential
    k f(Delta - region B_d)^2 / 2, as in ROSS's ``multi_rotor/mesh.py``."""
    w0, w1, w2, w3 = force_direction_t(sp, cp, fr, k)
    if not dynamic & FORCE_GRADIENT:
        return w0, w1, w2, w3
    P = dx * cp + dy * sp
    g0 = P * dp0 - region * db0
    g1 = P * dp1 - region * db1
    iep = k[K_IEP]
    ieg = k[K_IEG]
    return w0 + g0 * iep, w1 + g1 * iep, w2 - g0 * ieg, w3 - g1 * ieg


@kernel_inline
def force_direction_dpsi_t(sp, cp, fr, k):
    """dw/dpsi: derivative of :func:`force_direction_t` with respect to the meshing angle psi
    (friction factor fr held fixed)."""
    iep = k[K_IEP]
    ieg = k[K_IEG]
    return (
        (cp + fr * sp) * iep,
        (sp - fr * cp) * iep,
        -(cp + fr * sp) * ieg,
        -(sp - fr * cp) * ieg,
    )


@kernel_inline
def eom_residual_t(acc, state, force, direction, k):
    """Residual of the equations of motion (MODEL.md sec. 3b) r = a + C v + K q + w F - ext.

    ``acc`` = (a_0..a_4), ``state`` = (q_0..q_4, v_0..v_4, ...), ``force`` the mesh force Fhat
    (:func:`force_t`), ``direction`` = w (:func:`force_direction_t`). Bearings (:func:`bearing_t`)
    on X and Y, the weights ``ext`` on Y, and on U: r_4 = a_4 + F - F_s. Returns (r_0..r_4).
    """
    c_p, c_g, k_p, k_g = bearing_t(k)
    w0, w1, w2, w3 = direction
    return (
        acc[0] + c_p * state[5] + k_p * state[0] + w0 * force,
        acc[1] + c_p * state[6] + k_p * state[1] + w1 * force - k[K_EXT_P],
        acc[2] + c_g * state[7] + k_g * state[2] + w2 * force,
        acc[3] + c_g * state[8] + k_g * state[3] + w3 * force - k[K_EXT_G],
        acc[4] + force - k[K_FS],
    )


@kernel_inline
def psi_t(sp, cp, c, dynamic):
    """Meshing angle psi [rad] from sin and cos psi (alpha0 exactly for the constant model)."""
    if dynamic == 0:
        return c[C_ALPHA0]
    return math.atan2(sp, cp)


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
    db0, db1, dp0, dp1, bd, sp, cp = geometry_t(q[0], q[1], q[2], q[3], step_consts(c), dynamic)
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


@kernel
def accel(q, v, ce, se, omega, kk, c, dynamic, geo, a):
    """Accelerations a = q'' (natural time) at one instant; returns the mesh force Fhat.

    ``kk`` = 1 + kappa cos(phi + phi_k) is the stiffness factor; psi is left in geo[0]. The U row's
    load is the mean F_s (a fluctuating torque's phase is not an argument here: the drivers apply it,
    :func:`step_consts_at`).
    """
    k = step_consts(c)
    delta, ddelta, bd, f, region = mesh_state(q, v, ce, se, omega, c, dynamic, geo)
    F = force_t(ddelta, f, kk, k)
    fr = friction_t(ce, se, k)  # [friction extension] 0 unless GearParams.friction > 0
    w = mesh_direction_t(
        geo[12], geo[13], fr, k, dynamic, region, geo[2], geo[3], geo[7], geo[8], q[0] - q[2], q[1] - q[3]
    )
    s = (q[0], q[1], q[2], q[3], q[4], v[0], v[1], v[2], v[3], v[4])
    r = eom_residual_t((0.0, 0.0, 0.0, 0.0, 0.0), s, F, w, k)  # a = -r(0, q, v)
    for i in range(5):
        a[i] = -r[i]
    return F


@kernel
def static_equilibrium(c, dynamic, phi0, out):
    """Drive-side static equilibrium with kappa = 0 and the TE (and a fluctuating torque) frozen at
    phase phi0 (A10).

    Writes positions and zero velocities into ``out`` (10). Solves the equations of motion at
    rest, r(0, q, 0) = 0 (:func:`eom_residual_t`): its U row gives F = F_s; for that force the
    bearing rows are linear in the bearing positions (q_i = -r_i(q = 0) / K_i), and U closes
    Delta = B_d + F_s (:func:`backlash_inverse`). The dynamic model's geometry depends on the
    positions, so the solve repeats until psi and B_d no longer change (with the gradient force,
    :func:`mesh_direction_t`, the force direction follows the last iterate's geometry).
    """
    k = step_consts_at(step_consts(c), phi0, c, torque_fluctuates_t(c))  # the torques frozen at phi0 too
    ce, se, _kk = excitation(phi0, c)
    fr = friction_t(ce, se, k)
    Fs = k[K_FS]
    _c_p, _c_g, k_p, k_g = bearing_t(k)
    rest = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    sp = k[K_SIN_A0]
    cp = k[K_COS_A0]
    bd = k[K_BC]
    db0 = db1 = dp0 = dp1 = 0.0
    s = rest
    for _it in range(100):
        w = mesh_direction_t(sp, cp, fr, k, dynamic, 1, db0, db1, dp0, dp1, s[0] - s[2], s[1] - s[3])
        r = eom_residual_t(rest, rest, Fs, w, k)
        s = (-r[0] / k_p, -r[1] / k_p, -r[2] / k_g, -r[3] / k_g, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        delta0, _dd = deflection_t(s, sp, cp, 0.0, 0.0, ce, se, 0.0, k, 0)  # Delta with U = 0
        s = (s[0], s[1], s[2], s[3], backlash_inverse(Fs, bd) - delta0, 0.0, 0.0, 0.0, 0.0, 0.0)
        if dynamic == 0:
            break
        db0, db1, dp0, dp1, bd1, sp1, cp1 = geometry_t(s[0], s[1], s[2], s[3], k, dynamic)
        if abs(sp1 - sp) < 1e-15 and abs(cp1 - cp) < 1e-15 and abs(bd1 - bd) < 1e-15:
            break
        sp = sp1
        cp = cp1
        bd = bd1
    for i in range(10):
        out[i] = s[i]
