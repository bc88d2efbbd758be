"""Interval statistics of :func:`~gear_env.sim.kernels.integrate_stats`: the accumulators a driver
keeps in registers during its loop (``_acc_*``) and their merge into the ``ST_*`` vector."""

from __future__ import annotations

import math

import numpy as np

from ..params import C_ALPHA0
from .jit import kernel, kernel_inline
from .layout import (
    N_STATS,
    ST_BACK_IMPACTS,
    ST_BACK_TIME,
    ST_BD_MAX,
    ST_BD_MIN,
    ST_D_MAX,
    ST_D_MIN,
    ST_DRIVE_IMPACTS,
    ST_F_MAX,
    ST_F_MIN,
    ST_F_SQ,
    ST_F_SUM,
    ST_PSI_MAX,
    ST_PSI_MIN,
    ST_SEP_TIME,
    ST_SPLITS,
    ST_STEPS,
    ST_TIME,
    ST_TR_MAX,
    ST_TR_SQ,
    ST_U_MAX,
    ST_U_MIN,
)


@kernel
def _stats_init(stats):
    for i in range(N_STATS):
        stats[i] = 0.0
    for i in (ST_F_MAX, ST_U_MAX, ST_D_MAX, ST_BD_MAX, ST_PSI_MAX, ST_TR_MAX):
        stats[i] = -np.inf
    for i in (ST_F_MIN, ST_U_MIN, ST_D_MIN, ST_BD_MIN, ST_PSI_MIN):
        stats[i] = np.inf


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


_SUMS = (ST_TIME, ST_SEP_TIME, ST_BACK_TIME, ST_BACK_IMPACTS, ST_DRIVE_IMPACTS, ST_F_SUM, ST_F_SQ, ST_TR_SQ, ST_STEPS,
         ST_SPLITS)  # fmt: skip
_MAXS = (ST_F_MAX, ST_TR_MAX, ST_U_MAX, ST_D_MAX, ST_BD_MAX, ST_PSI_MAX)
_MINS = (ST_F_MIN, ST_U_MIN, ST_D_MIN, ST_BD_MIN, ST_PSI_MIN)


@kernel
def _stats_merge(dst, src):
    """Merge the interval statistics ``src`` of a later interval into ``dst`` (sums add, extrema)."""
    for i in _SUMS:
        dst[i] += src[i]
    for i in _MAXS:
        dst[i] = max(dst[i], src[i])
    for i in _MINS:
        dst[i] = min(dst[i], src[i])
