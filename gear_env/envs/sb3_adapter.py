"""stable-baselines3 ``VecEnv`` adapter of the batched GearSpeed engine.

Kept apart from :mod:`gear_env.envs.vector_env` so that Gymnasium users do not import SB3 and torch.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from .._extras import require
from .env_config import GearSpeedConfig
from .env_core import INFO_KEYS
from .vector_env import GearSpeedVectorEnv

VecEnv = require("stable_baselines3.common.vec_env", "gear_env.envs.sb3_adapter (the SB3 VecEnv adapter)").VecEnv


class SB3VecEnvAdapter(VecEnv):
    """stable-baselines3 ``VecEnv`` over the batched GearSpeed engine (one numba call per step).

    SB3 expects auto-reset in the same step: when a sub-env finishes, the returned observation
    is the first one of its next episode, ``infos[i]["terminal_observation"]`` holds the last one,
    and ``infos[i]["TimeLimit.truncated"]`` is True if the episode was cut by ``max_steps`` (not by
    divergence). Each info dict also carries SB3's ``episode`` entry (``r``, ``l``, ``t``) at the end
    of an episode, so ``Monitor``/``VecMonitor`` are not needed for episode statistics.

    Args:
        num_envs: number of sub-environments.
        config: settings (:class:`GearSpeedConfig`, dict) plus keyword overrides.
        seed: base seed (sub-env i uses seed + i at the first reset).
        render_mode: ``"rgb_array"`` or None.
    """

    def __init__(
        self,
        num_envs: int = 1,
        config: GearSpeedConfig | dict | None = None,
        seed: int | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        self.venv = GearSpeedVectorEnv(
            num_envs, config, autoreset_mode=AutoresetMode.SAME_STEP, render_mode=render_mode, **kwargs
        )
        self.render_mode = render_mode
        self.config = self.venv.config
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        if seed is not None:
            self.seed(seed)
        self._actions: np.ndarray | None = None
        self._ep_start = np.zeros(num_envs)
        self._time0 = 0.0

    # VecEnv API -----------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        """Reset every sub-env (with the seeds of a preceding ``seed()`` call and the options of a
        preceding ``set_options()`` call, e.g. ``{"omega": 1.2}``, if any)."""
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        opts = [dict(o or {}) for o in self._options]
        if opts and all(o == opts[0] for o in opts):
            obs, _ = self.venv.reset(seed=seeds, options=opts[0] or None)
        else:  # different options per sub-env: one masked reset each
            self.venv.reset(seed=seeds)
            for i, o in enumerate(opts):
                mask = np.arange(self.num_envs) == i
                obs, _ = self.venv.reset(options={**o, "reset_mask": mask})
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._time0 = time.time()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_async() must be called before step_wait()")
        a = self._actions
        if a.size == self.num_envs:  # SB3 passes (n, 1) or (n,); anything else is reported by check_action
            a = a.reshape(self.num_envs, 1)
        obs, rewards, term, trunc, info = self.venv.step(a)
        self._actions = None
        dones = term | trunc
        keys = INFO_KEYS.keys()
        infos: list[dict[str, Any]] = []
        final_info = info.get("final_info", {})
        for i in range(self.num_envs):
            src = final_info if dones[i] else info
            d = {k: INFO_KEYS[k](src[k][i]) for k in keys}
            if dones[i]:
                d["terminal_observation"] = info["final_obs"][i]
                d["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
                d["episode"] = {
                    "r": float(d["episode_return"]),
                    "l": int(d["episode_steps"]),
                    "t": round(time.time() - self._time0, 6),
                }
            infos.append(d)
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, (int, np.integer)):
            return [int(indices)]
        return [int(i) for i in indices]

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """Attribute of the (shared) vector env for each index, e.g. ``config``, ``render_mode``."""
        if attr_name in ("render_mode", "config"):
            value = getattr(self, attr_name)
        elif attr_name == "omega":
            return [float(self.venv._core.omega[i]) for i in self._indices(indices)]
        else:
            value = getattr(self.venv, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """Set an attribute on the vector env (shared by all sub-envs)."""
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        """Call a method of the vector env once per requested index (results repeated)."""
        fn = getattr(self.venv, method_name)
        return [fn(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        """True only for SB3's ``Monitor``: the adapter already reports ``info["episode"]`` like it."""
        from stable_baselines3.common.monitor import Monitor

        return [wrapper_class is Monitor for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        frame = self.venv.render() if self.render_mode == "rgb_array" else None
        return [frame] + [None] * (self.num_envs - 1)

    def render(self, mode: str | None = None) -> np.ndarray | None:
        """Frame of sub-env 0 (``render_mode="rgb_array"``)."""
        if self.render_mode != "rgb_array":
            return None
        return self.venv.render()


__all__ = ["SB3VecEnvAdapter"]
