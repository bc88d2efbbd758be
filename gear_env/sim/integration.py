"""The one Python-side way into the integration kernels.

Every caller that advances the gear model (the simulator, ``simulate_batch``, the environment
core, the Floquet period map) goes through :func:`integrate`: it checks nothing the caller has
not already validated, allocates the output arrays it is not given, passes the constants
read-only (one compiled copy of each kernel, see :func:`gear_env.sim.kernels.readonly`), picks the
kernel for the shape of the input and fills in the Newton settings:

==============================  =====================================================
input                            kernel
==============================  =====================================================
one state, ``record=True``       :func:`gear_env.sim.kernels.integrate_record`
one state                        :func:`gear_env.sim.kernels.integrate_stats_lazy` (its table kept)
a batch, ``simd=True``           :func:`gear_env.sim.batch_kernels.integrate_stats_lanes`
a batch, ``simd=False``          :func:`gear_env.sim.kernels.integrate_stats_batch`
==============================  =====================================================

All four give the same numbers bit for bit. Kernels that call the integrators from compiled code
(the Lyapunov pair kernel, the environment's kernels) call them directly.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from . import batch_kernels as BK
from . import kernels as K
from .params import N_CONSTS

NEWTON_MAX_ITER = 12
"""Newton iterations per Newmark step before the step is split."""
NEWTON_TOL = 1e-10
"""Relative tolerance of a Newton update of the dynamic model (see ``kernels.newton_iter_t``)."""
TOL_N_START = 32
"""First coarse step count per mesh period of an error-controlled interval (``err_tol``)."""


class IntervalRun(NamedTuple):
    """Result of :func:`integrate`. For one state the counts are numbers, for a batch arrays (n,).

    Attributes:
        status: kernel status (``kernels.OK``, ``DIVERGED``, ``NEWTON_FAILED``).
        done: mesh periods completed (stats; None for a batch with ``simd=False``); rows written
            (``record=True``).
        elapsed: natural time elapsed (omega_n t).
        poincare: Poincare samples (periods, N_PC) or (n, periods, N_PC); None with ``record``.
        stats: interval statistics (N_STATS) or (n, N_STATS); None with ``record``.
        record: the time series (periods * steps_per_period + 1, N_REC) with ``record=True``.
    """

    status: Any
    done: Any
    elapsed: Any
    # typed Any: which of the three is None depends on ``record`` (documented above)
    poincare: Any
    stats: Any
    record: Any = None
    steps_last: Any = None
    """With ``err_tol``: the coarse run's steps per mesh period chosen for the last period."""


CONTACT_STEPS = (48, 64, 80)
"""Steps per mesh period of :func:`contact_steps` (Fox-Goodwin): out of drive-side contact at most
``CONTACT_SEPARATION[0]`` of the time, up to ``CONTACT_SEPARATION[1]``, more."""
CONTACT_SEPARATION = (0.2, 0.5)
"""Fractions of time out of drive-side contact that bound the classes of :data:`CONTACT_STEPS`."""
CORRECTED_CONTACT_STEPS = (32, 64, 64)
"""Steps per mesh period of :func:`contact_steps` for steps whose contact kinks are corrected (``corrected=True``):
32 where the teeth keep contact (their kinks corrected, the quiet orbits need fewer steps than plain Fox-Goodwin's
48), 64 for the other two classes."""


def contact_steps(separation: Any, periodic: Any = True, corrected: bool = False) -> Any:
    """Steps per mesh period for Fox-Goodwin (Newmark beta 1/12) from the fraction of time out of drive-side
    contact (teeth apart or in back-side contact: ``(stats[ST_SEP_TIME] + stats[ST_BACK_TIME]) / stats[ST_TIME]``
    of the interval before, the environments' contact-loss feature; a number or an array): 48 up to 0.2, 64 up to
    0.5, 80 above (:data:`CONTACT_STEPS`, :data:`CONTACT_SEPARATION`; NaN: 80). ``periodic`` False (a number or an
    array): 64 in place of 80, because the rule was calibrated on period-1 orbits, and where the motion is not
    periodic the trajectory error grows whatever the step.

    Why: Newmark's error is largest where the contact changes (a kink in the mesh force inside a step), so the
    separated fraction sorts the period-1 orbits by the steps they need. On the 197 orbits of
    ``benchmarks/bench_tolerance.py --omega-step 0.01`` (both models, omega 0.30-1.62) and 193 more at omega
    0.305 + 0.01 k, never used to choose the classes, the rule keeps every orbit within 9.2e-4 b0 of the
    event-located reference (p95 6.1e-4 / 5.8e-4) at 59.5 steps per period on average; 64 fixed steps leave 6 of
    the 197 above 1e-3. On five pairs of the Demand tasks' plant family it leaves 8 of 296 orbits above 1e-3 (64
    steps: 11): a worn, loaded pair needs more (``benchmarks/contact_steps.py``; docs/ENVIRONMENT.md, "Integration
    accuracy"). Not calibrated for the paper's beta 1/4.

    ``corrected`` True: the count for steps whose contact kinks are corrected (``correct_kinks``, the kernels'
    ``CONTACTS_CORRECTED``): 32 up to 0.2, else 64 (:data:`CORRECTED_CONTACT_STEPS`). The third class is dropped
    because the error it bought down, the kinks inside the steps, is what the correction removes: on 686 period-1
    orbits (the two Table 1 sets and the family's five pairs) the corrected steps stay within 7.1e-4 b0 at 32 steps
    for the orbits up to 0.2 (p95 4.1e-4 to 5.1e-4 per set; at 40 steps 4.4e-4, at 48 2.9e-4, at 24 1.3e-2 near
    omega's stability floor) and within 8.3e-4 at 64 for the rest (at 48 they reach 1.6e-3, at 56 1.1e-3)."""
    a, b = CONTACT_SEPARATION
    lo, mid, hi = CORRECTED_CONTACT_STEPS if corrected else CONTACT_STEPS
    if np.ndim(separation) == 0 and np.ndim(periodic) == 0:
        f = float(separation)
        return lo if f <= a else mid if (f <= b or not periodic) else hi
    fa = np.asarray(separation, float)
    return np.where(fa <= a, lo, np.where((fa <= b) | ~np.asarray(periodic, bool), mid, hi)).astype(np.int64)


_TABLES: dict[tuple[int, bytes], np.ndarray] = {}
"""Excitation tables of the one-state driver, by (steps per period, constants); at most ``_MAX_TABLES``."""
_MAX_TABLES = 64


def _excitation_table(steps_per_period: int, c: np.ndarray) -> np.ndarray:
    """``kernels._excitation_table(0, steps_per_period, c)``, computed once per step count and constants (the
    kernel only reads it; a numba call of ~3 us saved per interval, which short intervals feel)."""
    key = (int(steps_per_period), c.tobytes())
    tab = _TABLES.get(key)
    if tab is None:
        if len(_TABLES) >= _MAX_TABLES:
            _TABLES.clear()
        tab = _TABLES[key] = K._excitation_table(0.0, int(steps_per_period), c)
    return tab


def _check_buffers(x, a, c, periods, poincare, stats) -> None:
    """Shapes that the kernels rely on (they index without bounds checks): a mismatch would write outside the
    arrays. A few attribute reads; raises ``ValueError`` naming the argument."""
    n = None if x.ndim == 1 else x.shape[0]
    lead = () if n is None else (n,)
    want = {"x": (x, lead + (K.NSTATE,)), "a": (a, lead + (K.NDOF,))}
    if poincare is not None:
        want["poincare"] = (poincare, lead + (periods, K.N_PC))
    if stats is not None:
        want["stats"] = (stats, lead + (K.N_STATS,))
    for name, (arr, shape) in want.items():
        if arr.shape != shape:
            raise ValueError(f"integrate: {name} must have shape {shape}, got {arr.shape}")
    if c.shape[-1] < N_CONSTS or (n is not None and c.ndim == 2 and c.shape[0] != n):
        raise ValueError(f"integrate: consts must be GearParams.consts (one row per system), got shape {c.shape}")


def integrate(
    x: np.ndarray,
    a: np.ndarray,
    consts: np.ndarray,
    dynamic: Any,
    omega0: Any,
    omega1: Any,
    periods: int,
    steps_per_period: int | np.ndarray,
    *,
    record: bool = False,
    poincare: np.ndarray | None = None,
    stats: np.ndarray | None = None,
    simd: bool = True,
    max_iter: int = NEWTON_MAX_ITER,
    tol: float = NEWTON_TOL,
    err_tol: float | None = None,
    n_start: int = TOL_N_START,
) -> IntervalRun:
    """Advance one system (x of shape (10,)) or a batch (x of shape (n, 10)) in place.

    Every system starts at mesh phase 0 (a Poincare section) and omega goes linearly in time from
    ``omega0`` to ``omega1`` over ``periods`` mesh periods of ``steps_per_period`` Newmark steps.
    Arguments are not validated (the public entries do that before calling).

    Args:
        x: state(s) in b0 units, float64, C order; updated in place (a failed batch row is left
            in an unspecified state).
        a: accelerations (5,) or (n, 5), updated in place (the start value is recomputed).
        consts: ``GearParams.consts`` (one row per system for a batch); passed read-only.
        dynamic: model code (0 constant, 1 dynamic), the same for every row of a batch.
        omega0, omega1: meshing frequency Omega/omega_n at the start and the end (numbers for one
            system, float64 arrays (n,) for a batch).
        periods: mesh periods (>= 1).
        steps_per_period: Newmark steps per mesh period; for a batch with ``simd``, also an int64 array (n,), each
            row at its own count in one call (each row's numbers as it gives alone).
        record: one system only: return the full time series instead of statistics.
        poincare, stats: output arrays to fill (allocated when None); reused buffers save an
            allocation on the environment's hot path. One system: (periods, N_PC) and (N_STATS);
            a batch: (n, periods, N_PC) and (n, N_STATS).
        simd: batch only: step the rows together (``batch_kernels``, one model code) rather
            than one after the other.
        max_iter, tol: Newton settings (the defaults are those of every published result).
        err_tol: one system, statistics only: integrate with the error per mesh period controlled
            (:func:`gear_env.sim.kernels.integrate_tol`, b0 units) instead of ``steps_per_period``
            steps; ``n_start`` is the coarse run's first step count per mesh period.

    Returns:
        :class:`IntervalRun`.
    """
    c = K.readonly(consts)  # one compiled signature whoever calls
    _check_buffers(x, a, c, periods, poincare, stats)  # the kernels index them unchecked: no write out of bounds
    if x.ndim == 1:
        if record:
            out = np.empty((periods * steps_per_period + 1, K.N_REC))
            status, rows, el = K.integrate_record(
                x, a, 0.0, omega0, omega1, periods, steps_per_period, c, dynamic, out, max_iter, tol
            )
            return IntervalRun(status, rows, el, None, None, out)
        if poincare is None:
            poincare = np.empty((periods, K.N_PC))
        if stats is None:
            stats = np.empty(K.N_STATS)
        if err_tol is not None:
            cost = np.empty(periods)
            status, done, el, n_last = K.integrate_tol(
                x,
                a,
                omega0,
                omega1,
                periods,
                n_start,
                c,
                dynamic,
                poincare,
                stats,
                max_iter,
                tol,
                err_tol,
                cost,
                float(K.TOL_DQ_SCALE),
            )
            return IntervalRun(status, done, el, poincare, stats, None, n_last)
        # the period's excitation table kept between calls (the same numbers: it is a function of the step count
        # and the constants only); a third of the cost of a one-period call
        tab = _excitation_table(int(steps_per_period), c)
        status, done, el = K.integrate_stats_lazy(
            x, a, 0.0, omega0, omega1, periods, steps_per_period, c, dynamic, poincare, stats, max_iter, tol, True, tab
        )
        return IntervalRun(status, done, el, poincare, stats)
    if record:
        raise ValueError("record=True takes one state of shape (10,), not a batch")
    n = x.shape[0]
    if poincare is None:
        poincare = np.zeros((n, periods, K.N_PC))
    if stats is None:
        stats = np.zeros((n, K.N_STATS))
    status = np.zeros(n, np.int64)
    elapsed = np.zeros(n)
    if simd:
        done = BK.integrate_stats_lanes(
            x, a, omega0, omega1, periods, steps_per_period, c, int(dynamic), poincare, stats, status, elapsed,
            max_iter, tol,
        )  # fmt: skip
    else:
        codes = np.full(n, dynamic, np.int64)
        K.integrate_stats_batch(
            x, a, omega0, omega1, periods, steps_per_period, c, codes, poincare, stats, status, elapsed,
            max_iter, tol,
        )  # fmt: skip
        done = None
    return IntervalRun(status, done, elapsed, poincare, stats)
