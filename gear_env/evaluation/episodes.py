"""Roll out speed policies on ``GearSpeed-v0``: one episode (:func:`run_episode`) or several
policies on the same episode seeds (:func:`evaluate_policies`, which returns a
:class:`gear_env.evaluation.report.EvaluationReport`). A policy is any object with SB3's
``predict(obs, state, episode_start, deterministic)`` (SB3 models, :mod:`gear_env.envs.schedules`).
Also importable from :mod:`gear_env.evaluation`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..envs.env import GearSpeedEnv
from ..envs.env_config import GearSpeedConfig
from ..envs.schedules import SpeedSchedule
from .report import EpisodeResult, EvaluationReport


def _bind(policy: Any, config: GearSpeedConfig) -> Any:
    """``policy`` for the task ``config``: a schedule or any policy with a ``bind(config)`` method is bound
    (rebuilt for the task if it was built without one, refused if built for another); others as they are."""
    if isinstance(policy, SpeedSchedule) or callable(getattr(policy, "bind", None)):
        return policy.bind(config)
    return policy


def run_episode(
    env: Any, policy: Any, seed: int | None, on_step: Callable[[dict[str, Any]], None] | None = None
) -> EpisodeResult:
    """Roll out one episode of ``policy`` (``predict(obs, state, episode_start, deterministic)``);
    ``on_step``, if given, is called with each step's ``info`` (e.g. to sum reward terms). A
    :class:`~gear_env.envs.schedules.SpeedSchedule` is bound to ``env``'s task first (one bound to a task whose
    actions mean something else is refused with a ``ValueError``); so is any policy with a ``bind(config)``
    method (the scripted policies of ``agents``)."""
    policy = _bind(policy, env.unwrapped.config)
    obs, info = env.reset(seed=seed)
    if hasattr(policy, "observe_episode"):  # a privileged baseline (the oracle): it is told the scenario
        policy.observe_episode(env.unwrapped.episode)
    state = None
    start = np.ones((1,), bool)
    omegas: list[float] = []
    vib: list[float] = []
    ret = cost = delivered = demanded = 0.0
    done = False
    while not done:
        action, state = policy.predict(obs[None, :], state=state, episode_start=start, deterministic=True)
        start = np.zeros((1,), bool)
        obs, r, term, trunc, info = env.step(np.asarray(action, np.float32).reshape(1))
        ret += r
        omegas.append(info["omega"])
        vib.append(info["force_peak"])
        cost += float(info.get("cost", 0.0))
        d = float(info.get("demand", 0.0) or 0.0)
        if d > 0:
            delivered += min(float(info["omega_mean"]), d)
            demanded += d
        if on_step is not None:
            on_step(info)
        done = term or trunc
    q = max(1, len(omegas) // 4)
    return EpisodeResult(
        ret=float(ret),
        throughput=info["episode_throughput"],
        chaotic_fraction=info["episode_steps_nonperiodic"] / max(info["episode_steps"], 1),
        contact_loss=info["episode_contact_loss"],
        impacts=int(info["episode_impacts"]),
        settled_omega=float(np.mean(omegas[-q:])),
        steps=int(info["episode_steps"]),
        diverged=bool(info["diverged"]),
        omega=omegas,
        vibration=vib,
        cost=cost,
        demand_delivered=delivered / demanded if demanded > 0 else float("nan"),
    )


def evaluate_policies(
    policies: Mapping[str, Any],
    config: GearSpeedConfig | Mapping[str, Any] | None = None,
    episodes: int = 5,
    seed: int = 0,
    reference: str | None = None,
) -> EvaluationReport:
    """Evaluate policies on the same episode seeds.

    Args:
        policies: name -> object with SB3's ``predict(obs, state=None, episode_start=None,
            deterministic=True) -> (actions, state)`` (SB3 models, :class:`SpeedSchedule`...).
        config: environment settings.
        episodes: episodes per policy (>= 1); episode k uses seed ``seed + k`` for every policy.
        seed: base seed.
        reference: name of the policy the report's "% of" column divides by (e.g. ``"oracle"``); by
            default ``"oracle"`` if a policy has that name, else none.

    Returns:
        :class:`EvaluationReport`.
    """
    if not policies:
        raise ValueError("policies must name at least one policy")
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    cfg = GearSpeedConfig.from_kwargs(config)
    env = GearSpeedEnv(cfg)
    out: dict[str, list[EpisodeResult]] = {}
    for name, pol in policies.items():
        if not hasattr(pol, "predict"):
            raise ValueError(f"policy {name!r} has no predict(obs, state, episode_start, deterministic) method")
        pol = _bind(pol, cfg)  # once, not per episode (an unbound oracle is rebuilt for the task)
        out[name] = [run_episode(env, pol, int(seed) + k) for k in range(episodes)]
    if reference is None and "oracle" in out:
        reference = "oracle"
    return EvaluationReport(out, cfg, int(seed), reference)


__all__ = ["evaluate_policies", "run_episode"]
