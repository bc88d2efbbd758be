"""Environment construction for training and evaluation: configs to/from JSON, vector envs for SB3.

The environments are the GearSpeed tasks (``gear_env.envs.env.GearSpeedEnv`` with the task's frozen
``GearSpeedConfig``; :data:`GEAR_ENV_ID`, GearSpeed-v1, where no task is given); their native vector
form ``gear_env.envs.vector_env.GearSpeedVectorEnv`` steps every sub-environment in one numba call and is
presented to stable-baselines3 through the adapter in that module. Any other Gymnasium id (e.g.
``Pendulum-v1``) is accepted as a stand-in so the training plumbing can be tested without the gear
model; it is wrapped in SB3's ``DummyVecEnv``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

GEAR_ENV_ID = "GearSpeed-v1"
"""The task where none is given (``config=None`` of a policy or an oracle, ``TrainOptions.env_id``); the
CLI's default too (``gear_env.cli.common.DEFAULT_ENV``)."""
GEAR_ENV_IDS = (
    "GearSpeed-v0",
    "GearSpeed-v1",
    "GearSpeedDemand-v0",
    "GearSpeedDemandHard-v0",
    "GearSpeedDemandLimit-v0",
    "GearSpeed-v2",
    "GearSpeedDemand-v1",
    "GearSpeedDemandHard-v1",
    "GearSpeedDemandLimit-v1",
)
"""The registered gear tasks (``gear_env.envs.tasks.TASK_SETTINGS``): one config class, different settings."""


# --------------------------------------------------------------------------------------------------
# configuration
# --------------------------------------------------------------------------------------------------
def _config_class() -> Any:
    from gear_env.envs.env import GearSpeedConfig

    return GearSpeedConfig


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """A JSON-ready dict of an environment config (GearSpeedConfig, dataclass or mapping)."""
    if cfg is None:
        return {}
    if isinstance(cfg, Mapping):
        return json.loads(json.dumps(dict(cfg), default=_jsonable))
    for meth in ("to_dict", "as_dict"):
        f = getattr(cfg, meth, None)
        if callable(f):
            return json.loads(json.dumps(f(), default=_jsonable))
    if dataclasses.is_dataclass(cfg) and not isinstance(cfg, type):
        return json.loads(json.dumps(dataclasses.asdict(cfg), default=_jsonable))
    raise TypeError(f"cannot serialise environment config of type {type(cfg).__name__}")


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    for meth in ("to_dict", "as_dict"):
        f = getattr(obj, meth, None)
        if callable(f):
            return f()
    if isinstance(obj, (tuple, set)):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def make_config(env_id: str, cfg: Any = None) -> Any:
    """The config object the environment takes: a ``GearSpeedConfig`` for a gear task (from a dict of
    settings over the task's own, an existing config or None = the task's settings), a plain dict for
    stand-in environments."""
    if env_id not in GEAR_ENV_IDS:
        return dict(cfg or {})
    cls = _config_class()
    from gear_env.envs.env_config import task_config

    if cfg is None:
        return task_config(env_id)
    if isinstance(cfg, cls):
        return cfg
    if isinstance(cfg, Mapping):
        return task_config(env_id, dict(cfg))
    raise TypeError(f"environment config must be a GearSpeedConfig or a dict, got {type(cfg).__name__}")


def load_config_file(path: str | os.PathLike) -> dict[str, Any]:
    """Read an environment config JSON file (a flat dict of GearSpeedConfig fields).

    A run folder's config.json is accepted too (its ``env_config`` is used)."""
    from gear_env.io import read_json

    p = Path(path)
    if p.is_dir():
        p = p / "config.json"
    data = read_json(p, "--config", max_bytes=1024 * 1024)  # size, depth and integer length bounded
    if isinstance(data, dict) and "env_config" in data and "format" in data:
        data = data["env_config"]
    if not isinstance(data, dict):
        raise ValueError(f"--config: {str(path)!r} must hold a JSON object of config fields")
    return data


# --------------------------------------------------------------------------------------------------
# environments
# --------------------------------------------------------------------------------------------------
def make_env(env_id: str, cfg: Any = None, **kwargs: Any) -> Any:
    """One Gymnasium environment (``gym.make``) for ``env_id`` with config ``cfg``."""
    import gymnasium as gym

    import gear_env  # noqa: F401  (registers GearSpeed-v0)

    if env_id in GEAR_ENV_IDS:
        from gear_env.envs.env import GearSpeedEnv

        return GearSpeedEnv(make_config(env_id, cfg), **kwargs)
    return gym.make(env_id, **dict(cfg or {}), **kwargs)


def make_sb3_vec_env(env_id: str, cfg: Any, num_envs: int, seed: int | None) -> Any:
    """A stable-baselines3 ``VecEnv`` with ``num_envs`` sub-environments, seeded with ``seed``.

    For GearSpeed-v0 this is the native vector env behind its SB3 adapter (one numba call per
    step for all sub-environments); for stand-ins it is a ``DummyVecEnv``."""
    if not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    if env_id in GEAR_ENV_IDS:
        venv = _gear_sb3_vec_env(make_config(env_id, cfg), num_envs)
    else:
        from stable_baselines3.common.env_util import make_vec_env

        venv = make_vec_env(env_id, n_envs=num_envs, env_kwargs=dict(cfg or {}))
    if seed is not None:
        venv.seed(int(seed))
    return venv


def _gear_sb3_vec_env(config: Any, num_envs: int) -> Any:
    from gear_env.envs.sb3_adapter import SB3VecEnvAdapter

    return SB3VecEnvAdapter(num_envs=num_envs, config=config)


def control_parameters(cfg: Any) -> dict[str, Any]:
    """The action/observation conventions of a GearSpeed config that scripted policies need.

    Returns ``omega_min``, ``omega_max`` (observation[0] maps [omega_min, omega_max] linearly to
    [-1, 1]), ``max_domega`` (largest change of omega per step; action 1 in delta mode),
    ``action_mode`` ("delta", "target", "limit" or "limit_rate"), ``action_low``, ``action_high`` (the speeds
    the actions -1 and +1 mean in target and limit modes), ``reference_filter`` (target and limit modes: fraction of the
    set-point error closed per step before the rate limit), ``max_steps`` (episode length) and ``action_delay``
    (actuator dead time in steps: an action drives the step ``action_delay`` steps later),
    ``sensor_noise`` (std of the noise on the continuous sensor features), ``limit_rate`` (limit_rate mode: the
    change of the speed limit per unit action) and ``limit_column`` (the observation entry ``speed_limit``; -1
    if there is none)."""
    from gear_env.envs.env_terms import action_bounds

    c = make_config(GEAR_ENV_ID, cfg)
    lo, hi = action_bounds(c)
    names = c.TERMS.observation_names(c)
    return {
        "action_low": lo,
        "action_high": hi,
        "omega_min": float(c.omega_min),
        "omega_max": float(c.omega_max),
        "max_domega": float(c.max_domega),
        "action_mode": str(c.action_mode),
        "reference_filter": float(c.reference_filter),
        "max_steps": int(c.max_steps),
        "has_demand": c.demand is not None,
        "action_delay": int(getattr(c, "action_delay", 0)),
        "sensor_noise": float(getattr(c, "sensor_noise", 0.0)),
        "limit_rate": float(c.limit_rate),
        "limit_column": names.index("speed_limit") if "speed_limit" in names else -1,
    }


__all__ = [
    "GEAR_ENV_ID",
    "GEAR_ENV_IDS",
    "config_to_dict",
    "control_parameters",
    "load_config_file",
    "make_config",
    "make_env",
    "make_sb3_vec_env",
]
