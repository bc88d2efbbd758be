"""The evaluation report: per policy a list of episode results, their means and 95 % confidence
intervals, as Markdown, JSON and a figure. Built by :func:`gear_env.episodes.evaluate_policies`;
also importable from :mod:`gear_env.evaluation`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .bands import RegimeBands, regime_bands
from .env_config import GearSpeedConfig


@dataclass
class EpisodeResult:
    """Metrics of one episode.

    Attributes:
        ret: undiscounted return.
        throughput: mean omega over the steps.
        chaotic_fraction: fraction of steps with non-periodic motion (c > 0.5).
        contact_loss: time-weighted contact-loss fraction.
        impacts: drive re-impacts + back impacts.
        settled_omega: mean omega over the last quarter of the episode.
        steps: steps taken; diverged: True if the episode ended by divergence.
        omega: omega after each step (for plots); vibration: peak mesh force / F_s per step.
    """

    ret: float
    throughput: float
    chaotic_fraction: float
    contact_loss: float
    impacts: int
    settled_omega: float
    steps: int
    diverged: bool
    omega: list[float] = field(default_factory=list)
    vibration: list[float] = field(default_factory=list)


def _ci95(x: Sequence[float]) -> tuple[float, float]:
    """Mean and the half-width of a 95 % t confidence interval (0 for one value)."""
    a = np.asarray(x, float)
    if a.size < 2:
        return float(a.mean()) if a.size else math.nan, 0.0
    from scipy import stats

    half = float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return float(a.mean()), half


METRICS = ("ret", "throughput", "chaotic_fraction", "contact_loss", "impacts", "settled_omega")


@dataclass
class EvaluationReport:
    """Results of :func:`evaluate_policies`: per policy, a list of :class:`EpisodeResult`."""

    episodes: dict[str, list[EpisodeResult]]
    config: GearSpeedConfig
    seed: int

    def summary(self, name: str) -> dict[str, tuple[float, float]]:
        """Mean and 95 % CI half-width of each metric of policy ``name``."""
        eps = self.episodes[name]
        return {m: _ci95([getattr(e, m) for e in eps]) for m in METRICS}

    def to_markdown(self) -> str:
        """The comparison table (mean +- 95 % CI over episodes)."""
        head = (
            "| policy | return | throughput (mean omega) | chaotic fraction | contact loss | impacts | settled omega |"
        )
        lines = [head, "|---|---:|---:|---:|---:|---:|---:|"]
        for name in self.episodes:
            s = self.summary(name)
            cells = []
            for m, fmt in zip(METRICS, ("{:.2f}", "{:.3f}", "{:.3f}", "{:.3f}", "{:.0f}", "{:.3f}")):
                mean, half = s[m]
                cells.append(fmt.format(mean) + (" ± " + fmt.format(half) if half > 0 else ""))
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        n = len(next(iter(self.episodes.values()), []))
        lines.append("")
        lines.append(f"{n} episode(s) per policy, seed {self.seed}; ± = 95 % confidence interval (t).")
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict: per policy the means, CIs and per-episode values."""
        out: dict[str, Any] = {"seed": self.seed, "config": self.config.to_dict(), "policies": {}}
        for name, eps in self.episodes.items():
            s = self.summary(name)
            out["policies"][name] = {
                "episodes": len(eps),
                "return_mean": s["ret"][0],
                "return_ci95": s["ret"][1],
                "throughput_mean": s["throughput"][0],
                "throughput_ci95": s["throughput"][1],
                "chaotic_fraction": s["chaotic_fraction"][0],
                "chaotic_fraction_ci95": s["chaotic_fraction"][1],
                "contact_loss_fraction": s["contact_loss"][0],
                "contact_loss_fraction_ci95": s["contact_loss"][1],
                "impacts_mean": s["impacts"][0],
                "impacts_ci95": s["impacts"][1],
                "settled_omega_mean": s["settled_omega"][0],
                "settled_omega": [e.settled_omega for e in eps],
                "returns": [e.ret for e in eps],
                "diverged": sum(e.diverged for e in eps),
            }
        return out

    def plot(self, path: str | None = None, bands: RegimeBands | None = None):
        """omega(t) of the first episode of each policy over the regime bands, vibration below."""
        from .plots.env import plot_evaluation

        fig = plot_evaluation(self, bands if bands is not None else regime_bands(self.config))
        if path is not None:
            from .plots.common import save_figure

            save_figure(fig, path)
        return fig


__all__ = ["METRICS", "EpisodeResult", "EvaluationReport"]
