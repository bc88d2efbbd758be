"""Evaluation layer: roll out speed policies on the tasks and report them (one import for all).

The code lives in one module per concern; this package re-exports their public names (the steady
reward map and the regime bands belong to the environment layer, :mod:`gear_env.envs`, because the
environment's render frame uses them):

* :func:`steady_reward_map`, :class:`SteadyRewardMap` (:mod:`gear_env.envs.steady_map`) - the per-step
  reward (and every term) of holding each omega constant, after a settling time.
* :func:`regime_bands`, :class:`RegimeBands` (:mod:`gear_env.envs.bands`) - periodic / non-periodic
  bands of omega for the figures (the shipped Floquet map, else steady runs).
* :func:`evaluate_policies`, :func:`run_episode` (:mod:`gear_env.evaluation.episodes`) - roll out policies
  (SB3 models, :mod:`gear_env.envs.schedules`, or any object with ``predict``) for some episodes.
* :class:`EvaluationReport`, :class:`EpisodeResult`, ``METRICS`` (:mod:`gear_env.evaluation.report`) - the
  results, their confidence intervals, Markdown/JSON and the figure.

``python -m gear_env.evaluation`` prints the steady reward map; its command line is
:mod:`gear_env.cli.steady`.
"""

from __future__ import annotations

from ..envs.bands import RegimeBands, regime_bands
from ..envs.env_core import INFO_KEYS
from ..envs.steady_map import SteadyRewardMap, steady_reward_map
from .episodes import evaluate_policies, run_episode
from .report import METRICS, EpisodeResult, EvaluationReport

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
