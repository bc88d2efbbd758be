"""Run a policy with the SB3-style ``predict`` interface on an SB3 ``VecEnv`` for whole episodes.

Used by the evaluation callback during training (the full evaluation report is
``gear_env.evaluation.evaluate_policies``)."""

from __future__ import annotations

from typing import Any

import numpy as np


def run_episodes(policy: Any, venv: Any, n_episodes: int, deterministic: bool = True) -> list[dict[str, Any]]:
    """Play ``n_episodes`` complete episodes, spread over the sub-environments of ``venv``.

    Returns one dict per episode: ``return`` (sum of rewards), ``length`` (steps) and
    ``settled_omega`` (mean of ``info["omega"]`` over the last quarter of the episode; NaN-free:
    None when the environment reports no omega). The venv is reset first."""
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
    n_envs = venv.num_envs
    targets = np.array([(n_episodes + i) // n_envs for i in range(n_envs)], dtype=int)
    counts = np.zeros(n_envs, dtype=int)
    rets = np.zeros(n_envs)
    lens = np.zeros(n_envs, dtype=int)
    omegas: list[list[float]] = [[] for _ in range(n_envs)]
    out: list[dict[str, Any]] = []
    obs = venv.reset()
    state = None
    starts = np.ones(n_envs, dtype=bool)
    while (counts < targets).any():
        actions, state = policy.predict(obs, state=state, episode_start=starts, deterministic=deterministic)
        obs, rewards, dones, infos = venv.step(actions)
        rets += rewards
        lens += 1
        for i in range(n_envs):
            if counts[i] >= targets[i]:
                continue
            w = infos[i].get("omega")
            if w is not None:
                omegas[i].append(float(w))
            if dones[i]:
                ws = omegas[i]
                q = ws[len(ws) - max(1, len(ws) // 4) :] if ws else []
                out.append(
                    {
                        "return": float(rets[i]),
                        "length": int(lens[i]),
                        "settled_omega": float(np.mean(q)) if q else None,
                        "chaotic_fraction": _frac(infos[i], "chaotic"),
                    }
                )
                counts[i] += 1
                rets[i] = 0.0
                lens[i] = 0
                omegas[i] = []
        starts = np.asarray(dones, dtype=bool)
    return out


def _frac(info: dict[str, Any], key: str) -> float | None:
    """An episode-level fraction from the final info, if the environment reports one."""
    ep = info.get("episode_stats") or info.get("episode_totals") or info.get("episode") or {}
    for k in (f"{key}_fraction", f"frac_{key}", key):
        if isinstance(ep, dict) and k in ep:
            try:
                return float(ep[k])
            except (TypeError, ValueError):
                return None
    return None


__all__ = ["run_episodes"]
