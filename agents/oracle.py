"""The oracle: the best speed schedule computed from the simulator's own steady reward map.

The oracle knows what no sensor-driven policy knows: the steady per-step reward R(omega) of every
constant speed (``gear_env.evaluation.steady_reward_map``, which runs the environment itself at
each omega) and the reward definition (throughput, penalties, and the rate penalty
``w_rate (domega / max_domega)^2``). It plans with a quasi-static model of an episode:

    reward of a step from w0 to w1 = (R(w0) + R(w1)) / 2 - w_rate ((w1 - w0) / max_domega)^2,
    |w1 - w0| <= max_domega,

and solves it exactly by backward dynamic programming over the remaining steps on a fine omega
grid (linear interpolation between grid points; actions on a grid of ``n_actions`` rate levels).
With a demand profile, the environment's shortfall penalty ``w_demand max(0, demand(t) -
omega_mean) / omega_max`` is added to each step (the plan then depends on time for real).
The result is a time-varying policy ``a*(t, omega)``: it typically goes at the full rate to the
omega of best steady reward, crossing bad bands by the shortest route, and near the end of an
episode it stops moving where moving no longer pays. If :mod:`gear_env.analysis.stability`
provides a stability map for the model, the planned hold speed is checked against its stable
intervals (``OraclePolicy.stable_window``); the planning itself uses only the reward map.

The model ignores transients and hysteresis (coexisting attractors), so the oracle is the best
schedule *on its own reward map*, and a learned policy can in principle beat it in the real
environment; :func:`plan_return` evaluates any omega path on the same map, which is how the tests
check that no baseline beats the oracle there.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.envs.steady_map import undisturbed_config

from .baselines import ScriptedPolicy
from .envs import GEAR_ENV_ID, config_to_dict, make_config

_MAP_CACHE: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def _cache_dir() -> Path:
    env = os.environ.get("GEAR_ENV_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "gear-env"


def reward_map(
    config: Any = None, spacing: float | None = None, disk_cache: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """(omegas, steady reward per step) on a uniform grid over [omega_min, omega_max].

    ``spacing`` defaults to max_domega / 2 (0.025 with the defaults: 117 points). Computed with
    ``gear_env.evaluation.steady_reward_map`` (all omegas in one batched run) and cached in memory
    and on disk (``$GEAR_ENV_CACHE`` or ``~/.cache/gear-env``, keyed by the SHA-256 of the config)."""
    cfg = make_config(GEAR_ENV_ID, config)
    # the map is of the undisturbed plant: no randomisation, no demand (as steady_reward_map does)
    base = undisturbed_config(cfg)
    d = float(spacing) if spacing is not None else base.max_domega / 2.0
    if not np.isfinite(d) or d <= 0:
        raise ValueError(f"spacing must be a positive number, got {spacing!r}")
    n = int(round((base.omega_max - base.omega_min) / d)) + 1
    omegas = np.linspace(base.omega_min, base.omega_max, max(n, 2))
    fields = config_to_dict(base)
    fields.pop("action_range")  # always None here (undisturbed_config); kept out so that the keys of maps cached
    # before the setting existed still match
    fields.pop("scheme", None)  # params.newmark_beta and velocity_correction say it (a scheme only sets them)
    key_src = json.dumps({"v": 1, "config": fields, "n": len(omegas)}, sort_keys=True, default=str)
    key = hashlib.sha256(key_src.encode()).hexdigest()[:24]
    if key in _MAP_CACHE:
        return _MAP_CACHE[key]
    path = _cache_dir() / f"steady_reward_{key}.json"
    if disk_cache and path.is_file():
        try:
            from gear_env.io import read_json

            data = read_json(path, "steady reward cache")
            w, r = np.asarray(data["omegas"], float), np.asarray(data["reward"], float)
            if w.shape == omegas.shape and np.allclose(w, omegas) and np.all(np.isfinite(r)):
                _MAP_CACHE[key] = (w, r)
                return w, r
        except (OSError, ValueError, KeyError, TypeError):
            pass  # recompute a corrupt cache entry
    from gear_env.evaluation import steady_reward_map

    smap = steady_reward_map(base, omegas)
    w, r = np.asarray(smap.omegas, float), np.asarray(smap.reward, float)
    if not np.all(np.isfinite(r)):
        raise ValueError("steady reward map has non-finite values")
    _MAP_CACHE[key] = (w, r)
    if disk_cache:
        try:
            from gear_env.io import atomic_write_text

            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, json.dumps({"omegas": w.tolist(), "reward": r.tolist(), "config": key_src}))
        except OSError:
            pass  # a read-only home is not an error
    return w, r


def best_constant_omega(config: Any = None) -> float:
    """The omega of the largest steady reward (the 'best constant speed', found by grid search)."""
    w, r = reward_map(config)
    return float(w[int(np.argmax(r))])


class QuasiStaticModel:
    """The oracle's planning model: steady reward map + rate penalty (see module docstring)."""

    def __init__(self, omegas: np.ndarray, reward: np.ndarray, max_domega: float, w_rate: float):
        self.omegas = np.asarray(omegas, float)
        self.reward = np.asarray(reward, float)
        self.max_domega = float(max_domega)
        self.w_rate = float(w_rate)

    @classmethod
    def from_config(cls, config: Any = None) -> QuasiStaticModel:
        cfg = make_config(GEAR_ENV_ID, config)
        w, r = reward_map(cfg)
        return cls(w, r, cfg.max_domega, cfg.w_rate)

    def R(self, w: np.ndarray) -> np.ndarray:
        """Steady reward per step at omega ``w`` (linear interpolation)."""
        return np.interp(w, self.omegas, self.reward)

    def step_reward(self, w0: np.ndarray, w1: np.ndarray) -> np.ndarray:
        """Model reward of one step from w0 to w1 (|w1 - w0| <= max_domega)."""
        a = (np.asarray(w1) - np.asarray(w0)) / self.max_domega
        return 0.5 * (self.R(w0) + self.R(w1)) - self.w_rate * a * a


def plan_return(model: QuasiStaticModel, omegas: np.ndarray) -> float:
    """Model return of an omega path (omega before the first step, then after every step)."""
    w = np.asarray(omegas, float)
    if np.any(np.abs(np.diff(w)) > model.max_domega * (1 + 1e-9)):
        raise ValueError("the path changes omega faster than max_domega per step")
    return float(np.sum(model.step_reward(w[:-1], w[1:])))


class OraclePolicy(ScriptedPolicy):
    """Time-varying optimal policy of the quasi-static model, by backward dynamic programming.

    ``value[t, i]``: best model return from omega grid point i with t steps left. The policy
    evaluates ``n_actions`` rate levels in [-1, 1] with the interpolated value function (so it
    works from any omega, not only grid points). The step count comes from ``state`` (reset at
    ``episode_start``), so the oracle knows how many steps the episode has left. ``model``
    replaces the environment's reward map (for tests and what-if studies)."""

    name = "oracle"

    def __init__(
        self,
        config: Any = None,
        n_actions: int = 41,
        grid_spacing: float | None = None,
        model: QuasiStaticModel | None = None,
    ):
        super().__init__(config)
        cfg = make_config(GEAR_ENV_ID, config)
        self.model = model if model is not None else QuasiStaticModel.from_config(cfg)
        d = grid_spacing if grid_spacing is not None else cfg.max_domega / 10.0
        self.grid = np.linspace(self.omega_min, self.omega_max, int(round((self.omega_max - self.omega_min) / d)) + 1)
        self.rates = np.linspace(-1.0, 1.0, int(n_actions))
        # a demand profile adds the environment's time-dependent shortfall penalty to the model
        self.demand = cfg.demand_at(np.arange(self.max_steps)) if cfg.demand is not None else None
        self.w_demand = float(cfg.w_demand)
        self.value = self._solve(self.max_steps)
        self.best_omega = float(self.grid[int(np.argmax(self.model.R(self.grid)))])
        self.stable_window = _stable_window_containing(cfg, self.best_omega)

    def _next(self, w: np.ndarray) -> np.ndarray:
        """(len(w), n_actions) next omegas of every rate level (clipped like the environment)."""
        return np.clip(w[:, None] + self.rates[None, :] * self.max_domega, self.omega_min, self.omega_max)

    def _demand_penalty(self, w0: np.ndarray, w1: np.ndarray, step: np.ndarray | int) -> np.ndarray | float:
        """Shortfall penalty of a step from w0 to w1 taken at step index ``step`` (0 without demand)."""
        if self.demand is None:
            return 0.0
        d = self.demand[np.clip(np.asarray(step), 0, self.max_steps - 1)]
        d = d[:, None] if np.ndim(d) else d
        return -self.w_demand * np.maximum(0.0, d - 0.5 * (w0 + w1)) / self.omega_max

    def _solve(self, horizon: int) -> np.ndarray:
        g = self.grid
        nxt = self._next(g)
        r = self.model.step_reward(g[:, None], nxt)
        V = np.zeros((horizon + 1, len(g)))
        for left in range(1, horizon + 1):
            q = r + self._demand_penalty(g[:, None], nxt, horizon - left) + np.interp(nxt, g, V[left - 1])
            V[left] = q.max(axis=1)
        return V

    def plan(self, omega0: float, steps: int | None = None) -> np.ndarray:
        """The planned omega path from ``omega0`` (length steps + 1), following the policy."""
        n = self.max_steps if steps is None else int(steps)
        w = [float(omega0)]
        for t in range(n):
            w.append(float(self._best_next(np.array([w[-1]]), np.array([t]))[0]))
        return np.array(w)

    def _best_next(self, omega: np.ndarray, t: np.ndarray) -> np.ndarray:
        left = np.clip(self.max_steps - t, 1, self.max_steps)  # steps left including this one
        # candidates: the rate levels, plus every grid point within reach (where V is exact)
        h = self.grid[1] - self.grid[0]
        k = int(np.floor(self.max_domega / h))
        base = np.round((omega - self.omega_min) / h)
        snap = self.omega_min + (base[:, None] + np.arange(-k, k + 1)[None, :]) * h
        snap = np.where(np.abs(snap - omega[:, None]) <= self.max_domega, snap, omega[:, None])
        nxt = np.clip(np.concatenate([self._next(omega), snap], axis=1), self.omega_min, self.omega_max)
        q = self.model.step_reward(omega[:, None], nxt) + self._demand_penalty(
            omega[:, None], nxt, self.max_steps - left
        )
        for i in range(len(omega)):
            q[i] += np.interp(nxt[i], self.grid, self.value[left[i] - 1])
        # prefer the smallest move among (numerically) equal choices: no dithering at the optimum
        best = q.max(axis=1, keepdims=True)
        near = q >= best - 1e-9
        pick = np.argmin(np.where(near, np.abs(nxt - omega[:, None]), np.inf), axis=1)
        return nxt[np.arange(len(omega)), pick]

    def _targets(self, omega, obs, state):
        target = self._best_next(omega, state["t"])
        state["t"] = state["t"] + 1
        return target, state


def _stable_window_containing(cfg: Any, omega: float) -> tuple[float, float] | None:
    """The stable interval of the shipped/cached stability map that contains ``omega``, if any."""
    try:
        from gear_env.analysis.stability import default_stability_map
        from gear_env.sim.params import GearParams

        if cfg.params != GearParams():  # the shipped map is for the default parameters only
            return None
        smap = default_stability_map(cfg.model)
        for lo, hi in smap.stable_intervals():
            if lo <= omega <= hi:
                return (float(lo), float(hi))
    except Exception:  # no stability module or map: the oracle works without it
        return None
    return None


__all__ = ["OraclePolicy", "QuasiStaticModel", "best_constant_omega", "plan_return", "reward_map"]
