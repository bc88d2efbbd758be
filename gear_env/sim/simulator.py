"""Python API of the simulator: validation, state handling and results objects.

* :func:`simulate` - one run at a fixed meshing frequency: a transient, then recorded periods.
* :class:`GearSimulator` - a stateful simulator that advances by whole mesh periods under a
  constant or linearly ramping meshing frequency and keeps its state between calls (the
  environment uses it).

Units: the meshing frequency ``omega`` is Omega/omega_n (dimensionless); displacements are in
b0 units (b0 = half backlash by default); time ``s`` is natural time omega_n t (use
``Trajectory.time_seconds`` for seconds).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._numba_cache import announce_compile
from ..errors import SimulationDivergedError
from . import kernels as K
from .integration import NEWTON_MAX_ITER as NEWTON_MAX_ITER  # re-exported (older imports)
from .integration import NEWTON_TOL as NEWTON_TOL
from .integration import TOL_N_START, integrate
from .linear import min_steps_per_period, newmark_step_limit
from .params import (
    C_E1,
    C_PHI_E,
    FOX_GOODWIN_BETA,
    NEWMARK_BETA,
    GearParams,
    kernel_code,
    model_code,
    refuse_extensions,
    stack_consts,
)

SIM_COMPILE_TIME = "15 s on an idle 2-core machine, several times that under load"
"""What the first-use notice says the simulator kernels take to compile (measured: 13 s for both models)."""

DEFAULT_STEPS_PER_PERIOD = 192
"""Fewest Newmark steps per mesh period of the automatic choice (:func:`default_steps_per_period`);
chosen by the convergence study in docs/SIMULATOR.md."""

MAX_NATURAL_STEP = 0.12
"""Largest natural-time step 2 pi / (omega N) of the automatic choice (binds below omega ~ 0.27)."""

FOX_GOODWIN_STEPS_PER_PERIOD = 88
"""Steps per mesh period of the automatic choice under Fox-Goodwin's beta (``GearParams.newmark_beta = 1/12``),
raised to the stability floor below omega ~ 0.11: on the period-1 orbits of docs/SIMULATOR.md it is at least as
accurate as the paper's scheme at its automatic 192 (p95 4.6e-4 against 5.8e-4 b0, max 8.8e-4 against 1.0e-3) at
about twice the mesh periods per second, and below 1e-3 b0 down to omega 0.12."""

VC_STEPS_PER_PERIOD = 68
"""Steps per mesh period of the automatic choice under Fox-Goodwin with the velocity correction
(``GearParams.velocity_correction``), raised to its stability floor below omega ~ 0.16: on the period-1 orbits of
docs/SIMULATOR.md it is more accurate than the paper's scheme at its automatic 192 (p95 3.8e-4 against 5.8e-4 b0,
max 8.1e-4 against 1.0e-3) with 2.8x fewer steps."""


STATE_NAMES = ("X_p", "Y_p", "X_g", "Y_g", "U", "dX_p", "dY_p", "dX_g", "dY_g", "dU")

_STATUS_TEXT = {
    K.DIVERGED: f"state became non-finite or exceeded {K.DIVERGENCE_LIMIT:g} b0",
    K.NEWTON_FAILED: "Newton iteration did not converge even after splitting the step 64 times",
}


OMEGA_MIN = 1e-3
OMEGA_MAX = 100.0


def check_omega(omega: Any, name: str = "omega") -> float:
    """Validate a dimensionless meshing frequency (in [OMEGA_MIN, OMEGA_MAX]) and return it as float."""
    if isinstance(omega, bool) or not isinstance(omega, (int, float, np.integer, np.floating)):
        raise ValueError(
            f"{name} (Omega/omega_n) must be a real number in [{OMEGA_MIN:g}, {OMEGA_MAX:g}], got {omega!r}"
        )
    w = float(omega)
    if not (math.isfinite(w) and OMEGA_MIN <= w <= OMEGA_MAX):
        raise ValueError(
            f"{name} (Omega/omega_n) must be a finite number in [{OMEGA_MIN:g}, {OMEGA_MAX:g}], got {omega!r}"
        )
    return w


def check_count(value: Any, name: str, minimum: int = 1) -> int:
    """Validate an integer count >= minimum and return it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def check_steps(steps_per_period: Any) -> int:
    """Validate the number of Newmark steps per mesh period (8 .. 100000)."""
    n = check_count(steps_per_period, "steps_per_period", 8)
    if n > 100_000:
        raise ValueError(f"steps_per_period must be in [8, 100000], got {steps_per_period!r}")
    return n


def check_tol(tol: Any) -> float | None:
    """The error tolerance per mesh period (b0 units) validated: None or a number in [1e-8, 0.1]."""
    if tol is None:
        return None
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)):
        raise ValueError(f"tol must be a number in [1e-8, 0.1] (b0 units) or None, got {tol!r}")
    t = float(tol)
    if not (math.isfinite(t) and 1e-8 <= t <= 0.1):
        raise ValueError(f"tol must be a number in [1e-8, 0.1] (b0 units) or None, got {tol!r}")
    return t


def default_steps_per_period(omega: float, params: GearParams | None = None) -> int:
    """Default Newmark steps per mesh period at meshing frequency omega (Omega/omega_n) for ``params``' scheme.

    The paper's scheme (``params`` None or ``newmark_beta`` 1/4; also any other beta):
    ``max(DEFAULT_STEPS_PER_PERIOD, ceil(2 pi / (MAX_NATURAL_STEP omega)))``: 192 steps per mesh
    period, and more below omega ~ 0.27 so that the step in natural time stays <= 0.12 (at low
    omega a mesh period is long compared with the structural modes). With it the Poincare points
    agree with the independent solve_ivp reference to < 1e-3 b0 in every periodic regime of the
    convergence study (docs/SIMULATOR.md); it is stable for every allowed beta.

    Fox-Goodwin (``newmark_beta`` = ``FOX_GOODWIN_BETA``): ``max(FOX_GOODWIN_STEPS_PER_PERIOD,
    min_steps_per_period(params, omega))``: 88 steps, more below omega ~ 0.11 where the scheme needs them to be
    stable; with ``velocity_correction``, ``max(VC_STEPS_PER_PERIOD, min_steps_per_period(params, omega))``: 68
    steps, more below omega ~ 0.16.
    """
    w = check_omega(omega)
    if params is not None and params.velocity_correction:
        return max(VC_STEPS_PER_PERIOD, min_steps_per_period(params, w))
    if params is not None and params.newmark_beta == FOX_GOODWIN_BETA:
        return max(FOX_GOODWIN_STEPS_PER_PERIOD, min_steps_per_period(params, w))
    return max(DEFAULT_STEPS_PER_PERIOD, math.ceil(2.0 * math.pi / (MAX_NATURAL_STEP * w)))


def auto_steps_rule(params: GearParams | None = None) -> str:
    """The rule :func:`default_steps_per_period` applies for ``params`` (a text for cache keys and records)."""
    if params is not None and params.velocity_correction:
        return f"auto-fox-goodwin-vc(max({VC_STEPS_PER_PERIOD}, stability floor))"
    if params is not None and params.newmark_beta == FOX_GOODWIN_BETA:
        return f"auto-fox-goodwin(max({FOX_GOODWIN_STEPS_PER_PERIOD}, stability floor))"
    return f"auto(max({DEFAULT_STEPS_PER_PERIOD}, 2 pi / ({MAX_NATURAL_STEP} omega)))"


def resolve_steps(steps_per_period: Any, omega: float, params: GearParams | None = None) -> int:
    """``steps_per_period`` validated, or :func:`default_steps_per_period` (omega, params) if it is None."""
    if steps_per_period is None:
        return default_steps_per_period(omega, params)
    return check_steps(steps_per_period)


def check_stable_steps(params: GearParams, steps_per_period: int, omega: float, h_limit: float | None = None) -> None:
    """ValueError if ``steps_per_period`` Newmark steps per mesh period at meshing frequency ``omega`` (the
    lowest of an interval) exceed the stability limit of ``params.newmark_beta`` (none for the paper's 1/4;
    :func:`gear_env.sim.linear.newmark_step_limit` for Fox-Goodwin's 1/12). ``h_limit``: that limit, if
    already computed (natural time)."""
    h = newmark_step_limit(params) if h_limit is None else h_limit
    if not math.isfinite(h) or 2.0 * math.pi / (omega * steps_per_period) <= h:
        return
    need = math.ceil(2.0 * math.pi / (omega * h))
    raise ValueError(
        f"steps_per_period = {steps_per_period} is unstable with GearParams.newmark_beta = "
        f"{params.newmark_beta:.6g} at omega = {omega:g}: the step 2 pi / (omega N) = "
        f"{2.0 * math.pi / (omega * steps_per_period):.4g} exceeds the scheme's stable step {h:.4g} (natural time); "
        f"give steps_per_period >= {need} at this omega, or newmark_beta = {NEWMARK_BETA} (unconditionally stable)"
    )


def default_initial_state(params: GearParams, model: str = "dynamic") -> np.ndarray:
    """Default initial state (MODEL.md A10): drive-side static equilibrium, zero velocities.

    Returns a float64 array of 10 values [X_p, Y_p, X_g, Y_g, U, and their derivatives] in b0
    units (derivatives per unit natural time).
    """
    out = np.zeros(K.NSTATE)
    K.static_equilibrium(params.consts, kernel_code(model, params), 0.0, out)
    return out


def _check_params(params: Any) -> GearParams:
    """``params`` if it is a GearParams, the default (Table 1, kappa = 0.2) if None."""
    p = params if params is not None else GearParams()
    if not isinstance(p, GearParams):
        raise ValueError(f"params must be a GearParams, got {type(p).__name__}")
    return p


def _check_params_rows(params: Any, n_omegas: int) -> list[GearParams]:
    """simulate_batch's ``params``: [one GearParams] (None or a GearParams, shared) or one per
    system (a list or tuple of GearParams whose length is ``n_omegas``, or any length if there is
    one omega)."""
    if params is None or isinstance(params, GearParams):
        return [_check_params(params)]
    if not isinstance(params, (list, tuple)):
        raise ValueError(f"params must be a GearParams or a list of GearParams, got {type(params).__name__}")
    if len(params) == 0:
        raise ValueError("params must not be an empty list")
    if n_omegas != 1 and len(params) != n_omegas:
        raise ValueError(
            f"params has {len(params)} entries but there are {n_omegas} omegas: give one GearParams per omega, "
            "one shared GearParams, or a single omega"
        )
    for i, q in enumerate(params):
        if not isinstance(q, GearParams):
            raise ValueError(f"params[{i}] must be a GearParams, got {type(q).__name__}")
    return list(params)


def _refuse_complex(value: Any, name: str) -> None:
    """ValueError if ``value`` holds complex numbers (float conversion would drop the imaginary
    part with only a warning); ragged input passes, for the caller's shape check to refuse."""
    try:
        cplx = np.iscomplexobj(value)
    except (TypeError, ValueError):
        cplx = False
    if cplx:
        raise ValueError(f"{name} must be real numbers, got complex values")


def _check_state(state: Any) -> np.ndarray:
    _refuse_complex(state, "initial_state")
    arr = np.asarray(state, dtype=float)
    if arr.shape != (K.NSTATE,):
        raise ValueError(f"initial_state must have shape (10,) [5 positions, 5 velocities], got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("initial_state must be finite")
    return arr.copy()


AMPLITUDE_STATS = {
    "U": (K.ST_U_MAX, K.ST_U_MIN),
    "delta": (K.ST_D_MAX, K.ST_D_MIN),
    "bd": (K.ST_BD_MAX, K.ST_BD_MIN),
    "psi": (K.ST_PSI_MAX, K.ST_PSI_MIN),
    "force": (K.ST_F_MAX, K.ST_F_MIN),
}
"""Channel name -> (max, min) indices of the kernels' interval statistics vector."""


def stats_amplitude(stats: np.ndarray, name: str) -> float:
    """Half peak-to-peak of a channel from an interval statistics vector (``kernels.ST_*``).

    ``name``: 'U', 'delta', 'bd' (b0 units), 'psi' [rad] or 'force' (k_m0 b0 units).
    """
    if name not in AMPLITUDE_STATS:
        raise ValueError(f"amplitude name must be one of {sorted(AMPLITUDE_STATS)}, got {name!r}")
    hi, lo = AMPLITUDE_STATS[name]
    return float(0.5 * (stats[hi] - stats[lo]))


@dataclass
class IntervalStats:
    """Statistics of one advance of :class:`GearSimulator` (no time series).

    Attributes:
        omega_start, omega_end: meshing frequency at the start and end of the interval.
        periods: mesh periods simulated.
        duration: natural time elapsed (omega_n t).
        poincare: (periods, 14) array; columns 0-9 the state at each phase 2 pi k, then Delta,
            B_d, psi [rad], mesh force (all b0 / k_m0 b0 units).
        stats: raw statistics vector (see ``kernels.ST_*``).
    """

    omega_start: float
    omega_end: float
    periods: int
    duration: float
    poincare: np.ndarray
    stats: np.ndarray

    @property
    def separation_fraction(self) -> float:
        """Fraction of time the teeth were apart or in back contact (contact loss)."""
        return float((self.stats[K.ST_SEP_TIME] + self.stats[K.ST_BACK_TIME]) / max(self.stats[K.ST_TIME], 1e-300))

    @property
    def back_impacts(self) -> int:
        """Number of entries into back-side contact."""
        return int(self.stats[K.ST_BACK_IMPACTS])

    @property
    def drive_impacts(self) -> int:
        """Number of re-entries into drive-side contact after a separation."""
        return int(self.stats[K.ST_DRIVE_IMPACTS])

    @property
    def force_mean(self) -> float:
        """Time mean of the dimensionless mesh force F/(k_m0 b0)."""
        return float(self.stats[K.ST_F_SUM] / self.stats[K.ST_TIME])

    @property
    def force_rms_dynamic(self) -> float:
        """RMS of the fluctuation of the mesh force about its mean (k_m0 b0 units)."""
        t = self.stats[K.ST_TIME]
        m = self.stats[K.ST_F_SUM] / t
        return float(math.sqrt(max(self.stats[K.ST_F_SQ] / t - m * m, 0.0)))

    @property
    def force_peak(self) -> float:
        """Largest dimensionless mesh force in the interval."""
        return float(self.stats[K.ST_F_MAX])

    @property
    def translation_rms(self) -> float:
        """RMS bearing deflection sqrt(mean((X_p^2+Y_p^2+X_g^2+Y_g^2)/2)) [b0]."""
        return float(math.sqrt(self.stats[K.ST_TR_SQ] / self.stats[K.ST_TIME]))

    @property
    def translation_peak(self) -> float:
        """Largest radial bearing deflection of either gear [b0]."""
        return float(self.stats[K.ST_TR_MAX])

    def amplitude(self, name: str) -> float:
        """Half peak-to-peak of 'U', 'delta', 'bd', 'psi' or 'force' over the interval."""
        return stats_amplitude(self.stats, name)


class GearSimulator:
    """Stateful simulator of the gear-bearing pair, advanced by whole mesh periods.

    Each call to :meth:`advance` starts and ends on the Poincare section (mesh phase 2 pi k), so
    successive calls continue one trajectory seamlessly; omega may ramp linearly in time within
    a call (a motor's bounded acceleration).

    Args:
        params: physical parameters (SI); default Table 1.
        model: ``"constant"`` or ``"dynamic"`` backlash.
        steps_per_period: Newmark steps per mesh period, or None (default) for
            :func:`default_steps_per_period` of the lower omega of each :meth:`advance` /
            :meth:`record` call (192 for omega >= 0.27, more below).
        omega: meshing frequency Omega/omega_n at the start.
        initial_state: 10 values in b0 units, or None for MODEL.md A10.
        tol: error per mesh period (b0 units, all 10 states) instead of a step count: each mesh
            period of :meth:`advance` is integrated with contact changes located, with N and 2N
            steps, N chosen so that their estimated error is at most ``tol``, and Richardson-
            extrapolated (:func:`gear_env.sim.kernels.integrate_tol`; measured errors in
            docs/SIMULATOR.md). :meth:`record` then takes fixed steps, twice the last N. In
            [1e-8, 0.1]; not together with ``steps_per_period``. None (default): fixed steps. Below
            omega ~ 0.5, next to the period doublings, the error over many periods is not bounded by
            ``tol`` (up to 1.5e-2 b0 over 40 periods at tol 3e-3, omega = 0.3): use fixed steps or
            tol <= 3e-4 there (docs/SIMULATOR.md).
    """

    def __init__(
        self,
        params: GearParams | None = None,
        model: str = "dynamic",
        steps_per_period: int | None = None,
        omega: float = 1.0,
        initial_state: Any = None,
        tol: float | None = None,
    ):
        self.params = _check_params(params)
        self.tol = check_tol(tol)
        if self.tol is not None and steps_per_period is not None:
            raise ValueError(f"give steps_per_period or tol, not both (got {steps_per_period!r} and {tol!r})")
        self._n_tol = TOL_N_START
        announce_compile("drivers", "the simulator kernels", SIM_COMPILE_TIME)  # once per process, not per step
        self.model = model
        self.model_code = kernel_code(model, self.params)  # 2: the dynamic model under the involute backlash law
        if self.tol is not None and self.params.torque_fluctuates:
            raise ValueError(
                "tol (error control) does not take a torque fluctuation (GearParams.T_p1, T_g1 > 0): "
                "its periods restart the mesh phase; give steps_per_period instead"
            )
        if self.tol is not None and (self.params.newmark_beta != NEWMARK_BETA or self.params.velocity_correction):
            raise ValueError(
                f"tol (error control) takes only the paper's Newmark beta (GearParams.newmark_beta = {NEWMARK_BETA}, "
                f"velocity_correction = False), got {self.params.newmark_beta:.6g} and "
                f"{self.params.velocity_correction}; give steps_per_period instead"
            )
        self.auto_steps = steps_per_period is None
        self.steps_per_period = resolve_steps(steps_per_period, check_omega(omega), self.params)
        """Steps per mesh period of the last interval (fixed unless ``auto_steps``)."""
        self._h_limit = newmark_step_limit(self.params)
        check_stable_steps(self.params, self.steps_per_period, check_omega(omega), self._h_limit)
        self._consts = K.readonly(np.ascontiguousarray(self.params.consts))
        self.reset(initial_state=initial_state, omega=omega)

    def _interval_consts(self) -> np.ndarray:
        """The constants of the next interval: those of the parameters, with a fluctuating torque's
        phases advanced to the periods already done (every interval starts at mesh phase 0)."""
        if not self.params.torque_fluctuates:
            return self._consts
        return K.readonly(np.ascontiguousarray(self.params.consts_at_period(self.periods_done)))

    def _steps(self, w0: float, w1: float) -> int:
        """Steps per mesh period of an interval from w0 to w1 (updates ``steps_per_period``)."""
        if self.auto_steps:
            self.steps_per_period = default_steps_per_period(min(w0, w1), self.params)
        return self.steps_per_period

    def reset(self, initial_state: Any = None, omega: float | None = None) -> None:
        """Return to the given state (default A10) at time 0 and mesh phase 0."""
        if omega is not None:
            self.omega = check_omega(omega)
        self.x = (
            default_initial_state(self.params, self.model) if initial_state is None else _check_state(initial_state)
        )
        self.a = np.zeros(K.NDOF)
        self.time = 0.0
        self.periods_done = 0

    @property
    def state(self) -> np.ndarray:
        """Copy of the current state (10 values, b0 units)."""
        return self.x.copy()

    def _raise(self, status: int, period: int, omega: float) -> None:
        raise SimulationDivergedError(self.periods_done + period, _STATUS_TEXT.get(status, f"status {status}"), omega)

    def advance(self, periods: int, omega_end: float | None = None) -> IntervalStats:
        """Advance by ``periods`` mesh periods while omega goes linearly in time to ``omega_end``.

        Returns :class:`IntervalStats` (Poincare samples and interval statistics). Raises
        :class:`SimulationDivergedError` if the state blows up; the simulator's state is then
        left unchanged (the interval is discarded).
        """
        n = check_count(periods, "periods")
        w0 = self.omega
        w1 = w0 if omega_end is None else check_omega(omega_end, "omega_end")
        x = self.x.copy()
        a = self.a.copy()
        if self.tol is not None:
            r = integrate(x, a, self._consts, self.model_code, w0, w1, n, 0, err_tol=self.tol, n_start=self._n_tol)
            if r.status == K.OK:
                self._n_tol = int(r.steps_last)
                self.steps_per_period = 2 * self._n_tol
        else:
            nsp = self._steps(w0, w1)
            check_stable_steps(self.params, nsp, min(w0, w1), self._h_limit)
            r = integrate(x, a, self._interval_consts(), self.model_code, w0, w1, n, nsp)
        if r.status != K.OK:
            self._raise(r.status, r.done, w0)
        self.x, self.a = x, a
        self.omega = w1
        self.time += r.elapsed
        self.periods_done += n
        return IntervalStats(w0, w1, n, r.elapsed, r.poincare, r.stats)

    def record(self, periods: int, omega_end: float | None = None) -> Trajectory:
        """Like :meth:`advance` but returns the full time series of the interval."""
        n = check_count(periods, "periods")
        w0 = self.omega
        w1 = w0 if omega_end is None else check_omega(omega_end, "omega_end")
        x = self.x.copy()
        a = self.a.copy()
        nsp = 2 * self._n_tol if self.tol is not None else self._steps(w0, w1)
        check_stable_steps(self.params, nsp, min(w0, w1), self._h_limit)
        r = integrate(x, a, self._interval_consts(), self.model_code, w0, w1, n, nsp, record=True)
        if r.status != K.OK:
            self._raise(r.status, (r.done - 1) // nsp, w0)
        out = r.record
        out[:, K.REC_S] += self.time
        self.x, self.a = x, a
        self.omega = w1
        self.time += r.elapsed
        self.periods_done += n
        return Trajectory(
            data=out,
            steps_per_period=nsp,
            model=self.model,
            params=self.params,
        )


@dataclass
class Trajectory:
    """Recorded time series of a run, one row per Newmark step (plus the start).

    Columns of ``data``: the 10 states, natural time s, mesh phase phi [rad], omega, Delta, B_d,
    psi [rad], mesh force F/(k_m0 b0), contact region (+1 drive, 0 apart, -1 back). Poincare
    samples are the rows at phase 2 pi k (every ``steps_per_period`` rows).
    """

    data: np.ndarray
    steps_per_period: int
    model: str
    params: GearParams
    meta: dict[str, Any] = field(default_factory=dict)

    # time series accessors -------------------------------------------------------------
    @property
    def s(self) -> np.ndarray:
        """Natural time omega_n t."""
        return self.data[:, K.REC_S]

    @property
    def time_seconds(self) -> np.ndarray:
        """Physical time [s]."""
        return self.s / self.params.omega_n

    @property
    def phase(self) -> np.ndarray:
        """Mesh phase [rad]."""
        return self.data[:, K.REC_PHI]

    @property
    def omega(self) -> np.ndarray:
        """Meshing frequency Omega/omega_n at each row."""
        return self.data[:, K.REC_OMEGA]

    @property
    def states(self) -> np.ndarray:
        """(rows, 10) states in b0 units."""
        return self.data[:, : K.NSTATE]

    def __getitem__(self, name: str) -> np.ndarray:
        """A column by name: a state name (``'U'``, ``'dU'``, ``'X_p'``...) or ``'delta'``,
        ``'ddelta'`` (dDelta/ds), ``'bd'``, ``'psi'``, ``'force'``, ``'region'``, ``'s'``, ``'phase'``,
        ``'omega'``."""
        if name in STATE_NAMES:
            return self.data[:, STATE_NAMES.index(name)]
        if name == "ddelta":
            return self._ddelta()
        cols = {
            "s": K.REC_S,
            "phase": K.REC_PHI,
            "omega": K.REC_OMEGA,
            "delta": K.REC_DELTA,
            "bd": K.REC_BD,
            "psi": K.REC_PSI,
            "force": K.REC_FORCE,
            "region": K.REC_REGION,
        }
        if name not in cols:
            raise KeyError(f"unknown channel {name!r}; valid: {list(STATE_NAMES) + ['ddelta'] + list(cols)}")
        return self.data[:, cols[name]]

    def _ddelta(self) -> np.ndarray:
        """dDelta/ds from the recorded state (the psi' term is omitted: it is ~1e-15, MODEL.md 6)."""
        d = self.data
        psi = d[:, K.REC_PSI]
        sp, cp = np.sin(psi), np.cos(psi)
        if not self.params.te_harmonics:
            c = self.params.consts
            te = c[C_E1] * d[:, K.REC_OMEGA] * np.sin(d[:, K.REC_PHI] + c[C_PHI_E])
        else:  # the TE series: -omega de/dphi in b0 units
            te = -d[:, K.REC_OMEGA] * self.params.transmission_error(d[:, K.REC_PHI])[1] / self.params.length_scale
        return (d[:, 5] - d[:, 7]) * sp - (d[:, 6] - d[:, 8]) * cp + d[:, 9] + te

    @property
    def poincare_rows(self) -> np.ndarray:
        """Rows at phase 2 pi k after the first (one per recorded mesh period)."""
        return self.data[self.steps_per_period :: self.steps_per_period]

    def poincare(self, name: str) -> np.ndarray:
        """Poincare samples (one per recorded mesh period) of a channel (see ``__getitem__``)."""
        return self[name][self.steps_per_period :: self.steps_per_period]

    def amplitude(self, name: str) -> float:
        """Half peak-to-peak of a channel over the record (the paper's amplitude)."""
        v = self[name]
        return float(0.5 * (v.max() - v.min()))

    @property
    def contact_loss_fraction(self) -> float:
        """Fraction of steps (time-weighted) with the teeth apart or in back contact."""
        s = self.s
        h = np.diff(s)
        reg = self["region"][1:]
        return float(h[reg != 1].sum() / h.sum()) if h.sum() > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the ``gear-env simulate --json`` file)."""
        w = self.omega
        return {
            "omega": float(w[0]) if np.all(w == w[0]) else w.tolist(),
            "model": self.model,
            "steps_per_period": self.steps_per_period,
            "periods": (len(self.data) - 1) // self.steps_per_period,
            "units": "displacements in b0 (half backlash); force in k_m0 b0; psi in rad",
            "b0_m": self.params.length_scale,
            "amplitude_u": self.amplitude("U"),
            "amplitude_delta": self.amplitude("delta"),
            "amplitude_bd": self.amplitude("bd"),
            "amplitude_psi": self.amplitude("psi"),
            "amplitude_force": self.amplitude("force"),
            "contact_loss_fraction": self.contact_loss_fraction,
            "poincare_delta": self.poincare("delta").tolist(),
            "poincare_u": self.poincare("U").tolist(),
            "poincare_du": self.poincare("dU").tolist(),
            "params": self.params.to_dict(),
            **self.meta,
        }

    def to_json(self, path: str) -> None:
        """Write :meth:`to_dict` to ``path`` atomically."""
        from ..io import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=1))


def simulate(
    omega: float,
    model: str = "dynamic",
    periods: int = 200,
    transient: int = 300,
    steps_per_period: int | None = None,
    params: GearParams | None = None,
    initial_state: Any = None,
    tol: float | None = None,
) -> Trajectory:
    """Simulate the gear pair at a fixed meshing frequency.

    Args:
        omega: meshing frequency Omega/omega_n (> 0).
        model: ``"constant"`` or ``"dynamic"`` backlash (MODEL.md A8/A9).
        periods: mesh periods recorded after the transient (>= 1).
        transient: mesh periods discarded first (>= 0).
        steps_per_period: Newmark steps per mesh period; None (default) for
            :func:`default_steps_per_period` (omega) (192 for omega >= 0.27, more below).
        params: physical parameters (SI); default Table 1 with kappa = 0.2.
        initial_state: 10 values in b0 units, or None for the static equilibrium (A10).
        tol: error per mesh period (b0 units) instead of ``steps_per_period``: the transient is
            integrated error-controlled and the recorded periods with twice the coarse step count
            that met ``tol`` at its end (see :class:`GearSimulator`).

    Returns:
        :class:`Trajectory` of the recorded periods (time series and Poincare samples).

    Raises:
        ValueError: on invalid arguments (the message names the argument).
        SimulationDivergedError: if the state blows up.
    """
    w = check_omega(omega)
    check_count(periods, "periods")
    tr = check_count(transient, "transient", 0)
    sim = GearSimulator(params, model, steps_per_period, w, initial_state, tol)
    if tr > 0:
        sim.advance(tr)
    traj = sim.record(periods)
    traj.meta.update({"transient": tr})
    return traj


def simulate_batch(
    omegas: Any,
    model: str = "dynamic",
    periods: int = 200,
    transient: int = 300,
    steps_per_period: int | None = None,
    params: GearParams | Sequence[GearParams] | None = None,
    omega_end: Any = None,
    initial_states: Any = None,
    tol: float | None = None,
) -> list[IntervalStats]:
    """Simulate independent gear pairs at several meshing frequencies in one SIMD call.

    Each omega starts from the A10 initial state (or from ``initial_states``), runs ``transient`` mesh periods and then
    ``periods`` recorded ones, exactly as ``GearSimulator(params, model, N, omega)`` followed by
    ``advance(transient)`` and ``advance(periods)`` would, bit for bit, but the systems are
    stepped together (``batch_kernels.integrate_stats_lanes``, 4 per AVX2 instruction): about
    2x the throughput of one trajectory after the other. For parameter studies and
    fresh-start bifurcation diagrams; a continuation sweep (each point starting from the last,
    :func:`gear_env.analysis.sweep`) is sequential by nature. ``params`` may give one parameter
    set per system (a study over kappa, backlash, damping...); a single omega is then used for
    all of them. With ``omega_end`` the recorded periods are a ramp (omega linear in time from
    each omega to its omega_end, as ``advance(periods, omega_end=...)``): run-up and run-down
    studies. ``initial_states`` replaces the A10 start: one state per system (basins of
    attraction: many starts at one omega, see ``examples/basins.py``) or one shared state.

    Args:
        omegas: meshing frequencies Omega/omega_n (each finite and > 0); at least one.
        model: ``"constant"`` or ``"dynamic"`` backlash.
        periods: recorded mesh periods (>= 1).
        transient: mesh periods discarded first (>= 0).
        steps_per_period: Newmark steps per mesh period for every omega; None (default) for
            :func:`default_steps_per_period` of the smallest omega (the most demanding one).
        params: physical parameters (SI): one GearParams shared by all systems (default Table 1
            with kappa = 0.2), or a sequence of them, one per system; its length must equal the
            number of omegas, or omegas may be a single value. Each system's results are in its
            own parameter set's units (b0 = its half backlash unless ``b0`` is set).
        omega_end: None (default: omega held), one value for all systems or one per system:
            omega at the end of the recorded periods (each finite and > 0). The transient is at
            the start omegas. The default step count then follows the smallest of all omegas.
        initial_states: None (default: each system's A10 static equilibrium), one state of 10
            values [X_p, Y_p, X_g, Y_g, U and their derivatives; b0 units, derivatives per unit
            natural time] for all systems, or an (n, 10) array, one row per system. With one
            omega and one parameter set, n rows make n systems.
        tol: error per mesh period (b0 units) instead of ``steps_per_period``, as in
            :class:`GearSimulator`: each system then runs error-controlled, one after another (the
            SIMD lanes take one fixed step count), with exactly the result of
            ``GearSimulator(params_i, model, omega=omega_i, initial_state=state_i, tol=tol)``
            followed by ``advance(transient)`` and ``advance(periods, omega_end=omega_end_i)``.

    Returns:
        One :class:`IntervalStats` of the recorded periods per system, in order.

    Raises:
        ValueError: on invalid arguments (the message names the argument).
        SimulationDivergedError: if any system blows up (the first such omega is named).
    """
    announce_compile("drivers", "the simulator kernels", SIM_COMPILE_TIME)
    w = _check_omega_list(omegas, "omegas")
    n_rec = check_count(periods, "periods")
    n_tr = check_count(transient, "transient", 0)
    code = model_code(model)
    ps = _check_params_rows(params, w.size)
    for q in ps:
        refuse_extensions(q, "simulate_batch")
    S = None if initial_states is None else _check_states_rows(initial_states)
    n = max(w.size, len(ps), 1 if S is None else len(S))
    for name, size in (("omegas", w.size), ("params", len(ps)), ("initial_states", 1 if S is None else len(S))):
        if size not in (1, n):
            raise ValueError(
                f"{name} has {size} entries but there are {n} systems: give one per system or one shared value"
            )
    if w.size == 1:
        w = np.full(n, w[0])
    w_end = w if omega_end is None else _check_omega_end(omega_end, n)
    err_tol = check_tol(tol)
    if err_tol is not None:
        if steps_per_period is not None:
            raise ValueError(f"give steps_per_period or tol, not both (got {steps_per_period!r} and {tol!r})")
        return [_tol_system(ps[i if len(ps) == n else 0], model, float(w[i]), float(w_end[i]),
                            None if S is None else S[i if len(S) == n else 0], err_tol, n_tr, n_rec, i, n)
                for i in range(n)]  # fmt: skip
    w_lo = float(min(w.min(), w_end.min()))
    nsp = max(resolve_steps(steps_per_period, w_lo, q) for q in ps)  # the automatic count of each row's scheme
    per_row = len(ps) == n  # else one shared parameter set
    for i in range(n):
        check_stable_steps(ps[i if per_row else 0], nsp, float(min(w[i], w_end[i])))
    C = stack_consts([q.consts for q in (ps if per_row else ps * n)])
    if S is not None:
        X = np.repeat(S, n, axis=0) if len(S) == 1 else S
    else:
        x0 = [default_initial_state(q, model) for q in ps]
        X = np.stack(x0 if per_row else x0 * n)
    A = np.zeros((n, K.NDOF))

    def run(count: int, periods_before: int, w1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance every system by ``count`` periods (omega w -> w1); (poincare, stats, elapsed) or raise."""
        r = integrate(X, A, C, code, w, w1, count, nsp)
        bad = np.flatnonzero(r.status != K.OK)
        if bad.size:
            i = int(bad[0])
            why = _STATUS_TEXT.get(int(r.status[i]), f"status {r.status[i]}")
            raise SimulationDivergedError(periods_before + int(r.done[i]), f"{why} (system {i} of {n})", float(w[i]))
        return r.poincare, r.stats, r.elapsed

    if n_tr > 0:
        run(n_tr, 0, w)
    pc, st, el = run(n_rec, n_tr, w_end)
    return [IntervalStats(float(w[i]), float(w_end[i]), n_rec, float(el[i]), pc[i], st[i]) for i in range(n)]


def _tol_system(
    params: GearParams,
    model: str,
    w: float,
    w_end: float,
    state: Any,
    tol: float,
    n_tr: int,
    n_rec: int,
    i: int,
    n: int,
) -> IntervalStats:
    """One system of :func:`simulate_batch` with ``tol``: the error-controlled single simulator."""
    sim = GearSimulator(params, model, None, w, state, tol)
    done = 0
    try:
        if n_tr > 0:
            sim.advance(n_tr)
            done = n_tr
        return sim.advance(n_rec, omega_end=None if w_end == w else w_end)
    except SimulationDivergedError as exc:  # counted from the start of the call, as the SIMD path does
        raise SimulationDivergedError(done + exc.period, f"{exc.reason} (system {i} of {n})", w) from None


def _check_states_rows(states: Any) -> np.ndarray:
    """simulate_batch's ``initial_states``: one state (10,) or one per system (m, 10), all finite;
    a float array of shape (m, 10)."""
    _refuse_complex(states, "initial_states")
    try:
        arr = np.array(states, dtype=float, order="C")  # C order: the kernels' one compiled layout
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"initial_states must be numbers of shape (10,) or (n, 10), got {type(states).__name__}"
        ) from exc
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] != K.NSTATE:
        raise ValueError(
            "initial_states must have shape (10,) or (n, 10) [5 positions, 5 velocities per system], "
            f"got {np.shape(states)}"
        )
    bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
    if bad.size:
        raise ValueError(f"initial_states[{bad[0]}] must be finite, got {arr[bad[0]].tolist()}")
    return arr


def _check_omega_list(values: Any, name: str) -> np.ndarray:
    """A non-empty 1-D sequence (or one value) of meshing frequencies, each checked by
    :func:`check_omega` under the name ``name[i]``; a float array."""
    arr = np.atleast_1d(np.asarray(values, dtype=object))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence of frequencies, got shape {arr.shape}")
    return np.array([check_omega(v, f"{name}[{i}]") for i, v in enumerate(arr)])


def _check_omega_end(omega_end: Any, n: int) -> np.ndarray:
    """simulate_batch's ``omega_end``: one value for all n systems or n values, each a valid omega."""
    vals = _check_omega_list(omega_end, "omega_end")
    if vals.size not in (1, n):
        raise ValueError(f"omega_end must be one value or {n} values (one per system), got shape {vals.shape}")
    return np.full(n, vals[0]) if vals.size == 1 else vals
