"""Planners that know (part of) an episode's scenario: the oracle and the fixed-best schedule of
``GearSpeedDemand-v0``.

Both plan with the quasi-static model of :mod:`agents.oracle` (steady cost of each omega, computed by
the environment itself, plus the rate penalty), made time-varying by the episode: the demand d(t) and
the load duty cycle are known, and a step from w0 to w1 (mean wm) at step t is worth

    w_throughput * (min(wm, d(t)) if throughput == "delivered" else wm) / omega_max
  - w_demand * max(0, d(t) - wm) / omega_max
  + (C_t(w0) + C_t(w1)) / 2 - w_rate ((w1 - w0) / max_domega)^2,

where C_t is the steady cost map (reward minus throughput) of the plant under the load of step t.
Backward dynamic programming over the episode gives the policy.

* :class:`EpisodeOracle` (``oracle``): C_t of the episode's own plant (``knows="plant"``).
* ``knows="nominal"``: C_t of the nominal plant under the same duty cycle;
  ``knows="family"``: the family's robust map, the mean of C_t over a fixed sample of the family.
* :class:`FixedBest` (``fixed-best``): knows the family, the demand and the duty cycle, not the plant;
  per episode it follows the better (by mean model return over the family sample) of the nominal and
  the robust plan.

These policies are *privileged*: the evaluation hands them the episode's scenario through
``observe_episode(episode)`` (:func:`gear_env.evaluation.run_episode` does so for every policy that
has the method); their ``predict`` is the common one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .baselines import ScriptedPolicy
from .envs import GEAR_ENV_ID, make_config
from .oracle import reward_map

FAMILY_SAMPLE = 24
"""Plants drawn (with a fixed seed) from the family for its robust map and for FixedBest's choice."""
FAMILY_SAMPLE_SEED = 20261202


def _plain(cfg: Any) -> Any:
    """The config of one fixed plant (no family, duty cycle or demand: what the steady map measures)."""
    return cfg.replace(
        plant_family=None, duty_cycle=None, wear=None, demand=None, throughput="all", action_mode="delta"
    )


def cost_map(cfg: Any, params: Any) -> tuple[np.ndarray, np.ndarray]:
    """(omegas, steady cost per step) of the plant ``params``: the steady reward minus the throughput term."""
    w, r = reward_map(_plain(cfg).replace(params=params))
    return w, r - cfg.w_throughput * w / cfg.omega_max


def worn(factors: dict[str, float], wear: float) -> dict[str, float]:
    """Family factors with the transmission error times ``wear`` (a :class:`gear_env.envs.tasks.WearChange`)."""
    return {**factors, "e_m1": factors["e_m1"] * wear}


def family_sample(cfg: Any) -> list[dict[str, float]]:
    """The fixed sample of the family's factors behind the robust map (``FAMILY_SAMPLE`` draws)."""
    rng = np.random.default_rng(FAMILY_SAMPLE_SEED)
    return [cfg.plant_family.draw(rng) for _ in range(FAMILY_SAMPLE)]


class EpisodePlanner:
    """Backward DP over one episode on per-step cost maps (see the module docstring)."""

    def __init__(self, cfg: Any, omegas: np.ndarray, costs: np.ndarray, demand: np.ndarray | None, n_actions: int = 41):
        self.cfg = cfg
        self.lo, self.hi, self.dmax = cfg.omega_min, cfg.omega_max, cfg.max_domega
        self.T = costs.shape[0]
        self.grid = np.linspace(self.lo, self.hi, int(round((self.hi - self.lo) / (self.dmax / 10))) + 1)
        self.cost = np.array([np.interp(self.grid, omegas, c) for c in costs])  # (T, G)
        self.demand = demand
        self.rates = np.linspace(-1.0, 1.0, int(n_actions))
        self.value = self._solve()

    def step_reward(self, t: int, w0: np.ndarray, w1: np.ndarray) -> np.ndarray:
        c = self.cfg
        wm = 0.5 * (w0 + w1)
        if self.demand is not None:
            d = self.demand[min(t, len(self.demand) - 1)]
            thr = np.minimum(wm, d) if c.throughput == "delivered" else wm
            r = (c.w_throughput * thr - c.w_demand * np.maximum(0.0, d - wm)) / self.hi
        else:
            r = c.w_throughput * wm / self.hi
        ct = self.cost[min(t, self.T - 1)]
        a = (w1 - w0) / self.dmax
        return r + 0.5 * (np.interp(w0, self.grid, ct) + np.interp(w1, self.grid, ct)) - c.w_rate * a * a

    def reachable(self, t: int, w0: np.ndarray, nxt: np.ndarray) -> np.ndarray:
        """``nxt`` (omegas after step ``t`` from ``w0``) limited to what the action mode can reach. In limit mode
        the set-point is min(demand of the step, limit) with the limit in the action range [lo, hi], so it lies in
        [min(d, lo), min(d, hi)] and omega moves towards it (reference filter and rate limit applied). limit_rate
        mode is planned as limit mode (the limit's own rate, ``limit_rate`` per step, is not modelled: the plan
        may ask the limit to move faster than it can). Other modes: ``nxt`` as given (the rate limit only)."""
        c = self.cfg
        from gear_env.envs.env_terms import LIMIT_MODES, action_bounds

        if c.action_mode not in LIMIT_MODES or self.demand is None:
            return nxt

        lo, hi = action_bounds(c)
        d = self.demand[min(t, len(self.demand) - 1)]

        def reach(setpoint: float) -> np.ndarray:
            return np.clip(w0 + c.reference_filter * (setpoint - w0), w0 - self.dmax, w0 + self.dmax)

        return np.clip(nxt, reach(min(d, lo)), reach(min(d, hi)))

    def _solve(self) -> np.ndarray:
        g = self.grid
        V = np.zeros((self.T + 1, len(g)))
        for left in range(1, self.T + 1):
            t = self.T - left
            nxt = self.reachable(t, g[:, None], np.clip(g[:, None] + self.rates[None, :] * self.dmax, self.lo, self.hi))
            V[left] = (self.step_reward(t, g[:, None], nxt) + np.interp(nxt, g, V[left - 1])).max(axis=1)
        return V

    def best_next(self, omega: float, t: int) -> float:
        """The planned omega after step ``t`` from ``omega``."""
        left = min(max(self.T - t, 1), self.T)
        nxt = np.clip(omega + self.rates * self.dmax, self.lo, self.hi)
        nxt = self.reachable(t, np.full(len(self.rates), omega), nxt)
        q = self.step_reward(t, np.full_like(nxt, omega), nxt) + np.interp(nxt, self.grid, self.value[left - 1])
        best = q.max()
        near = q >= best - 1e-9
        return float(nxt[np.argmin(np.where(near, np.abs(nxt - omega), np.inf))])

    def path(self, omega0: float) -> np.ndarray:
        """The planned omega path from ``omega0`` (T + 1 values)."""
        w = [float(omega0)]
        for t in range(self.T):
            w.append(self.best_next(w[-1], t))
        return np.array(w)

    def path_return(self, path: np.ndarray) -> float:
        """Model return of an omega path on this planner's maps."""
        return float(sum(self.step_reward(t, path[t], path[t + 1]) for t in range(len(path) - 1)))


class EpisodeOracle(ScriptedPolicy):
    """DP plan on the maps of the episode's plant (``knows="plant"``), of the nominal plant, or of the
    family's robust map; the episode comes from ``observe_episode``."""

    def __init__(self, config: Any = None, knows: str = "plant", name: str | None = None):
        super().__init__(config)
        if knows not in ("plant", "nominal", "family"):
            raise ValueError(f"knows must be 'plant', 'nominal' or 'family', got {knows!r}")
        self.cfg = make_config(GEAR_ENV_ID, config)
        self.knows = knows
        self.name = name or {"plant": "oracle", "nominal": "nominal-map", "family": "robust-map"}[knows]
        self.planner: EpisodePlanner | None = None

    def maps_for(self, episode: Any, knows: str) -> tuple[np.ndarray, np.ndarray]:
        """(omegas, (T, m) cost map per step) for the episode under the given knowledge."""
        cfg = self.cfg
        conds = [tuple(c) for c in episode.conditions().tolist()]  # (duty level, e_m1 wear) of every step
        cache: dict[tuple[float, float], np.ndarray] = {}
        w = None
        for lv, wear in sorted(set(conds)):
            if knows == "plant":
                w, c = cost_map(cfg, episode.params_at_level(lv, wear))
            elif knows == "nominal":
                w, c = cost_map(cfg, cfg.plant_family.plant(cfg.params, {"load": 1.0, "e_m1": wear}, lv))
            else:
                cs = [cost_map(cfg, cfg.plant_family.plant(cfg.params, worn(f, wear), lv)) for f in family_sample(cfg)]
                w, c = cs[0][0], np.mean([x[1] for x in cs], axis=0)
            cache[(lv, wear)] = c
        return w, np.array([cache[c] for c in conds])

    def observe_episode(self, episode: Any) -> None:
        """Plan for a new episode (called at reset by the evaluation)."""
        w, costs = self.maps_for(episode, self.knows)
        self.planner = EpisodePlanner(self.cfg, w, costs, episode.demand)

    def _targets(self, omega, obs, state):
        if self.planner is None:
            raise ValueError(
                f"policy {self.name!r} needs the episode's scenario: call observe_episode(env.unwrapped.episode) "
                "after each reset (gear_env.evaluation.evaluate_policies does)"
            )
        if len(omega) != 1:
            raise ValueError(f"policy {self.name!r} plans one episode at a time (got a batch of {len(omega)})")
        t = int(state["t"][0])
        if self.action_delay:  # plan the step the action will drive, from the omega the sent actions leave
            target = np.array([self.planner.best_next(float(state["omega_ahead"][0]), t + self.action_delay)])
        else:
            target = np.array([self.planner.best_next(float(omega[0]), t)])
        state["t"] = state["t"] + 1
        return target, state


class FixedBest(EpisodeOracle):
    """The best schedule that knows the family, the demand and the duty cycle but not the plant: per
    episode, the better of the nominal-map plan and the robust-map plan, judged by their mean model
    return over the family sample (from the episode's initial omega)."""

    def __init__(self, config: Any = None, name: str = "fixed-best"):
        super().__init__(config, knows="family", name=name)
        self.choice: str | None = None

    def observe_episode(self, episode: Any, omega0: float | None = None) -> None:
        cfg = self.cfg
        w, nominal = self.maps_for(episode, "nominal")
        _, robust = self.maps_for(episode, "family")
        plans = {
            "nominal": EpisodePlanner(cfg, w, nominal, episode.demand),
            "family": EpisodePlanner(cfg, w, robust, episode.demand),
        }
        start = float(episode.initial_omega if omega0 is None else omega0)
        paths = {k: p.path(start) for k, p in plans.items()}
        score = {k: 0.0 for k in plans}
        conds = [tuple(c) for c in episode.conditions().tolist()]
        for f in family_sample(cfg):
            by_cond = {
                (lv, wear): cost_map(cfg, cfg.plant_family.plant(cfg.params, worn(f, wear), lv))[1]
                for lv, wear in set(conds)
            }
            judge = EpisodePlanner.__new__(EpisodePlanner)  # maps only, no DP needed
            judge.cfg, judge.lo, judge.hi, judge.dmax = cfg, cfg.omega_min, cfg.omega_max, cfg.max_domega
            judge.grid, judge.T, judge.demand = w, len(conds), episode.demand
            judge.cost = np.array([by_cond[c] for c in conds])
            for k in plans:
                score[k] += judge.path_return(paths[k])
        self.choice = max(score, key=score.get)
        self.planner = plans[self.choice]


__all__ = ["EpisodeOracle", "EpisodePlanner", "FixedBest", "cost_map", "family_sample", "worn"]
