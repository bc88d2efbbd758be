"""Agents for the GearSpeed tasks: PPO training (:mod:`agents.ppo`), scripted baselines
(:mod:`agents.baselines`), the oracle (:mod:`agents.oracle`), trained-policy loading
(:mod:`agents.trained`), run folders (:mod:`agents.runs`), the comparison report
(:mod:`agents.report`) and the policy registry (:func:`agents.registry.resolve_policy`) through
which ``gear-env evaluate --policy SPEC`` loads them all. Scoring your own model against the oracle
is one call: :func:`agents.compare` (:mod:`agents.scoring`).

Every policy has the stable-baselines3 interface
``predict(observation, state=None, episode_start=None, deterministic=True) -> (actions, state)``,
written once in :class:`agents.policy.BasePolicy` (users of policies depend on the
:class:`agents.policy.Policy` protocol). The command line (argument parsing) is in
:mod:`gear_env.cli.train`; this package holds no argparse code.
"""

from __future__ import annotations

from typing import Any

__all__ = ["compare", "resolve_policy"]


def compare(model: Any, env_id: str = "GearSpeed-v1", episodes: int = 20, seed: int = 9001, **kwargs: Any) -> Any:
    """``model`` against the oracle and fixed-best on the same episodes; see :func:`agents.scoring.compare`."""
    from .scoring import compare as _compare

    return _compare(model, env_id=env_id, episodes=episodes, seed=seed, **kwargs)


def resolve_policy(spec: str, config: Any = None) -> Any:
    """The policy named by ``spec`` for the environment ``config``; see :func:`agents.registry.resolve_policy`."""
    from .registry import resolve_policy as _resolve

    return _resolve(spec, config)
