"""The N-period Poincare map of the gear model together with its exact Jacobian (tangent map).

The map is the one every other result uses: the simulator's Newmark-beta step with its Newton
solve (``kernels.newmark_try_t``, the same physics, the same starting guesses, the same step
splitting as ``kernels.integrate_stats``), so ``P`` here (``corrected`` = 0 or 1) equals
``floquet.PeriodMap(located=False)`` bit for bit; ``corrected`` = 2 is the map with contact changes
located inside the step that ``floquet.PeriodMap`` and the continuation use by default.
Alongside every step the variational equations of the *discrete* step are propagated:

* A converged implicit step satisfies ``a1 = A(q1, v1, phi1)`` with ``q1 = q~ + beta h^2 a1`` and
  ``v1 = v~ + gamma h a1`` (predictors ``q~ = q0 + h v0 + (1/2 - beta) h^2 a0``,
  ``v~ = v0 + (1 - gamma) h a0``). Differentiating gives the tangent of the step,

      (I - beta h^2 J_q - gamma h J_v) da1 = J_q dq~ + J_v dv~,

  with ``J = dA/d(q, v)`` at the end of the step: the Newton matrix of the step solved once
  more for 10 right-hand sides (a dense 5x5 elimination; it is the same matrix the kernel's
  Sherman-Morrison solve inverts, plus the small terms of the force direction's dependence on psi).
* ``J`` is that of the contact region the kernel's Newton iteration converged to (``region``), so
  at a contact change inside a step the derivative is one-sided: the one of the branch the
  discrete map actually took. (The backlash force is continuous, so both one-sided derivatives
  describe the same continuous map; they differ only on the kink itself.)
* The start acceleration is ``A(x)`` (``kernels.start_step``), so ``da0 = J(x0) dx0``.

The derivative of the acceleration :func:`accel_jacobian` is written here (the kernels compute
the force, not its full derivative); tests/test_continuation.py checks it against finite
differences of ``kernels.accel``. It takes the force, its branch and slopes, the force
direction, the bearing terms and the line of action from the leaves of ``kernels.mesh`` and
adds the dependence of the force direction and of Delta on psi. Neglected: the second
derivative of psi times the relative displacement perpendicular to the line of action (exactly
zero on every motion of the model, MODEL.md sec. 6).
"""

from __future__ import annotations

import math

import numpy as np

from ..sim import kernels as K

# entries of the ``info`` vector written by :func:`tangent_map`
INFO_U_MAX = 0
INFO_U_MIN = 1
INFO_D_MAX = 2
INFO_D_MIN = 3
INFO_BD_MAX = 4
INFO_BD_MIN = 5
INFO_SWITCHES = 6  # contact-region changes over the interval (step ends, start region included)
INFO_SEP = 7  # fraction of steps ending with the teeth apart
INFO_SPLITS = 8  # steps that needed sub-steps
INFO_BACK = 9  # fraction of steps ending in back-side contact
INFO_LOCATED = 10  # steps split at a located contact change (``corrected`` = 2)
N_INFO = 11


@K.kernel_inline
def accel_jacobian(s, ce, se, omega, kk, k, dynamic, region, J):
    """Derivative of the accelerations ``A(q, v)`` (``kernels.accel``) with respect to (q, v).

    ``s`` is a state tuple (q (5), v (5), ...), ``(ce, se, kk)`` the excitation, ``k`` the
    :func:`kernels.step_consts` tuple and ``region`` the contact region whose branch of the
    backlash function is differentiated (+1 drive, 0 apart, -1 back). Writes ``J`` (5, 10):
    columns 0-4 d/dq, 5-9 d/dv (natural time, dimensionless). Returns the mesh force Fhat.
    """
    delta, ddelta, bd, f, reg0, sp, cp, db0, db1, dp0, dp1 = K.mesh_t(s, ce, se, omega, k, dynamic)
    # the force of the requested branch (continuous across the kink) and its slopes
    F = K.force_t(ddelta, K.backlash_branch(delta, bd, region), kk, k)
    sd, sb = K.backlash_slopes(delta, bd, region)
    dF_ddd = K.force_gradient_t(delta, bd, region, kk, k)[0]  # dF/dDelta'
    fr = K.friction_t(ce, se, k)
    dx = s[0] - s[2]
    dy = s[1] - s[3]
    dvx = s[5] - s[7]
    dvy = s[6] - s[8]
    P = dx * cp + dy * sp
    Q = -dx * sp + dy * cp
    A = dvx * cp + dvy * sp
    psid = dp0 * dvx + dp1 * dvy
    pq = (dp0, dp1, -dp0, -dp1, 0.0)
    g = K.deflection_gradient_t(sp, cp)
    dPq = (cp, sp, -cp, -sp, 0.0)
    dbq = (db0, db1, -db0, -db1, 0.0)
    w0, w1, w2, w3 = K.force_direction_t(sp, cp, fr, k)
    wv = (w0, w1, w2, w3, 1.0)
    dw0, dw1, dw2, dw3 = K.force_direction_dpsi_t(sp, cp, fr, k)
    dw = (dw0, dw1, dw2, dw3, 0.0)
    c_p, c_g, k_p, k_g = K.bearing_t(k)
    dk = (k_p, k_p, k_g, k_g, 0.0)
    dc = (c_p, c_p, c_g, c_g, 0.0)
    for i in range(5):
        for j in range(10):
            J[i, j] = 0.0
    for j in range(5):
        ddel_q = g[j] + P * pq[j]  # dDelta/dq = dDelta'/dv
        dddel_q = (A + psid * Q) * pq[j] + psid * dPq[j]
        df_q = sd * ddel_q + sb * dbq[j]
        dF_q = K.force_t(dddel_q, df_q, kk, k)  # force_t is linear in (Delta', f)
        dF_v = dF_ddd * ddel_q
        for i in range(5):
            J[i, j] = -wv[i] * dF_q - F * dw[i] * pq[j]
            J[i, 5 + j] = -wv[i] * dF_v
        J[j, j] -= dk[j]
        J[j, 5 + j] -= dc[j]
    return F


@K.kernel_inline
def _step_tangent(T, J, s1, ce, se, kk, omega, hc, k, dynamic, region, Mn, R, old_region, theta, J2):
    """Tangent of one converged Newmark step (module docstring): T (15, 10) rows (q, v, a) of the
    start state's derivatives in, of the end state's out. J (5, 10), Mn (5, 5), R (5, 10), J2
    (5, 10) work. With ``theta`` in [0, 1] (crossing-corrected mode) the step crossed from
    ``old_region`` into ``region`` after the fraction theta of its length: the end-of-step
    Jacobian is replaced by (2 theta - 1) J_old + 2 (1 - theta) J_new so that the trapezoidal
    weights of the two regions are theta and 1 - theta, and the acceleration rows are reset to
    J_new (q, v) afterwards. ``theta`` < 0: the exact tangent of the discrete step."""
    h, bh2, gh, hh, h1 = hc[0], hc[1], hc[2], hc[3], hc[4]
    accel_jacobian(s1, ce, se, omega, kk, k, dynamic, region, J)
    if theta >= 0.0:
        for i in range(5):
            for j in range(10):
                J2[i, j] = J[i, j]
        accel_jacobian(s1, ce, se, omega, kk, k, dynamic, old_region, J)
        for i in range(5):
            for j in range(10):
                J[i, j] = (2.0 * theta - 1.0) * J[i, j] + 2.0 * (1.0 - theta) * J2[i, j]
    ncol = T.shape[1]
    for c_ in range(ncol):
        for i in range(5):
            T[i, c_] = T[i, c_] + h * T[5 + i, c_] + hh * T[10 + i, c_]  # dq~
            T[5 + i, c_] = T[5 + i, c_] + h1 * T[10 + i, c_]  # dv~
    for i in range(5):
        for c_ in range(ncol):
            acc = 0.0
            for j in range(5):
                acc += J[i, j] * T[j, c_] + J[i, 5 + j] * T[5 + j, c_]
            R[i, c_] = acc
        for j in range(5):
            Mn[i, j] = -bh2 * J[i, j] - gh * J[i, 5 + j]
        Mn[i, i] += 1.0
    # Gaussian elimination with partial pivoting, 5 x 5, ncol right-hand sides
    for p in range(5):
        piv = p
        for i in range(p + 1, 5):
            if abs(Mn[i, p]) > abs(Mn[piv, p]):
                piv = i
        if piv != p:
            for j in range(5):
                tmp = Mn[p, j]
                Mn[p, j] = Mn[piv, j]
                Mn[piv, j] = tmp
            for c_ in range(ncol):
                tmp = R[p, c_]
                R[p, c_] = R[piv, c_]
                R[piv, c_] = tmp
        inv = 1.0 / Mn[p, p]
        for i in range(p + 1, 5):
            fac = Mn[i, p] * inv
            if fac != 0.0:
                for j in range(p, 5):
                    Mn[i, j] -= fac * Mn[p, j]
                for c_ in range(ncol):
                    R[i, c_] -= fac * R[p, c_]
    for p in range(4, -1, -1):
        inv = 1.0 / Mn[p, p]
        for c_ in range(ncol):
            acc = R[p, c_]
            for j in range(p + 1, 5):
                acc -= Mn[p, j] * R[j, c_]
            R[p, c_] = acc * inv
    for c_ in range(ncol):
        for i in range(5):
            T[10 + i, c_] = R[i, c_]
            T[i, c_] += bh2 * R[i, c_]
            T[5 + i, c_] += gh * R[i, c_]
    if theta >= 0.0:
        for i in range(5):
            for c_ in range(ncol):
                acc = 0.0
                for j in range(5):
                    acc += J2[i, j] * T[j, c_] + J2[i, 5 + j] * T[5 + j, c_]
                T[10 + i, c_] = acc


THETA_FD = 1e-6
"""Step of the central difference in the split fraction theta of a located contact change
(:func:`_located_tangent`)."""


@K.kernel_inline
def _gap_gradient(s, ce, se, omega, k, dynamic, side):
    """d(Delta - side B_d)/dq at the state tuple s (5 entries; the gap does not depend on v)."""
    delta, ddelta, bd, f, reg, sp, cp, db0, db1, dp0, dp1 = K.mesh_t(s, ce, se, omega, k, dynamic)
    g = K.deflection_gradient_t(sp, cp)
    P = (s[0] - s[2]) * cp + (s[1] - s[3]) * sp
    return (
        g[0] + P * dp0 - side * db0,
        g[1] + P * dp1 - side * db1,
        g[2] - P * dp0 + side * db0,
        g[3] - P * dp1 + side * db1,
        g[4],
    )


@K.kernel
def _located_tangent(T, J, J2, Mn, R, Tm, s, sm, wm, a1, th, reg0, side, phi_a, dphi, omega, ce, se, kk, c, k,
                     dynamic, max_iter, tol):  # fmt: skip
    """Take a step split at the located contact change (fraction ``th``, state ``sm`` there, see
    ``kernels.crossing_t``) and propagate T through it, exactly: the tangents of the two parts,
    each on its branch, plus the dependence of the split point on the start state,
    T += dS/dtheta (x) dtheta/dx, with dtheta/dx = -(grad gap . dsm/dx) / (dgap/dtheta) from the
    crossing condition gap(sm) = 0, and dS/dtheta (the change of the step's end state with the split
    point at fixed start) and dgap/dtheta by central differences in theta (:data:`THETA_FD`).
    Returns (ok, end state, F, region, Delta, B_d, sin psi, cos psi)."""
    ok, _sm, _wm, s2, F, region, delta, bd, sp, cp = K.split_at_t(
        s, a1, th, reg0, phi_a, dphi, omega, omega, ce, se, kk, c, k, dynamic, max_iter, tol
    )
    okp, smp, wmp, s2p, _F, _r, _d, _b, _s, _c = K.split_at_t(
        s, a1, th + THETA_FD, reg0, phi_a, dphi, omega, omega, ce, se, kk, c, k, dynamic, max_iter, tol
    )
    okm, smm, wmm, s2m, _F, _r, _d, _b, _s, _c = K.split_at_t(
        s, a1, th - THETA_FD, reg0, phi_a, dphi, omega, omega, ce, se, kk, c, k, dynamic, max_iter, tol
    )
    if not (ok and okp and okm):
        return False, s2, F, region, delta, bd, sp, cp
    cem, sem, kkm = K.excitation(phi_a + th * dphi, c)
    _step_tangent(T, J, sm, cem, sem, kkm, wm, K.step_coeffs(th * dphi / omega, k), k, dynamic, reg0, Mn, R, reg0,
                  -1.0, J2)  # fmt: skip
    ncol = T.shape[1]
    for r_ in range(15):
        for c_ in range(ncol):
            Tm[r_, c_] = T[r_, c_]
    _step_tangent(T, J, s2, ce, se, kk, omega, K.step_coeffs((1.0 - th) * dphi / omega, k), k, dynamic, region, Mn,
                  R, region, -1.0, J2)  # fmt: skip
    cep, sep_, kkp = K.excitation(phi_a + (th + THETA_FD) * dphi, c)
    cen, sen, kkn = K.excitation(phi_a + (th - THETA_FD) * dphi, c)
    mp = K.mesh_t(smp, cep, sep_, omega, k, dynamic)
    mm = K.mesh_t(smm, cen, sen, omega, k, dynamic)
    dgap = ((mp[0] - side * mp[2]) - (mm[0] - side * mm[2])) / (2.0 * THETA_FD)
    if dgap == 0.0:
        return False, s2, F, region, delta, bd, sp, cp
    gg = _gap_gradient(sm, cem, sem, omega, k, dynamic, side)
    for c_ in range(ncol):
        dth = (
            -(gg[0] * Tm[0, c_] + gg[1] * Tm[1, c_] + gg[2] * Tm[2, c_] + gg[3] * Tm[3, c_] + gg[4] * Tm[4, c_]) / dgap
        )
        for r_ in range(15):
            T[r_, c_] += (s2p[r_] - s2m[r_]) / (2.0 * THETA_FD) * dth
    return True, s2, F, region, delta, bd, sp, cp


@K.kernel
def tangent_map(x, omega, n_periods, n_steps, c, dynamic, max_iter, tol, jac, pc, info, corrected):
    """Advance ``x`` (10, in place) by ``n_periods`` mesh periods at constant ``omega`` from mesh
    phase 0 and compute the Jacobian of that map.

    The trajectory is the one of ``kernels.integrate_stats`` (same steps, guesses and splitting).
    Writes ``jac`` (10, 10) = dP^N/dx, ``pc`` (n_periods, 10) the state at the end of every mesh
    period and ``info`` (N_INFO, see ``INFO_*``). Returns the kernel status (``kernels.OK``,
    ``DIVERGED`` or ``NEWTON_FAILED``).

    ``corrected`` = 0: ``jac`` is the exact Jacobian of the discrete map (one-sided at contact
    changes). ``corrected`` = 1: in a step whose end lies in another contact region than its start,
    the crossing is located by linear interpolation of the gap function (Delta - B_d or
    Delta + B_d) and the step's tangent weights the two regions' Jacobians by the time spent in
    each (:func:`_step_tangent`): the monodromy of the ODE to O(h^2) rather than O(h) per contact
    change (the discrete map's own Jacobian jumps each time a contact change moves from one step
    to the next, a sawtooth of ~0.04 in |mu| at 192 steps per period).

    ``corrected`` = 2 (located): a step whose end lies in another contact region than its start is
    split at the contact change, located to 1e-13 of the step (``kernels.crossing_t``): the part
    before it is taken with the force held on the old branch, the rest from the crossing as a
    normal step. The map then changes smoothly with omega and x (no contact change sits inside a
    step), and ``jac`` is the product of the parts' exact tangents, each on its own branch; it
    omits the derivative of the crossing time, whose factor (the change of the step's end with the
    split point) vanishes for the exact flow because the force is continuous at the crossing, so
    ``jac`` is the monodromy of the ODE to O(h^2) and smooth in omega. The trajectory is no longer
    bit-identical to ``kernels.integrate_stats`` (it differs at O(h^2) from the unlocated one).
    """
    k = K.step_consts(c)
    tab = K._excitation_table(0.0, n_steps, c)
    work = np.zeros(K.WORK_SIZE)
    a = np.zeros(K.NDOF)
    K.start_step(x, a, 0.0, omega, c, dynamic, work)
    s = K.load_t(x, a)
    mesh0 = K.mesh_t(s, tab[0, 0], tab[0, 1], omega, k, dynamic)
    reg_prev = mesh0[4]
    T = np.zeros((15, 10))
    Ts = np.zeros((15, 10))
    Tm = np.zeros((15, 10))
    J = np.zeros((5, 10))
    J2 = np.zeros((5, 10))
    Mn = np.zeros((5, 5))
    R = np.zeros((5, 10))
    accel_jacobian(s, tab[0, 0], tab[0, 1], omega, tab[0, 2], k, dynamic, reg_prev, J)
    for i in range(10):
        T[i, i] = 1.0
    for i in range(5):
        for j in range(10):
            T[10 + i, j] = J[i, j]
    u_max = s[4]
    u_min = s[4]
    d_max = mesh0[0]
    d_min = mesh0[0]
    bd_max = mesh0[2]
    bd_min = mesh0[2]
    switches = 0.0
    sep = 0.0
    back = 0.0
    splits = 0.0
    located_n = 0.0
    total = n_periods * n_steps
    dphi = K.TWO_PI / n_steps
    hc = K.step_coeffs(dphi / omega, k)
    g = (a[0], a[1], a[2], a[3], a[4])
    status = K.OK
    d_prev = mesh0[0]
    bd_prev = mesh0[2]
    for j in range(total):
        m = (j + 1) % n_steps
        ok, s1, F, region, delta, bd, sp, cp = K.newmark_try_t(
            s, g, tab[m, 0], tab[m, 1], tab[m, 2], omega, hc, k, dynamic, max_iter, tol
        )
        located = False
        if ok and corrected == 2 and region != reg_prev:
            # split the step at the located contact change: the part before it on the old branch
            side = K.crossing_side_t(reg_prev, region)
            a1 = (s1[10], s1[11], s1[12], s1[13], s1[14])
            located, th, sm, wm, Fm, dm, bdm, spm, cpm = K.crossing_t(
                s, a1, reg_prev, side, d_prev - side * bd_prev, dphi * j, dphi, omega, omega, c, k, dynamic, max_iter,
                tol,
            )  # fmt: skip
            if located:
                located, s2, F, region, delta, bd, sp, cp = _located_tangent(
                    T, J, J2, Mn, R, Tm, s, sm, wm, a1, th, reg_prev, side, dphi * j, dphi, omega, tab[m, 0],
                    tab[m, 1], tab[m, 2], c, k, dynamic, max_iter, tol,
                )  # fmt: skip
                if located:
                    s1 = s2
                    g = K.guess_t(s, s1, True)
                    located_n += 1.0
        if ok and not located:
            theta = -1.0
            if corrected == 1 and region != reg_prev and region * reg_prev == 0:
                sg = float(region + reg_prev)  # the boundary crossed: +1 drive, -1 back side
                g0 = d_prev - sg * bd_prev
                g1 = delta - sg * bd
                if g0 != g1:
                    theta = min(1.0, max(0.0, g0 / (g0 - g1)))
            _step_tangent(
                T, J, s1, tab[m, 0], tab[m, 1], tab[m, 2], omega, hc, k, dynamic, region, Mn, R, reg_prev, theta, J2
            )
            g = K.guess_t(s, s1, dynamic == 0)
        elif not ok:
            # the step again in 2, 4, ... sub-steps, as kernels.split_step_t does, with tangents
            phi_a = dphi * j
            good = False
            for level in range(1, K.MAX_SPLIT_LEVEL + 1):
                nsub = 1 << level
                ss = s
                sub = dphi / nsub
                for r_ in range(15):
                    for c_ in range(10):
                        Ts[r_, c_] = T[r_, c_]
                good = True
                for js in range(nsub):
                    frac = (js + 1.0) / nsub
                    wk = math.sqrt(omega * omega + (omega * omega - omega * omega) * frac)
                    hcs = K.step_coeffs(2.0 * sub / (omega + wk), k)
                    cek, sek, kkk = K.excitation(phi_a + sub * (js + 1.0), c)
                    ga = (ss[10], ss[11], ss[12], ss[13], ss[14])
                    oks, ss, F, region, delta, bd, sp, cp = K.newmark_try_t(
                        ss, ga, cek, sek, kkk, wk, hcs, k, dynamic, max_iter, tol
                    )
                    if not oks:
                        good = False
                        break
                    _step_tangent(Ts, J, ss, cek, sek, kkk, wk, hcs, k, dynamic, region, Mn, R, region, -1.0, J2)
                if good:
                    break
            if not good:
                status = K.NEWTON_FAILED
                break
            for r_ in range(15):
                for c_ in range(10):
                    T[r_, c_] = Ts[r_, c_]
            s1 = ss
            splits += 1.0
            g = K.guess_t(s, s1, True)
        s = s1
        if K._diverged_t(s):
            status = K.DIVERGED
            break
        if region != reg_prev:
            switches += 1.0
        reg_prev = region
        d_prev = delta
        bd_prev = bd
        if region == 0:
            sep += 1.0
        elif region < 0:
            back += 1.0
        u_max = max(u_max, s[4])
        u_min = min(u_min, s[4])
        d_max = max(d_max, delta)
        d_min = min(d_min, delta)
        bd_max = max(bd_max, bd)
        bd_min = min(bd_min, bd)
        if m == 0:
            p = (j + 1) // n_steps - 1
            for i in range(10):
                pc[p, i] = s[i]
    for i in range(10):
        x[i] = s[i]
        for j in range(10):
            jac[i, j] = T[i, j]
    info[INFO_U_MAX] = u_max
    info[INFO_U_MIN] = u_min
    info[INFO_D_MAX] = d_max
    info[INFO_D_MIN] = d_min
    info[INFO_BD_MAX] = bd_max
    info[INFO_BD_MIN] = bd_min
    info[INFO_SWITCHES] = switches
    info[INFO_SEP] = sep / total
    info[INFO_SPLITS] = splits
    info[INFO_BACK] = back / total
    info[INFO_LOCATED] = located_n
    return status


def run_tangent_map(
    x: np.ndarray, omega: float, period: int, steps: int, consts: np.ndarray, code: int, mode: int
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`tangent_map` with its buffers allocated here and the simulator's Newton settings:
    ``period`` mesh periods from the state ``x`` (10, b0 units, natural-time velocities; not modified) at
    constant ``omega`` (Omega/omega_n), ``steps`` Newmark steps per mesh period, ``mode`` its
    ``corrected`` argument (0, 1 or 2 = located). Returns (kernel status, P^N(x) (10,), dP^N/dx (10, 10),
    info (``N_INFO``), the state at the end of every mesh period (period, 10)); the caller checks the
    status and finiteness."""
    from ..sim.integration import NEWTON_MAX_ITER, NEWTON_TOL
    from ..sim.params import C_VC

    if consts[C_VC] != 0.0:
        raise ValueError("the tangent map takes the plain Newmark step (GearParams.velocity_correction = False)")
    y = np.array(x, dtype=float)
    jac = np.empty((K.NSTATE, K.NSTATE))
    pc = np.empty((int(period), K.NSTATE))
    info = np.empty(N_INFO)
    status = tangent_map(
        y, float(omega), int(period), int(steps), consts, int(code), NEWTON_MAX_ITER, NEWTON_TOL, jac, pc, info,
        int(mode),
    )  # fmt: skip
    return int(status), y, jac, info, pc


@K.kernel
def accel_jacobian_array(x, phi, omega, c, dynamic, region, J):
    """Array form of :func:`accel_jacobian` at state ``x`` (10) and mesh phase ``phi`` (for tests).
    ``region`` < -1 means: the region of ``x`` itself. Returns the region used."""
    k = K.step_consts(c)
    ce, se, kk = K.excitation(phi, c)
    s = (x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9])
    if region < -1:
        region = K.mesh_t(s, ce, se, omega, k, dynamic)[4]
    accel_jacobian(s, ce, se, omega, kk, k, dynamic, region, J)
    return region
