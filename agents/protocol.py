"""The evaluation protocol of the learned policies: named, disjoint seed sets and the statistics of every table.

One place for the seeds (docs/ENVIRONMENT.md, "Evaluation protocol"):

* ``TRAIN_RUN_SEEDS``: the ``--seed`` of the training runs reported (``gear-env train --seed S``). A run with
  seed S and ``n`` sub-environments starts sub-env ``i`` with episode seed ``S + i`` and continues that
  generator; its in-training evaluation (checkpoint choice, ``best_model.zip``) uses ``S + 1_000_003 + i``
  (``agents.ppo.EVAL_SEED_OFFSET``). ``TRAIN_ENV_SEEDS`` and ``IN_TRAINING_EVAL_SEEDS`` bound both.
* ``VALIDATION_SEEDS``: episode seeds (``gear-env evaluate --seed``) for choosing between runs, checkpoints,
  hyper-parameters and the constants of scripted policies.
* ``TEST_SEEDS``: episode seeds used only for the reported numbers, never for a choice.

The ranges are fresh: the docs before this protocol quoted 100-119 and 9001-9020, issue #23 500-529.

Statistics (all paired by episode seed, since the plant draw dominates the spread of a return):

* :func:`mean_ci`: mean and percentile-bootstrap 95 % interval of per-episode values;
* :func:`paired_diff`: mean per-episode difference a - b with its bootstrap 95 % interval;
* :func:`gap_closed`: (mean(x) - mean(F)) / (mean(O) - mean(F)) with F fixed-best, O the oracle, and its
  interval from resampling episodes jointly (the three returns of an episode stay together);
* :func:`iqm_ci`: interquartile mean of a (runs, episodes) score matrix with the stratified bootstrap of
  rliable (Agarwal et al. 2021): runs resampled, then episodes within each run.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

TRAIN_RUN_SEEDS = tuple(range(10))
"""``gear-env train --seed S`` of the reported runs (the first five are the >= 5 seeds of the tables)."""
TRAIN_ENV_SEEDS = range(0, 2_000)
"""Episode seeds of the training environments (run seed + sub-env index; runs use S < 10, <= 1024 envs)."""
IN_TRAINING_EVAL_SEEDS = range(1_000_003, 1_002_003)
"""Episode seeds of the evaluations during training (run seed + 1_000_003 + sub-env index)."""
VALIDATION_SEEDS = range(700_000, 700_050)
"""50 episode seeds for every choice: runs, checkpoints, hyper-parameters, scripted policies' constants."""
TEST_SEEDS = range(800_000, 800_100)
"""100 episode seeds for the reported numbers only."""
SEED_SETS = {
    "train": TRAIN_ENV_SEEDS,
    "in-training-eval": IN_TRAINING_EVAL_SEEDS,
    "validation": VALIDATION_SEEDS,
    "test": TEST_SEEDS,
}
"""Every named set of episode seeds (pairwise disjoint; ``tests/test_protocol.py`` checks it)."""

N_BOOT = 5_000
BOOT_SEED = 0


def seed_set(name: str) -> range:
    """The episode seeds of the set ``name`` (``validation``, ``test``, ...); a clear error otherwise."""
    if name not in SEED_SETS:
        raise ValueError(f"unknown seed set {name!r}; valid: {', '.join(SEED_SETS)}")
    return SEED_SETS[name]


def _episodes(x: Sequence[float] | np.ndarray, what: str) -> np.ndarray:
    a = np.asarray(x, float)
    if a.ndim != 1 or a.size < 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be a 1-D array of >= 2 finite per-episode values, got shape {a.shape}")
    return a


def _boot_index(n: int, reps: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, n, size=(reps, n))


def mean_ci(x: Sequence[float], reps: int = N_BOOT, seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """(mean, low, high): the mean of per-episode values and its 95 % percentile-bootstrap interval."""
    a = _episodes(x, "x")
    m = a[_boot_index(a.size, reps, seed)].mean(axis=1)
    return float(a.mean()), float(np.percentile(m, 2.5)), float(np.percentile(m, 97.5))


def paired_diff(a: Sequence[float], b: Sequence[float], reps: int = N_BOOT, seed: int = BOOT_SEED) -> tuple:
    """(mean, low, high) of the per-episode difference a - b (same episode seeds) with a 95 % bootstrap CI."""
    x, y = _episodes(a, "a"), _episodes(b, "b")
    if x.shape != y.shape:
        raise ValueError(f"paired values need the same episodes, got {x.size} and {y.size}")
    return mean_ci(x - y, reps, seed)


def gap_closed(
    x: Sequence[float], fixed: Sequence[float], oracle: Sequence[float], reps: int = N_BOOT, seed: int = BOOT_SEED
) -> tuple[float, float, float]:
    """(share, low, high): the share of the fixed-best -> oracle gap that ``x`` closes on the same episodes,
    (mean x - mean F) / (mean O - mean F), with a 95 % bootstrap CI (episodes resampled jointly)."""
    X, F, O = _episodes(x, "x"), _episodes(fixed, "fixed"), _episodes(oracle, "oracle")
    if not X.shape == F.shape == O.shape:
        raise ValueError("x, fixed and oracle must hold the returns of the same episodes")
    if not O.mean() > F.mean():
        raise ValueError(f"no gap to close: mean oracle {O.mean():.4g} <= mean fixed-best {F.mean():.4g}")
    idx = _boot_index(X.size, reps, seed)
    xm, fm, om = X[idx].mean(axis=1), F[idx].mean(axis=1), O[idx].mean(axis=1)
    share = (xm - fm) / np.where(om - fm > 0, om - fm, np.nan)
    share = share[np.isfinite(share)]
    g = (X.mean() - F.mean()) / (O.mean() - F.mean())
    return float(g), float(np.percentile(share, 2.5)), float(np.percentile(share, 97.5))


def iqm(x: np.ndarray) -> float:
    """Interquartile mean: the mean of the middle 50 % of all values (rliable's definition)."""
    a = np.sort(np.asarray(x, float).ravel())
    n = a.size
    return float(a[int(np.floor(0.25 * n)) : int(np.ceil(0.75 * n))].mean())


def iqm_ci(scores: np.ndarray, reps: int = 2000, seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """IQM of a (runs, episodes) score matrix and its 95 % stratified-bootstrap interval (runs resampled,
    then episodes within each resampled run)."""
    s = np.asarray(scores, float)
    if s.ndim != 2 or s.shape[0] < 1 or s.shape[1] < 2:
        raise ValueError(f"scores must be a (runs, episodes) matrix with >= 2 episodes, got shape {s.shape}")
    rng = np.random.default_rng(seed)
    stats = []
    for _ in range(reps):
        runs = s[rng.integers(0, s.shape[0], s.shape[0])]
        eps = np.take_along_axis(runs, rng.integers(0, s.shape[1], runs.shape), axis=1)
        stats.append(iqm(eps))
    return iqm(s), float(np.percentile(stats, 2.5)), float(np.percentile(stats, 97.5))


def gap_scores(returns: np.ndarray, fixed: Sequence[float], oracle: Sequence[float]) -> np.ndarray:
    """Per-episode gap scores (r - F_e) / (mean O - mean F) of a (runs, episodes) return matrix: episode e's
    return above fixed-best's on the same episode, in units of the mean gap (their mean is :func:`gap_closed`;
    the IQM over runs x episodes is the rliable-style summary)."""
    F, O = np.asarray(fixed, float), np.asarray(oracle, float)
    return (np.asarray(returns, float) - F[None, :]) / (O.mean() - F.mean())


__all__ = [
    "IN_TRAINING_EVAL_SEEDS",
    "SEED_SETS",
    "TEST_SEEDS",
    "TRAIN_ENV_SEEDS",
    "TRAIN_RUN_SEEDS",
    "VALIDATION_SEEDS",
    "gap_closed",
    "gap_scores",
    "iqm",
    "iqm_ci",
    "mean_ci",
    "paired_diff",
    "seed_set",
]
