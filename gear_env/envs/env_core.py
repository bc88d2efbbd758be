"""Batched engine behind ``GearSpeedEnv`` and ``GearSpeedVectorEnv``.

One :class:`GearSpeedCore` holds ``n`` independent gear pairs as plain arrays (state, omega,
Poincare history, episode accumulators) and advances any subset of them with the numba kernels.
The single environment is a core with ``n = 1`` (advanced with ``kernels.integrate_stats_lazy``), the
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
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._numba_cache import announce_compile
from ..sim import kernels as K
from ..sim.integration import (
    CONTACT_STEPS,
    NEWTON_MAX_ITER,
    NEWTON_TOL,
    TOL_N_START,
    _excitation_table,
    contact_steps,
    integrate,
)
from ..sim.linear import stability_frequency, stable_betas
from ..sim.params import (
    C_BETA,
    C_FS,
    C_LOC,
    C_VC,
    CONTACTS_CORRECTED,
    CONTACTS_LOCATED,
    FOX_GOODWIN_BETA,
    GearParams,
    model_code,
    refuse_extensions,
)
from . import env_kernels as EK
from . import env_terms as ET
from . import force_level as FL
from .env_config import GearSpeedConfig
from .tasks import Episode, random_demand

MAX_PERIOD = EK.MAX_PERIOD
"""Longest periodic orbit (in mesh periods) recognised by the periodicity defect."""
LANES_MIN = 2
"""Batches of at least this many rows are advanced by ``batch_kernels.integrate_stats_lanes``."""
AUTO_FIRST_STEPS = CONTACT_STEPS[1]
"""``steps_per_period="auto"``: the steps per mesh period of a row's first interval in an episode (the warm-up)."""
AUTO_OTHER_STEPS = 64
"""``steps_per_period="auto"``: the steps per mesh period of a row whose beta is not Fox-Goodwin's."""
AUTO_PERIODIC_SAMPLES = 8
"""``steps_per_period="auto"``: the last Poincare samples of an interval that must repeat for period-1 motion."""
AUTO_PERIODIC_DEFECT = 1e-3
"""``steps_per_period="auto"``: largest change [b0] between those samples that still counts as period-1 motion."""

TERMS = ET.task("GearSpeed-v0")
"""The ``GearSpeed-v0`` entries of :mod:`gear_env.envs.env_terms`."""
NOISY_SENSORS = ("force_rms", "force_peak", "translation_rms", "defect", "contact_loss")
"""Observation entries that ``sensor_noise`` perturbs (with their ``prev_`` memory copies)."""
SENSOR_NAMES = tuple(o.name for o in TERMS.observations if o.when is None)
"""Names of the observation entries present in every configuration."""
FULL_STATE_NAMES = ("X_p", "Y_p", "X_g", "Y_g", "U", "dX_p", "dY_p", "dX_g", "dY_g", "dU")
FEATURE_CLIP = ET.FEATURE_CLIP  # upper bound of the log-scaled and per-period features
STATE_CLIP = ET.STATE_CLIP

INFO_KEYS: dict[str, type] = TERMS.info_keys
"""Info keys of ``GearSpeed-v0`` (identical on every step and on reset) and the type of each value."""
REWARD_KEYS = TERMS.reward_keys
"""``reward_*`` keys; the reward is their sum, in this order."""
COST_KEYS = TERMS.cost_keys
"""``cost_*`` keys (none in ``GearSpeed-v0``); ``info["cost"]`` is their sum."""


def check_options(options: Any, allowed: Sequence[str]) -> dict[str, Any]:
    """Reset options as a dict: None (no options) or a mapping whose keys are in ``allowed``.

    Raises ``ValueError`` naming the options for anything else (a string, list, number, unknown key).
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be a dict or None, got {type(options).__name__} {_short(options)}")
    unknown = [k for k in options if k not in allowed]
    if unknown:
        raise ValueError(f"unknown reset option(s) {_short(unknown)}; valid options: {list(allowed)}")
    return dict(options)


def check_seed(seed: Any, what: str = "seed") -> int | None:
    """A seed: None or an integer >= 0 (bools, floats, strings and negative numbers raise ``ValueError``)."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"{what} must be None or an integer >= 0, got {_short(seed)}")
    return int(seed)


def _short(v: Any) -> str:
    r = repr(v)
    return r if len(r) <= 80 else r[:77] + "..."


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
        single: advance with ``integrate_stats_lazy`` one system at a time (the single env) instead of
            the batch kernels (``integrate_stats_lanes`` from LANES_MIN rows up,
            ``integrate_stats_batch`` below); all give identical numbers.
    """

    def __init__(self, config: GearSpeedConfig, n: int, single: bool = False):
        announce_compile(
            "env_kernels",
            "the environment's kernels",
            "10-25 s on an idle 2-core machine, several times that under load",
        )
        self.config = cfg = config
        self.n = n
        self.single = single
        self.code = model_code(cfg.model)
        self.terms = terms = cfg.TERMS  # the task's entries of env_terms
        self.observation_names = terms.observation_names(cfg)
        self.n_obs = len(self.observation_names)
        self._obs_cols = terms.observation_columns(cfg)
        self._reward_cols = terms.reward_columns()
        self._cost_cols = terms.cost_columns()
        info_cols = terms.info_columns()
        # the info dict reads these columns of I (all of them in the common case: no copy)
        self._info_cols = None if np.array_equal(info_cols, np.arange(ET.N_INFO)) else info_cols
        self._info_items = tuple(terms.info_keys.items())
        # info_row: the keys in column order, and the (position, type) of the few that are not floats
        self._info_keys = tuple(k for k, _ in self._info_items)
        self._info_casts = tuple((j, k, t) for j, (k, t) in enumerate(self._info_items) if t is not float)
        self._demand_pts = cfg.demand_points()
        # the episode scenario of every row (gear_env.envs.tasks.Episode: plant, duty cycle, demand), and the
        # demand and load level of every step of it (tables only when they vary)
        self.episodes: list[Any] = [None] * n
        self._plants: list[dict[tuple[float, float], tuple]] = [{} for _ in range(n)]  # see _apply_duty
        self._scenario = (
            cfg.plant_family is not None or cfg.duty_cycle is not None or cfg.demand == "random" or cfg.wear is not None
        )
        self._dem = np.zeros((n, cfg.max_steps + 2) if cfg.demand is not None else (n, 0))
        if self._demand_pts is not None:
            t = np.arange(cfg.max_steps + 2, dtype=float)
            self._dem[:] = np.interp(t, self._demand_pts[:, 0], self._demand_pts[:, 1])
        self._load = np.ones((n, cfg.max_steps + 1) if cfg.duty_cycle is not None else (n, 0))
        self._wear = np.ones((n, cfg.max_steps + 1) if cfg.wear is not None else (n, 0))
        # sensor noise: the observation entries it touches, the entries that carry the previous step's
        # value of one of them, and every row's table of standard normal draws (one row per step)
        names = list(self.observation_names)
        noisy = [k for k in NOISY_SENSORS if k in names] if cfg.sensor_noise > 0 else []
        self._noise_idx = np.array([names.index(k) for k in noisy], np.int64)
        prev = [(names.index("prev_" + k), noisy.index(k)) for k in noisy if "prev_" + k in names]
        self._noise_prev = np.array(prev, np.int64).reshape(-1, 2)
        self._noise = np.zeros((n, cfg.max_steps + 1, len(noisy)))
        lo_b, hi_b = terms.observation_bounds(cfg)
        self._obs_lo, self._obs_hi = lo_b.astype(float), hi_b.astype(float)
        # actuator dead time: the actions waiting to reach the drive, oldest first (row 0 of each column; it is
        # also the `pending_action` feature, and stays 0 without a dead time)
        self._pending = np.zeros((max(cfg.action_delay, 1), n))
        # limit_rate mode: the speed limit of each row (omega), moved by the actions; observed as speed_limit
        self.limit = np.zeros(n)
        self._limit_mode = cfg.action_mode == "limit_rate"
        # force_level: columns the derived entries are computed from and written to, and each row's steady level
        self._levels = bool(cfg.force_level)
        if self._levels:
            col = {k: names.index(k) for k in ("omega", "domega", "force_rms", "defect", "contact_loss",
                                               "drive_impacts", "back_impacts", "force_level", "force_level_known",
                                               "steady_force_level", "steady_force_level_known")}  # fmt: skip
            self._level_cols = col
            self._steady = np.zeros((n, 2))  # (level, known) of the last clean, steady step
            self._window = int(cfg.level_window)
            if self._window:
                col.update({k: names.index(k) for k in ("mean_force_level", "mean_force_level_count")})
                self._mean = np.zeros((n, 2))  # (mean q, clean steps counted) of the level_window average
        self.X = np.zeros((n, K.NSTATE))
        self.A = np.zeros((n, K.NDOF))
        self.C = np.tile(np.asarray(cfg.params.consts, float), (n, 1))
        # the kernels' C_LOC (how a step over a contact change is taken), kept over plant changes
        self._loc = CONTACTS_LOCATED if cfg.locate_contacts else CONTACTS_CORRECTED if cfg.correct_kinks else 0.0
        self.C[:, C_LOC] = self._loc
        self._C_ro = K.readonly(self.C)  # rows as the kernels take them (one compiled signature)
        self.codes = np.full(n, self.code, np.int64)
        self.omega_n = np.full(n, cfg.params.omega_n)
        self.fs = self.C[:, C_FS].copy()
        self.tr_ref = np.ones(n)
        self.omega = np.full(n, cfg.omega_min)
        self.hist = np.zeros((n, cfg.poincare_window, 2))
        self.steps = np.zeros(n, np.int64)
        self.obs = np.zeros((n, self.n_obs), np.float32)
        self.I = np.zeros((n, ET.N_INFO))
        self.F = np.zeros((n, ET.N_FEATURES), np.float32)
        self.ACC = np.zeros((n, EK.N_ACC))
        self.S = terms.settings_vector(cfg)
        self.n_tol = np.full(n, TOL_N_START, np.int64)  # with `tol`: each row's coarse step count N
        # steps_per_period="auto": each row's steps per mesh period for its next interval (contact_steps of its last)
        self.auto = cfg.steps_per_period == "auto"
        self.n_steps = np.full(n, AUTO_FIRST_STEPS if self.auto else cfg.steps_per_period, np.int64)
        # each row's stable Newmark step (natural time; inf for the paper's beta 1/4): steps_per_period is raised
        # to it per row and interval (Fox-Goodwin at low omega), so a row's steps depend only on its own omega
        self.beta = np.full(n, float(cfg.params.newmark_beta))  # each row's own Newmark beta
        self.w_stab = np.full(n, stability_frequency(cfg.params))  # Omega_max / margin, 0: unconditionally stable
        # the same for the plain Newmark step (differs under the velocity correction, whose limit is lower): the
        # beta a row moves to, with the correction off for that interval
        self.w_plain = np.full(n, stability_frequency(cfg.params, plain=True))
        self.w_floor = np.zeros(n)  # below w_floor / N a row's beta is unstable at N steps per mesh period
        self._set_floor(slice(None))
        self._pc_buf = np.zeros((1, cfg.periods_per_step, K.N_PC))
        self._st_buf = np.zeros((1, K.N_STATS))
        self._zeros = np.zeros(n)

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        d = self.__dict__.copy()
        # a view of C: pickled (or deep-copied) on its own it would become a copy frozen at this
        # moment, and every later episode would run with these physics (issue 15 item 7)
        del d["_C_ro"]
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        self.__dict__.update(d)
        self._C_ro = K.readonly(self.C)

    # ------------------------------------------------------------------ info access
    @property
    def info(self) -> dict[str, np.ndarray]:
        """Info of every row as typed arrays (n,), keys as :data:`INFO_KEYS` (fresh arrays)."""
        I = self.I if self._info_cols is None else self.I[:, self._info_cols]
        cols = I.T.copy()  # one copy; the float columns are rows of it
        return {k: cols[j] if t is float else cols[j].astype(t) for j, (k, t) in enumerate(self._info_items)}

    def info_row(self, r: int) -> dict[str, Any]:
        """Plain-Python info dict of row ``r`` (floats, ints, bools)."""
        row = (self.I[r] if self._info_cols is None else self.I[r, self._info_cols]).tolist()
        out = dict(zip(self._info_keys, row))  # tolist gives Python floats; cast the int and bool keys
        for j, k, t in self._info_casts:
            out[k] = t(row[j])
        return out

    # ------------------------------------------------------------------ kernels
    def _integrate(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int):
        """Advance ``rows`` by ``periods`` mesh periods (omega linear in time w0 -> w1).

        Returns (poincare (m, periods, N_PC), stats (m, N_STATS), ok (m,), elapsed (m,)). Rows whose
        integration failed keep their previous state.
        """
        cfg = self.config
        if cfg.tol is not None:
            return self._integrate_tol(rows, w0, w1, periods)
        if not self.auto:
            return self._integrate_n(rows, w0, w1, periods, cfg.steps_per_period)
        if len(rows) == 0:
            return self._integrate_n(rows, w0, w1, periods, AUTO_OTHER_STEPS)
        ns = self.n_steps[rows]
        if self.conditional:  # below the scheme's stable omega at the row's count: no fewer than 64 (see _next_steps)
            low = np.minimum(np.asarray(w0, float), np.asarray(w1, float)) < self.w_floor[rows] / ns
            ns = np.where(low & (ns < AUTO_OTHER_STEPS), AUTO_OTHER_STEPS, ns)
        n0 = int(ns[0])
        # rows of different counts: one SIMD call, each row at its own (batch_kernels.integrate_stats_lanes)
        nsp = n0 if len(rows) == 1 or bool((ns == n0).all()) else ns.astype(np.int64)
        out = self._integrate_n(rows, w0, w1, periods, nsp)
        self._next_steps(rows, out[0], out[1], out[2])
        return out

    def _integrate_n(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int, nsp: int | np.ndarray):
        """:meth:`_integrate` with ``nsp`` steps per mesh period for every row of ``rows`` (an int64 array: one count
        per row, which the SIMD lanes take in one call)."""
        if self.conditional:
            return self._integrate_stable(rows, w0, w1, periods, nsp)
        return self._integrate_fixed(rows, w0, w1, periods, nsp)

    def _next_steps(self, rows: np.ndarray, pc: np.ndarray, st: np.ndarray, ok: np.ndarray) -> None:
        """``steps_per_period="auto"``: each row's steps per mesh period for its next interval, from its contact
        loss (time out of drive-side contact) in the interval just integrated and whether its last Poincare
        samples repeat (period 1 within :data:`AUTO_PERIODIC_DEFECT`): :func:`~gear_env.sim.integration.contact_steps`
        for Fox-Goodwin's beta (its ``corrected`` classes, 32 or 64, with ``correct_kinks``), else 64. A failed row
        keeps its count. (:meth:`_integrate` raises a count below 64 to 64 for an interval that reaches below the
        beta's stable omega at that count, at 48 steps about 0.21 (0.23 with the velocity correction), at 32 about
        0.32 (0.34), so that the row keeps its scheme there as at the tasks' 64 steps.)"""
        k = min(pc.shape[1], AUTO_PERIODIC_SAMPLES)
        if len(rows) == 1:  # plain floats (the single env)
            r = int(rows[0])
            if ok[0]:
                if self.beta[r] != FOX_GOODWIN_BETA:
                    self.n_steps[r] = AUTO_OTHER_STEPS
                    return
                sep = float(st[0, K.ST_SEP_TIME] + st[0, K.ST_BACK_TIME]) / max(float(st[0, K.ST_TIME]), 1e-300)
                p = pc[0, -k:, : K.NSTATE]
                periodic = k > 1 and float(np.abs(p[1:] - p[:-1]).max()) <= AUTO_PERIODIC_DEFECT
                self.n_steps[r] = contact_steps(sep, periodic, self.config.correct_kinks)
            return
        good = rows[ok]
        sep = (st[ok, K.ST_SEP_TIME] + st[ok, K.ST_BACK_TIME]) / np.maximum(st[ok, K.ST_TIME], 1e-300)
        p = pc[ok][:, -k:, : K.NSTATE]
        periodic = (np.abs(p[:, 1:] - p[:, :-1]).max(axis=(1, 2), initial=0.0) <= AUTO_PERIODIC_DEFECT) & (k > 1)
        n = contact_steps(sep, periodic, self.config.correct_kinks)
        self.n_steps[good] = np.where(self.beta[good] == FOX_GOODWIN_BETA, n, AUTO_OTHER_STEPS)

    def _set_floor(self, r: int | slice) -> None:
        """``w_floor`` of rows ``r``: N times the omega below which :func:`~gear_env.sim.linear.stable_betas` moves
        their beta at N steps per mesh period (0 for the paper's beta), and the flag that any row may need it."""
        b = np.minimum(self.beta[r], 0.25 - 1e-300)
        self.w_floor[r] = np.where(
            self.w_stab[r] > 0,
            (2.0 * math.pi) * self.w_stab[r] * np.sqrt((0.25 - b) / (1.0 - 1e-9)),
            0.0,
        )
        self.conditional = bool((self.w_floor > 0).any())

    def _integrate_stable(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int, nsp: int | np.ndarray):
        """:meth:`_integrate` under a conditionally stable Newmark beta (``params.newmark_beta`` < 1/4): every
        row keeps ``nsp`` steps; a row whose interval reaches below its ``w_floor / nsp`` (where that beta is
        unstable at this step count) takes, for this interval, the beta closest to its own that is stable there
        (:func:`gear_env.sim.linear.stable_betas`, towards the paper's 1/4). The cost per step stays that of
        the fixed count, all rows are stepped together, and a row's beta depends only on its own interval (so
        single and vector env agree bit for bit). Under the velocity correction a row leaves it where its own limit
        is exceeded (``w_stab``) and takes the plain Newmark step there, of beta 1/12 where plain Fox-Goodwin is
        stable and the beta :func:`stable_betas` gives for the plain step (``w_plain``) below."""
        if len(rows) == 1:  # the single env: plain floats
            if min(float(w0[0]), float(w1[0])) >= self.w_floor[rows[0]] / nsp:
                return self._integrate_fixed(rows, w0, w1, periods, nsp)
            moved = np.ones(1, bool)
        else:
            moved = np.minimum(w0, w1) < self.w_floor[rows] / nsp
            if not moved.any():
                return self._integrate_fixed(rows, w0, w1, periods, nsp)
        mr = rows[moved]
        w_low = np.minimum(np.asarray(w0, float)[moved], np.asarray(w1, float)[moved])
        vc = self.C[mr, C_VC].copy()  # the velocity correction (its own, lower limit) is left for the interval
        self.C[mr, C_BETA] = stable_betas(
            self.beta[mr], self.w_plain[mr], w_low, nsp[moved] if isinstance(nsp, np.ndarray) else nsp
        )
        self.C[mr, C_VC] = 0.0
        try:
            return self._integrate_fixed(rows, w0, w1, periods, nsp)
        finally:
            self.C[mr, C_BETA] = self.beta[mr]
            self.C[mr, C_VC] = vc

    def _integrate_fixed(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int, nsp: int | np.ndarray):
        """:meth:`_integrate` with ``nsp`` fixed steps per mesh period for every row."""
        m = len(rows)
        if self.single and m == 1:  # fast path of the single env: no fancy indexing, reused buffers
            r = int(rows[0])
            if self._pc_buf.shape[1] != periods:
                self._pc_buf = np.zeros((1, periods, K.N_PC))
            pc, st = self._pc_buf, self._st_buf
            x = self.X[r].copy()
            a = self.A[r].copy()
            c = self._C_ro[r]
            # integrate()'s one-system call without its argument checks (these buffers are the env's own, sized
            # above): the same kernel, the same numbers
            status, _done, el = K.integrate_stats_lazy(
                x, a, 0.0, float(w0[0]), float(w1[0]), periods, nsp, c, self.code, pc[0], st[0], NEWTON_MAX_ITER,
                NEWTON_TOL, True, _excitation_table(int(nsp), c),
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
        # (a count per row: the SIMD lanes whatever the number of rows)
        run = integrate(
            X, A, self.C[rows], self.code, W0, W1, periods, nsp, simd=m >= LANES_MIN or isinstance(nsp, np.ndarray)
        )
        status, elapsed, pc, st = run.status, run.elapsed, run.poincare, run.stats
        # the kernel flags non-finite or exploding states; a non-finite statistic would mean the same
        ok = (status == K.OK) & np.isfinite(st).all(axis=1)
        self.X[rows[ok]] = X[ok]
        self.A[rows[ok]] = A[ok]
        return pc, st, ok, elapsed

    def _integrate_tol(self, rows: np.ndarray, w0: np.ndarray, w1: np.ndarray, periods: int):
        """:meth:`_integrate` with the error-controlled integrator (``tol``), one row after another (the
        SIMD lanes take one fixed step count); each row carries its step count from period to period."""
        m = len(rows)
        pc = np.zeros((m, periods, K.N_PC))
        st = np.zeros((m, K.N_STATS))
        ok = np.zeros(m, bool)
        elapsed = np.zeros(m)
        for i, r in enumerate(rows):
            x = self.X[r].copy()
            a = self.A[r].copy()
            run = integrate(
                x, a, self._C_ro[r], self.code, float(w0[i]), float(w1[i]), periods, 0, poincare=pc[i], stats=st[i],
                err_tol=float(self.config.tol), n_start=int(self.n_tol[r]),
            )  # fmt: skip
            ok[i] = run.status == K.OK and bool(np.isfinite(st[i]).all())
            elapsed[i] = run.elapsed
            if ok[i]:
                self.X[r] = x
                self.A[r] = a
                if run.steps_last:
                    self.n_tol[r] = int(run.steps_last)
        return pc, st, ok, elapsed

    def demand(self, step: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Required omega at env step index ``step`` of ``rows`` (default 0..m-1; 0 without a demand).

        Beyond the episode's ``max_steps`` the last value holds."""
        if self.config.demand is None:
            return np.zeros(np.shape(step))
        st = np.minimum(np.asarray(step, np.int64), self._dem.shape[1] - 1)
        return self._dem[np.arange(len(st)) if rows is None else rows, st]

    # ------------------------------------------------------------------ observation space
    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) float32 arrays of the observation Box."""
        return self.terms.observation_bounds(self.config)

    def obs_names(self) -> list[str]:
        """Name of each observation entry (also :attr:`observation_names`)."""
        return list(self.observation_names)

    # ------------------------------------------------------------------ reset / step
    def _episode_params(self, rng: np.random.Generator) -> GearParams:
        cfg = self.config
        p = cfg.params
        if not cfg.randomize_params:
            return p
        s = cfg.randomize_scale
        f = rng.uniform(1.0 - s, 1.0 + s, size=6)
        return p.replace(
            xi_m=p.xi_m * f[1],
            xi_p=p.xi_p * f[2],
            xi_g=p.xi_g * f[3],
            T_p=p.T_p * f[4],
            T_g=p.T_g * f[5],
        ).with_stiffness_scale(f[0])

    def _post(self, rows, st, ok, elapsed, w0, w1, is_reset):
        m = len(rows)
        reward = np.zeros(m)
        terminated = np.zeros(m, np.bool_)
        truncated = np.zeros(m, np.bool_)
        if self.config.demand is None:
            demand = demand_next = self._zeros[:m]
        else:
            steps = self.steps[rows]
            demand = self.demand(steps, rows)
            demand_next = demand if is_reset else self.demand(steps + 1, rows)
        EK.post_step(
            rows, st, ok, elapsed, w0, w1, demand, demand_next, is_reset, self.S, self.hist, self.tr_ref, self.fs,
            self.omega_n, self.steps, self.X, self.ACC, self.I, self._reward_cols, self._cost_cols, self.F,
            self._obs_cols, self.obs, reward, terminated, truncated, self._pending[0],
        )  # fmt: skip
        return reward, terminated, truncated

    def reset_rows(self, rows: np.ndarray, rngs: list[np.random.Generator], options: dict | None = None) -> None:
        """Start new episodes in ``rows``; ``rngs[j]`` is the generator of row ``rows[j]``.

        ``options`` may hold ``"omega"`` (initial omega, overrides the configured draw).
        """
        cfg = self.config
        rows = np.asarray(rows, np.int64)
        w_init = np.empty(len(rows))
        raw = None if not options else check_options(options, ("omega",)).get("omega")
        forced: float | None = None
        if raw is not None:
            try:  # a string, list or bool is reported like an out-of-range number
                forced = math.nan if isinstance(raw, bool) else float(raw)
            except (TypeError, ValueError):
                forced = math.nan
            if not (math.isfinite(forced) and cfg.omega_min <= forced <= cfg.omega_max):
                raise ValueError(f"reset option 'omega' must be in [{cfg.omega_min:g}, {cfg.omega_max:g}], got {raw!r}")
        T = cfg.max_steps
        for j, r in enumerate(rows):
            # draws from the row's generator, in this order: parameter jitter, plant of the family,
            # initial omega, duty cycle, demand (v0 draws only the first and the third, as before)
            rng = rngs[j]
            p = self._episode_params(rng) if cfg.randomize_params else cfg.params
            factors = {"load": 1.0, "e_m1": 1.0}
            if cfg.plant_family is not None:
                factors = cfg.plant_family.draw(rng)
                p = cfg.plant_family.plant(p, factors)
            iw = cfg.initial_omega
            if forced is not None:
                w_init[j] = forced
            elif iw is None:
                w_init[j] = rng.uniform(cfg.omega_min, cfg.omega_max)
            elif isinstance(iw, tuple):
                w_init[j] = rng.uniform(iw[0], iw[1]) if iw[1] > iw[0] else iw[0]
            else:
                w_init[j] = iw
            load = None
            if cfg.duty_cycle is not None:
                load = cfg.duty_cycle.draw(rng, T)
                self._load[r, :T] = load
                self._load[r, T] = load[-1]
            if cfg.demand == "random":
                lo, hi = cfg.demand_range or (cfg.omega_min, cfg.omega_max)
                self._dem[r, : T + 1] = random_demand(rng, T, lo, hi, cfg.demand_segment_steps)
                self._dem[r, T + 1] = self._dem[r, T]
            wear = None
            if cfg.wear is not None:
                wear = cfg.wear.draw(rng, T)
                self._wear[r, :T] = wear
                self._wear[r, T] = wear[-1]
            if len(self._noise_idx):
                self._noise[r] = rng.standard_normal((T + 1, len(self._noise_idx)))
            if self._scenario or cfg.demand is not None:
                dem = self._dem[r, : T + 1].copy() if cfg.demand is not None else None
                self.episodes[r] = Episode(
                    p, factors, np.ones(T) if load is None else load.copy(), dem, float(w_init[j]),
                    None if wear is None else wear.copy(),
                )  # fmt: skip
            changes = load is not None or wear is not None
            plant = self._derive_plant(self.episodes[r].params_at(0) if changes else p)
            self._plants[r] = {self._level(r, 0): plant}  # a new episode pair: its levels are derived anew
            self._set_plant(r, plant, equilibrium=True)
        self.omega[rows] = w_init
        if self._limit_mode:  # the limit starts at the bottom of its band
            self.limit[rows] = ET.action_bounds(cfg)[0]
            self._show_limit(rows)
        if cfg.action_delay:  # the drive holds the initial speed until the first action arrives
            alo, ahi = ET.action_bounds(cfg)
            hold = 2.0 * (w_init - alo) / (ahi - alo) - 1.0
            self._pending[:, rows] = 0.0 if cfg.action_mode == "delta" else hold
        self.hist[rows] = 0.0
        # a new episode is at step 0 before its warm-up: the reset observation shows the demand of step 0, not of the
        # step the row's previous episode ended at (reset(seed) alone determines the episode)
        self.steps[rows] = 0
        self.n_tol[rows] = TOL_N_START  # with `tol`: a fresh episode starts from the same step count
        if self.auto:
            self.n_steps[rows] = AUTO_FIRST_STEPS  # and with "auto"
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
        self._add_noise(rows, ok_all)
        if self._levels:
            self._steady[rows] = 0.0
            if self._window:
                self._mean[rows] = 0.0
            self._add_levels(rows, ok_all)

    def _add_noise(self, rows: np.ndarray, fresh: np.ndarray) -> None:
        """Sensor noise on the observation of the ``rows`` whose observation was just written (``fresh``):
        the entry of step t gets ``sensor_noise`` times draw t of its column, a ``prev_`` entry draw t - 1
        (the value the previous observation showed), clipped to the observation bounds."""
        if not len(self._noise_idx):
            return
        rows = np.asarray(rows, np.int64)[np.asarray(fresh, bool)]
        if not len(rows):
            return
        sig = self.config.sensor_noise
        t = np.minimum(self.steps[rows], self.config.max_steps)
        obs, lo, hi = self.obs, self._obs_lo, self._obs_hi
        idx = self._noise_idx
        obs[rows[:, None], idx] = np.clip(obs[rows][:, idx] + sig * self._noise[rows, t], lo[idx], hi[idx])
        if len(self._noise_prev):  # at the reset the memory copy is the first reading itself
            k, c = self._noise_prev[:, 0], self._noise_prev[:, 1]
            z = self._noise[rows, np.maximum(t - 1, 0)][:, c]
            obs[rows[:, None], k] = np.clip(obs[rows][:, k] + sig * z, lo[k], hi[k])

    def _add_levels(self, rows: np.ndarray, fresh: np.ndarray) -> None:
        """The ``force_level`` entries of the ``rows`` whose observation was just written (``fresh``), from that
        observation itself (after any sensor noise): gear_env/envs/force_level.py."""
        rows = np.asarray(rows, np.int64)[np.asarray(fresh, bool)]
        if not len(rows):
            return
        cfg, c, o = self.config, self._level_cols, self.obs
        x = o[rows].astype(float)
        w_end = cfg.omega_min + 0.5 * (x[:, c["omega"]] + 1.0) * (cfg.omega_max - cfg.omega_min)
        w_mid = FL.step_mean_omega(w_end, x[:, c["domega"]], cfg.max_domega)
        level, known = FL.force_level(w_mid, x[:, c["force_rms"]])
        level = np.clip(np.nan_to_num(level, nan=0.0), -FL.LEVEL_CLIP, FL.LEVEL_CLIP)
        trouble = FL.troubled(
            x[:, c["contact_loss"]], x[:, c["drive_impacts"]] + x[:, c["back_impacts"]], x[:, c["defect"]]
        )
        steady = known & ~trouble & (np.abs(x[:, c["domega"]]) <= FL.STEADY_DOMEGA + 1e-6)
        st = self._steady[rows]
        st[steady, 0] = level[steady]
        st[steady, 1] = 1.0
        self._steady[rows] = st
        o[rows, c["force_level"]] = level
        o[rows, c["force_level_known"]] = known
        o[rows, c["steady_force_level"]] = st[:, 0]
        o[rows, c["steady_force_level_known"]] = st[:, 1]
        if self._window:  # the level_window average of q over clean steps (FL.mean_level_update)
            noisy = FL.troubled(
                x[:, c["contact_loss"]],
                x[:, c["drive_impacts"]] + x[:, c["back_impacts"]],
                x[:, c["defect"]],
                margin=2.0 * cfg.sensor_noise,
            )
            m = self._mean[rows]
            m[:, 0], m[:, 1] = FL.mean_level_update(
                m[:, 0], m[:, 1], w_mid, x[:, c["force_rms"]], known & ~noisy, self._window
            )
            self._mean[rows] = m
            o[rows, c["mean_force_level"]] = np.where(
                m[:, 1] > 0, np.clip(np.log(np.maximum(m[:, 0], 1e-6)), -FL.LEVEL_CLIP, FL.LEVEL_CLIP), 0.0
            )
            o[rows, c["mean_force_level_count"]] = np.minimum(m[:, 1], self._window) / self._window

    def _derive_plant(self, p: GearParams) -> tuple:
        """What the gear pair ``p`` gives a row of the environment: (constants with the env's ``C_LOC``, Newmark
        beta, stable omega, that of the plain step, static equilibrium state, its transmission-error reference).
        Refuses a pair with extensions or another number of constants than the environment's."""
        refuse_extensions(p, "the environment's plant")
        if len(p.consts) != self.C.shape[1]:
            raise ValueError(
                f"a plant's parameters have {len(p.consts)} constants where the environment's have "
                f"{self.C.shape[1]}: every plant of a family must have as many excitation harmonics as the base"
            )
        c = np.array(p.consts, float)
        c[C_LOC] = self._loc
        x0 = np.zeros(K.NSTATE)
        K.static_equilibrium(K.readonly(c), self.code, 0.0, x0)
        tr_ref = math.sqrt(max(0.5 * float(np.sum(x0[:4] ** 2)), 1e-300))
        return c, float(p.newmark_beta), stability_frequency(p), stability_frequency(p, plain=True), x0, tr_ref

    def _set_plant(self, r: int, plant: tuple, equilibrium: bool = False) -> None:
        """Row ``r`` simulates the pair derived in ``plant`` (:meth:`_derive_plant`) from now on (the features' static
        references follow its load); ``equilibrium``: also restart it from the static equilibrium (a new episode)."""
        c, self.beta[r], self.w_stab[r], self.w_plain[r], x0, self.tr_ref[r] = plant
        self.C[r] = c
        self._set_floor(r)
        self.fs[r] = c[C_FS]
        if equilibrium:
            self.X[r] = x0
            self.A[r] = 0.0

    def _level(self, r: int, t: int) -> tuple[float, float]:
        """The (load, wear) factors of row ``r`` at step ``t``: the key of its derived pair then (``_plants``)."""
        return (
            float(self._load[r, t]) if self.config.duty_cycle is not None else 1.0,
            float(self._wear[r, t]) if self.config.wear is not None else 1.0,
        )

    def _apply_duty(self, rows: np.ndarray) -> None:
        """Change the load of the rows whose duty cycle steps to a new level in the coming step."""
        cfg = self.config
        if cfg.duty_cycle is None and cfg.wear is None:
            return
        T = cfg.max_steps
        L, Wr = self._load, self._wear
        for r, t in zip(rows.tolist(), self.steps[rows].tolist()):
            if 0 < t < T and (
                (cfg.duty_cycle is not None and L[r, t] != L[r, t - 1])
                or (cfg.wear is not None and Wr[r, t] != Wr[r, t - 1])
            ):
                # each level's pair is derived once per episode (reset_rows clears them): a duty cycle returns to
                # its levels several times an episode
                level = self._level(r, t)
                plant = self._plants[r].get(level)
                if plant is None:
                    plant = self._plants[r][level] = self._derive_plant(self.episodes[r].params_at(t))
                self._set_plant(r, plant)

    def _show_limit(self, rows: np.ndarray) -> None:
        """Write the rows' speed limit into the feature the observation gathers (scaled like omega)."""
        lo, hi = self.config.omega_min, self.config.omega_max
        self.F[rows, ET.F.speed_limit] = np.clip(2.0 * (self.limit[rows] - lo) / (hi - lo) - 1.0, -1.0, 1.0)

    def decode(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Omega at the end of the next step for actions in [-1, 1] (rate-limited, clipped)."""
        out = np.empty(len(rows))
        limit = self.config.action_mode in ET.LIMIT_MODES  # only the limit modes read the demand of the step
        demand = self.demand(self.steps[rows], rows) if limit else self._zeros[: len(rows)]
        EK.decode_actions(self.omega[rows], actions, demand, self.S, ET.ACTION_CODES[self.config.action_mode], out)
        return out

    def step_rows(self, rows: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance ``rows`` by one control step with actions (m,) in [-1, 1].

        Updates ``obs``, the info matrix and the episode sums of the rows; returns (reward,
        terminated, truncated) arrays (m,). A diverged row keeps its state, omega and observation.
        """
        rows = np.asarray(rows, np.int64)
        self._apply_duty(rows)
        w0 = self.omega[rows]
        if self.config.action_delay:  # the oldest waiting action reaches the drive; this one queues
            q = self._pending
            applied = q[0, rows]
            q[:-1, rows] = q[1:, rows]
            q[-1, rows] = np.clip(np.asarray(actions, float), -1.0, 1.0)
            actions = applied
        if self._limit_mode:  # the action moves the speed limit; the drive then follows the demand under it
            self.limit[rows] = ET.limit_after(self.config, self.limit[rows], actions)
            self._show_limit(rows)
            actions = ET.limit_action(self.config, self.limit[rows])
        w1 = self.decode(rows, actions)
        pc, st, ok, elapsed = self._integrate(rows, w0, w1, self.config.periods_per_step)
        EK.push_history(rows, pc, w0, w1, ok, self.hist)
        self.omega[rows] = np.where(ok, w1, w0)
        out = self._post(rows, st, ok, elapsed, w0, w1, False)
        self._add_noise(rows, ok)
        if self._levels:
            self._add_levels(rows, ok)
        return out


__all__ = [
    "COST_KEYS",
    "GearSpeedCore",
    "check_options",
    "check_seed",
    "INFO_KEYS",
    "REWARD_KEYS",
    "SENSOR_NAMES",
    "TERMS",
    "periodicity_defect",
]
