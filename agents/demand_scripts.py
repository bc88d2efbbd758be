"""Baselines of ``GearSpeedDemand-v0`` that bound what a policy can get: the delayed oracle and two
sensor-only scripts.

The physics behind the scripts (docs/ENVIRONMENT.md, "Evaluation protocol"): below contact loss the mesh
force is linear in the transmission error, so the sensed RMS of the dynamic mesh force over the static one,
``rho = expm1(observation["force_rms"])``, factorises into the pair and the speed,

    log rho = log q + log h(omega),     q = (e_m1 factor) / (load factor x duty level),

with one shape ``h`` for the whole family (``LOG_H``: to +-0.03 across the family, measured by
:func:`force_shape`). One clean step at any speed therefore senses ``log q`` (:func:`log_q`), and with it the
speed the oracle would hold below a high demand (``EDGE_LOGQ`` -> ``EDGE_OMEGA``, the "sensor map").

* :class:`SensorServo` (``sensor-servo``, memoryless): each step, half-way from omega to ``min(demand,
  hold(log q sensed in that step))``, never below the floor; on trouble (contact loss, impacts, a
  periodicity defect) it backs off at the full rate.
* :class:`IdentifyFollow` (``identify-follow``): the same map, but ``log q`` is identified on clean steps and
  kept (updated only on steps that barely moved, since a ramp biases the sensed level; a troubled step
  raises it by ``penalty``), and it goes to its target at the full rate.
* :class:`DelayedOracle` (``delayed-oracle:K``): fixed-best for the first K steps, then the oracle that knows
  the pair (the information bound of a policy that needs K steps to identify the plant).

Calibration uses only data outside the validation and test seeds of :mod:`agents.protocol`: ``LOG_H`` is the
steady force shape of one pair of the family (no episode), the map's boundaries come from the oracle's holds on
the training episode seeds 0-119 (``python benchmarks/demand_protocol.py --calibrate`` prints them), and the
gains were compared on training seeds 0-39 (docs/RESULTS.md, "Demand: protocol tables").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gear_env.envs.force_level import H_OMEGAS, force_level, mean_level_update, step_mean_omega, troubled

from .baselines import OBS_BACK_IMPACTS, OBS_CONTACT, OBS_DEFECT, OBS_DRIVE_IMPACTS, ScriptedPolicy, _obs_demand

OBS_DOMEGA = 1  # change of omega in the step / max_domega
OBS_FORCE_RMS = 2  # log1p(RMS of the dynamic mesh force / F_s)

EDGE_LOGQ = np.array([-1.368, -1.298, -1.235, -1.133, -0.941, -0.842, -0.638, -0.498, -0.25, 0.0, 0.354, 0.839])
EDGE_OMEGA = np.round(np.arange(1.75, 1.1499, -0.05), 3)
"""The "sensor map": hold ``EDGE_OMEGA[i]`` when the demand is above it and the sensed log q (:func:`log_q`)
lies in [EDGE_LOGQ[i-1], EDGE_LOGQ[i]): the speeds the oracle held (its maps are on a 0.05 grid) on the clean,
steady steps where the demand was above its hold, classified by the log q sensed there, over the training
episodes 0-119 (boundaries between the 95th and 5th percentiles of neighbouring holds)."""
FLOOR = 1.15
"""Lowest speed the scripts hold (the minimum of h: below it lies the contact-loss band of the slow speeds)."""


def force_shape(config: Any = None, e_m1: float = 0.25, load: float = 1.5, steps: int = 4) -> np.ndarray:
    """log h at ``H_OMEGAS``: log(expm1(force_rms) / q) after holding each omega ``steps`` steps on the pair
    (e_m1 x``e_m1``, load x``load``) of the task's family, no duty cycle (what ``LOG_H`` stores)."""
    from gear_env.envs.env import GearSpeedEnv

    from .envs import GEAR_ENV_ID, make_config

    cfg = make_config(GEAR_ENV_ID, config).replace(
        plant_family={"load": (load, load), "e_m1": (e_m1, e_m1)},
        duty_cycle=None,
        action_mode="target",
        action_range=None,
    )
    env = GearSpeedEnv(cfg)
    out = []
    for w in H_OMEGAS:
        obs, _ = env.reset(seed=0, options={"omega": float(w)})
        a = np.array([2.0 * (w - cfg.omega_min) / (cfg.omega_max - cfg.omega_min) - 1.0], np.float32)
        for _ in range(steps):
            obs, *_ = env.step(a)
        out.append(np.log(np.expm1(obs[OBS_FORCE_RMS]) / (e_m1 / load)))
    return np.array(out)


def _demand(policy: ScriptedPolicy, obs: np.ndarray) -> np.ndarray:
    return _obs_demand(policy, obs)


def _trouble(obs: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Troubled steps: contact loss, an impact or a periodicity defect (``gear_env.envs.force_level.troubled``);
    ``margin`` raises the thresholds of the continuous sensors (for noisy ones; impacts are counted events, exact)."""
    impacts = obs[:, OBS_DRIVE_IMPACTS] + obs[:, OBS_BACK_IMPACTS]
    return troubled(obs[:, OBS_CONTACT], impacts, obs[:, OBS_DEFECT], margin)


def _need_demand(policy: ScriptedPolicy) -> None:
    if not policy.has_demand:
        raise ValueError(f"policy {policy.name!r} follows a demand: use it on GearSpeedDemand-v0 (demand='random')")


def log_q(omega: np.ndarray, obs: np.ndarray, max_domega: float) -> np.ndarray:
    """The pair's log q sensed in one step: log rho - log h at the step's mean speed (NaN outside the table;
    ``gear_env.envs.force_level.force_level``, the observation entry ``force_level`` of ``force_level=True``)."""
    w = step_mean_omega(omega, obs[:, OBS_DOMEGA], max_domega)
    return force_level(w, obs[:, OBS_FORCE_RMS])[0]


class SensorServo(ScriptedPolicy):
    """Memoryless: each step the hold speed of the log q sensed in that step (``edge``), capped by the demand;
    full-rate back-off on trouble (module docstring)."""

    name = "sensor-servo"

    def __init__(self, config: Any = None, shift: float = 0.0, floor: float = FLOOR, gain: float = 0.5):
        super().__init__(config)
        _need_demand(self)
        self.shift, self.floor, self.gain = float(shift), float(floor), float(gain)

    def edge(self, logq: np.ndarray) -> np.ndarray:
        """Hold speed for ``log q`` (``EDGE_OMEGA`` + ``shift``); the floor for an unknown (NaN) q."""
        e = EDGE_OMEGA[np.searchsorted(EDGE_LOGQ, np.nan_to_num(logq, nan=np.inf), side="right")] + self.shift
        return np.where(np.isfinite(logq), e, self.floor)

    def _targets(self, omega, obs, state):
        state["t"] = state["t"] + 1
        goal = np.minimum(self.edge(log_q(omega, obs, self.max_domega)), _demand(self, obs))
        target = omega + self.gain * (goal - omega)  # damped: a moving step senses a biased level
        target = np.where(_trouble(obs), np.minimum(target, omega - self.max_domega), target)
        return np.maximum(target, self.floor), state


class IdentifyFollow(SensorServo):
    """Identify the pair's log q on clean steps (kept through troubled ones; a troubled step raises it by
    ``penalty``), follow the demand up to the hold speed of that estimate."""

    name = "identify-follow"

    def __init__(
        self,
        config: Any = None,
        shift: float = 0.0,
        floor: float = FLOOR,
        penalty: float = 0.1,
        still: float = 0.3,
        gain: float = 1.0,
    ):
        super().__init__(config, shift, floor, gain)
        self.penalty, self.still = float(penalty), float(still)

    def initial_state(self, n: int) -> dict[str, np.ndarray]:
        return {"t": np.zeros(n, np.int64), "logq": np.full(n, np.nan)}

    def _targets(self, omega, obs, state):
        state["t"] = state["t"] + 1
        trouble = _trouble(obs)
        sensed = log_q(omega, obs, self.max_domega)
        # identify on clean steps, and once known only on steps that barely moved (a ramp biases the level)
        use = ~trouble & np.isfinite(sensed) & (np.isnan(state["logq"]) | (np.abs(obs[:, OBS_DOMEGA]) <= self.still))
        logq = np.where(use, sensed, state["logq"])
        logq = np.where(trouble & (omega >= self.floor), logq + self.penalty, logq)
        state["logq"] = logq
        goal = np.minimum(self.edge(logq), _demand(self, obs))
        target = omega + self.gain * (goal - omega)
        target = np.where(trouble, np.minimum(target, omega - self.max_domega), target)
        return np.maximum(target, self.floor), state


FILTERED_FOLLOW_SHIFT = (-0.5, 0.5)
"""The range of :class:`FilteredFollow`'s ``shift`` of the hold speed (omega units; ``filtered-follow:N:S``)."""


class FilteredFollow(SensorServo):
    """For noisy sensors (``GearSpeedDemandHard-v0``): the pair's q = rho / h(omega) sensed on every clean step
    is averaged (a running mean over the first ``window`` clean steps, then an exponential average with weight
    1/``window``: it tracks a pair that changes), a troubled step multiplies the estimate by exp(``penalty``),
    and the script follows the demand up to the hold speed of the estimate, at the full rate. Averaging q
    rather than log q keeps the mean unbiased under the additive sensor noise, which for a precise pair is
    larger than the reading itself."""

    name = "filtered-follow"

    def __init__(
        self, config: Any = None, window: int = 8, shift: float = 0.0, floor: float = FLOOR, penalty: float = 0.1
    ):
        super().__init__(config, shift, floor, 1.0)
        if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or not 1 <= window <= 1000:
            raise ValueError(f"filtered-follow:N needs a window N in [1, 1000] steps, got {window!r}")
        lo, hi = FILTERED_FOLLOW_SHIFT
        if not lo <= self.shift <= hi:  # also refuses NaN and inf
            raise ValueError(
                f"filtered-follow:N:S needs a shift S in [{lo}, {hi}] (omega units added to the hold speed, e.g. "
                f"filtered-follow:6:-0.02), got {shift!r}"
            )
        self.window, self.penalty = int(window), float(penalty)
        self.margin = 2.0 * self.sensor_noise
        suffix = (f":{self.window}" if window != 8 or shift else "") + (f":{shift:g}" if shift else "")
        self.name = "filtered-follow" + suffix  # its policy spec

    def initial_state(self, n: int) -> dict[str, np.ndarray]:
        return {"t": np.zeros(n, np.int64), "q": np.zeros(n), "count": np.zeros(n)}

    def _targets(self, omega, obs, state):
        state["t"] = state["t"] + 1
        trouble = _trouble(obs, self.margin)  # thresholds raised by twice the noise
        w = step_mean_omega(omega, obs[:, OBS_DOMEGA], self.max_domega)
        known = force_level(w, obs[:, OBS_FORCE_RMS])[1]
        use = ~trouble & known
        q, count = mean_level_update(state["q"], state["count"], w, obs[:, OBS_FORCE_RMS], use, self.window)
        q = np.where(trouble & (omega >= self.floor) & (count > 0), q * np.exp(self.penalty), q)
        state["q"], state["count"] = q, count
        logq = np.where(count > 0, np.log(np.maximum(q, 1e-6)), np.nan)
        goal = np.minimum(self.edge(logq), _demand(self, obs))
        target = np.where(trouble, np.minimum(goal, omega - self.max_domega), goal)
        return np.maximum(target, self.floor), state


class DelayedOracle(ScriptedPolicy):
    """Fixed-best for the first ``k`` steps, then the oracle that knows the pair (``delayed-oracle:K``)."""

    def __init__(self, config: Any = None, k: int = 10):
        super().__init__(config)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= self.max_steps:
            raise ValueError(f"delayed-oracle:K needs an integer K in [0, {self.max_steps}] (max_steps), got {k!r}")
        from .episode_oracle import EpisodeOracle, FixedBest

        self.k = int(k)
        self.name = f"delayed-oracle:{self.k}"
        self.fixed, self.oracle = FixedBest(config), EpisodeOracle(config)

    def observe_episode(self, episode: Any) -> None:
        """Plan both schedules for a new episode (the evaluation calls it at reset)."""
        self.fixed.observe_episode(episode)
        self.oracle.observe_episode(episode)

    def _targets(self, omega, obs, state):
        src = self.fixed if int(state["t"][0]) < self.k else self.oracle
        return src._targets(omega, obs, state)


__all__ = ["FILTERED_FOLLOW_SHIFT", "DelayedOracle", "FilteredFollow", "IdentifyFollow", "SensorServo", "force_shape"]
