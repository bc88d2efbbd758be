"""The evaluation report: per policy a list of episode results, their means and 95 % confidence
intervals, as Markdown, JSON and a figure. Built by :func:`gear_env.evaluation.episodes.evaluate_policies`;
also importable from :mod:`gear_env.evaluation`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..envs.bands import RegimeBands, regime_bands
from ..envs.env_config import GearSpeedConfig


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
        cost: sum over the episode of ``info["cost"]`` (the safe-RL constraint signal: non-periodic
            motion, contact loss, impacts).
        demand_delivered: with a demand profile, the fraction of the demand delivered,
            sum of min(mean omega, demand) / sum of demand over the steps; NaN without one.
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
    cost: float = 0.0
    demand_delivered: float = math.nan


def _ci95(x: Sequence[float]) -> tuple[float, float]:
    """Mean and the half-width of a 95 % t confidence interval (0 for one value)."""
    a = np.asarray(x, float)
    if a.size < 2:
        return float(a.mean()) if a.size else math.nan, 0.0
    from scipy import stats

    half = float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return float(a.mean()), half


METRICS = (
    "ret",
    "throughput",
    "chaotic_fraction",
    "contact_loss",
    "impacts",
    "settled_omega",
    "cost",
    "demand_delivered",
)


@dataclass
class EvaluationReport:
    """Results of :func:`evaluate_policies`: per policy, a list of :class:`EpisodeResult`."""

    episodes: dict[str, list[EpisodeResult]]
    config: GearSpeedConfig
    seed: int
    reference: str | None = None
    """Name of the policy the "% of" column divides by (e.g. ``"oracle"``); None: no such column."""

    def __post_init__(self) -> None:
        if self.reference is not None and self.reference not in self.episodes:
            raise ValueError(f"reference {self.reference!r} is not one of the policies {list(self.episodes)}")

    def percent_of_reference(self, name: str) -> float:
        """Mean return of ``name`` as a percentage of the reference policy's (same seeds); NaN without one.

        A reference that plans on steady maps (the oracle) is not an upper bound: a policy can exceed
        100 % where holding one speed is best (docs/ENVIRONMENT.md, "Baselines")."""
        if self.reference is None:
            return math.nan
        ref = float(np.mean([e.ret for e in self.episodes[self.reference]]))
        return 100.0 * float(np.mean([e.ret for e in self.episodes[name]])) / abs(ref) if ref != 0 else math.nan

    def summary(self, name: str) -> dict[str, tuple[float, float]]:
        """Mean and 95 % CI half-width of each metric of policy ``name``."""
        eps = self.episodes[name]
        return {m: _ci95([getattr(e, m) for e in eps]) for m in METRICS}

    def to_markdown(self) -> str:
        """The comparison table (mean +- 95 % CI over episodes): return, "% of" the reference policy (if
        set), cost, demand delivered (with a demand profile), throughput, chaos, contact loss, impacts and
        settled omega."""
        demand = self.config.demand is not None
        cols = [("ret", "return", "{:.2f}"), ("cost", "cost", "{:.2f}")]
        if demand:
            cols.append(("demand_delivered", "demand delivered", "{:.3f}"))
        cols += [
            ("throughput", "throughput (mean omega)", "{:.3f}"),
            ("chaotic_fraction", "chaotic fraction", "{:.3f}"),
            ("contact_loss", "contact loss", "{:.3f}"),
            ("impacts", "impacts", "{:.0f}"),
            ("settled_omega", "settled omega", "{:.3f}"),
        ]
        heads = [c[1] for c in cols]
        if self.reference is not None:
            heads.insert(1, f"% of {self.reference}")
        lines = ["| policy | " + " | ".join(heads) + " |", "|---|" + "---:|" * len(heads)]
        for name in self.episodes:
            s = self.summary(name)
            cells = []
            for m, _, fmt in cols:
                mean, half = s[m]
                cells.append(fmt.format(mean) + (" ± " + fmt.format(half) if half > 0 else ""))
            if self.reference is not None:
                cells.insert(1, f"{self.percent_of_reference(name):.1f} %")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        n = len(next(iter(self.episodes.values()), []))
        lines.append("")
        note = f"{n} episode(s) per policy, seed {self.seed}; ± = 95 % confidence interval (t)."
        note += ' cost = sum of info["cost"] over the episode.'
        if demand:
            note += " demand delivered = sum of min(omega, demand) / sum of demand."
        if self.reference is not None:
            note += f" % of {self.reference}: mean return over {self.reference}'s on the same seeds"
            if self.reference == "oracle":
                note += " (the oracle plans on steady maps; a fixed speed can score slightly above it)"
            note += "."
        lines.append(note)
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict: per policy the means, CIs and per-episode values."""
        out: dict[str, Any] = {
            "seed": self.seed,
            "config": self.config.to_dict(),
            "reference": self.reference,
            "policies": {},
        }
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
                "cost_mean": s["cost"][0],
                "cost_ci95": s["cost"][1],
                "demand_delivered_mean": s["demand_delivered"][0] if self.config.demand is not None else None,
                "percent_of_reference": self.percent_of_reference(name) if self.reference is not None else None,
                "settled_omega": [e.settled_omega for e in eps],
                "returns": [e.ret for e in eps],
                "diverged": sum(e.diverged for e in eps),
            }
        return out

    def plot(self, path: str | None = None, bands: RegimeBands | None = None):
        """omega(t) of the first episode of each policy over the regime bands, vibration below."""
        from ..plots.env import plot_evaluation

        fig = plot_evaluation(self, bands if bands is not None else regime_bands(self.config))
        if path is not None:
            from ..plots.common import save_figure

            save_figure(fig, path)
        return fig


__all__ = ["METRICS", "EpisodeResult", "EvaluationReport"]
