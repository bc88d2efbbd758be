"""Largest Lyapunov exponent from two nearby trajectories renormalised every mesh period.

Method (Benettin et al. 1980): a reference trajectory and a copy displaced by ``d0`` (Euclidean
norm in the 10-dimensional state space, b0 units and b0 per unit natural time) are advanced one
mesh period at a time with the simulator's own Newmark kernel (``kernels.integrate_stats``); after
each period the separation ``d`` is measured, ``log(d/d0)`` accumulated, and the copy is pulled back
to distance ``d0`` along the current separation direction. The first ``skip`` periods only align
the separation with the most unstable direction and are not counted.

Units: the exponent is **per unit natural time** s = omega_n t (multiply by 2 pi/omega to get the
growth per mesh period, or by omega_n for 1/s). A linear oscillator with damping ratio xi gives
-xi in these units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import SimulationDivergedError
from ..sim import kernels as K
from ..sim.params import GearParams, model_code, refuse_extensions
from ..sim.simulator import (
    NEWTON_MAX_ITER,
    NEWTON_TOL,
    _check_state,
    check_count,
    check_omega,
    check_stable_steps,
    resolve_steps,
)

DEFAULT_D0 = 1e-8
"""Default initial separation (b0 units): large against the Newton tolerance, small against b0."""


def start_direction(n: int) -> np.ndarray:
    """Fixed initial separation direction (1, 1.1, 1.2, ...)/norm: deterministic results."""
    v = 1.0 + 0.1 * np.arange(n, dtype=float)
    return v / np.linalg.norm(v)


def default_skip(periods: int) -> int:
    """Periods used only to align the separation vector: 10 % of the record, at most 20."""
    return min(20, periods // 10)


def largest_lyapunov(
    omega: float,
    model: str = "dynamic",
    params: GearParams | None = None,
    state: Any = None,
    periods: int = 200,
    steps_per_period: int | None = None,
    d0: float = DEFAULT_D0,
    transient: int = 0,
) -> float:
    """Largest Lyapunov exponent of the gear model at meshing frequency ``omega``.

    Args:
        omega: meshing frequency Omega/omega_n (> 0).
        model: ``"constant"`` or ``"dynamic"`` backlash.
        params: physical parameters (default Table 1).
        state: start state (10 values, b0 units), or None for the static equilibrium; it should
            already lie on the attractor (or pass ``transient``).
        periods: mesh periods over which separations are averaged (renormalised every period).
        steps_per_period: Newmark steps per mesh period; None: ``default_steps_per_period(omega)``.
        d0: separation (state-space Euclidean norm, b0 units) restored every period.
        transient: mesh periods simulated first and discarded.

    Returns:
        The exponent **per unit natural time** (omega_n t); ``* 2 pi / omega`` gives it per mesh
        period. Positive: chaos; about zero: quasi-periodic; negative: a stable periodic orbit.

    Raises:
        ValueError: invalid arguments; SimulationDivergedError: the trajectory blew up.
    """
    from ..sim.simulator import GearSimulator

    w = check_omega(omega)
    n = check_count(periods, "periods", 2)
    nsteps = resolve_steps(steps_per_period, w, params)
    check_stable_steps(params if params is not None else GearParams(), nsteps, w)
    tr = check_count(transient, "transient", 0)
    if not (isinstance(d0, (int, float)) and 0.0 < float(d0) < 1e-2 and math.isfinite(d0)):
        raise ValueError(f"d0 must be a finite separation in (0, 1e-2) b0, got {d0!r}")
    params = params if params is not None else GearParams()
    refuse_extensions(params, "lyapunov")
    sim = GearSimulator(params, model, nsteps, w, None if state is None else _check_state(state))
    if tr:
        sim.advance(tr)
    x = sim.state
    lam = lyapunov_record(x, w, n, nsteps, params.consts, model_code(model), float(d0))[0]
    return lam


_ADD = np.array([K.ST_TIME, K.ST_SEP_TIME, K.ST_BACK_TIME, K.ST_BACK_IMPACTS, K.ST_DRIVE_IMPACTS, K.ST_F_SUM,
                 K.ST_F_SQ, K.ST_TR_SQ, K.ST_STEPS, K.ST_SPLITS])  # fmt: skip
_MAX = np.array([K.ST_F_MAX, K.ST_U_MAX, K.ST_D_MAX, K.ST_BD_MAX, K.ST_PSI_MAX, K.ST_TR_MAX])
_MIN = np.array([K.ST_F_MIN, K.ST_U_MIN, K.ST_D_MIN, K.ST_BD_MIN, K.ST_PSI_MIN])


def merge_stats(per_period: np.ndarray) -> np.ndarray:
    """Interval statistics of consecutive periods (rows of ``ST_*`` vectors) combined."""
    out = np.empty(K.N_STATS)
    out[_ADD] = per_period[:, _ADD].sum(axis=0)
    out[_MAX] = per_period[:, _MAX].max(axis=0)
    out[_MIN] = per_period[:, _MIN].min(axis=0)
    return out


def lyapunov_record(
    x: np.ndarray,
    omega: float,
    periods: int,
    steps_per_period: int,
    consts: np.ndarray,
    code: int,
    d0: float,
    direction: np.ndarray | None = None,
    skip: int | None = None,
) -> tuple[float, np.ndarray, np.ndarray, float, float, float]:
    """Record ``periods`` mesh periods from state ``x`` (updated in place) at constant ``omega``
    while a copy displaced by ``d0`` runs alongside and is renormalised every period.

    Both copies and the renormalisation run in one compiled call
    (:func:`gear_env.analysis.lyapunov_kernel.lyapunov_pair`), one ``kernels.integrate_stats`` call
    per period and copy, so the copy costs the physics and nothing else.

    ``direction``: None (a fixed start direction; the first :func:`default_skip` periods only align
    the separation), or a writeable float64 array of shape (10,), e.g. the one a previous record of
    the same trajectory left: the copy starts along it, and on return it holds this record's final
    unit separation direction (so consecutive records are one). Continuing the copy across the
    windows of a long record matters on a torus, where realigning a fresh copy adds a positive
    stretch of order 1 per window that reads as weak chaos. ``skip``: periods excluded from the
    exponent, an integer in [0, periods) (None: :func:`default_skip` without ``direction``, 0 with it).

    Returns (exponent per unit natural time, Poincare samples (periods, 14), interval stats,
    natural time elapsed, sum of log(d/d0), natural time it was averaged over; the last two let
    a caller pool several windows). Raises ValueError on a bad ``direction`` or ``skip`` (before
    any work) and SimulationDivergedError on blow-up.
    """
    from .lyapunov_kernel import lyapunov_pair

    if skip is not None and (
        isinstance(skip, bool) or not isinstance(skip, (int, np.integer)) or not 0 <= skip < periods
    ):
        raise ValueError(f"skip must be an integer in [0, periods) = [0, {periods}), got {skip!r}")
    if direction is None:
        skip = default_skip(periods) if skip is None else int(skip)
        u = start_direction(K.NSTATE)
    else:
        if not (
            isinstance(direction, np.ndarray)
            and direction.shape == (K.NSTATE,)
            and direction.dtype == np.float64
            and direction.flags.writeable
        ):
            raise ValueError(
                f"direction must be a writeable float64 array of shape ({K.NSTATE},), got "
                f"{type(direction).__name__} {getattr(direction, 'shape', '')} {getattr(direction, 'dtype', '')}"
            )
        skip = 0 if skip is None else int(skip)
        u = np.ascontiguousarray(direction).copy()
        nu = float(np.linalg.norm(u))
        if not (math.isfinite(nu) and nu > 0):
            raise ValueError("direction must be 10 finite values, not all zero")
        u /= nu
    xr = np.ascontiguousarray(x, dtype=float).copy()
    pc = np.empty((periods, K.N_PC))
    st_all = np.empty((periods, K.N_STATS))
    status, failed, sum_log, t_count, t_all = lyapunov_pair(
        xr, float(omega), int(periods), int(steps_per_period), consts, int(code), float(d0),
        u, int(skip), pc, st_all, NEWTON_MAX_ITER, NEWTON_TOL,
    )  # fmt: skip
    if status != K.OK:
        raise SimulationDivergedError(
            int(failed), f"integration failed (status {status}) in the Lyapunov record", omega
        )
    x[:] = xr
    if direction is not None:
        direction[:] = u / np.linalg.norm(u)  # (xc - x) / d0 after the last renormalisation: unit to ~1e-8
    lam = sum_log / t_count if t_count > 0 else 0.0
    return float(lam), pc, merge_stats(st_all), float(t_all), float(sum_log), float(t_count)


def lyapunov_map(
    advance: Callable[[np.ndarray], float],
    x0: Any,
    periods: int,
    d0: float = DEFAULT_D0,
    skip: int | None = None,
) -> float:
    """Generic two-trajectory estimate for any system given by a one-period map.

    ``advance(x)`` must integrate the state ``x`` (1-D float array, modified in place) over one
    forcing period and return the elapsed time. Returns the exponent per unit of that time.
    Used for the test systems (:mod:`gear_env.analysis.testsystems`) with known exponents.
    """
    x = np.array(x0, dtype=float)
    n = check_count(periods, "periods", 2)
    skip = default_skip(n) if skip is None else int(skip)
    u = start_direction(x.size)
    xp = x + d0 * u
    sum_log = 0.0
    t_count = 0.0
    for p in range(n):
        t = advance(x)
        advance(xp)
        d = float(np.linalg.norm(xp - x))
        if not math.isfinite(d):
            raise ValueError("lyapunov_map: the trajectory became non-finite")
        if p >= skip:
            sum_log += math.log(max(d, 1e-300) / d0)
            t_count += t
        xp = x + d0 * (xp - x) / d if d > 0 else x + d0 * u
    return sum_log / t_count
