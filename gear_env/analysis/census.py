"""Attractor census: which attractors a grid of start states reaches at one omega, with basin
fractions (the idea of Attractors.jl's ``basins_fractions``).

The starts are a rectangular grid in the torsional coordinate and its velocity, (U, U'), around
the static equilibrium (MODEL.md A10; the bearing coordinates start there too), because the
torsional mode carries the impacts. All starts run together in one SIMD call
(``simulate_batch(initial_states=...)``); after the transient, each run's Poincare points are
labelled by :func:`classify.classify_motion` (recurrence, and the nearest-neighbour divergence
rate for non-periodic runs) and grouped:

* two periodic runs belong to the same attractor if they have the same period and the same set
  of N section points within ``tol`` (``classify.same_orbit``: the phase along the orbit does
  not matter);
* two non-periodic runs belong together if they have the same label and their Poincare clouds
  have the same centre and spread (per coordinate) within ``10 tol`` of the largest |coordinate|
  (a chaotic or quasi-periodic attractor is sampled differently by each run).

A run that is still approaching its orbit after the transient is labelled with ``converged =
False`` (it counts where its label puts it); lengthen ``transient`` when such runs appear.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..sim.params import GearParams
from ..sim.simulator import check_count, check_omega, default_initial_state, simulate_batch
from .classify import DEFAULT_TOL, classify_motion, same_orbit


@dataclass
class Attractor:
    """One attractor found by :func:`attractor_census`.

    Attributes:
        label: ``period-N``, ``quasi-periodic`` or ``chaotic``.
        period: N (0 if not periodic).
        fraction: share of the start states that reach it (basin fraction).
        count: number of such starts.
        amplitude_u: half peak-to-peak of U over the recorded periods (b0), of its first run.
        points: (periods, 10) Poincare points of its first run (the last N are the orbit if periodic).
        members: indices of the starts that reach it.
    """

    label: str
    period: int
    fraction: float
    count: int
    amplitude_u: float
    points: np.ndarray
    members: list[int] = field(default_factory=list)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready summary (without the point cloud of a non-periodic attractor)."""
        return {
            "label": self.label,
            "period": self.period,
            "fraction": self.fraction,
            "count": self.count,
            "amplitude_u": self.amplitude_u,
            "points_u": [float(v) for v in self.points[-self.period :, 4]] if self.period else None,
        }


@dataclass
class Census:
    """Result of :func:`attractor_census`: the attractors (largest basin first), the start states
    (n, 10) and for each start the index of the attractor it reached."""

    omega: float
    model: str
    attractors: list[Attractor]
    starts: np.ndarray
    assignment: np.ndarray

    def to_json_dict(self) -> dict[str, Any]:
        """``{"omega", "model", "attractors": [...], "starts": n}``."""
        return {
            "omega": self.omega,
            "model": self.model,
            "starts": int(len(self.starts)),
            "attractors": [a.to_json_dict() for a in self.attractors],
        }


def start_grid(params: GearParams, model: str, omega: float, n_u: int, n_v: int, span_u: float,
               span_v: float) -> np.ndarray:  # fmt: skip
    """(n_u * n_v, 10) start states: the A10 equilibrium with U shifted by a uniform grid on
    [-span_u, span_u] and U' (natural time) set on [-span_v, span_v] (b0 units)."""
    x0 = default_initial_state(params, model)
    us = np.linspace(-span_u, span_u, n_u) if n_u > 1 else np.zeros(1)
    vs = np.linspace(-span_v, span_v, n_v) if n_v > 1 else np.zeros(1)
    out = np.repeat(x0[None, :], n_u * n_v, axis=0)
    uu, vv = np.meshgrid(us, vs, indexing="ij")
    out[:, 4] += uu.ravel()
    out[:, 9] = vv.ravel()
    return out


def _same_cloud(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1e-300)
    return bool(
        np.max(np.abs(a.mean(0) - b.mean(0))) <= 10 * tol * scale
        and np.max(np.abs(a.std(0) - b.std(0))) <= 10 * tol * scale
    )


def attractor_census(
    omega: float,
    model: str = "dynamic",
    params: GearParams | None = None,
    *,
    n_u: int = 8,
    n_v: int = 8,
    span_u: float = 2.0,
    span_v: float | None = None,
    transient: int = 600,
    periods: int = 64,
    tol: float = DEFAULT_TOL,
    starts: Any = None,
) -> Census:
    """Attractors reached from a grid of start states at fixed ``omega``, with basin fractions.

    Args:
        omega: meshing frequency Omega/omega_n.
        model: ``"constant"`` or ``"dynamic"``.
        params: GearParams (default Table 1).
        n_u, n_v: grid points in U and U' (each >= 1; n_u * n_v starts).
        span_u: half-width of the U grid around the equilibrium (b0, > 0).
        span_v: half-width of the U' grid (b0 per unit natural time); default ``span_u * omega``
            (a harmonic motion of amplitude span_u at the mesh frequency).
        transient: mesh periods discarded (>= 1).
        periods: recorded mesh periods (>= 4; at least twice the largest period to recognise).
        tol: recurrence and grouping tolerance (relative, in (0, 0.5)).
        starts: explicit (n, 10) start states instead of the grid.

    Returns:
        :class:`Census`, attractors sorted by decreasing basin fraction.
    """
    w = check_omega(omega)
    p = params if params is not None else GearParams()
    if not isinstance(p, GearParams):
        raise ValueError(f"params must be a GearParams, got {type(p).__name__}")
    n_u = check_count(n_u, "n_u")
    n_v = check_count(n_v, "n_v")
    if not (isinstance(span_u, (int, float)) and math.isfinite(span_u) and span_u > 0):
        raise ValueError(f"span_u must be a finite number > 0 (b0), got {span_u!r}")
    sv = span_u * w if span_v is None else span_v
    if not (isinstance(sv, (int, float)) and math.isfinite(sv) and sv >= 0):
        raise ValueError(f"span_v must be a finite number >= 0, got {span_v!r}")
    transient = check_count(transient, "transient")
    periods = check_count(periods, "periods", 4)
    if not (isinstance(tol, (int, float)) and 0 < tol < 0.5):
        raise ValueError(f"tol must be in (0, 0.5), got {tol!r}")
    X = start_grid(p, model, w, n_u, n_v, span_u, float(sv)) if starts is None else np.asarray(starts, float)
    if X.ndim != 2 or X.shape[1] != 10 or len(X) < 1:
        raise ValueError(f"starts must be an (n, 10) array, got shape {X.shape}")
    runs = simulate_batch(w, model, periods=periods, transient=transient, params=p, initial_states=X)
    max_period = max(1, periods // 2)
    attractors: list[Attractor] = []
    assign = np.empty(len(X), dtype=int)
    for i, iv in enumerate(runs):
        pts = iv.poincare[:, :10]
        cls = classify_motion(pts, None, tol, max_period)
        k = -1
        for j, a in enumerate(attractors):
            if a.label != cls.label:
                continue
            if cls.periodic:
                if same_orbit(a.points, pts, cls.period, tol):
                    k = j
                    break
            elif _same_cloud(a.points, pts, tol):
                k = j
                break
        if k < 0:
            attractors.append(Attractor(cls.label, cls.period, 0.0, 0, iv.amplitude("U"), pts.copy()))
            k = len(attractors) - 1
        attractors[k].members.append(i)
        assign[i] = k
    n = len(X)
    for a in attractors:
        a.count = len(a.members)
        a.fraction = a.count / n
    order = sorted(range(len(attractors)), key=lambda j: -attractors[j].count)
    remap = np.empty(len(order), dtype=int)
    remap[order] = np.arange(len(order))
    return Census(w, model, [attractors[j] for j in order], X, remap[assign])


__all__ = ["Attractor", "Census", "attractor_census", "start_grid"]
