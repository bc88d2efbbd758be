"""The steady reward map: the per-step reward (and every term) of holding each omega constant.

:func:`steady_reward_map` runs the environment's core (:class:`gear_env.envs.env_core.GearSpeedCore`)
at constant speeds, all omegas in one batched kernel call per step: the landscape an oracle or a
reader uses to judge a policy (docs/ENVIRONMENT.md). Also importable from :mod:`gear_env.evaluation`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .env_config import GearSpeedConfig
from .env_core import REWARD_KEYS, GearSpeedCore


@dataclass
class SteadyRewardMap:
    """Steady per-step reward of constant speeds.

    Attributes:
        omegas: (m,) meshing frequencies Omega/omega_n.
        reward: (m,) mean reward per step over the averaging steps.
        terms: each ``reward_*`` term (m,), and the features ``chaos``, ``contact_loss``,
            ``force_peak`` (/F_s), ``defect`` [b0], ``period``, ``drive_impacts`` and
            ``back_impacts`` (per mesh period), averaged the same way.
        settle_steps, average_steps: env steps discarded / averaged per omega.
    """

    omegas: np.ndarray
    reward: np.ndarray
    terms: dict[str, np.ndarray]
    settle_steps: int
    average_steps: int

    @property
    def best_omega(self) -> float:
        """The omega with the largest steady reward."""
        return float(self.omegas[int(np.argmax(self.reward))])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "omegas": self.omegas.tolist(),
            "reward": self.reward.tolist(),
            "terms": {k: v.tolist() for k, v in self.terms.items()},
            "settle_steps": self.settle_steps,
            "average_steps": self.average_steps,
            "best_omega": self.best_omega,
        }

    def to_markdown(self) -> str:
        """A table omega | reward | main terms."""
        t = self.terms
        lines = [
            "| omega | reward | chaos c | contact loss | impacts/period | F_peak/F_s | period |",
            "|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for i, w in enumerate(self.omegas):
            lines.append(
                f"| {w:.2f} | {self.reward[i]:+.3f} | {t['chaos'][i]:.2f} | {t['contact_loss'][i]:.2f} | "
                f"{t['drive_impacts'][i] + t['back_impacts'][i]:.2f} | {t['force_peak'][i]:.2f} | "
                f"{t['period'][i]:.1f} |"
            )
        return "\n".join(lines)


def undisturbed_config(cfg: GearSpeedConfig) -> GearSpeedConfig:
    """``cfg`` as a steady map sees it: the undisturbed plant (no randomisation, demand, plant family,
    duty cycle, wear change, dead time or sensor noise; all throughput paid) under delta actions without a
    reference filter or action range, so that every task built on the same physics and weights shares one map."""
    return cfg.replace(
        randomize_params=False,
        demand=None,
        throughput="all",
        plant_family=None,
        duty_cycle=None,
        action_mode="delta",
        action_range=None,
        reference_filter=1.0,
        wear=None,
        action_delay=0,
        sensor_noise=0.0,
    )


def steady_reward_map(
    config: GearSpeedConfig | Mapping[str, Any] | None = None,
    omegas: Sequence[float] | np.ndarray | None = None,
    settle_steps: int = 10,
    average_steps: int = 10,
) -> SteadyRewardMap:
    """Steady reward of holding each omega constant (action 0 in delta mode).

    Each omega starts from the static equilibrium, runs the configured warm-up plus
    ``settle_steps`` environment steps, then averages the reward terms over ``average_steps``
    steps. All omegas advance together in one batched kernel call per step. Parameter
    randomisation and the demand profile are switched off.

    Args:
        config: environment settings (default: the defaults of ``GearSpeed-v0``).
        omegas: meshing frequencies in [omega_min, omega_max] (default 59 points over the range).
        settle_steps: steps discarded after the warm-up (>= 0).
        average_steps: steps averaged (>= 1).

    Returns:
        :class:`SteadyRewardMap`.
    """
    cfg = undisturbed_config(GearSpeedConfig.from_kwargs(config)).replace(max_steps=10**6)
    if omegas is None:
        omegas = np.linspace(cfg.omega_min, cfg.omega_max, 59)
    w = np.asarray(omegas, float).ravel()
    if w.size == 0 or not np.all(np.isfinite(w)) or w.min() < cfg.omega_min or w.max() > cfg.omega_max:
        raise ValueError(f"omegas must be non-empty and in [{cfg.omega_min:g}, {cfg.omega_max:g}], got {omegas!r}")
    if isinstance(settle_steps, bool) or not isinstance(settle_steps, (int, np.integer)) or settle_steps < 0:
        raise ValueError(f"settle_steps must be an integer >= 0, got {settle_steps!r}")
    if isinstance(average_steps, bool) or not isinstance(average_steps, (int, np.integer)) or average_steps < 1:
        raise ValueError(f"average_steps must be an integer >= 1, got {average_steps!r}")
    m = w.size
    core = GearSpeedCore(cfg, m)
    rng = np.random.default_rng(0)  # unused: initial omegas are forced, nothing random remains
    for i in range(m):
        core.reset_rows(np.array([i]), [rng], {"omega": float(w[i])})
    rows = np.arange(m)
    zero = np.zeros(m)
    keys = list(REWARD_KEYS) + [
        "chaos",
        "contact_loss",
        "force_peak",
        "defect",
        "period",
        "drive_impacts",
        "back_impacts",
    ]
    sums = {k: np.zeros(m) for k in keys}
    total = np.zeros(m)
    for k in range(settle_steps + average_steps):
        r, _, _ = core.step_rows(rows, zero)
        if k >= settle_steps:
            total += r
            for key in keys:
                sums[key] += core.info[key]
    pps = cfg.periods_per_step
    terms = {k: v / average_steps for k, v in sums.items()}
    terms["drive_impacts"] = terms["drive_impacts"] / pps
    terms["back_impacts"] = terms["back_impacts"] / pps
    return SteadyRewardMap(w, total / average_steps, terms, settle_steps, average_steps)


__all__ = ["SteadyRewardMap", "steady_reward_map", "undisturbed_config"]
