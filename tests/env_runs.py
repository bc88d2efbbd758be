"""Shared by the scheme tests: one episode of a registered task through ``gym.make`` or the same seeds through the
vector env, for comparing the single and the vector env bit for bit."""

from __future__ import annotations

import numpy as np


def env_run(env_id: str, seed: int, actions, n: int | None = None, **kw):
    """Observations of ``len(actions) + 1`` steps (reset included) and the environment. ``n=None``: one env from
    ``gym.make(env_id, **kw)`` reset with ``seed`` -> ((steps + 1, obs_dim), the unwrapped env); else
    ``GearSpeedVectorEnv(n)`` on the task's settings with ``kw``, seeds ``seed + i`` -> ((n, steps + 1, obs_dim),
    the vector env). Every sub-environment takes the same set-point ``actions[k]`` at step k."""
    import gymnasium as gym

    import gear_env  # noqa: F401  (registers the ids)
    from gear_env.envs.env_config import task_config
    from gear_env.envs.vector_env import GearSpeedVectorEnv

    if n is None:
        env = gym.make(env_id, **kw)
        o, _ = env.reset(seed=seed)
        obs = [o]
        for a in actions:
            o, *_ = env.step(np.array([a], np.float32))
            obs.append(o)
        return np.array(obs), env.unwrapped
    vec = GearSpeedVectorEnv(n, task_config(env_id, kw))
    o, _ = vec.reset(seed=[seed + i for i in range(n)])
    obs = [o]
    for a in actions:
        o, *_ = vec.step(np.full((n, 1), a, np.float32))
        obs.append(o)
    return np.stack(obs, 1), vec
