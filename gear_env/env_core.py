"""Batched engine behind ``GearSpeedEnv`` and ``GearSpeedVectorEnv``.

One :class:`GearSpeedCore` holds ``n`` independent gear pairs as plain arrays (state, omega,
Poincare history, episode accumulators) and advances any subset of them with the numba kernels.
The single environment is a core with ``n = 1`` (advanced with ``kernels.integrate_stats``), the
vector environment a core with ``n = num_envs`` (all rows in one call of
``batch_kernels.integrate_stats_lanes``, which steps the rows together with SIMD, or of
``kernels.integrate_stats_batch`` below LANES_MIN rows); features and rewards are computed by the
same compiled code, and every physics kernel does the same arithmetic per system, so the two give
bit-identical trajectories for the same seeds.

Units: omega is Omega/omega_n; displacements in b0; forces in k_m0 b0 (normalised here by the
static mesh force F_s); time per step in seconds of physical time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import env_kernels as EK
from . import kernels as K
from .env_config import GearSpeedConfig
from .integration import integrate
from .params import C_FS, GearParams, model_code

MAX_PERIOD = EK.MAX_PERIOD
"""Longest periodic orbit (in mesh periods) recognised by the periodicity defect."""
LANES_MIN = 2
"""Batches of at least this many rows are advanced by ``batch_kernels.integrate_stats_lanes``."""

SENSOR_NAMES = (
    "omega",
    "domega",
    "force_rms",
    "force_peak",
    "translation_rms",
    "defect",
    "period",
    "contact_loss",
    "drive_impacts",
    "back_impacts",
)
FULL_STATE_NAMES = ("X_p", "Y_p", "X_g", "Y_g", "U", "dX_p", "dY_p", "dX_g", "dY_g", "dU")
FEATURE_CLIP = EK.FEATURE_CLIP  # upper bound of the log-scaled and per-period features
STATE_CLIP = EK.STATE_CLIP

# info keys (identical on every step and on reset); value dtype
INFO_KEYS: dict[str, type] = {
    "reward_throughput": float,
    "reward_chaos": float,
    "reward_contact": float,
    "reward_impact": float,
    "reward_vibration": float,
    "reward_rate": float,
    "reward_demand": float,
    "reward_divergence": float,
    "step": int,
    "omega": float,
    "omega_mean": float,
    "domega": float,
    "demand": float,
    "force_rms": float,
    "force_peak": float,
    "translation_rms": float,
    "defect": float,
    "period": int,
    "chaos": float,
    "nonperiodic": bool,
    "contact_loss": float,
    "drive_impacts": int,
    "back_impacts": int,
    "step_time_s": float,
    "diverged": bool,
    "episode_return": float,
    "episode_steps": int,
    "episode_throughput": float,
    "episode_time_s": float,
    "episode_time_periodic_s": float,
    "episode_time_nonperiodic_s": float,
    "episode_steps_periodic": int,
    "episode_steps_nonperiodic": int,
    "episode_impacts": int,
    "episode_back_impacts": int,
    "episode_contact_loss": float,
}
REWARD_KEYS = tuple(k for k in INFO_KEYS if k.startswith("reward_"))


def periodicity_defect(hist: np.ndarray, defect_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Periodicity defect and detected period of Poincare sequences (NumPy reference of the kernel).

    Args:
        hist: (n, W, m) Poincare samples (W consecutive mesh periods, m channels in b0 units).
        defect_scale: defect [b0] treated as fully non-periodic.

    Returns:
        (defect, period): ``defect[i] = min_{p=1..8} max_k max_j |hist[i,k+p,j] - hist[i,k,j]|`` [b0]
        and the smallest p whose defect is <= defect_scale/2 (0 if none).
    """
    n, W, _ = hist.shape
    pmax = min(MAX_PERIOD, W - 1)
    d = np.empty((n, pmax))
    for p in range(1, pmax + 1):
        d[:, p - 1] = np.abs(hist[:, p:, :] - hist[:, :-p, :]).max(axis=(1, 2))
    defect = d.min(axis=1)
    ok = d <= 0.5 * defect_scale
    period = np.where(ok.any(axis=1), ok.argmax(axis=1) + 1, 0)
    return defect, period


class GearSpeedCore:
    """``n`` gear pairs under speed control, stepped together (see module docstring).

    Args:
        config: validated :class:`GearSpeedConfig`.
        n: number of systems.
        single: advance with ``integrate_stats`` one system at a time (the single env) instead of
            the batch kernels (``integrate_stats_lanes`` from LANES_MIN rows up,
            ``integrate_stats_batch`` below); all give identical numbers.
    """

    def __init__(self, config: GearSpeedConfig, n: int, single: bool = False):
        self.config = cfg = config
        self.n = n
        self.single = single
        self.code = model_code(cfg.model)
        self.n_obs = len(SENSOR_NAMES) + (1 if cfg.demand is not None else 0)
        if cfg.observation == "full":
            self.n_obs += K.NSTATE
        self._demand_pts = cfg.demand_points()
        self.X = np.zeros((n, K.NSTATE))
        self.A = np.zeros((n, K.NDOF))
        self.C = np.tile(np.asarray(cfg.params.consts, float), (n, 1))
        self._C_ro = K.readonly(self.C)  # rows as the kernels take them (one compiled signature)
        self.codes = np.full(n, self.code, np.int64)
        self.omega_n = np.full(n, cfg.params.omega_n)
        self.fs = self.C[:, C_FS].copy()
        self.tr_ref = np.ones(n)
        self.omega = np.full(n, cfg.omega_min)
        self.hist = np.zeros((n, cfg.poincare_window, 2))
        self.steps = np.zeros(n, np.int64)
        self.obs = np.zeros((n, self.n_obs), np.float32)
        self.I = np.zeros((n, EK.N_INFO))
        self.ACC = np.zeros((n, EK.N_ACC))
        S = np.zeros(EK.N_SETTINGS)
        S[EK.S_LO], S[EK.S_HI], S[EK.S_DMAX] = cfg.omega_min, cfg.omega_max, cfg.max_domega
        S[EK.S_DSCALE] = cfg.defect_scale
        S[EK.S_W_THR], S[EK.S_W_CHAOS], S[EK.S_W_CONTACT] = cfg.w_throughput, cfg.w_chaos, cfg.w_contact
        S[EK.S_W_IMPACT], S[EK.S_W_VIB], S[EK.S_W_RATE] = cfg.w_impact, cfg.w_vibration, cfg.w_rate
        S[EK.S_W_DEMAND], S[EK.S_BACK_W], S[EK.S_DIV_PEN] = cfg.w_demand, cfg.back_impact_weight, cfg.divergence_penalty
        S[EK.S_HAS_DEMAND] = 1.0 if cfg.demand is not None else 0.0
        S[EK.S_FULL] = 1.0 if cfg.observation == "full" else 0.0
        S[EK.S_MAX_STEPS], S[EK.S_PPS] = cfg.max_steps, cfg.periods_per_step
        self.S = S
        self._pc_buf = np.zeros((1, cfg.periods_per_step, K.N_PC))
        self._st_buf = np.zeros((1, K.N_STATS))
        self._zeros = np.zeros(n)

    # ------------------------------------------------------------------ info access
    @property
    def info(self) -> dict[str, np.ndarray]:
        """Info of every row as typed arrays (n,), keys as :data:`INFO_KEYS` (fresh arrays)."""
        cols = self.I.T.copy()  # one copy; the float columns are rows of it
        return {k: cols[j] if t is float else cols[j].astype(t) for j, (k, t) in enumerate(_INFO_ITEMS)}

    def info_row(self, r: int) -> dict[str, Any]:
        """Plain-Python info dict of row ``r`` (floats, ints, bools)."""
        row = self.I[r].tolist()
        return {k: t(v) for (k, t), v in zip(_INFO_ITEMS, row)}

    # ------------------------------------------------------------------ kernels
    def _integrate(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int):
        """Advance ``rows`` by ``periods`` mesh periods (omega linear in time w0 -> w1).

        Returns (poincare (m, periods, N_PC), stats (m, N_STATS), ok (m,), elapsed (m,)). Rows whose
        integration failed keep their previous state.
        """
        cfg = self.config
        m = len(rows)
        if self.single and m == 1:  # fast path of the single env: no fancy indexing, reused buffers
            r = int(rows[0])
            if self._pc_buf.shape[1] != periods:
                self._pc_buf = np.zeros((1, periods, K.N_PC))
            pc, st = self._pc_buf, self._st_buf
            x = self.X[r].copy()
            a = self.A[r].copy()
            status, _, el, _, _, _ = integrate(
                x, a, self._C_ro[r], self.code, float(w0[0]), float(w1[0]), periods, cfg.steps_per_period,
                poincare=pc[0], stats=st[0],
            )  # fmt: skip
            good = status == K.OK and math.isfinite(float(st[0].sum()))
            if good:
                self.X[r] = x
                self.A[r] = a
            return pc, st, np.array([good]), np.array([el])
        X = self.X[rows]
        A = self.A[rows]
        W0 = np.ascontiguousarray(w0, float)
        W1 = np.ascontiguousarray(w1, float)
        # SIMD across the rows from LANES_MIN up (same numbers as the scalar batch kernel)
        status, _, elapsed, pc, st, _ = integrate(
            X, A, self.C[rows], self.code, W0, W1, periods, cfg.steps_per_period, simd=m >= LANES_MIN
        )
        # the kernel flags non-finite or exploding states; a non-finite statistic would mean the same
        ok = (status == K.OK) & np.isfinite(st).all(axis=1)
        self.X[rows[ok]] = X[ok]
        self.A[rows[ok]] = A[ok]
        return pc, st, ok, elapsed

    def demand(self, step: np.ndarray) -> np.ndarray:
        """Required omega at env step index ``step`` (0 when no demand profile is set)."""
        if self._demand_pts is None:
            return np.zeros(np.shape(step))
        return np.interp(np.asarray(step, float), self._demand_pts[:, 0], self._demand_pts[:, 1])

    # ------------------------------------------------------------------ observation space
    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) float32 arrays of the observation Box."""
        lo = np.zeros(self.n_obs, np.float32)
        hi = np.full(self.n_obs, FEATURE_CLIP, np.float32)
        lo[0:2] = -1.0
        hi[0:2] = 1.0
        hi[6:8] = 1.0  # period n/8, contact-loss fraction
        j = len(SENSOR_NAMES)
        if self.config.demand is not None:
            lo[j], hi[j] = -1.0, 1.0
            j += 1
        lo[j:] = -STATE_CLIP
        hi[j:] = STATE_CLIP
        return lo, hi

    def obs_names(self) -> list[str]:
        """Name of each observation entry."""
        names = list(SENSOR_NAMES)
        if self.config.demand is not None:
            names.append("demand")
        if self.config.observation == "full":
            names += list(FULL_STATE_NAMES)
        return names

    # ------------------------------------------------------------------ reset / step
    def _episode_params(self, rng: np.random.Generator) -> GearParams:
        cfg = self.config
        p = cfg.params
        if not cfg.randomize_params:
            return p
        s = cfg.randomize_scale
        f = rng.uniform(1.0 - s, 1.0 + s, size=6)
        return p.replace(
            kappa=min(p.kappa * f[0], 0.99),
            xi_m=p.xi_m * f[1],
            xi_p=p.xi_p * f[2],
            xi_g=p.xi_g * f[3],
            T_p=p.T_p * f[4],
            T_g=p.T_g * f[5],
        )

    def _post(self, rows, st, ok, elapsed, w0, w1, is_reset):
        m = len(rows)
        reward = np.zeros(m)
        terminated = np.zeros(m, np.bool_)
        truncated = np.zeros(m, np.bool_)
        if self._demand_pts is None:
            demand = demand_next = self._zeros[:m]
        else:
            steps = self.steps[rows]
            demand = self.demand(steps)
            demand_next = demand if is_reset else self.demand(steps + 1)
        EK.post_step(
            rows, st, ok, elapsed, w0, w1, demand, demand_next, is_reset, self.S, self.hist, self.tr_ref, self.fs,
            self.omega_n, self.steps, self.X, self.ACC, self.I, self.obs, reward, terminated, truncated,
        )  # fmt: skip
        return reward, terminated, truncated

    def reset_rows(self, rows: np.ndarray, rngs: list[np.random.Generator], options: dict | None = None) -> None:
        """Start new episodes in ``rows``; ``rngs[j]`` is the generator of row ``rows[j]``.

        ``options`` may hold ``"omega"`` (initial omega, overrides the configured draw).
        """
        cfg = self.config
        rows = np.asarray(rows, np.int64)
        w_init = np.empty(len(rows))
        raw = None if not options else options.get("omega")
        forced: float | None = None
        if raw is not None:
            try:  # a string, list or bool is reported like an out-of-range number
                forced = math.nan if isinstance(raw, bool) else float(raw)
            except (TypeError, ValueError):
                forced = math.nan
            if not (math.isfinite(forced) and cfg.omega_min <= forced <= cfg.omega_max):
                raise ValueError(f"reset option 'omega' must be in [{cfg.omega_min:g}, {cfg.omega_max:g}], got {raw!r}")
        for j, r in enumerate(rows):
            rng = rngs[j]
            if cfg.randomize_params:
                self.C[r] = self._episode_params(rng).consts
            else:
                self.C[r] = cfg.params.consts
            self.fs[r] = self.C[r, C_FS]
            x0 = np.zeros(K.NSTATE)
            K.static_equilibrium(self._C_ro[r], self.code, 0.0, x0)
            self.X[r] = x0
            self.A[r] = 0.0
            self.tr_ref[r] = math.sqrt(max(0.5 * float(np.sum(x0[:4] ** 2)), 1e-300))
            iw = cfg.initial_omega
            if forced is not None:
                w_init[j] = forced
            elif iw is None:
                w_init[j] = rng.uniform(cfg.omega_min, cfg.omega_max)
            elif isinstance(iw, tuple):
                w_init[j] = rng.uniform(iw[0], iw[1]) if iw[1] > iw[0] else iw[0]
            else:
                w_init[j] = iw
        self.omega[rows] = w_init
        self.hist[rows] = 0.0
        pps = cfg.periods_per_step
        pre = cfg.warmup_total - pps
        ok_all = np.ones(len(rows), bool)
        if pre > 0:
            pc, st, ok, _ = self._integrate(rows, w_init, w_init, pre)
            EK.push_history(rows, pc, w_init, w_init, ok, self.hist)
            ok_all &= ok
        pc, st, ok, elapsed = self._integrate(rows, w_init, w_init, pps)
        EK.push_history(rows, pc, w_init, w_init, ok, self.hist)
        ok_all &= ok
        self._post(rows, st, ok_all, elapsed, w_init, w_init, True)

    def decode(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Omega at the end of the next step for actions in [-1, 1] (rate-limited, clipped)."""
        out = np.empty(len(rows))
        EK.decode_actions(self.omega[rows], actions, self.S, self.config.action_mode == "target", out)
        return out

    def step_rows(self, rows: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance ``rows`` by one control step with actions (m,) in [-1, 1].

        Updates ``obs``, the info matrix and the episode sums of the rows; returns (reward,
        terminated, truncated) arrays (m,). A diverged row keeps its state, omega and observation.
        """
        rows = np.asarray(rows, np.int64)
        w0 = self.omega[rows]
        w1 = self.decode(rows, actions)
        pc, st, ok, elapsed = self._integrate(rows, w0, w1, self.config.periods_per_step)
        EK.push_history(rows, pc, w0, w1, ok, self.hist)
        self.omega[rows] = np.where(ok, w1, w0)
        return self._post(rows, st, ok, elapsed, w0, w1, False)


_INFO_ITEMS = tuple(INFO_KEYS.items())
assert tuple(INFO_KEYS) == EK.INFO_COLUMNS


__all__ = ["GearSpeedCore", "INFO_KEYS", "REWARD_KEYS", "SENSOR_NAMES", "periodicity_defect"]
