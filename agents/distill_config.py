"""The settings of the distillation (:mod:`agents.distill`): defaults and their check, in a module of their own so
that the run folder's reader (:mod:`agents.runs`) validates a ``config.json`` without importing the trainer."""

from __future__ import annotations

from typing import Any

DISTILL_DEFAULTS: dict[str, Any] = {
    "episodes": 100, "epochs": 20, "learning_rate": 1e-3, "batch_size": 256, "final_lr_fraction": 1.0,
    "quantile": None,
}  # fmt: skip
"""Defaults of the distillation (per iteration: ``episodes`` rollouts, then ``epochs`` passes over all labels,
the learning rate going linearly from ``learning_rate`` to ``final_lr_fraction`` x ``learning_rate``; the actor
fits the teacher's mean action (squared error) or, with ``quantile`` q in (0, 1), its q-quantile given the
observation (pinball loss): below 0.5 a student that acts below the teacher where what it senses leaves the
teacher's action uncertain, and like it where it does not)."""
MAX_ITERATIONS = 1_000
MAX_EPISODES = 100_000


def check_distill(iterations: Any, params: dict[str, Any]) -> None:
    """ValueError naming the field unless ``iterations`` and ``params`` (``DISTILL_DEFAULTS`` keys) are valid."""
    if isinstance(iterations, bool) or not isinstance(iterations, int) or not 0 <= iterations <= MAX_ITERATIONS:
        raise ValueError(f"distill (DAgger iterations) must be an integer in [0, {MAX_ITERATIONS}], got {iterations!r}")
    unknown = sorted(set(params) - set(DISTILL_DEFAULTS))
    if unknown:
        raise ValueError(f"unknown distillation setting(s) {unknown}; valid: {sorted(DISTILL_DEFAULTS)}")
    for k, lo, hi in (("episodes", 1, MAX_EPISODES), ("epochs", 1, 10_000), ("batch_size", 1, 1_000_000)):
        v = params.get(k, DISTILL_DEFAULTS[k])
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ValueError(f"distill_{k} must be an integer in [{lo}, {hi}], got {v!r}")
    q = params.get("quantile")
    if q is not None and (isinstance(q, bool) or not isinstance(q, (int, float)) or not 0.0 < float(q) < 1.0):
        raise ValueError(f"distill_quantile must be null (squared error) or a number in (0, 1), got {q!r}")
    for k in ("learning_rate", "final_lr_fraction"):
        v = params.get(k, DISTILL_DEFAULTS[k])
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 < float(v) <= 1.0:
            raise ValueError(f"distill_{k} must be a number in (0, 1], got {v!r}")


__all__ = ["DISTILL_DEFAULTS", "MAX_EPISODES", "MAX_ITERATIONS", "check_distill"]
