"""numba kernel that advances a batch of independent gear systems with SIMD across the batch.

:func:`integrate_stats_lanes` does what ``kernels.integrate_stats_batch`` does (every system by
the same number of mesh periods, each with its own omega ramp and constants) and returns the same
numbers bit for bit, but it steps all systems together, one Newmark step at a time, with the state
held in structure-of-arrays form (one row per state component, one column per system). The
systems are "lanes": the common case of a step (predictor, one Newton iteration, the dynamic
model's Taylor update, the statistics) is a loop over lanes without calls or early exits, which
LLVM vectorises (4 lanes per AVX2 instruction). The rare lanes whose first Newton iteration did
not finish (a contact change inside the step, a long step at low omega, a step to be split, the
friction extension) are then finished one by one with the scalar Newton iteration
(``kernels.newmark_resume_t``, which goes on from the lanes' first iteration, or ``kernels.newmark_try_t``
from the start where friction is on or the iteration failed); a step that Newton does not finish at
all (rarer still) stops the kernel, is split into sub-steps from Python (:func:`_split_lane`, compiled on first need, as
``kernels.split_resume`` for one system) and the kernel goes on. So every lane follows exactly
the arithmetic of the scalar kernel.

Why it matters: a Newmark step of the dynamic model is ~300 floating-point operations with 2-4
divisions and square roots, limited by instruction throughput (``benchmarks/kernel_interleave.py``
shows that two independent trajectories interleaved in one scalar loop run no faster). SIMD lanes
are the way to more operations per cycle. The vector environment uses this kernel.
"""

from __future__ import annotations

import math

import numpy as np

from . import kernels as K
from .kernels import kernel, kernel_inline

LANES = 16
"""Most systems stepped together: a block of up to LANES lanes lives in one (N_ROWS, LANES) buffer
whose row stride is a compile-time constant, so LLVM proves that its rows do not overlap and
vectorises the loops over lanes (whose trip count is the block's lane count, padded to a multiple
of PAD)."""
PAD = 8
"""A block's lane count is padded to a multiple of PAD with copies of its last system (never live): LLVM runs the lane
loops 8 doubles at a time (AVX-512, or AVX2 unrolled twice) and the rest in a scalar epilogue, so a block of 4 or
12 lanes padded only to 4 cost more than one of 8 or 16 (a vector env of 4 ran 1.65x the env-steps/s padded to 8,
of 12 1.55x: ``benchmarks/ab_compare.py --only env-vec-4 env-vec-12``, docs/BENCHMARKS.md)."""
N_K = K.N_K  # length of kernels.step_consts
# rows of the block buffer: state (q, v, a), Newton guess, their copies from before the step,
# step constants, then the rest
R_S = 0
R_G = R_S + K.NSTATE + K.NDOF
R_OLD = R_G + K.NDOF
R_K = R_OLD + K.NSTATE + 2 * K.NDOF
# step outputs
# (O_HL: the natural time of the step's last part, what the corrected velocity of a Poincare sample takes
# (newmark.output_t): the step's own, that of the part after a located contact change, 0 after a split step;
# O_RESUME: 1 where the first Newton iteration returned NEWTON_MORE without friction, so that the scalar redo
# resumes from its iterate, newmark.newmark_resume_t; O_DMAX: that iteration's largest update)
O_F, O_REG, O_DELTA, O_BD, O_SP, O_CP, O_H, O_WB, O_DONE, O_SPLIT, O_BAD, O_HL, O_RESUME, O_DMAX = range(
    R_K + N_K, R_K + N_K + 14
)
# accumulators (as in kernels.integrate_stats_tab) and per-lane settings
(
    Q_T, Q_N, Q_NSPLIT, Q_SEP, Q_BACK, Q_BACK_IMP, Q_DRIVE_IMP, Q_FSUM, Q_FSQ, Q_TRSQ, Q_RPMAX,
    Q_FMAX, Q_FMIN, Q_UMAX, Q_UMIN, Q_DMAX, Q_DMIN, Q_BDMAX, Q_BDMIN, Q_SPMAX, Q_SPMIN,
    Q_FPREV, Q_TRPREV, Q_REGPREV, Q_EL, Q_LIVE, Q_W0, Q_WW, Q_WA, Q_DPREV, Q_BDPREV,
) = range(O_DMAX + 1, O_DMAX + 32)  # fmt: skip
# per-lane step counts: steps per mesh period, its phase step, the excitation row of the step's end (the lane's own
# (j + 1) mod steps) and the excitation there (copied from TB before the first pass, so that it reads rows); Q_SYS: the
# system the lane steps (a lane's column moves when a mixed block is compacted, see _compact)
Q_NS, Q_DPHI, Q_M, Q_CE, Q_SE, Q_KK, Q_SYS = range(Q_BDPREV + 1, Q_BDPREV + 8)
N_ROWS = Q_SYS + 1


@kernel_inline
def _lane_k(B, e):
    """The step constants (``kernels.step_consts``, N_K = 23 of them) of lane e, rows R_K, R_K + 1, ...

    Written out: ``to_fixed_tuple`` of the column slice gives the same numbers but stops LLVM from
    vectorising the lane loop (3x slower in an interleaved A/B run, benchmarks/ab_compare.py)."""
    r = R_K
    return (
        B[r, e], B[r + 1, e], B[r + 2, e], B[r + 3, e], B[r + 4, e], B[r + 5, e], B[r + 6, e], B[r + 7, e],
        B[r + 8, e], B[r + 9, e], B[r + 10, e], B[r + 11, e], B[r + 12, e], B[r + 13, e], B[r + 14, e],
        B[r + 15, e], B[r + 16, e], B[r + 17, e], B[r + 18, e], B[r + 19, e], B[r + 20, e], B[r + 21, e],
        B[r + 22, e],
    )  # fmt: skip


@kernel_inline
def _lane_s(B, e, r=R_S):
    """State tuple (q, v, a) of lane e (from rows r, r + 1, ...)."""
    return (
        B[r, e], B[r + 1, e], B[r + 2, e], B[r + 3, e], B[r + 4, e], B[r + 5, e], B[r + 6, e], B[r + 7, e],
        B[r + 8, e], B[r + 9, e], B[r + 10, e], B[r + 11, e], B[r + 12, e], B[r + 13, e], B[r + 14, e],
    )  # fmt: skip


@kernel_inline
def _lane_g(B, e, r=R_G):
    """Newton's starting guess of lane e (from rows r, ..., r + 4)."""
    return (B[r, e], B[r + 1, e], B[r + 2, e], B[r + 3, e], B[r + 4, e])


@kernel_inline
def _first_pass(B, nl, jj, dynamic, tol):
    """One Newmark step of every lane with a single Newton iteration (vectorised loop).

    Every lane's state and guess are overwritten with the result (the pre-step ones are copied to
    the R_OLD rows); O_DONE = 1 where the iteration finished the step. ``jj`` = step index + 1; each lane's
    phase step and its step's excitation are in its rows Q_DPHI and Q_CE, Q_SE, Q_KK.

    Stores are unconditional on purpose: ``x = new if ok else x`` becomes a masked store, which
    is microcoded and slow on AMD Zen. Returns the number of lanes whose iteration did not finish (an
    integer sum, which keeps the loop vectorised), so that the scalar scan for them can be skipped.
    """
    nredo = 0
    for e in range(nl):
        k = _lane_k(B, e)
        w0 = B[Q_W0, e]
        ww = B[Q_WW, e]
        wa = B[Q_WA, e]
        wb = w0 if ww == 0.0 else math.sqrt(w0 * w0 + ww * jj)
        hc = K.step_coeffs(2.0 * B[Q_DPHI, e] / (wa + wb), k)
        s = _lane_s(B, e)
        g = _lane_g(B, e)
        ce = B[Q_CE, e]
        se = B[Q_SE, e]
        kk = B[Q_KK, e]
        pv, t, mesh = K.newton_start_t(s, g, ce, se, wb, hc, k, dynamic)
        code, a, t, mesh, fin, dmax = K.newton_iter_t(pv, g, t, mesh, ce, se, kk, wb, hc, k, dynamic, tol, True, False)
        ok = code == K.NEWTON_DONE and k[K.K_MU] == 0.0  # steps with friction: redone by the scalar path
        more = code == K.NEWTON_MORE and k[K.K_MU] == 0.0  # the scalar redo resumes from this iterate
        # the pre-step state and guess, for the scalar redo (written out: a loop here over the
        # tuple stops the vectorisation)
        B[R_OLD + 0, e] = s[0]
        B[R_OLD + 1, e] = s[1]
        B[R_OLD + 2, e] = s[2]
        B[R_OLD + 3, e] = s[3]
        B[R_OLD + 4, e] = s[4]
        B[R_OLD + 5, e] = s[5]
        B[R_OLD + 6, e] = s[6]
        B[R_OLD + 7, e] = s[7]
        B[R_OLD + 8, e] = s[8]
        B[R_OLD + 9, e] = s[9]
        B[R_OLD + 10, e] = s[10]
        B[R_OLD + 11, e] = s[11]
        B[R_OLD + 12, e] = s[12]
        B[R_OLD + 13, e] = s[13]
        B[R_OLD + 14, e] = s[14]
        B[R_OLD + 15, e] = g[0]
        B[R_OLD + 16, e] = g[1]
        B[R_OLD + 17, e] = g[2]
        B[R_OLD + 18, e] = g[3]
        B[R_OLD + 19, e] = g[4]
        s1 = K.state_vc_t(t, a[0], a[1], a[2], a[3], a[4], s, k[K.K_VC] * hc[0])  # Newmark's v (newmark.state_t)
        for i in range(K.NSTATE):
            B[R_S + i, e] = s1[i]
        for i in range(K.NDOF):
            an = a[i]
            B[R_S + K.NSTATE + i, e] = an
            # next guess: linear extrapolation (dynamic model), the acceleration itself (constant)
            B[R_G + i, e] = an if dynamic == 0 else 2.0 * an - s[K.NSTATE + i]
        B[O_F, e] = fin[0]
        B[O_REG, e] = float(fin[1])
        B[O_DELTA, e] = fin[2]
        B[O_BD, e] = fin[3]
        B[O_SP, e] = fin[4]
        B[O_CP, e] = fin[5]
        B[O_H, e] = hc[0]
        B[O_HL, e] = hc[0]
        B[O_WB, e] = wb
        B[O_DONE, e] = 1.0 if ok else 0.0
        B[O_RESUME, e] = 1.0 if more else 0.0
        B[O_DMAX, e] = dmax
        B[O_SPLIT, e] = 0.0
        nredo += 0 if ok else 1
    return nredo


@kernel_inline
def _check_pass(B, nl):
    """Elapsed time and the divergence check of every lane after a step (vectorised loop):
    O_BAD = 1 where the state is non-finite or |q|_1 + |v|_1 > DIVERGENCE_LIMIT
    (``kernels._diverged_t``). Returns the number of such lanes."""
    nbad = 0
    for e in range(nl):
        B[Q_EL, e] += B[O_H, e]
        m = abs(B[0, e]) + abs(B[1, e]) + abs(B[2, e]) + abs(B[3, e]) + abs(B[4, e])
        m += abs(B[5, e]) + abs(B[6, e]) + abs(B[7, e]) + abs(B[8, e]) + abs(B[9, e])
        good = m <= K.DIVERGENCE_LIMIT
        B[O_BAD, e] = 0.0 if good else 1.0
        nbad += 0 if good else 1
    return nbad


@kernel_inline
def _stats_pass(B, nl):
    """Interval statistics of every lane after a step (vectorised loop), the loop body of
    ``kernels.integrate_stats_tab``. Lanes are not masked: a lane that stopped was retired with
    its statistics before, and what this adds to it afterwards is never read.

    No branches and no ``x = y if c else x`` (LLVM turns that into a masked store, microcoded and
    slow on AMD Zen): region tests multiply by 0/1, and the extremes are stored as
    ``max(x, y) + 0.0``, which differs from ``max(x, y)`` only by the sign of a zero.
    """
    for e in range(nl):
        h = B[O_H, e]
        F = B[O_F, e]
        region = B[O_REG, e]
        delta = B[O_DELTA, e]
        bd = B[O_BD, e]
        sp = B[O_SP, e]
        reg_prev = B[Q_REGPREV, e]
        F_prev = B[Q_FPREV, e]
        q0, q1, q2, q3, q4 = B[0, e], B[1, e], B[2, e], B[3, e], B[4, e]
        rpp = q0 * q0 + q1 * q1
        rpg = q2 * q2 + q3 * q3
        tr = 0.5 * (rpp + rpg)
        apart = 1.0 if region == 0.0 else 0.0
        back = 1.0 if region < 0.0 else 0.0
        B[Q_T, e] += h
        B[Q_N, e] += 1.0
        B[Q_NSPLIT, e] += B[O_SPLIT, e]
        B[Q_SEP, e] += h * apart
        B[Q_BACK, e] += h * back
        B[Q_BACK_IMP, e] += back * (1.0 if reg_prev >= 0.0 else 0.0)
        B[Q_DRIVE_IMP, e] += (1.0 if region > 0.0 else 0.0) * (1.0 if reg_prev == 0.0 else 0.0)
        B[Q_FSUM, e] += 0.5 * h * (F + F_prev)
        B[Q_FSQ, e] += 0.5 * h * (F * F + F_prev * F_prev)
        B[Q_TRSQ, e] += 0.5 * h * (tr + B[Q_TRPREV, e])
        B[Q_RPMAX, e] = max(B[Q_RPMAX, e], max(rpp, rpg)) + 0.0
        B[Q_FMAX, e] = max(B[Q_FMAX, e], F) + 0.0
        B[Q_FMIN, e] = min(B[Q_FMIN, e], F) + 0.0
        B[Q_UMAX, e] = max(B[Q_UMAX, e], q4) + 0.0
        B[Q_UMIN, e] = min(B[Q_UMIN, e], q4) + 0.0
        B[Q_DMAX, e] = max(B[Q_DMAX, e], delta) + 0.0
        B[Q_DMIN, e] = min(B[Q_DMIN, e], delta) + 0.0
        B[Q_BDMAX, e] = max(B[Q_BDMAX, e], bd) + 0.0
        B[Q_BDMIN, e] = min(B[Q_BDMIN, e], bd) + 0.0
        B[Q_SPMAX, e] = max(B[Q_SPMAX, e], sp) + 0.0
        B[Q_SPMIN, e] = min(B[Q_SPMIN, e], sp) + 0.0
        B[Q_FPREV, e] = F
        B[Q_TRPREV, e] = tr
        B[Q_REGPREV, e] = region
        B[Q_DPREV, e] = delta
        B[Q_BDPREV, e] = bd
        B[Q_WA, e] = B[O_WB, e]


@kernel
def _redo_lane(B, TB, el, m, j, dphi, c, dynamic, max_iter, tol):
    """Step j of lane el again from its pre-step state (R_OLD rows) with the scalar Newton
    iteration (``kernels.newmark_try_t``: the same first iteration, then more; from the first pass's iterate on,
    ``kernels.newmark_resume_t``, where that iteration returned NEWTON_MORE without friction) and store the
    result like :func:`_first_pass`. Returns OK, or SPLIT_PENDING if Newton does not finish the
    step: then :func:`_split_lane`, compiled on first need, takes it in sub-steps (as
    ``kernels.newmark_step_t`` would). Compiled apart from the vectorised loops (it is rare, and
    inlining it doubles the compile time)."""
    k = _lane_k(B, el)
    wa = B[Q_WA, el]
    wb = B[O_WB, el]
    hc = K.step_coeffs(2.0 * dphi / (wa + wb), k)
    s = _lane_s(B, el, R_OLD)
    if B[O_RESUME, el] != 0.0:  # from the first iteration's iterate (the accelerations of the R_S rows)
        ok, s1, F, region, delta, bd, sp, cp = K.newmark_resume_t(
            s, _lane_g(B, el, R_S + K.NSTATE), B[O_DMAX, el], np.int64(B[O_REG, el]), TB[m, 0, el], TB[m, 1, el],
            TB[m, 2, el], wb, hc, k, dynamic, max_iter, tol,
        )  # fmt: skip
    else:
        ok, s1, F, region, delta, bd, sp, cp = K.newmark_try_t(
            s, _lane_g(B, el, R_OLD + K.NSTATE + K.NDOF), TB[m, 0, el], TB[m, 1, el], TB[m, 2, el], wb, hc, k,
            dynamic, max_iter, tol,
        )  # fmt: skip
    if not ok:
        return K.SPLIT_PENDING
    _store_lane(B, el, s, s1, F, region, delta, bd, sp, cp, 0, dynamic)
    return K.OK


@kernel_inline
def _store_lane(B, el, s, s1, F, region, delta, bd, sp, cp, split, dynamic):
    """Lane el's step result (new state tuple s1 from s) into the block buffer, as
    :func:`_first_pass` stores it."""
    ng = K.guess_t(s, s1, split != 0 or dynamic == 0)
    for i in range(K.NSTATE + K.NDOF):
        B[R_S + i, el] = s1[i]
    for i in range(K.NDOF):
        B[R_G + i, el] = ng[i]
    B[O_F, el] = F
    B[O_REG, el] = float(region)
    B[O_DELTA, el] = delta
    B[O_BD, el] = bd
    B[O_SP, el] = sp
    B[O_CP, el] = cp
    B[O_SPLIT, el] = float(split)


@kernel
def _split_lane(B, el, j, dphi, c, dynamic, max_iter, tol):
    """Step j of lane el (block buffer B as :func:`_integrate` saved it at SPLIT_PENDING) in
    2, 4, ... sub-steps (``kernels.split_step_t``), stored like :func:`_redo_lane`. Returns the
    step's status. Called from Python (:func:`integrate_stats_lanes`), so the second copy of the
    Newmark step in ``split_step_t`` (~5-9 s of compile) is compiled only when a step first needs
    it, and is the copy that the single-system entry (``kernels.split_resume``) uses."""
    k = _lane_k(B, el)
    wa = B[Q_WA, el]
    wb = B[O_WB, el]
    s = _lane_s(B, el, R_OLD)
    st, s1, F, region, delta, bd, sp, cp, split = K.split_step_t(
        s, dphi * j, dphi, wa, wb, c, k, dynamic, max_iter, tol
    )
    if st != K.OK:
        return st
    _store_lane(B, el, s, s1, F, region, delta, bd, sp, cp, split, dynamic)
    B[O_HL, el] = 0.0  # its Poincare sample: Newmark's velocity (as kernels.split_resume stores it)
    return K.OK


@kernel
def _locate_lane(B, TB, el, m, j, n_steps, dphi, c, dynamic, max_iter, tol):
    """Step j of lane el changed the contact region and the lane locates contact changes (``K_LOC``): take it
    again from its pre-step state (R_OLD rows), split at the crossing (``kernels.located_step_t``, as
    ``kernels.stats_segment`` does), and store the result like :func:`_redo_lane` (a located step counts as split);
    the R_OLD accelerations become those at the start of the step's last part, for its Poincare sample. A step in
    which no crossing is found keeps its unlocated result (a lane that corrects kinks, ``kernels.corrects_kink``, takes
    :func:`_correct_lane` instead). Compiled apart from the vectorised loops (rare)."""
    k = _lane_k(B, el)
    s = _lane_s(B, el, R_OLD)
    ja = j % n_steps
    s1, F, region, delta, bd, sp, cp, h, nloc, sa, hl = K.located_fixed_step(
        s, _lane_s(B, el), B[O_F, el], np.int64(B[O_REG, el]), B[O_DELTA, el], B[O_BD, el], B[O_SP, el],
        B[O_CP, el], np.int64(B[Q_REGPREV, el]), B[Q_DPREV, el], B[Q_BDPREV, el], dphi * j, dphi, B[Q_WA, el],
        B[O_WB, el], TB[m, 0, el], TB[m, 1, el], TB[m, 2, el], c, k, dynamic, max_iter, tol, TB[ja, 0, el],
        TB[ja, 1, el],
    )  # fmt: skip
    if nloc == 0:
        return
    _store_lane(B, el, s, s1, F, region, delta, bd, sp, cp, 1, dynamic)
    B[O_H, el] = h
    B[O_HL, el] = hl
    for i in range(K.NDOF):
        B[R_OLD + K.NSTATE + i, el] = sa[K.NSTATE + i]


@kernel_inline
def _correct_lane(B, TB, el, m, ja, dphi, dynamic):
    """Step j of lane el (``ja`` = j mod steps per period, ``m`` = its end's excitation row) changed the contact
    region across one edge and the lane corrects kinks (``kernels.corrects_kink``): correct its result
    (``kernels.kink_correct_t``; the one-system loop calls it through ``kernels.corrected_fixed_step``, the same
    arithmetic) and store it like :func:`_redo_lane` (not a split step). Inlined in the loop: ~0.4 lanes per step
    take it under random set-points, and the call it went through before (with the buffers and tuples it reloads)
    cost about as much as the correction itself (the kernel timed with the correction removed, docs/BENCHMARKS.md)."""
    k = _lane_k(B, el)
    s = _lane_s(B, el, R_OLD)
    wa = B[Q_WA, el]
    wb = B[O_WB, el]
    s1, F, region, delta, bd, sp, cp = K.kink_correct_t(
        s, _lane_s(B, el), np.int64(B[Q_REGPREV, el]), TB[ja, 0, el], TB[ja, 1, el], wa, TB[m, 0, el],
        TB[m, 1, el], TB[m, 2, el], wb, K.step_coeffs(2.0 * dphi / (wa + wb), k), k, dynamic,
    )  # fmt: skip
    _store_lane(B, el, s, s1, F, region, delta, bd, sp, cp, 0, dynamic)


@kernel_inline
def _copy_block(B, TB, B_to, TB_to, n_steps):
    """Copy a block's buffers (B: (N_ROWS, LANES), TB: (n_steps, 3, LANES)) into B_to, TB_to: saved
    before a split step is handed to Python, restored when the kernel resumes."""
    for r in range(N_ROWS):
        for i in range(LANES):
            B_to[r, i] = B[r, i]
    for r in range(n_steps):
        for q in range(3):
            for i in range(LANES):
                TB_to[r, q, i] = TB[r, q, i]


@kernel
def _retire(B, el, e, r, X, A, stats, elapsed, el_time, c, dynamic):
    """Write lane el's state (from rows r), statistics and elapsed time to system e."""
    for i in range(K.NSTATE):
        X[e, i] = B[r + i, el]
    for i in range(K.NDOF):
        A[e, i] = B[r + K.NSTATE + i, el]
    _finish_stats(B, el, stats[e], c, dynamic)
    elapsed[e] = el_time
    B[Q_LIVE, el] = 0.0


@kernel
def _load_block(B, TB, nl, e0, X, A, W0, W1, n_periods, NS, C, dynamic, status, work):
    """Fill the block buffer with systems e0 .. e0 + nl - 1 (those beyond the last system are
    padding: a copy of the last system, never live), system e at NS[e] steps per mesh period."""
    n = X.shape[0]
    for el in range(nl):
        e = min(e0 + el, n - 1)
        c = C[e]
        n_steps = NS[e]
        total = n_periods * n_steps
        k = K.step_consts(c)
        for i in range(N_K):
            B[R_K + i, el] = k[i]
        tab = K._excitation_table(0.0, n_steps, c)
        for r in range(n_steps):
            for i in range(3):
                TB[r, i, el] = tab[r, i]
        x = X[e].copy()
        a = A[e].copy()
        # runtime_int: the copy of start_step that the single-system kernels use, not one for the literal
        F0, reg0, d0, bd0 = K.start_step(x, a, 0.0, W0[e], c, K.runtime_int(dynamic), work)
        for i in range(K.NSTATE):
            B[R_S + i, el] = x[i]
        for i in range(K.NDOF):
            B[R_S + K.NSTATE + i, el] = a[i]
            B[R_G + i, el] = a[i]
        for r in range(O_F, N_ROWS):
            B[r, el] = 0.0
        B[Q_W0, el] = W0[e]
        B[Q_WW, el] = (W1[e] * W1[e] - W0[e] * W0[e]) / total
        B[Q_NS, el] = float(n_steps)
        B[Q_DPHI, el] = K.TWO_PI / n_steps
        B[Q_M, el] = 0.0
        B[Q_WA, el] = W0[e]
        B[Q_FPREV, el] = F0
        B[Q_REGPREV, el] = float(reg0)
        B[Q_DPREV, el] = d0
        B[Q_BDPREV, el] = bd0
        B[Q_TRPREV, el] = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
        for i in (Q_RPMAX, Q_FMAX, Q_UMAX, Q_DMAX, Q_BDMAX, Q_SPMAX):
            B[i, el] = -np.inf
        for i in (Q_FMIN, Q_UMIN, Q_DMIN, Q_BDMIN, Q_SPMIN):
            B[i, el] = np.inf
        B[Q_SYS, el] = float(e)
        B[Q_LIVE, el] = 1.0 if e0 + el < n else 0.0
        if e0 + el < n:
            status[e] = K.OK


P_E0, P_J, P_EL, P_ST, P_NL = range(5)
"""Where :func:`_integrate` stopped at SPLIT_PENDING (entries of its ``pos`` argument): first
system of the block, step, lane; P_ST: the status of that lane's step (:func:`_split_lane`) when
the call that continues comes in; P_NL: the block's lane count then (fewer after :func:`_compact`)."""


@kernel_inline
def _compact(B, TB, nl, n_steps):
    """Move the live lanes of a block of ``nl`` lanes into its first PAD columns (over lanes that were retired) when
    they fit there, and return the block's new lane count (``nl`` when they do not fit).

    For a mixed block whose lanes of smaller counts have finished: its block steps go on only for the lanes of the
    largest count, and a block of PAD lanes costs about half one of 16 (the lanes of a column are independent, so the
    numbers do not change). A lane's column carries everything it needs (state, accumulators, its system in Q_SYS,
    its excitation table in TB)."""
    live = 0
    for el in range(nl):
        live += 1 if B[Q_LIVE, el] != 0.0 else 0
    if nl <= PAD or live > PAD:
        return nl
    dst = 0
    for src in range(PAD, nl):
        if B[Q_LIVE, src] == 0.0:
            continue
        while B[Q_LIVE, dst] != 0.0:
            dst += 1
        for r in range(N_ROWS):
            B[r, dst] = B[r, src]
        for r in range(n_steps):
            for q in range(3):
                TB[r, q, dst] = TB[r, q, src]
        B[Q_LIVE, src] = 0.0
    return PAD


@kernel_inline
def _integrate(
    X, A, W0, W1, n_periods, NS, C, dynamic, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos
):
    """The loop of :func:`integrate_stats_lanes`, up to a lane whose step Newton does not finish.

    ``NS`` (n,) int64: each system's steps per mesh period. A block whose lanes differ in it ("mixed") runs as many
    block steps as its largest count needs; each lane takes its own steps (its phase step, excitation rows,
    Poincare samples and end), a lane that has finished is retired and then stepped on at its final omega, its
    results untouched, like a padding lane.

    ``done`` (n,) periods completed (filled with n_periods by the caller). ``pos[P_J] < 0`` starts
    the batch. At a lane step that needs splitting the block (buffers B and TB) is saved into
    SB and STB, its place into ``pos``, and SPLIT_PENDING is returned; the caller takes that step
    (:func:`_split_lane` on SB), writes its status into pos[P_ST], and a call with the same
    arguments continues with the next lane of the step. Returns OK at the end.

    B and TB are allocated here (not taken from the caller) so that their row strides are
    compile-time constants (see LANES).
    """
    n = X.shape[0]
    n_max = STB.shape[0]  # the largest of NS
    B = np.empty((N_ROWS, LANES))
    TB = np.empty((n_max, 3, LANES))
    work = np.zeros(K.WORK_SIZE)
    r_old = K.runtime_int(R_OLD)  # not literals: one compiled copy of _retire
    r_s = K.runtime_int(R_S)
    resume = pos[P_J] >= 0
    if resume:  # continue after the split step of lane pos[P_EL]
        _copy_block(SB, STB, B, TB, n_max)
    for e0 in range(pos[P_E0] if resume else 0, n, LANES):
        nl = min(LANES, n - e0)
        nl = (nl + PAD - 1) // PAD * PAD
        j0 = 0
        if resume:
            j0 = pos[P_J]
            nl = pos[P_NL]
        else:
            _load_block(B, TB, nl, e0, X, A, W0, W1, n_periods, NS, C, dynamic, status, work)
        locating = False  # any lane of the block locates contact changes (K_LOC)
        ns0 = B[Q_NS, 0]
        mixed = False  # lanes of different step counts
        ns_max = ns0
        for el in range(nl):
            locating = locating or B[R_K + K.K_LOC, el] != 0.0
            mixed = mixed or B[Q_NS, el] != ns0
            ns_max = max(ns_max, B[Q_NS, el])
        n_steps = np.int64(ns0)  # the block's count where it is not mixed
        total = n_periods * np.int64(ns_max)
        j1 = j0
        while j1 < total:  # at most two parts, so that the block's width is a constant of each loop (_compact)
            j_next = total
            for j in range(j1, total):
                m = (j + 1) % n_steps  # (not mixed; mixed blocks read each lane's Q_M)
                el0 = 0
                nredo = nl  # lanes to scan for a scalar redo (all of them after a split step)
                n_m0 = nl  # lanes whose step ends a mesh period (all of them to scan after a split step)
                if resume:  # lane pos[P_EL]'s step was taken by _split_lane
                    resume = False
                    el0 = pos[P_EL]
                    st = pos[P_ST]
                    if st != K.OK:
                        e = np.int64(B[Q_SYS, el0])
                        status[e] = st
                        done[e] = j // np.int64(B[Q_NS, el0])
                        _retire(B, el0, e, r_old, X, A, stats, elapsed, B[Q_EL, el0] + B[O_H, el0], C[e], dynamic)
                    el0 += 1
                else:
                    # each lane's excitation row of the step's end, and the excitation there
                    if mixed:
                        n_m0 = 0
                        for el in range(nl):
                            mm = B[Q_M, el] + 1.0
                            mm = 0.0 if mm == B[Q_NS, el] else mm
                            B[Q_M, el] = mm
                            n_m0 += 1 if mm == 0.0 else 0
                            mi = np.int64(mm)
                            B[Q_CE, el] = TB[mi, 0, el]
                            B[Q_SE, el] = TB[mi, 1, el]
                            B[Q_KK, el] = TB[mi, 2, el]
                    else:
                        n_m0 = nl if m == 0 else 0
                        for el in range(nl):
                            B[Q_M, el] = float(m)
                            B[Q_CE, el] = TB[m, 0, el]
                            B[Q_SE, el] = TB[m, 1, el]
                            B[Q_KK, el] = TB[m, 2, el]
                    nredo = _first_pass(B, nl, j + 1.0, dynamic, tol)
                # lanes whose first Newton iteration did not finish: the scalar step from the start (the scans of
                # lanes below run only where a vectorised count says one is needed: each costs ~16 branches per step)
                for el in range(el0, nl if nredo != 0 else 0):
                    if B[Q_LIVE, el] == 0.0 or B[O_DONE, el] != 0.0:
                        continue
                    e = np.int64(B[Q_SYS, el])
                    st = _redo_lane(B, TB, el, np.int64(B[Q_M, el]), j, B[Q_DPHI, el], C[e], dynamic, max_iter, tol)
                    if st == K.SPLIT_PENDING:
                        _copy_block(B, TB, SB, STB, n_max)
                        pos[P_E0] = e0
                        pos[P_J] = j
                        pos[P_EL] = el
                        pos[P_NL] = nl
                        return K.SPLIT_PENDING
                    if st != K.OK:
                        status[e] = st
                        done[e] = j // np.int64(B[Q_NS, el])
                        _retire(B, el, e, r_old, X, A, stats, elapsed, B[Q_EL, el] + B[O_H, el], C[e], dynamic)
                # lanes that locate contact changes or correct their kinks and changed the contact region in this step
                # (not a split step): the correction inline (most contact changes finish in the first pass, so this
                # runs for ~0.4 lanes per step under random set-points), location in a call
                nchg = 0
                for el in range(nl if locating else 0):
                    nchg += 1 if B[O_REG, el] != B[Q_REGPREV, el] else 0
                for el in range(nl if nchg != 0 else 0):
                    if (
                        B[R_K + K.K_LOC, el] != 0.0
                        and B[Q_LIVE, el] != 0.0
                        and B[O_REG, el] != B[Q_REGPREV, el]
                        and B[O_HL, el] != 0.0
                    ):
                        ns_l = np.int64(B[Q_NS, el])
                        m_l = np.int64(B[Q_M, el])
                        if K.corrects_kink(_lane_k(B, el), np.int64(B[Q_REGPREV, el]), np.int64(B[O_REG, el])):
                            _correct_lane(B, TB, el, m_l, j % ns_l, B[Q_DPHI, el], dynamic)
                        else:
                            c_l = C[np.int64(B[Q_SYS, el])]
                            _locate_lane(B, TB, el, m_l, j, ns_l, B[Q_DPHI, el], c_l, dynamic, max_iter, tol)
                if _check_pass(B, nl) != 0:
                    for el in range(nl):
                        if B[O_BAD, el] != 0.0 and B[Q_LIVE, el] != 0.0:
                            e = np.int64(B[Q_SYS, el])
                            status[e] = K.DIVERGED
                            done[e] = j // np.int64(B[Q_NS, el])
                            _retire(B, el, e, r_s, X, A, stats, elapsed, B[Q_EL, el], C[e], dynamic)
                _stats_pass(B, nl)
                if n_m0 != 0:
                    for el in range(nl):
                        if B[Q_LIVE, el] == 0.0 or B[Q_M, el] != 0.0:
                            continue
                        p = (j + 1) // np.int64(B[Q_NS, el]) - 1
                        e = np.int64(B[Q_SYS, el])
                        # the velocity the forces felt (newmark.output_t; over the step's last part after a located
                        # contact change); Newmark's own after a split step (O_HL 0)
                        wh = B[R_K + K.K_VC, el] * B[O_HL, el]
                        for i in range(K.NDOF):
                            poincare[e, p, i] = B[R_S + i, el]
                        for i in range(K.NDOF, K.NSTATE):
                            poincare[e, p, i] = B[R_S + i, el] - wh * (
                                B[R_S + K.NDOF + i, el] - B[R_OLD + K.NDOF + i, el]
                            )
                        poincare[e, p, K.PC_DELTA] = B[O_DELTA, el]
                        poincare[e, p, K.PC_BD] = B[O_BD, el]
                        poincare[e, p, K.PC_PSI] = K.psi_t(B[O_SP, el], B[O_CP, el], C[e], dynamic)
                        poincare[e, p, K.PC_FORCE] = B[O_F, el]
                if mixed and (j + 1) % n_periods == 0:  # lanes at their last step: retired, then held at their omega
                    for el in range(nl):
                        if B[Q_LIVE, el] != 0.0 and j + 1 == n_periods * np.int64(B[Q_NS, el]):
                            e = np.int64(B[Q_SYS, el])
                            _retire(B, el, e, r_s, X, A, stats, elapsed, B[Q_EL, el], C[e], dynamic)
                            B[Q_W0, el] = B[Q_WA, el]
                            B[Q_WW, el] = 0.0
                    nc = _compact(B, TB, nl, n_max)
                    if nc != nl:
                        nl = nc
                        j_next = j + 1
                        break
            j1 = j_next
        for el in range(nl):
            if B[Q_LIVE, el] != 0.0:
                e = np.int64(B[Q_SYS, el])
                _retire(B, el, e, r_s, X, A, stats, elapsed, B[Q_EL, el], C[e], dynamic)
    return K.OK


@kernel
def _finish_stats(B, e, stats, c, dynamic):
    """Write lane e's accumulators into its stats vector as ``integrate_stats_tab`` does after a
    reset."""
    K._stats_init(stats)
    stats[K.ST_TIME] += B[Q_T, e]
    stats[K.ST_STEPS] += B[Q_N, e]
    stats[K.ST_SPLITS] += B[Q_NSPLIT, e]
    stats[K.ST_SEP_TIME] += B[Q_SEP, e]
    stats[K.ST_BACK_TIME] += B[Q_BACK, e]
    stats[K.ST_BACK_IMPACTS] += B[Q_BACK_IMP, e]
    stats[K.ST_DRIVE_IMPACTS] += B[Q_DRIVE_IMP, e]
    stats[K.ST_F_SUM] += B[Q_FSUM, e]
    stats[K.ST_F_SQ] += B[Q_FSQ, e]
    stats[K.ST_TR_SQ] += B[Q_TRSQ, e]
    if B[Q_N, e] > 0.0:
        stats[K.ST_TR_MAX] = max(stats[K.ST_TR_MAX], math.sqrt(B[Q_RPMAX, e]))
        stats[K.ST_F_MAX] = max(stats[K.ST_F_MAX], B[Q_FMAX, e])
        stats[K.ST_F_MIN] = min(stats[K.ST_F_MIN], B[Q_FMIN, e])
        stats[K.ST_U_MAX] = max(stats[K.ST_U_MAX], B[Q_UMAX, e])
        stats[K.ST_U_MIN] = min(stats[K.ST_U_MIN], B[Q_UMIN, e])
        stats[K.ST_D_MAX] = max(stats[K.ST_D_MAX], B[Q_DMAX, e])
        stats[K.ST_D_MIN] = min(stats[K.ST_D_MIN], B[Q_DMIN, e])
        stats[K.ST_BD_MAX] = max(stats[K.ST_BD_MAX], B[Q_BDMAX, e])
        stats[K.ST_BD_MIN] = min(stats[K.ST_BD_MIN], B[Q_BDMIN, e])
        if dynamic == 0:
            stats[K.ST_PSI_MAX] = max(stats[K.ST_PSI_MAX], c[K.C_ALPHA0])
            stats[K.ST_PSI_MIN] = min(stats[K.ST_PSI_MIN], c[K.C_ALPHA0])
        else:
            stats[K.ST_PSI_MAX] = max(stats[K.ST_PSI_MAX], math.asin(B[Q_SPMAX, e]))
            stats[K.ST_PSI_MIN] = min(stats[K.ST_PSI_MIN], math.asin(B[Q_SPMIN, e]))


@kernel
def _lanes_constant(
    X, A, W0, W1, n_periods, NS, C, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos
):
    return _integrate(
        X, A, W0, W1, n_periods, NS, C, 0, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos
    )


@kernel
def _lanes_dynamic(X, A, W0, W1, n_periods, NS, C, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos):
    return _integrate(
        X, A, W0, W1, n_periods, NS, C, 1, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos
    )


def integrate_stats_lanes(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter,
                          tol):  # fmt: skip
    """Advance a batch of independent systems by n_periods each, SIMD across the batch.

    Same arguments and results as ``kernels.integrate_stats_batch`` except that ``dynamic`` is
    one model code (0 constant, 1 dynamic) for every system and ``n_steps`` (steps per mesh period) may be an
    integer array (n,): each system then takes its own count, with the numbers it gives alone (a block of 16 lanes
    costs as many block steps as its largest count needs, where separate calls per count would each cost about a
    full block). X (n, 10), A (n, 5), W0/W1 (n,)
    omega at the start and end (linear in time), C (n, N_CONSTS) constants per system, poincare
    (n, n_periods, N_PC) (rows of periods a failed system did not reach are left as they were),
    stats (n, N_STATS), status (n,) int64, elapsed (n,) natural time. Every system starts at mesh
    phase 0. Returns the periods completed per system (n,). One compiled kernel per model (a
    Python-level choice, so that only the model in use is compiled: each takes ~15-30 s the first
    time, then loads from the disk cache).

    A Python loop: the kernel stops at a lane step that Newton does not finish (rare),
    :func:`_split_lane` takes that step in sub-steps and the kernel goes on, the same operations
    in the same order as a compiled call of the fallback would do, so the step-splitting code
    is compiled only when first needed.
    """
    fn = _lanes_constant if dynamic == 0 else _lanes_dynamic
    C = K.readonly(C)  # one compiled signature whoever calls (see kernels.readonly)
    NS = np.ascontiguousarray(np.broadcast_to(np.asarray(n_steps, np.int64), (X.shape[0],)))
    done = np.full(X.shape[0], n_periods, np.int64)
    SB = np.empty((N_ROWS, LANES))
    STB = np.empty((int(NS.max(initial=1)), 3, LANES))
    pos = np.full(5, -1, np.int64)
    args = (X, A, W0, W1, n_periods, NS, C, poincare, stats, status, elapsed, max_iter, tol, done, SB, STB, pos)
    while fn(*args) == K.SPLIT_PENDING:
        el = int(pos[P_EL])
        c = C[int(SB[Q_SYS, el])]
        pos[P_ST] = _split_lane(SB, el, int(pos[P_J]), float(SB[Q_DPHI, el]), c, int(dynamic), max_iter, tol)
    return done
