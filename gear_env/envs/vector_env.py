"""Native vector form of ``GearSpeed-v0`` and a stable-baselines3 ``VecEnv`` adapter.

* :class:`GearSpeedVectorEnv` - a ``gymnasium.vector.VectorEnv`` that advances all sub-envs in one
  compiled call per step, SIMD across them (``batch_kernels.integrate_stats_lanes``;
  ``gym.make_vec("GearSpeed-v0", num_envs=N)``).
  Sub-env ``i`` has its own random generator, seeded with ``seed + i`` by ``reset(seed=seed)``, so
  it reproduces a single :class:`~gear_env.envs.env.GearSpeedEnv` reset with ``seed + i`` exactly.
* ``SB3VecEnvAdapter`` (in :mod:`gear_env.envs.sb3_adapter`, which imports this module) - presents the
  same batch engine to stable-baselines3 (which accepts only its own ``VecEnv``): auto-reset inside
  ``step_wait``, ``terminal_observation`` and ``TimeLimit.truncated`` in the infos.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .env import check_action, check_time_limit
from .env_config import GearSpeedConfig
from .env_core import GearSpeedCore, check_options, check_seed


def _seed_generators(num_envs: int, seed: int | Sequence[int | None] | None) -> list[np.random.Generator]:
    """Per-sub-env generators: ``seed + i`` for an int seed, entries of a list, or fresh entropy."""
    if seed is None:
        ss = np.random.SeedSequence()
        return [np.random.default_rng(s) for s in ss.spawn(num_envs)]
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
        s0 = int(seed)
        check_seed(s0)  # the single env's rule: an integer >= 0
        return [gym.utils.seeding.np_random(s0 + i)[0] for i in range(num_envs)]
    try:
        seeds = [] if isinstance(seed, (bool, np.bool_, str, bytes)) else list(seed)
    except TypeError:  # e.g. a float
        seeds = []
    if len(seeds) != num_envs:
        raise ValueError(f"seed must be None, an integer >= 0 or a list of {num_envs} seeds, got {seed!r}")
    return [gym.utils.seeding.np_random(check_seed(s, f"seed[{i}]"))[0] for i, s in enumerate(seeds)]


def _make_vec_kwargs() -> dict[str, Any]:
    """The keyword arguments the user gave the ``gym.make_vec`` call building this env ({} if none)."""
    import sys

    from gymnasium.envs import registration

    frame: Any = sys._getframe(1)
    for _ in range(10):
        if frame is None:
            return {}
        if frame.f_code is registration.make_vec.__code__:
            kw = frame.f_locals.get("kwargs")
            return kw if isinstance(kw, dict) else {}
        frame = frame.f_back
    return {}


def _make_vec_time_limit() -> int | None:
    """The ``max_episode_steps`` the user gave ``gym.make_vec`` (checked, :func:`check_time_limit`), or None.

    Gymnasium passes the spec's own limit when the user gave none, and a registered ``max_steps`` would
    otherwise win silently: ``gym.make_vec(ID, max_episode_steps=7)`` ran episodes of the task's length and
    0, NaN or 1.5 were accepted."""
    kw = _make_vec_kwargs()
    return check_time_limit(kw["max_episode_steps"]) if "max_episode_steps" in kw else None


class GearSpeedVectorEnv(VectorEnv):
    """``num_envs`` independent GearSpeed environments stepped in one numba call.

    Spaces, reward, info and episode rules are those of :class:`gear_env.envs.env.GearSpeedEnv` (see its
    docstring); observations are stacked (num_envs, n_obs), actions (num_envs, 1).

    Args:
        num_envs: number of sub-environments (>= 1).
        config: :class:`GearSpeedConfig` or dict; keyword settings override it.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default; the step after an episode ends
            resets that sub-env and returns its first observation with reward 0),
            ``SAME_STEP`` (reset at once; the final observation/info are in ``info["final_obs"]``
            / ``info["final_info"]``) or ``DISABLED`` (call ``reset(options={"reset_mask": m})``).
        render_mode: ``"rgb_array"`` (frame of sub-env 0) or None.

    ``info`` is a dict of arrays (num_envs,) with the same keys as the single env plus Gymnasium's
    ``_key`` masks (all True: every key is present for every sub-env on every step).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        num_envs: int = 1,
        config: GearSpeedConfig | dict | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        max_episode_steps: int | None = None,
        **kwargs: Any,
    ):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        given = _make_vec_time_limit()
        if given is not None and given != -1:  # gym.make_vec(ID, max_episode_steps=N): episodes of N steps
            if "max_steps" in _make_vec_kwargs() and _make_vec_kwargs()["max_steps"] != given:
                raise ValueError(f"max_episode_steps={given} and max_steps={_make_vec_kwargs()['max_steps']} differ")
            kwargs["max_steps"] = given
        elif max_episode_steps is not None and given is None:  # the spec's limit (or a direct call's)
            kwargs.setdefault("max_steps", check_time_limit(max_episode_steps))
        self.config = GearSpeedConfig.from_kwargs(config, **kwargs)
        try:
            mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
        except ValueError:
            mode = None
        if not isinstance(mode, AutoresetMode):
            raise ValueError(
                f"autoreset_mode must be one of {[m.value for m in AutoresetMode]}, got {autoreset_mode!r}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.render_mode = render_mode
        self.num_envs = int(num_envs)
        self._core = GearSpeedCore(self.config, self.num_envs)
        lo, hi = self._core.observation_bounds()
        self.single_observation_space = spaces.Box(lo, hi, dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_names: tuple[str, ...] = self._core.observation_names
        """Name of each entry of a sub-env's observation (:mod:`gear_env.envs.env_terms` ``OBSERVATIONS``)."""
        self.obs_names = list(self.observation_names)  # older name, kept
        self._rngs = _seed_generators(self.num_envs, None)
        self._autoreset = np.zeros(self.num_envs, bool)
        self._needs_reset = True
        self._renderer: Any = None
        self._history: list[tuple[float, float, float, float]] = []

    # ------------------------------------------------------------------ helpers
    def _info(self, rows: np.ndarray | None = None) -> dict[str, Any]:
        info: dict[str, Any] = {}
        n = self.num_envs
        mask = np.ones(n, bool) if rows is None else np.isin(np.arange(n), rows)
        mask.flags.writeable = False  # one read-only mask shared by every key
        for k, v in self._core.info.items():
            info[k] = v
            info["_" + k] = mask
        return info

    def _reset_rows(self, rows: np.ndarray, options: dict | None = None) -> None:
        self._core.reset_rows(rows, [self._rngs[r] for r in rows], options)

    def _track(self) -> None:
        """Remember omega, chaos, contact loss and peak force of sub-env 0 (for render)."""
        if self.render_mode is None:
            return
        i = self._core.info_row(0)
        self._history.append((i["omega"], i["chaos"], i["contact_loss"], i["force_peak"]))

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Reset all sub-envs (or those in ``options["reset_mask"]``); ``seed`` -> ``seed + i``.

        ``seed``: None, an integer >= 0 or a list of ``num_envs`` such seeds (None entries draw
        fresh entropy); ``options``: None or a dict with keys ``"omega"`` and ``"reset_mask"``.
        Anything else raises ``ValueError`` (as the single env does) before the env changes.
        """
        opts = check_options(options, ("omega", "reset_mask"))
        mask = opts.pop("reset_mask", None)
        if mask is None:
            rows = np.arange(self.num_envs)
        else:
            m = np.asarray(mask, bool)
            if m.shape != (self.num_envs,):
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({self.num_envs},), got {m.shape}"
                )
            rows = np.flatnonzero(m)
        if seed is not None:  # checked (like the single env's) before anything changes
            self._rngs = _seed_generators(self.num_envs, seed)
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(
                int(seed) if isinstance(seed, (int, np.integer)) else None
            )
        self._reset_rows(rows, opts or None)
        self._autoreset[rows] = False
        self._needs_reset = False
        if 0 in rows:
            self._history = []
            self._track()
        return self._core.obs.copy(), self._info()

    def step(self, actions: Any):
        """Step every sub-env; returns batched (obs, rewards, terminations, truncations, info)."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        a = check_action(actions, self.num_envs)
        n = self.num_envs
        rewards = np.zeros(n)
        terminated = np.zeros(n, bool)
        truncated = np.zeros(n, bool)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            resetting = np.flatnonzero(self._autoreset)
            stepping = np.flatnonzero(~self._autoreset)
        else:
            resetting = np.zeros(0, np.int64)
            stepping = np.arange(n)
            if self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():
                raise RuntimeError(
                    f"sub-env(s) {np.flatnonzero(self._autoreset).tolist()} finished; with autoreset DISABLED call "
                    "reset(options={'reset_mask': mask}) first"
                )
        if len(stepping):
            r, te, tr = self._core.step_rows(stepping, a[stepping])
            rewards[stepping] = r
            terminated[stepping] = te
            truncated[stepping] = tr
        if len(resetting):
            self._reset_rows(resetting)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            rows = np.flatnonzero(done)
            final_obs = self._core.obs.copy()
            final_info = self._info(rows)
            self._reset_rows(rows)
            info = self._info()
            # Gymnasium's SyncVectorEnv convention: these keys only on a step where an episode
            # ended; final_obs None and final_info values 0 (mask False) for the other sub-envs
            fo = np.full(n, None, dtype=object)
            for i in rows:
                fo[i] = final_obs[i]
            info["final_obs"] = fo
            info["_final_obs"] = done.copy()
            for k, v in final_info.items():
                if not k.startswith("_"):  # the masks are one shared read-only array
                    v[~done] = 0
            info["final_info"] = final_info
            info["_final_info"] = done.copy()
        else:
            info = self._info()
        self._autoreset = done
        self._track()
        return self._core.obs.copy(), rewards, terminated, truncated, info

    def render(self):
        """An (H, W, 3) uint8 frame of sub-env 0 (``render_mode="rgb_array"``)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        from .render import EnvRenderer

        if self._renderer is None:
            self._renderer = EnvRenderer(self.config, human=False)
        return self._renderer.draw(np.array(self._history, float).reshape(-1, 4), self._core.hist[0].copy(), True)

    def close_extras(self, **kwargs: Any) -> None:
        # getattr: gymnasium < 1.3 calls close() from __del__, also when __init__ raised early
        if getattr(self, "_renderer", None) is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        d = self.__dict__.copy()
        d["_renderer"] = None
        return d


def __getattr__(name: str) -> Any:
    """``SB3VecEnvAdapter`` lives in :mod:`gear_env.envs.sb3_adapter` only (it builds on this module;
    a re-export here made an import cycle)."""
    if name == "SB3VecEnvAdapter":
        raise ImportError(
            "SB3VecEnvAdapter is in gear_env.envs.sb3_adapter: from gear_env.envs.sb3_adapter import SB3VecEnvAdapter"
        )
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["GearSpeedVectorEnv"]
