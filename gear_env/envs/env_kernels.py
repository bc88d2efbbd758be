"""numba kernels of the environment's bookkeeping: Poincare window, features, reward, observation.

These run after the physics kernels (``kernels.integrate_stats``, ``batch_kernels.integrate_stats_lanes``) and
replace ~100 small NumPy calls per step by one compiled call, so the Python overhead of a step is a
few microseconds. Plain arrays in, arrays out.

Every column and slot comes from the declarations in :mod:`gear_env.envs.env_terms`: the info matrix ``I``
has the columns ``INFO_COLUMNS`` (reward terms ``R.<name>``, cost terms ``C.<name>``, the other keys
``IX.<name>``), the settings vector ``S`` the slots ``P.<setting>``, the feature matrix ``Fm`` the
columns ``F.<feature>`` (the observation gathers its entries from it). The formula of each reward
and cost term is one line of :func:`post_step`; the reward is the sum of the columns the task lists
(``reward_cols``), ``info["cost"]`` the sum of ``cost_cols``. The accumulator matrix ``ACC`` holds
the running episode sums (``A_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..sim import kernels as K
from .env_terms import COST_COLUMN, FEATURE_CLIP, IX, N_INFO, STATE_CLIP, TROUBLE_CONTACT, F, P, R
from .env_terms import INFO_COLUMNS as _INFO_COLUMNS
from .env_terms import C as C  # the cost terms' columns, used by their formulas

kernel = njit(cache=True, error_model="numpy")

MAX_PERIOD = 8
assert STATE_CLIP == K.DIVERGENCE_LIMIT
# the hidden-state features are contiguous and in the kernels' state order
assert F._fields[F.X_p : F.X_p + K.NSTATE] == ("X_p", "Y_p", "X_g", "Y_g", "U", "dX_p", "dY_p", "dX_g", "dY_g", "dU")

INFO_COLUMNS = tuple(k for k, _ in _INFO_COLUMNS)
"""Info keys of every column of ``I``, in order (all tasks of the family)."""

# episode accumulators
A_RET, A_OMEGA, A_TIME, A_PER_S, A_NONPER_S, A_NAT, A_SEP, A_DRIVE, A_BACK, A_PER, A_NONPER = range(11)
N_ACC = 11


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
              ACC, I, reward_cols, cost_cols, Fm, obs_cols, obs, reward, terminated, truncated, pending):  # fmt: skip
    """Features, reward and cost terms, episode sums, info and observation of ``rows`` after an interval.

    ``is_reset``: the interval was the warm-up of a new episode (no reward; sums start at 0).
    ``demand``: required omega charged in this step; ``demand_next``: shown in the observation.
    ``reward_cols`` / ``cost_cols``: info columns the task sums into the reward / ``info["cost"]``;
    ``obs_cols``: feature columns of ``Fm`` the observation takes, in order. ``pending`` (n,): the action on
    its way to the drive of each row (the actuator dead time; 0 without one).
    Writes ``I`` (info matrix), ``Fm``, ``obs``, ``ACC``, ``steps`` and the (m,) outputs in place.
    """
    lo = S[P.omega_min]
    hi = S[P.omega_max]
    span = hi - lo
    scale = S[P.defect_scale]
    pps = S[P.periods_per_step]
    has_demand = S[P.demand] != 0.0
    tau = S[P.memory_steps]
    decay = math.exp(-1.0 / tau) if tau > 0.0 else 0.0
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
        for c in range(N_INFO):
            I[r, c] = 0.0
        rew = 0.0
        cost = 0.0
        seconds = 0.0
        if not is_reset:
            # ------------------------------------------------------------ reward and cost terms:
            # one line per entry of env_terms.REWARDS (I[r, R.<name>]) and env_terms.COSTS (I[r, C.<name>])
            if good:
                delivered = min(wmean, demand[j]) if S[P.throughput] != 0.0 else wmean
                I[r, R.throughput] = S[P.w_throughput] * delivered / hi
                I[r, R.chaos] = -S[P.w_chaos] * chaos
                I[r, R.contact] = -S[P.w_contact] * contact
                I[r, R.impact] = -S[P.w_impact] * (drive + S[P.back_impact_weight] * back) / pps
                I[r, R.vibration] = -S[P.w_vibration] * max(0.0, fpeak - 1.0) / 10.0
                I[r, R.rate] = -S[P.w_rate] * (dw / S[P.max_domega]) ** 2
                if has_demand:
                    I[r, R.demand] = -S[P.w_demand] * max(0.0, demand[j] - wmean) / hi
                I[r, C.nonperiodic] = S[P.w_nonperiodic] * chaos
                I[r, C.separation] = S[P.w_separation] * contact
                I[r, C.impacts] = S[P.w_impacts] * (drive + S[P.back_impact_weight] * back) / pps
            else:
                I[r, R.divergence] = -S[P.divergence_penalty]
            # ------------------------------------------------------------ sums
            for c in reward_cols:
                rew += I[r, c]
            for c in cost_cols:
                cost += I[r, c]
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
        truncated[j] = good and not is_reset and steps[r] >= S[P.max_steps]
        # ---------------------------------------------------------------- info
        if COST_COLUMN >= 0:
            I[r, COST_COLUMN] = cost
        I[r, IX.step] = steps[r]
        I[r, IX.omega] = wb
        I[r, IX.omega_mean] = wmean
        I[r, IX.domega] = dw
        I[r, IX.demand] = demand[j] if has_demand else 0.0
        I[r, IX.force_rms] = frms
        I[r, IX.force_peak] = fpeak
        I[r, IX.translation_rms] = tr
        I[r, IX.defect] = defect
        I[r, IX.period] = period
        I[r, IX.chaos] = chaos
        I[r, IX.nonperiodic] = 1.0 if (chaos > 0.5) else 0.0
        I[r, IX.contact_loss] = contact
        I[r, IX.drive_impacts] = drive
        I[r, IX.back_impacts] = back
        I[r, IX.step_time_s] = seconds
        I[r, IX.diverged] = 0.0 if good else 1.0
        a = ACC[r]
        ns = steps[r]
        I[r, IX.episode_return] = a[A_RET]
        I[r, IX.episode_steps] = ns
        I[r, IX.episode_throughput] = a[A_OMEGA] / ns if ns > 0 else 0.0
        I[r, IX.episode_time_s] = a[A_TIME]
        I[r, IX.episode_time_periodic_s] = a[A_PER_S]
        I[r, IX.episode_time_nonperiodic_s] = a[A_NONPER_S]
        I[r, IX.episode_steps_periodic] = a[A_PER]
        I[r, IX.episode_steps_nonperiodic] = a[A_NONPER]
        I[r, IX.episode_impacts] = a[A_DRIVE] + a[A_BACK]
        I[r, IX.episode_back_impacts] = a[A_BACK]
        I[r, IX.episode_contact_loss] = a[A_SEP] / a[A_NAT] if a[A_NAT] > 0 else 0.0
        # ---------------------------------------------------------------- observation: one line per
        # entry of env_terms.OBSERVATIONS (Fm[r, F.<name>]); the task's entries are gathered into obs
        if good or is_reset:
            f = Fm[r]
            frms_feature = _clip(math.log1p(frms), -1.0, FEATURE_CLIP)
            if tau > 0.0:  # memory: read the previous step's features before they are overwritten below
                trouble = contact > TROUBLE_CONTACT or drive > 0.0 or back > 0.0 or chaos > 0.5
                where = _clip(2.0 * (wmean - lo) / span - 1.0, -1.0, 1.0)
                if is_reset:
                    f[F.trouble_omega] = where if trouble else 1.0
                    f[F.trouble_recency] = 1.0 if trouble else 0.0
                    f[F.prev_force_rms] = frms_feature
                    f[F.prev_contact_loss] = contact
                else:
                    if trouble:  # recency 1: the previous step was troubled too (the spell goes on)
                        spell = f[F.trouble_recency] == 1.0
                        f[F.trouble_omega] = min(f[F.trouble_omega], where) if spell else where
                        f[F.trouble_recency] = 1.0
                    else:
                        f[F.trouble_recency] = f[F.trouble_recency] * decay
                    f[F.prev_force_rms] = f[F.force_rms]
                    f[F.prev_contact_loss] = f[F.contact_loss]
            f[F.omega] = _clip(2.0 * (wb - lo) / span - 1.0, -1.0, 1.0)
            f[F.domega] = _clip(dw / S[P.max_domega], -1.0, 1.0)
            f[F.force_rms] = frms_feature
            f[F.force_peak] = _clip(math.log1p(fpeak), -1.0, FEATURE_CLIP)
            f[F.translation_rms] = _clip(math.log1p(tr / tr_ref[r]), -1.0, FEATURE_CLIP)
            f[F.defect] = _clip(math.log1p(defect / scale), -1.0, FEATURE_CLIP)
            f[F.period] = period / MAX_PERIOD
            f[F.contact_loss] = contact
            f[F.drive_impacts] = _clip(drive / pps, -1.0, FEATURE_CLIP)
            f[F.back_impacts] = _clip(back / pps, -1.0, FEATURE_CLIP)
            f[F.demand] = _clip(2.0 * (demand_next[j] - lo) / span - 1.0, -1.0, 1.0) if has_demand else 0.0
            f[F.pending_action] = pending[r]
            for i in range(K.NSTATE):
                f[F.X_p + i] = _clip(X[r, i], -STATE_CLIP, STATE_CLIP)
            o = obs[r]
            for k in range(obs_cols.shape[0]):
                o[k] = f[obs_cols[k]]


@kernel
def decode_actions(w0, actions, demand, S, mode, out):
    """omega at the end of the step for actions in [-1, 1]. ``mode`` (``env_terms.ACTION_CODES``): 0 delta
    (w0 + a max_domega); 1 target (set-point T = lo + (a + 1)/2 (hi - lo), [lo, hi] the action range); 2 limit
    (T = min(demand, that value): the action is a speed limit and the drive follows ``demand`` under it). In
    target and limit modes the drive's reference moves reference_filter x (T - w0), then is rate-limited to
    max_domega. Clipped to [omega_min, omega_max]."""
    lo = S[P.omega_min]
    hi = S[P.omega_max]
    alo = S[P.action_lo]
    ahi = S[P.action_hi]
    dmax = S[P.max_domega]
    alpha = S[P.reference_filter]
    for j in range(w0.shape[0]):
        a = min(max(actions[j], -1.0), 1.0)
        if mode != 0:
            t = alo + 0.5 * (a + 1.0) * (ahi - alo)
            if mode == 2:
                t = min(t, demand[j])
            if alpha != 1.0:
                t = w0[j] + alpha * (t - w0[j])
            t = min(max(t, w0[j] - dmax), w0[j] + dmax)
        else:
            t = w0[j] + a * dmax
        out[j] = min(max(t, lo), hi)
