"""Regime bands of omega (periodic / impacting / non-periodic, or the Floquet labels of the
period-1 orbit): the background the environment's figures draw a speed schedule over.

:func:`regime_bands` takes them from the shipped Floquet stability map
(:mod:`gear_env.analysis.stability`) when the parameters are the defaults, else from constant-speed
runs of :func:`gear_env.envs.steady_map.steady_reward_map`. The plots receive the resulting
:class:`RegimeBands` as data. Also importable from :mod:`gear_env.evaluation`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .env_config import GearSpeedConfig
from .steady_map import steady_reward_map


@dataclass
class RegimeBands:
    """Intervals of omega by regime: lists of (lo, hi) for 'periodic', 'nonperiodic', 'impacting'."""

    bands: dict[str, list[tuple[float, float]]]
    source: str

    def to_dict(self) -> dict[str, Any]:
        return {"bands": {k: [list(b) for b in v] for k, v in self.bands.items()}, "source": self.source}


def mask_intervals(omegas: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Maximal runs of True in ``mask`` as (lo, hi) intervals of ``omegas`` (Omega/omega_n, sorted);
    interval edges lie half-way to the neighbouring grid points."""
    out = []
    n = len(omegas)
    edges = np.concatenate([[omegas[0]], 0.5 * (omegas[1:] + omegas[:-1]), [omegas[-1]]])
    i = 0
    while i < n:
        if mask[i]:
            j = i
            while j + 1 < n and mask[j + 1]:
                j += 1
            out.append((float(edges[i]), float(edges[j + 1])))
            i = j + 1
        else:
            i += 1
    return out


_intervals = mask_intervals  # the name used inside the package before it was public


_BAND_CACHE: dict[str, RegimeBands] = {}


def regime_bands(config: GearSpeedConfig | Mapping[str, Any] | None = None, points: int = 59) -> RegimeBands:
    """Regime bands of omega for plots: a shipped stability map if available, else steady runs.

    With the default parameters, the Floquet stability map of the period-1 orbit shipped with
    :mod:`gear_env.analysis.stability` (labels ``stable``, ``period-doubling``, ``neimark-sacker``,
    ``fold``, ``unconverged``). Otherwise (or if that module is missing) ``points`` constant-speed
    runs of :func:`steady_reward_map`, classified as ``nonperiodic`` (c > 0.5), ``impacting``
    (periodic with contact loss > 0.05) or ``periodic``. Results are cached per configuration.
    """
    cfg = GearSpeedConfig.from_kwargs(config)
    key = json.dumps(cfg.to_dict(), sort_keys=True, default=str) + f"|{points}"
    if key in _BAND_CACHE:
        return _BAND_CACHE[key]
    bands = _bands_from_stability_module(cfg)
    if bands is None:
        w = np.linspace(cfg.omega_min, cfg.omega_max, points)
        smap = steady_reward_map(cfg, w, settle_steps=6, average_steps=4)
        non = smap.terms["chaos"] > 0.5
        imp = (~non) & (smap.terms["contact_loss"] > 0.05)
        bands = RegimeBands(
            {
                "periodic": _intervals(w, (~non) & (~imp)),
                "impacting": _intervals(w, imp),
                "nonperiodic": _intervals(w, non),
            },
            source="steady_reward_map",
        )
    _BAND_CACHE[key] = bands
    return bands


def _bands_from_stability_module(cfg: GearSpeedConfig) -> RegimeBands | None:
    """Bands from the shipped Floquet stability map (:mod:`gear_env.analysis.stability`) when the
    configuration uses the default parameters; None otherwise (never raises)."""
    try:
        from ..analysis.stability import default_stability_map
        from ..sim.params import GearParams

        if cfg.params.to_dict() != GearParams().to_dict():
            return None
        smap = default_stability_map(cfg.model)
        bands: dict[str, list[tuple[float, float]]] = {}
        for lo, hi, label in smap.intervals():
            lo, hi = max(lo, cfg.omega_min), min(hi, cfg.omega_max)
            if hi > lo:
                bands.setdefault(str(label), []).append((float(lo), float(hi)))
        return (
            RegimeBands(bands, source=f"shipped Floquet map of the period-1 orbit, {cfg.model} backlash")
            if bands
            else None
        )
    except Exception:
        return None


__all__ = ["RegimeBands", "mask_intervals", "regime_bands"]
