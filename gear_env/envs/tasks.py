"""Per-episode scenarios of the speed-scheduling tasks: a plant family, a load duty cycle, a demand.

``GearSpeedDemand-v0`` draws, at every reset and from the environment's own ``np_random``:

1. a gear pair from a :class:`PlantFamily` (factors on the nominal :class:`~gear_env.sim.params.GearParams`:
   the load torque and the transmission-error amplitude ``e_m1``);
2. a load duty cycle from a :class:`DutyCycle` (the load torque is multiplied by a level that changes
   at random times during the episode);
3. an operator demand (a piecewise-constant required omega, a new level uniform over
   [omega_min, omega_max] every few steps);
4. with ``wear`` (``GearSpeedDemandHard-v0``), a :class:`WearChange`: at one random step the pair's
   transmission error is multiplied by a factor.

The result is an :class:`Episode`: what the environment simulates and what an oracle may know, never
what the agent observes. Units: torques in N m, ``e_m1`` in m (factors are dimensionless), time in
environment steps, omega = Omega/omega_n.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ..sim.params import C_FS, GearParams


def pair(owner: str, name: str, value: Any, lo: float, hi: float) -> tuple[float, float]:
    """Validate a (low, high) pair of factors inside [lo, hi] with low <= high."""
    where = f"{owner}.{name}"
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ValueError(f"{where} must be a pair (low, high) of numbers in [{lo:g}, {hi:g}], got {value!r}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
            raise ValueError(f"{where} must be a pair (low, high) of numbers in [{lo:g}, {hi:g}], got {value!r}")
        if not lo <= float(v) <= hi:
            raise ValueError(f"{where} must lie in [{lo:g}, {hi:g}], got {value!r}")
        out.append(float(v))
    if out[1] < out[0]:
        raise ValueError(f"{where} must be (low, high) with low <= high, got {value!r}")
    return out[0], out[1]


def int_pair(owner: str, name: str, value: Any, lo: int, hi: int) -> tuple[int, int]:
    where = f"{owner}.{name}"
    ok = not isinstance(value, (str, bytes)) and isinstance(value, Sequence) and len(value) == 2
    ok = ok and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value)
    if not ok or not (lo <= value[0] <= value[1] <= hi):
        raise ValueError(
            f"{where} must be a pair (low, high) of integers with {lo} <= low <= high <= {hi}, got {value!r}"
        )
    return int(value[0]), int(value[1])


def multipliers(where: str, value: Any, what: str) -> tuple[float, ...]:
    """Validate a non-empty list of multipliers, each in (0, 10]; ``what`` names them in the message."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) == 0:
        raise ValueError(f"{where} must be a non-empty list of {what} in (0, 10], got {value!r}")
    out = []
    for v in value:
        ok = not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
        if not ok or not math.isfinite(v) or not 0.0 < float(v) <= 10.0:
            raise ValueError(f"{where} must be {what} in (0, 10], got {value!r}")
        out.append(float(v))
    return tuple(out)


def from_value(cls: Any, owner: str, value: Any) -> Any:
    """None, an instance, or a dict of the dataclass's fields (unknown keys refused)."""
    if value is None or isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        valid = [f.name for f in fields(cls)]
        unknown = sorted(set(value) - set(valid))
        if unknown:
            raise ValueError(f"unknown {owner} key(s) {unknown}; valid keys: {valid}")
        return cls(**dict(value))
    raise ValueError(
        f"{owner} must be None, a {cls.__name__} or a dict of its fields {[f.name for f in fields(cls)]}, got {value!r}"
    )


@dataclass(frozen=True)
class PlantFamily:
    """A family of gear pairs: uniform factors on the nominal parameters, one draw per episode.

    Attributes:
        load: (low, high) factor on both torques T_p and T_g (the operating load; the same factor keeps
            the torque ratio of the pair). Default (0.4, 1.5): light to 150 % load.
        e_m1: (low, high) factor on the transmission-error amplitude e_m1 (manufacturing and wear;
            default (0.5, 2.0): half to twice the nominal profile error).

    Mesh stiffness (+-20 %) and its variation kappa (0.1-0.35) barely move the quiet window (measured in
    docs/ENVIRONMENT.md), so they stay at their nominal values.
    """

    load: tuple[float, float] = (0.4, 1.5)
    e_m1: tuple[float, float] = (0.5, 2.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "load", pair("plant_family", "load", self.load, 1e-3, 100.0))
        object.__setattr__(self, "e_m1", pair("plant_family", "e_m1", self.e_m1, 0.0, 100.0))

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """Factors of one plant: {"load": ..., "e_m1": ...} (two uniform draws, in this order)."""
        return {"load": float(rng.uniform(*self.load)), "e_m1": float(rng.uniform(*self.e_m1))}

    @staticmethod
    def plant(base: GearParams, factors: Mapping[str, float], duty: float = 1.0) -> GearParams:
        """The gear pair with ``factors`` applied to ``base`` and the load times ``duty``."""
        f = float(factors["load"]) * float(duty)
        te = float(factors["e_m1"])
        if base.te_harmonics or not (math.isfinite(te) and te >= 0.0):  # with_te_scale checks and scales a series
            return base.replace(T_p=base.T_p * f, T_g=base.T_g * f).with_te_scale(te)
        return base.replace(T_p=base.T_p * f, T_g=base.T_g * f, e_m1=base.e_m1 * te)  # the same pair, one validation

    def check(self, base: GearParams, duty_levels: Sequence[float], min_static_force: float) -> None:
        """Refuse a family whose draws leave the simulator's valid range (checked at the corners).

        Every corner of the (load x duty, e_m1) box must give valid :class:`GearParams` and a static mesh
        force >= ``min_static_force`` [k_m0 b0]; the message names the setting and the offending value.
        """
        for lf in self.load:
            for d in duty_levels:
                for ef in self.e_m1:
                    try:
                        p = self.plant(base, {"load": lf, "e_m1": ef}, d)
                    except ValueError as exc:
                        raise ValueError(
                            f"plant_family {self.to_dict()} with duty level {d:g} leaves the simulator's valid range "
                            f"at load x{lf * d:g}, e_m1 x{ef:g}: {exc}"
                        ) from None
                    if not p.consts[C_FS] >= min_static_force:
                        raise ValueError(
                            f"plant_family.load x duty level {lf:g} x {d:g} unloads the mesh: static mesh force "
                            f"{p.consts[C_FS]:g} k_m0 b0 (need >= {min_static_force:g}); raise plant_family.load[0] "
                            "or the duty levels"
                        )

    def to_dict(self) -> dict[str, Any]:
        return {"load": list(self.load), "e_m1": list(self.e_m1)}


@dataclass(frozen=True)
class DutyCycle:
    """A load duty cycle: the load torque times a level that changes at random times.

    Attributes:
        levels: load multipliers (each in (0, 10]); each segment draws one uniformly from them.
        segment_steps: (low, high) length of a segment in environment steps (uniform integers).
    """

    levels: tuple[float, ...] = (1.0, 0.6)
    segment_steps: tuple[int, int] = (20, 50)

    def __post_init__(self) -> None:
        object.__setattr__(self, "levels", multipliers("duty_cycle.levels", self.levels, "load multipliers"))
        object.__setattr__(self, "segment_steps", int_pair("duty_cycle", "segment_steps", self.segment_steps, 1, 10**6))

    def draw(self, rng: np.random.Generator, steps: int) -> np.ndarray:
        """Load multiplier of each of ``steps`` environment steps (segment length first, then its level)."""
        out = np.empty(steps)
        t = 0
        while t < steps:
            n = int(rng.integers(self.segment_steps[0], self.segment_steps[1] + 1))
            out[t : t + n] = self.levels[int(rng.integers(len(self.levels)))]
            t += n
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"levels": list(self.levels), "segment_steps": list(self.segment_steps)}


@dataclass(frozen=True)
class WearChange:
    """A change of the pair within the episode: at one random step the transmission-error amplitude
    ``e_m1`` is multiplied by a factor (a tooth wearing in or pitting, a thermal change of the
    profile error), so that a pair identified at the start is not the pair at the end.

    Attributes:
        factors: multipliers of ``e_m1`` (each in (0, 10]); each episode draws one uniformly from them
            (a finite set, so the planners' steady maps can be cached).
        at_step: (low, high) step at which the change happens (a uniform integer; the changed pair
            drives that step and every later one).
    """

    factors: tuple[float, ...] = (0.5, 0.7, 1.4, 2.0)
    at_step: tuple[int, int] = (25, 75)

    def __post_init__(self) -> None:
        object.__setattr__(self, "factors", multipliers("wear.factors", self.factors, "e_m1 multipliers"))
        object.__setattr__(self, "at_step", int_pair("wear", "at_step", self.at_step, 0, 10**6))

    def draw(self, rng: np.random.Generator, steps: int) -> np.ndarray:
        """``e_m1`` multiplier of each of ``steps`` environment steps (the step first, then the factor)."""
        at = int(rng.integers(self.at_step[0], self.at_step[1] + 1))
        f = self.factors[int(rng.integers(len(self.factors)))]
        out = np.ones(steps)
        out[min(at, steps) :] = f
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"factors": list(self.factors), "at_step": list(self.at_step)}


def random_demand(rng: np.random.Generator, steps: int, lo: float, hi: float, segment: tuple[int, int]) -> np.ndarray:
    """Piecewise-constant operator demand: a level uniform in [lo, hi] held for ``segment`` steps (uniform integers)."""
    out = np.empty(steps + 1)
    t = 0
    while t < steps + 1:
        n = int(rng.integers(segment[0], segment[1] + 1))
        out[t : t + n] = rng.uniform(lo, hi)
        t += n
    return out


@dataclass(frozen=True)
class Episode:
    """One episode's scenario: what the environment simulates (never observed by the agent).

    Attributes:
        params: the drawn gear pair at duty level 1.
        factors: the family factors of the draw ({"load", "e_m1"}; 1.0 without a family).
        load_factor: (max_steps,) duty multiplier of the load during step t (t = 0 is the first step;
            the warm-up runs at ``load_factor[0]``).
        demand: (max_steps + 1,) required omega charged in step t (entry t + 1 is shown after step t), or
            None without a demand.
        initial_omega: omega of the warm-up (the start of the episode).
        wear_factor: (max_steps,) multiplier of ``e_m1`` during step t (a :class:`WearChange`), or None
            (the pair does not change).
    """

    params: GearParams
    factors: dict[str, float]
    load_factor: np.ndarray
    demand: np.ndarray | None
    initial_omega: float
    wear_factor: np.ndarray | None = None

    def conditions(self) -> np.ndarray:
        """(max_steps, 2) duty level and ``e_m1`` multiplier of every step."""
        wear = np.ones(len(self.load_factor)) if self.wear_factor is None else self.wear_factor
        return np.column_stack([np.asarray(self.load_factor, float), np.asarray(wear, float)])

    def params_at(self, step: int) -> GearParams:
        """The gear pair during step ``step`` (0-based, clipped to the episode)."""
        i = min(max(int(step), 0), len(self.load_factor) - 1)
        wear = 1.0 if self.wear_factor is None else float(self.wear_factor[i])
        return self.params_at_level(float(self.load_factor[i]), wear)

    def params_at_level(self, level: float, wear: float = 1.0) -> GearParams:
        """The gear pair under duty level ``level`` (load torques times ``level``) and ``e_m1`` times ``wear``."""
        if level == 1.0 and wear == 1.0:
            return self.params
        return PlantFamily.plant(self.params, {"load": 1.0, "e_m1": wear}, level)

    def to_dict(self) -> dict[str, Any]:
        return {
            "factors": dict(self.factors),
            "initial_omega": self.initial_omega,
            "load_factor": self.load_factor.tolist(),
            "demand": None if self.demand is None else self.demand.tolist(),
            "wear_factor": None if self.wear_factor is None else self.wear_factor.tolist(),
        }


__all__ = ["DutyCycle", "Episode", "PlantFamily", "WearChange", "random_demand"]


V1_SETTINGS: dict[str, Any] = {
    "action_mode": "target",
    "periods_per_step": 48,
    "max_domega": 0.1,
    "max_steps": 100,
    "reference_filter": 0.1,
}
"""``GearSpeed-v1``: the settings that differ from ``GearSpeed-v0`` (docs/ENVIRONMENT.md says why)."""
DEMAND_SETTINGS: dict[str, Any] = {
    **V1_SETTINGS,
    "memory_steps": 20.0,
    "plant_family": {"load": (0.4, 1.5), "e_m1": (0.25, 2.0)},
    "duty_cycle": {"levels": (1.0, 0.6), "segment_steps": (20, 50)},
    "demand": "random",
    "demand_range": (1.2, 1.8),
    "demand_segment_steps": (10, 30),
    "throughput": "delivered",
    "w_demand": 1.0,
}
"""``GearSpeedDemand-v0``: the settings that differ from ``GearSpeed-v0``."""
DEMAND_HARD_SETTINGS: dict[str, Any] = {
    **DEMAND_SETTINGS,
    "sensor_noise": 0.1,
    "action_delay": 1,
    "wear": {"factors": (0.5, 0.7, 1.4, 2.0), "at_step": (25, 75)},
}
"""``GearSpeedDemandHard-v0``: ``GearSpeedDemand-v0`` with noisy sensors, a one-step actuator dead time and a pair whose
transmission error changes once within the episode (docs/tasks/GearSpeedDemandHard-v0.md)."""
DEMAND_LIMIT_SETTINGS: dict[str, Any] = {
    **DEMAND_SETTINGS,
    "action_mode": "limit_rate",
    "action_range": (1.15, 1.8),
    "limit_rate": 0.03,
    "reference_filter": 1.0,
    "force_level": True,
}
"""``GearSpeedDemandLimit-v0``: ``GearSpeedDemand-v0`` made learnable by stock learners: the action moves a speed limit
(by at most 0.03 per step, within [1.15, 1.8]) under which the drive follows the demand, and the observation adds
the limit and the speed-normalised force level (docs/tasks/GearSpeedDemandLimit-v0.md says why)."""
FOX_GOODWIN_TASKS: dict[str, str] = {
    "GearSpeed-v2": "GearSpeed-v1",
    "GearSpeedDemand-v1": "GearSpeedDemand-v0",
    "GearSpeedDemandLimit-v1": "GearSpeedDemandLimit-v0",
    "GearSpeedDemandHard-v1": "GearSpeedDemandHard-v0",
}
"""The tasks integrated with Fox-Goodwin's Newmark beta (1/12) and the velocity correction (``scheme="fox-goodwin-vc"``,
``GearParams.velocity_correction``) and the task each one is otherwise equal to: the same settings, spaces, rewards
and cost per step, 10x less integration error over the period-1 orbits (docs/ENVIRONMENT.md, "Integration
accuracy"). A new id, not a changed one, because the dynamics differ (Gymnasium's versioning rule): every published
number of the older ids stays valid."""
TASK_SETTINGS: dict[str, dict[str, Any]] = {
    "GearSpeed-v0": {},
    "GearSpeed-v1": V1_SETTINGS,
    "GearSpeedDemand-v0": DEMAND_SETTINGS,
    "GearSpeedDemandLimit-v0": DEMAND_LIMIT_SETTINGS,
    "GearSpeedDemandHard-v0": DEMAND_HARD_SETTINGS,
}
"""Registered tasks and their settings (``gym.make(ID)`` uses these; keywords override them)."""
FOX_GOODWIN_SETTINGS: dict[str, Any] = {"scheme": "fox-goodwin-vc"}
"""What a Fox-Goodwin task adds to the settings of the task it integrates differently."""
TASK_SETTINGS.update({new: {**TASK_SETTINGS[old], **FOX_GOODWIN_SETTINGS} for new, old in FOX_GOODWIN_TASKS.items()})


def base_task(env_id: str) -> str:
    """The task whose policies, hyperparameters and scripts ``env_id`` shares: the older id of a Fox-Goodwin task
    (:data:`FOX_GOODWIN_TASKS`), else ``env_id`` itself."""
    return FOX_GOODWIN_TASKS.get(env_id, env_id)
