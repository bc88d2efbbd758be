"""Evaluation of speed policies on ``GearSpeed-v0`` and the steady reward map (one import for all).

The code lives in one module per concern; this module re-exports their public names:

* :func:`steady_reward_map`, :class:`SteadyRewardMap` (:mod:`gear_env.steady_map`) - the per-step
  reward (and every term) of holding each omega constant, after a settling time.
* :func:`regime_bands`, :class:`RegimeBands` (:mod:`gear_env.bands`) - periodic / non-periodic
  bands of omega for the figures (the shipped Floquet map, else steady runs).
* :func:`evaluate_policies`, :func:`run_episode` (:mod:`gear_env.episodes`) - roll out policies
  (SB3 models, :mod:`gear_env.schedules`, or any object with ``predict``) for some episodes.
* :class:`EvaluationReport`, :class:`EpisodeResult`, ``METRICS`` (:mod:`gear_env.report`) - the
  results, their confidence intervals, Markdown/JSON and the figure.

``python -m gear_env.evaluation`` prints the steady reward map; its command line is
:mod:`gear_env.cli.steady`.
"""

from __future__ import annotations

from collections.abc import Sequence

from .bands import RegimeBands, regime_bands
from .env_core import INFO_KEYS
from .episodes import evaluate_policies, run_episode
from .report import METRICS, EpisodeResult, EvaluationReport
from .steady_map import SteadyRewardMap, steady_reward_map

__all__ = [
    "INFO_KEYS",
    "METRICS",
    "EpisodeResult",
    "EvaluationReport",
    "RegimeBands",
    "SteadyRewardMap",
    "evaluate_policies",
    "regime_bands",
    "run_episode",
    "steady_reward_map",
]


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gear_env.evaluation``: :func:`gear_env.cli.steady.main` (the steady reward map)."""
    from .cli.steady import main as steady_main

    return steady_main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
