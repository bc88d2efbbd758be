"""Score your own policy against the oracle and the baselines in one call: :func:`compare`.

    from agents import compare
    report = compare(model, env_id="GearSpeed-v1", episodes=20, seed=9001)
    print(report.to_markdown())          # return, % of the oracle, cost, throughput, chaos, ...

The model is any object with stable-baselines3's ``predict`` (an SB3 model, a loaded policy, a
:class:`gear_env.envs.schedules.SpeedSchedule`). The episodes are those of ``gear-env evaluate --env ENV_ID
--episodes N --seed S``: episode k uses seed ``seed + k`` for every policy, so the numbers compare with the
tables of docs/RESULTS.md (which use seeds 9001-9020, never used in training).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


class _Normalized:
    """A model whose observations pass through a VecNormalize's observation statistics first."""

    def __init__(self, model: Any, vecnormalize: Any):
        self.model, self.vecnormalize = model, vecnormalize

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        obs = self.vecnormalize.normalize_obs(np.asarray(observation, np.float32))
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)


def compare(
    model: Any,
    env_id: str = "GearSpeed-v1",
    episodes: int = 20,
    seed: int = 9001,
    baselines: Sequence[str] = ("oracle", "fixed-best"),
    name: str = "model",
    settings: Mapping[str, Any] | None = None,
    vecnormalize: Any = None,
) -> Any:
    """Evaluate ``model`` beside the named baselines on the same episodes of task ``env_id``.

    Args:
        model: object with ``predict(obs, state=None, episode_start=None, deterministic=True)``, e.g. a
            stable-baselines3 model trained on ``gym.make(env_id)``.
        env_id: a registered task (``GearSpeed-v0``, ``GearSpeed-v1``, ``GearSpeedDemand-v0``).
        episodes: episodes per policy (>= 1); episode k uses seed ``seed + k``.
        seed: seed of the first episode (default 9001: the seeds of docs/RESULTS.md).
        baselines: policy specs of :func:`agents.registry.resolve_policy` (``oracle``, ``fixed-best``,
            ``pretrained``, ``hill-climber``, ``constant:W``, ...); ``oracle`` becomes the reference of
            the report's "% of oracle" column.
        name: the model's row label.
        settings: task settings overriding ``env_id``'s own (as ``gym.make(env_id, **settings)``).
        vecnormalize: a stable-baselines3 ``VecNormalize`` the model was trained behind (its observation
            statistics are applied before ``predict``); None if it was trained on raw observations.

    Returns:
        :class:`gear_env.evaluation.report.EvaluationReport` (``to_markdown()``, ``to_json_dict()``, ``plot()``,
        ``percent_of_reference(name)``).

    Raises:
        ValueError: unknown task or baseline, a name used twice, or a model whose observation or action
            space does not fit the task (before any episode runs).
    """
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    from .registry import resolve_policy

    if not hasattr(model, "predict"):
        raise ValueError("model must have predict(obs, state, episode_start, deterministic), e.g. an SB3 model")
    cfg = task_config(env_id, settings)
    env = GearSpeedEnv(cfg)
    for space in ("observation_space", "action_space"):
        theirs = getattr(model, space, None)
        ours = getattr(env, space)
        if theirs is not None and getattr(theirs, "shape", None) != ours.shape:
            raise ValueError(
                f"the model's {space} has shape {getattr(theirs, 'shape', None)}, {env_id}'s has {ours.shape}: "
                f"it was trained on another task or settings"
            )
    if name in baselines:
        raise ValueError(f"name {name!r} is also a baseline: choose another row label")
    policies: dict[str, Any] = {name: _Normalized(model, vecnormalize) if vecnormalize is not None else model}
    for spec in baselines:
        policies[spec] = resolve_policy(spec, cfg, env_id=env_id)
    return evaluate_policies(
        policies, cfg, episodes=episodes, seed=seed, reference="oracle" if "oracle" in policies else None
    )


__all__ = ["compare"]
