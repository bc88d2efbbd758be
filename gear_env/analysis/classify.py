"""Classification of a steady motion from its Poincare points (and its largest Lyapunov exponent).

Method
------
0. **A positive exponent decides first.** A largest Lyapunov exponent ``lam`` above the zero
   band ``lyap_tol`` (the sweep passes ``lyapunov_tolerance(T)`` = max(5e-4, 2/T) per unit time
   for an estimate averaged over the natural time T) makes the motion ``chaotic`` whatever the
   recurrence test says: a periodic attractor's exponent tends to log|mu_max|/T_N < 0, and
   finite-time estimates on tori scatter by at most ~1.2/T (docs/ANALYSIS.md), so an exponent
   above 2/T is resolved. Weak chaos confined to a narrow band can bring its Poincare points back
   within the 1e-3 recurrence tolerance after N periods (dynamic model, omega = 0.45: a
   "period-32" recurrence with lam = +0.0011 per unit time, +0.015 per mesh period).
1. **Periodicity by recurrence.** With the points ``P[k]`` (one per forcing period, in time
   order) scaled by ``S = max |P|``, the recurrence residual of period ``N`` is
   ``r_N = max_k ||P[k+N] - P[k]||_inf / S``. The motion is ``period-N`` for the smallest
   ``N <= max_period`` with ``r_N <= tol`` (at least two full repetitions are required).
2. **Clusters.** The points are grouped greedily (leader clustering) with the same tolerance;
   for a periodic motion the number of clusters equals N unless two points of the orbit
   coincide within ``tol`` (reported, not used for the label).
3. **Non-periodic motions** are split by the largest Lyapunov exponent ``lam`` (per unit time):
   ``lam > lyap_tol`` -> ``chaotic``; ``|lam| <= lyap_tol`` -> ``quasi-periodic`` (a torus has
   a zero exponent); ``lam < -lyap_tol`` means the points are still converging to a periodic
   orbit (a slow transient or a period above ``max_period``): the best recurrence ``N`` is
   returned with ``converged=False`` so that a caller runs longer (:func:`sweep` does).
   Without an exponent, the growth of the distance between nearest-neighbour points over a
   few periods (:func:`divergence_rate`) decides: about 0 (a rotation on a torus) ->
   quasi-periodic, > 0.1 per period -> chaotic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

DEFAULT_TOL = 1e-3
"""Relative recurrence tolerance (of the largest |coordinate|)."""
DEFAULT_MAX_PERIOD = 32
DEFAULT_LYAP_TOL = 5e-4
"""Floor of the zero band of the exponent (per unit time), see :func:`lyapunov_tolerance`.
(1e-3 until the Lyapunov-first rule; at omega ~ 0.45 a mesh period lasts 14 time units, and
1e-3 per unit time is already 1.4 % growth per mesh period, the size of the weak chaos there.)"""
LYAP_NOISE = 2.0
"""Finite-time estimates over a time T on quasi-periodic gear motions scatter by up to 1.2/T
(measured, docs/ANALYSIS.md); exponents within 2/T of zero count as zero (3/T before the
Lyapunov-first rule)."""


def lyapunov_tolerance(averaging_time: float, floor: float = DEFAULT_LYAP_TOL, noise: float = LYAP_NOISE) -> float:
    """Half-width of the band of exponents treated as zero for an estimate averaged over
    ``averaging_time`` (time units of the exponent): ``max(floor, noise / averaging_time)``."""
    if not averaging_time > 0:
        return float("inf")
    return max(floor, noise / averaging_time)


REGIMES = ("period-N", "quasi-periodic", "chaotic")


@dataclass(frozen=True)
class Classification:
    """Result of :func:`classify_motion`.

    Attributes:
        label: ``"period-N"``, ``"quasi-periodic"`` or ``"chaotic"``.
        period: N for a periodic motion, else 0.
        n_clusters: clusters of Poincare points within the tolerance.
        residual: relative recurrence residual at ``period`` (or the smallest one found).
        best_period: the N with the smallest residual (1..max_period).
        lyapunov: the exponent used (per unit time), or None.
        divergence: :func:`divergence_rate` of the points (only computed for non-periodic
            motions without an exponent), or None.
        converged: False when the points are still approaching a periodic orbit (negative
            exponent, no recurrence within tol): run longer.
    """

    label: str
    period: int
    n_clusters: int
    residual: float
    best_period: int
    lyapunov: float | None = None
    divergence: float | None = None
    converged: bool = True

    @property
    def periodic(self) -> bool:
        """True for a ``period-N`` label."""
        return self.period > 0


def _check_points(points: Any) -> np.ndarray:
    try:
        p = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"poincare_points must be an (m, d) array of numbers ({exc})") from None
    if p.ndim == 1:
        p = p[:, None]
    if p.ndim != 2 or p.shape[0] < 2 or p.shape[1] < 1:
        raise ValueError(f"poincare_points must be an (m, d) array with m >= 2, got shape {np.shape(points)}")
    if not np.all(np.isfinite(p)):
        raise ValueError("poincare_points must be finite")
    return p


def recurrence_residuals(points: Any, max_period: int = DEFAULT_MAX_PERIOD) -> np.ndarray:
    """Relative recurrence residuals r_N for N = 1..min(max_period, m // 2) (index N-1)."""
    p = _check_points(points)
    m = p.shape[0]
    scale = max(float(np.max(np.abs(p))), 1e-300)
    nmax = max(1, min(int(max_period), m // 2))
    return np.array([float(np.max(np.abs(p[n:] - p[:-n]))) / scale for n in range(1, nmax + 1)])


def count_clusters(points: Any, tol: float = DEFAULT_TOL) -> int:
    """Greedy leader clustering in the max-norm with radius ``tol * max|P|``; returns the count."""
    p = _check_points(points)
    rad = tol * max(float(np.max(np.abs(p))), 1e-300)
    leaders: list[np.ndarray] = []
    for row in p:
        if leaders:
            d = np.max(np.abs(np.asarray(leaders) - row), axis=1)
            if float(d.min()) <= rad:
                continue
        leaders.append(row)
        if len(leaders) > 4 * DEFAULT_MAX_PERIOD:
            break
    return len(leaders)


def divergence_rate(points: Any, steps: int = 4) -> float:
    """Data-only estimate of the growth of small separations, per forcing period.

    For each point the nearest other point (at least ``steps + 1`` periods apart in time) is
    found, and ``log(|P[i+steps] - P[j+steps]| / |P[i] - P[j]|) / steps`` is averaged (median).
    A rotation on a torus keeps neighbours together (about 0); chaos separates them (> 0).
    """
    p = _check_points(points)
    span = np.ptp(p, axis=0)
    q = p / np.where(span > 0, span, 1.0)
    m = len(q) - steps
    if m < 4:
        return 0.0
    d = np.sqrt(((q[:m, None, :] - q[None, :m, :]) ** 2).sum(-1))
    idx = np.arange(m)
    d[np.abs(idx[:, None] - idx[None, :]) <= steps] = np.inf
    j = np.argmin(d, axis=1)
    d0 = d[idx, j]
    ok = np.isfinite(d0) & (d0 > 0)
    if not np.any(ok):
        return 0.0
    d1 = np.sqrt(((q[idx[ok] + steps] - q[j[ok] + steps]) ** 2).sum(-1))
    return float(np.median(np.log(np.maximum(d1, 1e-300) / d0[ok])) / steps)


DIVERGENCE_CHAOS = 0.1
"""divergence_rate (per forcing period) above which a non-periodic motion without an exponent is
called chaotic."""


def same_orbit(first: Any, second: Any, period: int, tol: float = DEFAULT_TOL) -> bool:
    """True if the last ``period`` points of two windows are the same set within ``tol``.

    Confirms a ``period-N`` label on a longer run: a slowly decaying spiral around a fixed point
    can recur after N periods within the tolerance while its points still drift; the points of
    a converged period-N orbit do not move from one window to the next.
    """
    a = _check_points(first)[-period:]
    b = _check_points(second)[-period:]
    scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1e-300)
    d = np.max(np.abs(a[:, None, :] - b[None, :, :]), axis=2) / scale
    return bool(np.all(d.min(axis=0) <= tol) and np.all(d.min(axis=1) <= tol))


def classify_motion(
    poincare_points: Any,
    lyapunov: float | None = None,
    tol: float = DEFAULT_TOL,
    max_period: int = DEFAULT_MAX_PERIOD,
    lyap_tol: float = DEFAULT_LYAP_TOL,
) -> Classification:
    """Label a steady motion from its Poincare points.

    Args:
        poincare_points: (m, d) array, one row per forcing period in time order (for the gear
            model use the 10 state columns of the ``PC_*`` layout).
        lyapunov: largest Lyapunov exponent (per unit time), or None.
        tol: relative recurrence tolerance (fraction of the largest |coordinate|), in (0, 0.5).
        max_period: largest N tested (>= 1).
        lyap_tol: exponents with |lam| <= lyap_tol count as zero (> 0); lam > lyap_tol is
            chaos even when the points recur (rule 0 of the module docstring).

    Returns:
        :class:`Classification`. Raises ValueError on invalid input.
    """
    p = _check_points(poincare_points)
    if not (isinstance(tol, (int, float)) and 0.0 < tol < 0.5):
        raise ValueError(f"tol must be in (0, 0.5), got {tol!r}")
    if isinstance(max_period, bool) or not isinstance(max_period, (int, np.integer)) or max_period < 1:
        raise ValueError(f"max_period must be an integer >= 1, got {max_period!r}")
    if not (isinstance(lyap_tol, (int, float)) and lyap_tol > 0 and math.isfinite(lyap_tol)):
        raise ValueError(f"lyap_tol must be a finite number > 0, got {lyap_tol!r}")
    if lyapunov is not None and not math.isfinite(float(lyapunov)):
        raise ValueError(f"lyapunov must be finite or None, got {lyapunov!r}")
    r = recurrence_residuals(p, max_period)
    best = int(np.argmin(r)) + 1
    hits = np.nonzero(r <= tol)[0]
    nclu = count_clusters(p, tol)
    lam = None if lyapunov is None else float(lyapunov)
    if lam is not None and lam > lyap_tol:  # rule 0: a resolved positive exponent is chaos
        return Classification("chaotic", 0, nclu, float(r[best - 1]), best, lam)
    if hits.size:
        n = int(hits[0]) + 1
        return Classification(f"period-{n}", n, nclu, float(r[n - 1]), best, lam)
    if lam is not None:
        if lam > lyap_tol:
            return Classification("chaotic", 0, nclu, float(r[best - 1]), best, lam)
        if lam >= -lyap_tol:
            return Classification("quasi-periodic", 0, nclu, float(r[best - 1]), best, lam)
        return Classification(f"period-{best}", best, nclu, float(r[best - 1]), best, lam, converged=False)
    rate = divergence_rate(p)
    label = "chaotic" if rate > DIVERGENCE_CHAOS else "quasi-periodic"
    return Classification(label, 0, nclu, float(r[best - 1]), best, None, rate)
