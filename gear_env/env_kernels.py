"""numba kernels of the environment's bookkeeping: Poincare window, features, reward, observation.

These run after the physics kernels (``kernels.integrate_stats``, ``batch_kernels.integrate_stats_lanes``) and
replace ~100 small NumPy calls per step by one compiled call, so the Python overhead of a step is a
few microseconds. Plain arrays in, arrays out. The column layout of the info matrix ``I`` follows
``INFO_COLUMNS`` (the info keys of the environment, in order); the accumulator matrix ``ACC`` holds
the running episode sums (``A_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import kernels as K

kernel = njit(cache=True, error_model="numpy")

MAX_PERIOD = 8
FEATURE_CLIP = 10.0
STATE_CLIP = K.DIVERGENCE_LIMIT

INFO_COLUMNS = (
    "reward_throughput",
    "reward_chaos",
    "reward_contact",
    "reward_impact",
    "reward_vibration",
    "reward_rate",
    "reward_demand",
    "reward_divergence",
    "step",
    "omega",
    "omega_mean",
    "domega",
    "demand",
    "force_rms",
    "force_peak",
    "translation_rms",
    "defect",
    "period",
    "chaos",
    "nonperiodic",
    "contact_loss",
    "drive_impacts",
    "back_impacts",
    "step_time_s",
    "diverged",
    "episode_return",
    "episode_steps",
    "episode_throughput",
    "episode_time_s",
    "episode_time_periodic_s",
    "episode_time_nonperiodic_s",
    "episode_steps_periodic",
    "episode_steps_nonperiodic",
    "episode_impacts",
    "episode_back_impacts",
    "episode_contact_loss",
)
(
    I_R_THR, I_R_CHAOS, I_R_CONTACT, I_R_IMPACT, I_R_VIB, I_R_RATE, I_R_DEMAND, I_R_DIV,
    I_STEP, I_OMEGA, I_OMEGA_MEAN, I_DOMEGA, I_DEMAND,
    I_FRMS, I_FPEAK, I_TR, I_DEFECT, I_PERIOD, I_CHAOS, I_NONPER, I_CONTACT, I_DRIVE, I_BACK,
    I_STEP_TIME, I_DIVERGED,
    I_EP_RET, I_EP_STEPS, I_EP_THR, I_EP_TIME, I_EP_PER_S, I_EP_NONPER_S, I_EP_PER, I_EP_NONPER,
    I_EP_IMPACTS, I_EP_BACK, I_EP_CONTACT,
) = range(len(INFO_COLUMNS))  # fmt: skip
N_INFO = len(INFO_COLUMNS)

# episode accumulators
A_RET, A_OMEGA, A_TIME, A_PER_S, A_NONPER_S, A_NAT, A_SEP, A_DRIVE, A_BACK, A_PER, A_NONPER = range(11)
N_ACC = 11

# settings vector (float64) passed to the kernels
(
    S_LO, S_HI, S_DMAX, S_DSCALE, S_W_THR, S_W_CHAOS, S_W_CONTACT, S_W_IMPACT, S_W_VIB, S_W_RATE,
    S_W_DEMAND, S_BACK_W, S_DIV_PEN, S_HAS_DEMAND, S_FULL, S_MAX_STEPS, S_PPS,
) = range(17)  # fmt: skip
N_SETTINGS = 17


@kernel
def push_history(rows, pc, w0, w1, ok, hist):
    """Append the Poincare samples (Delta, dU/omega) [b0] of rows that integrated OK to the window.

    ``pc`` (m, P, N_PC) from the physics kernel; omega at sample k is taken linear in the sample
    index, w0 + (w1 - w0)(k + 1)/P; ``hist`` (n, W, 2) is shifted in place.
    """
    m, P = pc.shape[0], pc.shape[1]
    W = hist.shape[1]
    for j in range(m):
        if not ok[j]:
            continue
        r = rows[j]
        if P < W:
            for i in range(W - P):
                hist[r, i, 0] = hist[r, i + P, 0]
                hist[r, i, 1] = hist[r, i + P, 1]
        first = max(P - W, 0)
        for k in range(first, P):
            w = w0[j] + (w1[j] - w0[j]) * (k + 1.0) / P
            i = W - P + k
            hist[r, i, 0] = pc[j, k, K.PC_DELTA]
            hist[r, i, 1] = pc[j, k, 9] / w


@kernel
def defect_of(h, scale):
    """Periodicity defect min_{p=1..8} max_k max_ch |h[k+p, ch] - h[k, ch]| of one window (W, 2)
    and the smallest p whose defect is <= scale/2 (0 if none)."""
    W = h.shape[0]
    pmax = min(MAX_PERIOD, W - 1)
    best = np.inf
    period = 0
    for p in range(1, pmax + 1):
        d = 0.0
        for k in range(W - p):
            for ch in range(h.shape[1]):
                v = abs(h[k + p, ch] - h[k, ch])
                if v > d:
                    d = v
        if d < best:
            best = d
        if period == 0 and d <= 0.5 * scale:
            period = p
    return best, period


@kernel
def _clip(x, lo, hi):
    if not math.isfinite(x):
        return 0.0 if x != x else (hi if x > 0 else lo)
    return min(max(x, lo), hi)


@kernel
def post_step(rows, st, ok, elapsed, w0, w1, demand, demand_next, is_reset, S, hist, tr_ref, fs, omega_n, steps, X,
              ACC, I, obs, reward, terminated, truncated):  # fmt: skip
    """Features, reward terms, episode sums, info and observation of ``rows`` after an interval.

    ``is_reset``: the interval was the warm-up of a new episode (no reward; sums start at 0).
    ``demand``: required omega charged in this step; ``demand_next``: shown in the observation.
    Writes ``I`` (info matrix), ``obs``, ``ACC``, ``steps`` and the (m,) outputs in place.
    """
    lo = S[S_LO]
    hi = S[S_HI]
    span = hi - lo
    scale = S[S_DSCALE]
    pps = S[S_PPS]
    has_demand = S[S_HAS_DEMAND] != 0.0
    full = S[S_FULL] != 0.0
    n_sens = 10
    for j in range(rows.shape[0]):
        r = rows[j]
        good = ok[j]
        # ---------------------------------------------------------------- features
        frms = fpeak = tr = defect = chaos = contact = 0.0
        period = 0
        drive = back = 0.0
        if good:
            T = max(st[j, K.ST_TIME], 1e-300)
            fmean = st[j, K.ST_F_SUM] / T
            frms = math.sqrt(max(st[j, K.ST_F_SQ] / T - fmean * fmean, 0.0)) / fs[r]
            fpeak = max(st[j, K.ST_F_MAX], 0.0) / fs[r]
            tr = math.sqrt(max(st[j, K.ST_TR_SQ] / T - tr_ref[r] * tr_ref[r], 0.0))
            defect, period = defect_of(hist[r], scale)
            chaos = min(max(defect / scale, 0.0), 1.0)
            contact = min(max((st[j, K.ST_SEP_TIME] + st[j, K.ST_BACK_TIME]) / T, 0.0), 1.0)
            drive = st[j, K.ST_DRIVE_IMPACTS]
            back = st[j, K.ST_BACK_IMPACTS]
        wa = w0[j]
        wb = w1[j] if good else w0[j]
        dw = wb - wa
        wmean = 0.5 * (wa + wb)
        nonper = good and chaos > 0.5
        per = good and not nonper
        # ---------------------------------------------------------------- reward
        for c in range(N_INFO):
            I[r, c] = 0.0
        rew = 0.0
        seconds = 0.0
        if not is_reset:
            if good:
                I[r, I_R_THR] = S[S_W_THR] * wmean / hi
                I[r, I_R_CHAOS] = -S[S_W_CHAOS] * chaos
                I[r, I_R_CONTACT] = -S[S_W_CONTACT] * contact
                I[r, I_R_IMPACT] = -S[S_W_IMPACT] * (drive + S[S_BACK_W] * back) / pps
                I[r, I_R_VIB] = -S[S_W_VIB] * max(0.0, fpeak - 1.0) / 10.0
                I[r, I_R_RATE] = -S[S_W_RATE] * (dw / S[S_DMAX]) ** 2
                if has_demand:
                    I[r, I_R_DEMAND] = -S[S_W_DEMAND] * max(0.0, demand[j] - wmean) / hi
            else:
                I[r, I_R_DIV] = -S[S_DIV_PEN]
            for c in range(I_R_THR, I_R_DIV + 1):
                rew += I[r, c]
            steps[r] += 1
            if good:
                seconds = elapsed[j] / omega_n[r]
            a = ACC[r]
            a[A_RET] += rew
            a[A_OMEGA] += wmean
            a[A_TIME] += seconds
            if per:
                a[A_PER_S] += seconds
                a[A_PER] += 1.0
            if nonper:
                a[A_NONPER_S] += seconds
                a[A_NONPER] += 1.0
            if good:
                a[A_NAT] += st[j, K.ST_TIME]
                a[A_SEP] += st[j, K.ST_SEP_TIME] + st[j, K.ST_BACK_TIME]
            a[A_DRIVE] += drive
            a[A_BACK] += back
        else:
            steps[r] = 0
            for c in range(N_ACC):
                ACC[r, c] = 0.0
        reward[j] = rew
        terminated[j] = not good and not is_reset
        truncated[j] = good and not is_reset and steps[r] >= S[S_MAX_STEPS]
        # ---------------------------------------------------------------- info
        I[r, I_STEP] = steps[r]
        I[r, I_OMEGA] = wb
        I[r, I_OMEGA_MEAN] = wmean
        I[r, I_DOMEGA] = dw
        I[r, I_DEMAND] = demand[j] if has_demand else 0.0
        I[r, I_FRMS] = frms
        I[r, I_FPEAK] = fpeak
        I[r, I_TR] = tr
        I[r, I_DEFECT] = defect
        I[r, I_PERIOD] = period
        I[r, I_CHAOS] = chaos
        I[r, I_NONPER] = 1.0 if (chaos > 0.5) else 0.0
        I[r, I_CONTACT] = contact
        I[r, I_DRIVE] = drive
        I[r, I_BACK] = back
        I[r, I_STEP_TIME] = seconds
        I[r, I_DIVERGED] = 0.0 if good else 1.0
        a = ACC[r]
        ns = steps[r]
        I[r, I_EP_RET] = a[A_RET]
        I[r, I_EP_STEPS] = ns
        I[r, I_EP_THR] = a[A_OMEGA] / ns if ns > 0 else 0.0
        I[r, I_EP_TIME] = a[A_TIME]
        I[r, I_EP_PER_S] = a[A_PER_S]
        I[r, I_EP_NONPER_S] = a[A_NONPER_S]
        I[r, I_EP_PER] = a[A_PER]
        I[r, I_EP_NONPER] = a[A_NONPER]
        I[r, I_EP_IMPACTS] = a[A_DRIVE] + a[A_BACK]
        I[r, I_EP_BACK] = a[A_BACK]
        I[r, I_EP_CONTACT] = a[A_SEP] / a[A_NAT] if a[A_NAT] > 0 else 0.0
        # ---------------------------------------------------------------- observation
        if good or is_reset:
            o = obs[r]
            o[0] = _clip(2.0 * (wb - lo) / span - 1.0, -1.0, 1.0)
            o[1] = _clip(dw / S[S_DMAX], -1.0, 1.0)
            o[2] = _clip(math.log1p(frms), -1.0, FEATURE_CLIP)
            o[3] = _clip(math.log1p(fpeak), -1.0, FEATURE_CLIP)
            o[4] = _clip(math.log1p(tr / tr_ref[r]), -1.0, FEATURE_CLIP)
            o[5] = _clip(math.log1p(defect / scale), -1.0, FEATURE_CLIP)
            o[6] = period / MAX_PERIOD
            o[7] = contact
            o[8] = _clip(drive / pps, -1.0, FEATURE_CLIP)
            o[9] = _clip(back / pps, -1.0, FEATURE_CLIP)
            c0 = n_sens
            if has_demand:
                o[c0] = _clip(2.0 * (demand_next[j] - lo) / span - 1.0, -1.0, 1.0)
                c0 += 1
            if full:
                for i in range(K.NSTATE):
                    o[c0 + i] = _clip(X[r, i], -STATE_CLIP, STATE_CLIP)


@kernel
def decode_actions(w0, actions, S, target_mode, out):
    """omega at the end of the step for actions in [-1, 1]: delta (w0 + a max_domega) or target
    mode (lo + (a + 1)/2 (hi - lo), rate-limited to max_domega); clipped to [lo, hi]."""
    lo = S[S_LO]
    hi = S[S_HI]
    dmax = S[S_DMAX]
    for j in range(w0.shape[0]):
        a = min(max(actions[j], -1.0), 1.0)
        if target_mode:
            t = lo + 0.5 * (a + 1.0) * (hi - lo)
            t = min(max(t, w0[j] - dmax), w0[j] + dmax)
        else:
            t = w0[j] + a * dmax
        out[j] = min(max(t, lo), hi)
