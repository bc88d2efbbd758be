"""Stability map of the period-1 orbit over the meshing frequency, cached on disk.

:func:`stability_map` continues the period-1 orbit (the T-periodic response) along a uniform omega
grid by shooting (:mod:`gear_env.analysis.floquet`): each Newton solve starts from the orbit of the
previous grid point, extrapolated linearly from the two previous ones (a secant predictor); if that
fails, from a simulation started at the previous orbit. The Floquet multipliers then say where the
period-1 orbit is stable and how it loses stability (period doubling: a real multiplier through -1;
Neimark-Sacker: a complex pair leaves the unit circle, a torus is born; fold: a real multiplier
through +1).

Continuation is in the natural parameter omega, so an orbit branch that folds back (a hysteresis
jump) is followed only as far as Newton converges; points where it does not converge are labelled
``"unconverged"`` and never enter a stable interval.

Results are cached as JSON in ``$GEAR_ENV_CACHE`` or ``~/.cache/gear-env`` (key: SHA-256 of the
parameters, model, grid and steps per period); a cache file that does not parse or does not match
its key is recomputed, never trusted. The maps of the default configuration for both models ship
with the package (``gear_env/data/stability_<model>.json``), see :func:`default_stability_map`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SimulationDivergedError
from ..io import atomic_write_text
from ..sim.params import GearParams, model_code, refuse_velocity_correction
from ..sim.simulator import (
    GearSimulator,
    auto_steps_rule,
    check_count,
    check_omega,
    check_stable_steps,
    check_steps,
    resolve_steps,
)
from .floquet import find_periodic_orbit

FORMAT_VERSION = 2
"""2: orbits and multipliers of the located map (contact changes located inside the step, exact
Jacobian; ``floquet.PeriodMap``); 1 (up to 0.4.0): the unlocated map with finite differences. A
version-1 file (cached or handed in) is refused and recomputed, never mixed in."""
LABELS = ("stable", "period-doubling", "neimark-sacker", "fold", "unconverged")
DEFAULT_POINTS = 296
"""Default grid: 296 points on [0.05, 3.0], a step of 0.01."""


@dataclass
class StabilityMap:
    """Floquet stability of the period-1 orbit along a grid of meshing frequencies.

    Attributes:
        model: backlash model.
        omega: (n,) grid of Omega/omega_n.
        multipliers: (n, 10) complex Floquet multipliers (sorted by decreasing modulus; zeros where
            Newton did not converge).
        max_multiplier: (n,) largest |multiplier| (0 where not converged).
        converged: (n,) bool, Newton converged.
        labels: (n,) str, one of ``LABELS``.
        states: (n, 10) period-1 orbit on the Poincare section.
        residual: (n,) Newton residual.
        steps_per_period: Newmark steps per mesh period, or None for ``default_steps_per_period``
            (omega) at every grid point.
        params: parameters (SI dict).
    """

    model: str
    omega: np.ndarray
    multipliers: np.ndarray
    max_multiplier: np.ndarray
    converged: np.ndarray
    labels: np.ndarray
    states: np.ndarray
    residual: np.ndarray
    steps_per_period: int | None
    params: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ queries
    def intervals(self) -> list[tuple[float, float, str]]:
        """Maximal runs of equal label as (omega_lo, omega_hi, label); the boundary between two
        runs is where max|mu| crosses 1 (linear interpolation) or the midpoint of the grid step."""
        out: list[tuple[float, float, str]] = []
        w = self.omega
        n = len(w)
        start = 0
        for i in range(1, n + 1):
            if i == n or self.labels[i] != self.labels[start]:
                lo = w[0] if start == 0 else self._boundary(start - 1, start)
                hi = w[-1] if i == n else self._boundary(i - 1, i)
                out.append((float(lo), float(hi), str(self.labels[start])))
                start = i
        return out

    def _boundary(self, i: int, j: int) -> float:
        a, b = self.max_multiplier[i] - 1.0, self.max_multiplier[j] - 1.0
        if self.converged[i] and self.converged[j] and a * b < 0:
            return float(self.omega[i] + (self.omega[j] - self.omega[i]) * a / (a - b))
        return float(0.5 * (self.omega[i] + self.omega[j]))

    def stable_intervals(self) -> list[tuple[float, float]]:
        """omega intervals where the period-1 orbit is stable."""
        return [(lo, hi) for lo, hi, lab in self.intervals() if lab == "stable"]

    def bifurcations(self) -> list[tuple[float, str, str]]:
        """Points where the label changes, as (omega, from_label, to_label)."""
        iv = self.intervals()
        return [(iv[k][1], iv[k][2], iv[k + 1][2]) for k in range(len(iv) - 1)]

    def label_at(self, omega: float) -> str:
        """Label of the interval containing ``omega`` (must lie within the grid)."""
        w = check_omega(omega)
        if w < self.omega[0] - 1e-12 or w > self.omega[-1] + 1e-12:
            raise ValueError(
                f"omega must be in [{self.omega[0]:g}, {self.omega[-1]:g}] (the map's grid), got {omega!r}"
            )
        for lo, hi, lab in self.intervals():
            if lo <= w <= hi:
                return lab
        return str(self.labels[int(np.argmin(np.abs(self.omega - w)))])  # pragma: no cover

    def is_stable(self, omega: float) -> bool:
        """True if the period-1 orbit is stable at ``omega`` (within the grid's resolution)."""
        return self.label_at(omega) == "stable"

    # ------------------------------------------------------------------ (de)serialisation
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (complex multipliers as [re, im] pairs)."""
        return {
            "format": "gear-env-stability-map",
            "version": FORMAT_VERSION,
            "map": "located",
            "model": self.model,
            "steps_per_period": self.steps_per_period,
            "params": self.params,
            "omega": self.omega.tolist(),
            "multipliers_re": self.multipliers.real.round(9).tolist(),
            "multipliers_im": self.multipliers.imag.round(9).tolist(),
            "max_multiplier": self.max_multiplier.round(9).tolist(),
            "converged": self.converged.astype(bool).tolist(),
            "labels": [str(s) for s in self.labels],
            "states": self.states.round(10).tolist(),
            "residual": [float(f"{r:.3g}") for r in self.residual],
            "intervals": [list(t) for t in self.intervals()],
            "stable_intervals": [list(t) for t in self.stable_intervals()],
            "bifurcations": [list(t) for t in self.bifurcations()],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StabilityMap:
        """Inverse of :meth:`to_dict`; raises ValueError on a malformed or incompatible dict."""
        if not isinstance(d, dict) or d.get("format") != "gear-env-stability-map":
            raise ValueError("not a gear-env stability map")
        if d.get("version") != FORMAT_VERSION:
            raise ValueError(f"stability map version {d.get('version')!r} is not {FORMAT_VERSION}")
        try:
            w = np.asarray(d["omega"], dtype=float)
            n = len(w)
            mu = np.asarray(d["multipliers_re"], dtype=float) + 1j * np.asarray(d["multipliers_im"], dtype=float)
            out = cls(
                model=str(d["model"]),
                omega=w,
                multipliers=mu,
                max_multiplier=np.asarray(d["max_multiplier"], dtype=float),
                converged=np.asarray(d["converged"], dtype=bool),
                labels=np.asarray(d["labels"], dtype=object),
                states=np.asarray(d["states"], dtype=float),
                residual=np.asarray(d["residual"], dtype=float),
                steps_per_period=None if d["steps_per_period"] is None else int(d["steps_per_period"]),
                params=dict(d["params"]),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"malformed stability map: {exc}") from exc
        shapes = [mu.shape == (n, 10), out.max_multiplier.shape == (n,), out.converged.shape == (n,)]
        shapes += [out.labels.shape == (n,), out.states.shape == (n, 10), out.residual.shape == (n,)]
        if n < 1 or not all(shapes) or not set(out.labels) <= set(LABELS):
            raise ValueError("malformed stability map: inconsistent array shapes or labels")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(mu)) and np.all(np.isfinite(out.states))):
            raise ValueError("malformed stability map: non-finite values")
        return out

    def save(self, path: str | os.PathLike) -> None:
        """Write the map as JSON, atomically."""
        atomic_write_text(path, json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | os.PathLike) -> StabilityMap:
        """Read a map written by :meth:`save` (ValueError if it is corrupt or incompatible)."""
        from ..io import read_json

        d = read_json(path, "stability map file")  # size, depth and numbers bounded
        try:
            return cls.from_dict(d)
        except (KeyError, TypeError, AttributeError, IndexError) as exc:
            raise ValueError(f"stability map file {str(path)!r} is incomplete: {type(exc).__name__}: {exc}") from None


# ---------------------------------------------------------------------- computation
def cache_dir() -> Path:
    """Cache folder: ``$GEAR_ENV_CACHE`` or ``~/.cache/gear-env``."""
    env = os.environ.get("GEAR_ENV_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "gear-env"


def cache_key(params: GearParams, model: str, omega: np.ndarray, steps_per_period: int | None) -> str:
    """SHA-256 (hex, 24 characters) of everything the map depends on."""
    steps: int | str = steps_per_period if steps_per_period is not None else auto_steps_rule(params)
    blob = json.dumps(
        {
            "v": FORMAT_VERSION,
            "params": params.to_dict(),
            "model": model,
            "omega": [float(f"{w:.12g}") for w in omega],
            "steps": steps,
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def _grid(omega_min: float, omega_max: float, points: int) -> np.ndarray:
    lo = check_omega(omega_min, "omega_min")
    hi = check_omega(omega_max, "omega_max")
    n = check_count(points, "points", 2)
    if hi <= lo:
        raise ValueError(f"omega_max must be > omega_min, got omega_min={omega_min!r}, omega_max={omega_max!r}")
    return np.linspace(lo, hi, n)


def compute_stability_map(
    omega: np.ndarray,
    model: str = "dynamic",
    params: GearParams | None = None,
    steps_per_period: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> StabilityMap:
    """Continue the period-1 orbit along ``omega`` (increasing) without any cache; see :func:`stability_map`."""
    p = params if params is not None else GearParams()
    model_code(model)
    fixed = None if steps_per_period is None else check_steps(steps_per_period)
    w = np.asarray(omega, dtype=float)
    n = len(w)
    mus = np.zeros((n, 10), dtype=complex)
    conv = np.zeros(n, dtype=bool)
    labels = np.empty(n, dtype=object)
    states = np.zeros((n, 10))
    res = np.zeros(n)
    prev: list[np.ndarray] = []  # last converged orbit states (for the predictor)
    prev_w: list[float] = []
    for i, wi in enumerate(w):
        steps = resolve_steps(fixed, float(wi), p)
        guesses: list[np.ndarray | None] = []
        if len(prev) >= 2 and abs(wi - prev_w[-1]) < 3 * abs(w[1] - w[0]) + 1e-12:
            t = (wi - prev_w[-1]) / (prev_w[-1] - prev_w[-2])
            guesses.append(prev[-1] + t * (prev[-1] - prev[-2]))
        if prev:
            guesses.append(prev[-1])
        guesses.append(None)  # simulation from the previous orbit (or A10)
        orbit = None
        for g in guesses:
            try:
                if g is None:
                    sim = GearSimulator(p, model, steps, wi, prev[-1] if prev else None)
                    sim.advance(300)
                    g = sim.state
                o = find_periodic_orbit(wi, model, p, 1, g, steps)
            except SimulationDivergedError:
                continue
            if orbit is None or o.residual < orbit.residual:
                orbit = o
            if o.converged:
                break
        if orbit is not None and orbit.converged:
            mus[i] = orbit.multipliers
            conv[i] = True
            labels[i] = orbit.bifurcation
            states[i] = orbit.state
            res[i] = orbit.residual
            prev = (prev + [orbit.state])[-2:]
            prev_w = (prev_w + [float(wi)])[-2:]
        else:
            labels[i] = "unconverged"
            if orbit is not None:
                states[i] = orbit.state
                res[i] = orbit.residual
            else:
                res[i] = math.inf
        if progress is not None:
            progress(i + 1, n)
    res = np.where(np.isfinite(res), res, 1e300)
    return StabilityMap(
        model=model,
        omega=w,
        multipliers=mus,
        max_multiplier=np.abs(mus[:, 0]),
        converged=conv,
        labels=labels,
        states=states,
        residual=res,
        steps_per_period=fixed,
        params=p.to_dict(),
    )


def default_stability_map(model: str = "dynamic") -> StabilityMap:
    """The precomputed map of the default configuration shipped with the package (no computation):
    Table 1 parameters, omega in [0.05, 3.0] with DEFAULT_POINTS points, default steps per period."""
    model_code(model)
    ref = resources.files("gear_env") / "data" / f"stability_{model}.json"
    from ..io import parse_json_text

    return StabilityMap.from_dict(parse_json_text(ref.read_text(encoding="utf-8"), f"packaged map {model!r}"))


def stability_map(
    model: str = "dynamic",
    params: GearParams | None = None,
    omega_min: float = 0.05,
    omega_max: float = 3.0,
    points: int = DEFAULT_POINTS,
    steps_per_period: int | None = None,
    *,
    cache: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> StabilityMap:
    """Floquet stability map of the period-1 orbit over ``points`` omegas in [omega_min, omega_max].

    Args:
        model: ``"constant"`` or ``"dynamic"``.
        params: physical parameters (default Table 1).
        omega_min, omega_max: grid limits (Omega/omega_n).
        points: grid points (>= 2), uniform.
        steps_per_period: Newmark steps per mesh period of the one-period map; None (default):
            ``default_steps_per_period(omega)`` at each grid point.
        cache: read/write the disk cache (and use the packaged default maps when they match).
        progress: optional callback ``progress(done, total)``.

    Returns:
        :class:`StabilityMap`; ``.stable_intervals()``, ``.is_stable(omega)``, ``.bifurcations()``.
    """
    p = params if params is not None else GearParams()
    if not isinstance(p, GearParams):
        raise ValueError(f"params must be a GearParams, got {type(p).__name__}")
    model_code(model)
    refuse_velocity_correction(p, "the stability map")  # Floquet multipliers of the plain step: before any work
    steps = None if steps_per_period is None else check_steps(steps_per_period)
    grid = _grid(omega_min, omega_max, points)
    for wi in grid:  # a conditionally stable Newmark beta (GearParams.newmark_beta): refused before any work
        check_stable_steps(p, resolve_steps(steps, float(wi), p), float(wi))
    key = cache_key(p, model, grid, steps)
    if cache:
        try:
            d = default_stability_map(model)
            if cache_key(GearParams.from_dict(d.params), d.model, d.omega, d.steps_per_period) == key:
                return d
        except (OSError, ValueError, FileNotFoundError):
            pass
        path = cache_dir() / f"stability-{model}-{key}.json"
        if path.exists():
            try:
                m = StabilityMap.load(path)
                if cache_key(GearParams.from_dict(m.params), m.model, m.omega, m.steps_per_period) == key:
                    return m
            except (OSError, ValueError):
                pass  # corrupt or foreign: recompute below
    m = compute_stability_map(grid, model, p, steps, progress)
    if cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            m.save(path)
        except OSError:
            pass  # a read-only cache folder must not break the computation
    return m


__all__ = [
    "DEFAULT_POINTS",
    "LABELS",
    "StabilityMap",
    "cache_dir",
    "cache_key",
    "compute_stability_map",
    "default_stability_map",
    "stability_map",
]
