"""The one policy interface of :mod:`agents`: stable-baselines3's ``predict``.

Every policy here (scripted baselines, the oracle, random actions, trained PPO models) is a
:class:`BasePolicy`: it implements :meth:`BasePolicy.predict_batch` for a batch of observations,
and the base class supplies SB3's ``predict(observation, state, episode_start, deterministic)``
for one observation or a batch. Code that only *uses* policies (the evaluation, the rollout
helper, ``gear-env evaluate``) depends on the :class:`Policy` protocol, which SB3 models and
:class:`gear_env.envs.schedules.SpeedSchedule` satisfy too.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Policy(Protocol):
    """Anything with SB3's ``predict``: actions (n, act_dim) for observations (n, obs_dim), or
    (act_dim,) for one observation (obs_dim,), plus the recurrent-style ``state`` to pass back."""

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]: ...


class BasePolicy(ABC):
    """Base of the policies of :mod:`agents`: one observation or a batch in, SB3's return out.

    Subclasses implement :meth:`predict_batch` on a 2-D batch; ``name`` labels the policy in reports."""

    name: str = "policy"

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Actions for one observation (obs_dim,) -> (act_dim,) or a batch (n, obs_dim) -> (n, act_dim).

        ``state`` is what the previous call returned (per-environment memory, or None);
        ``episode_start`` (n,) marks environments whose episode has just begun."""
        obs = np.asarray(observation)
        single = obs.ndim == 1
        batch = obs[None, :] if single else obs
        if batch.ndim != 2:
            raise ValueError(f"observation must have shape (obs_dim,) or (n, obs_dim), got {obs.shape}")
        actions, state = self.predict_batch(batch, state, episode_start, deterministic)
        return (actions[0] if single else actions), state

    @abstractmethod
    def predict_batch(
        self, observations: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """Actions (n, act_dim) for observations (n, obs_dim), and the new state."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


__all__ = ["BasePolicy", "Policy"]
