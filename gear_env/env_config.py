"""Configuration of the ``GearSpeed-v0`` environment: a frozen, validated dataclass.

Every field has a default; ``GearSpeedConfig.from_kwargs`` (used by ``gym.make``) rejects unknown
keys with the list of valid ones, and ``__post_init__`` rejects out-of-range values with a message
naming the field and its allowed range.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .params import C_FS, MODELS, GearParams

ACTION_MODES = ("delta", "target")
OBSERVATION_SETS = ("sensors", "full")
DEMAND_PRESETS = ("steps", "ramp")
MIN_STATIC_MESH_FORCE = 1e-6
"""Smallest static mesh force F_s [k_m0 b0] the env accepts (the default pair has 0.0275)."""


def _real(name: str, value: Any, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> float:
    """Validate a real number in [lo, hi] (or open ends) and return it as float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"GearSpeedConfig.{name} must be a real number, got {value!r}")
    v = float(value)
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"GearSpeedConfig.{name} must be in {rng}, got {value!r}")
    return v


def _int(name: str, value: Any, lo: int, hi: int) -> int:
    """Validate an integer in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"GearSpeedConfig.{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def _choice(name: str, value: Any, choices: Sequence[str]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"GearSpeedConfig.{name} must be one of {list(choices)}, got {value!r}")
    return value


@dataclass(frozen=True)
class GearSpeedConfig:
    """Settings of :class:`gear_env.env.GearSpeedEnv` (all keyword arguments of ``gym.make``).

    Physics:
        params: :class:`GearParams` or a dict of its fields (SI units); default Table 1.
        model: backlash model, ``"dynamic"`` (default) or ``"constant"``.
        steps_per_period: Newmark steps per mesh period, in [16, 1024]; default 64 (the env's fast
            preset, same regime boundaries as the simulator's 128; see docs/ENVIRONMENT.md).
        randomize_params: if True, every episode multiplies kappa, the three damping ratios and
            the two torques by independent factors uniform in [1 - s, 1 + s], s = ``randomize_scale``.
        randomize_scale: relative jitter s, in [0, 0.5].

    Control:
        periods_per_step: mesh periods per environment step, in [1, 1000] (default 24).
        omega_min, omega_max: admissible meshing frequency Omega/omega_n, 0 < min < max <= 20.
        max_domega: largest change of omega in one step, in (0, omega_max - omega_min].
        action_mode: ``"delta"`` (action = change of omega in units of max_domega) or ``"target"``
            (action maps linearly onto [omega_min, omega_max]; the change is rate-limited).

    Episode:
        max_steps: steps per episode (then truncated), in [1, 1e6].
        initial_omega: None (uniform over [omega_min, omega_max]), a number (fixed), or a pair
            (lo, hi) for a uniform draw; all inside [omega_min, omega_max].
        warmup_periods: mesh periods simulated at the initial omega before the first observation,
            in [0, 100000] (extended to ``max(periods_per_step, poincare_window)`` if shorter).
        demand: None, a preset (``"steps"``, ``"ramp"``), or a sequence of (t, omega) points with t
            in environment steps (non-decreasing, >= 0), linearly interpolated, held at the ends.

    Observation:
        observation: ``"sensors"`` (default, 10 features + demand if set) or ``"full"`` (adds the
            10 hidden states).
        poincare_window: Poincare samples (one per mesh period, kept across steps) used by the
            periodicity defect, in [9, 1000] (default 16: the last 16 of the step's 24; the earlier
            ones are treated as transient after a speed change).
        defect_scale: periodicity defect [b0] that counts as fully non-periodic (c = 1); default
            0.02 b0.

    Reward weights (see the class docstring of the env): w_throughput, w_chaos, w_contact,
        w_impact, w_vibration, w_rate, w_demand (all >= 0), back_impact_weight (a back-side impact
        costs this many drive-side re-impacts) and divergence_penalty (reward of a diverging step).
    """

    params: Any = None
    model: str = "dynamic"
    steps_per_period: int = 64
    randomize_params: bool = False
    randomize_scale: float = 0.1
    periods_per_step: int = 24
    omega_min: float = 0.1
    omega_max: float = 3.0
    max_domega: float = 0.05
    action_mode: str = "delta"
    max_steps: int = 200
    initial_omega: Any = None
    warmup_periods: int = 48
    demand: Any = None
    observation: str = "sensors"
    poincare_window: int = 16
    defect_scale: float = 0.02
    w_throughput: float = 1.0
    w_chaos: float = 1.0
    w_contact: float = 0.5
    w_impact: float = 0.2
    w_vibration: float = 0.5
    w_rate: float = 0.02
    w_demand: float = 2.0
    back_impact_weight: float = 5.0
    divergence_penalty: float = 10.0

    def __post_init__(self) -> None:
        s = object.__setattr__
        p = self.params
        if p is None:
            p = GearParams()
        elif isinstance(p, Mapping):
            p = GearParams.from_dict(dict(p))
        elif not isinstance(p, GearParams):
            raise ValueError(f"GearSpeedConfig.params must be a GearParams, a dict of its fields or None, got {p!r}")
        s(self, "params", p)
        if not p.consts[C_FS] >= MIN_STATIC_MESH_FORCE:  # features and rewards are forces / F_s: F_s = 0 gives inf
            raise ValueError(
                "GearSpeedConfig.params must load the mesh (T_p, T_g > 0): the env scales forces by the static mesh "
                f"force F_s, got F_s = {p.consts[C_FS]:g} k_m0 b0 (need >= {MIN_STATIC_MESH_FORCE:g})"
            )
        _choice("model", self.model, MODELS)
        s(self, "steps_per_period", _int("steps_per_period", self.steps_per_period, 16, 1024))
        if not isinstance(self.randomize_params, (bool, np.bool_)):
            raise ValueError(f"GearSpeedConfig.randomize_params must be True or False, got {self.randomize_params!r}")
        s(self, "randomize_params", bool(self.randomize_params))
        s(self, "randomize_scale", _real("randomize_scale", self.randomize_scale, 0.0, 0.5))
        s(self, "periods_per_step", _int("periods_per_step", self.periods_per_step, 1, 1000))
        s(self, "omega_min", _real("omega_min", self.omega_min, 0.0, 20.0, lo_open=True))
        s(self, "omega_max", _real("omega_max", self.omega_max, 0.0, 20.0, lo_open=True))
        if self.omega_max <= self.omega_min:
            raise ValueError(
                f"GearSpeedConfig.omega_max must be > omega_min ({self.omega_min:g}), got {self.omega_max!r}"
            )
        span = self.omega_max - self.omega_min
        s(self, "max_domega", _real("max_domega", self.max_domega, 0.0, span, lo_open=True))
        _choice("action_mode", self.action_mode, ACTION_MODES)
        s(self, "max_steps", _int("max_steps", self.max_steps, 1, 1_000_000))
        s(self, "initial_omega", self._check_initial_omega(self.initial_omega))
        s(self, "warmup_periods", _int("warmup_periods", self.warmup_periods, 0, 100_000))
        s(self, "demand", self._check_demand(self.demand))
        _choice("observation", self.observation, OBSERVATION_SETS)
        s(self, "poincare_window", _int("poincare_window", self.poincare_window, 9, 1000))
        s(self, "defect_scale", _real("defect_scale", self.defect_scale, 0.0, 100.0, lo_open=True))
        for name in ("w_throughput", "w_chaos", "w_contact", "w_impact", "w_vibration", "w_rate", "w_demand"):
            s(self, name, _real(name, getattr(self, name), 0.0, 1e6))
        s(self, "back_impact_weight", _real("back_impact_weight", self.back_impact_weight, 0.0, 1e6))
        s(self, "divergence_penalty", _real("divergence_penalty", self.divergence_penalty, 0.0, 1e6))

    # ------------------------------------------------------------------ validation helpers
    def _check_initial_omega(self, v: Any) -> Any:
        lo, hi = self.omega_min, self.omega_max
        if v is None:
            return None
        if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
            return _real("initial_omega", v, lo, hi)
        if isinstance(v, Sequence) and not isinstance(v, str) and len(v) == 2:
            a = _real("initial_omega[0]", v[0], lo, hi)
            b = _real("initial_omega[1]", v[1], lo, hi)
            if b < a:
                raise ValueError(f"GearSpeedConfig.initial_omega must be (lo, hi) with lo <= hi, got {v!r}")
            return (a, b)
        raise ValueError(
            f"GearSpeedConfig.initial_omega must be None, a number or a pair (lo, hi) in [{lo:g}, {hi:g}], got {v!r}"
        )

    def _check_demand(self, v: Any) -> Any:
        if v is None:
            return None
        if isinstance(v, str):
            return _choice("demand", v, DEMAND_PRESETS)
        if not isinstance(v, Sequence) or len(v) == 0:
            raise ValueError(
                f"GearSpeedConfig.demand must be None, one of {list(DEMAND_PRESETS)} or a non-empty list of "
                f"(t_steps, omega) points, got {v!r}"
            )
        pts: list[tuple[float, float]] = []
        for i, pt in enumerate(v):
            if not isinstance(pt, Sequence) or isinstance(pt, str) or len(pt) != 2:
                raise ValueError(f"GearSpeedConfig.demand[{i}] must be a (t_steps, omega) pair, got {pt!r}")
            t = _real(f"demand[{i}][0] (time in steps)", pt[0], 0.0, 1e9)
            w = _real(f"demand[{i}][1] (omega)", pt[1], self.omega_min, self.omega_max)
            if pts and t < pts[-1][0]:
                raise ValueError(
                    f"GearSpeedConfig.demand times must be non-decreasing; point {i} has t={t:g} < {pts[-1][0]:g}"
                )
            pts.append((t, w))
        return tuple(pts)

    # ------------------------------------------------------------------ derived quantities
    @property
    def warmup_total(self) -> int:
        """Mesh periods actually simulated before the first observation."""
        return max(self.warmup_periods, self.periods_per_step, self.poincare_window)

    def demand_points(self) -> np.ndarray | None:
        """The demand profile as an (m, 2) array of (t in steps, omega), or None."""
        d = self.demand
        if d is None:
            return None
        T = float(self.max_steps)
        lo, hi = self.omega_min, self.omega_max
        if d == "steps":  # piecewise constant thirds: 60 %, 90 %, 75 % of the way from omega_min to 1.3 (capped)
            top = min(1.3, hi)
            w1, w2, w3 = (lo + f * (top - lo) for f in (0.6, 0.9, 0.75))
            return np.array([(0, w1), (T / 3, w1), (T / 3, w2), (2 * T / 3, w2), (2 * T / 3, w3), (T, w3)], float)
        if d == "ramp":  # linear from omega_min + 10 % of the span to 1.4 (capped)
            return np.array([(0.0, lo + 0.1 * (hi - lo)), (T, min(1.4, hi))], float)
        return np.asarray(d, float)

    def demand_at(self, step: np.ndarray | float) -> np.ndarray | float:
        """Required omega at env step(s) ``step`` (0 where no demand is configured)."""
        pts = self.demand_points()
        if pts is None:
            return np.zeros_like(np.asarray(step, float)) if np.ndim(step) else 0.0
        t = np.asarray(step, float)
        # np.interp picks the right-hand value at a repeated time (a step change)
        out = np.interp(t, pts[:, 0], pts[:, 1])
        return out if np.ndim(step) else float(out)

    # ------------------------------------------------------------------ construction / export
    @classmethod
    def field_names(cls) -> list[str]:
        """Names of all settings."""
        return [f.name for f in fields(cls)]

    @classmethod
    def from_kwargs(cls, config: GearSpeedConfig | Mapping[str, Any] | None = None, **kwargs: Any) -> GearSpeedConfig:
        """Build from a config (or dict) plus keyword overrides; unknown keys raise ``ValueError``."""
        base: dict[str, Any] = {}
        if isinstance(config, GearSpeedConfig):
            base = {f.name: getattr(config, f.name) for f in fields(cls)}
        elif isinstance(config, Mapping):
            base = dict(config)
        elif config is not None:
            raise ValueError(f"config must be a GearSpeedConfig, a dict or None, got {type(config).__name__}")
        base.update(kwargs)
        valid = cls.field_names()
        unknown = sorted(set(base) - set(valid))
        if unknown:
            raise ValueError(f"unknown GearSpeedConfig key(s) {unknown}; valid keys: {valid}")
        return cls(**base)

    def replace(self, **changes: Any) -> GearSpeedConfig:
        """A copy with some settings changed (validated again)."""
        return GearSpeedConfig.from_kwargs(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (``params`` as a dict of SI values)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, GearParams):
                v = v.to_dict()
            elif isinstance(v, tuple):
                v = [list(p) if isinstance(p, tuple) else p for p in v]
            out[f.name] = v
        return out

    @classmethod
    def from_json(cls, path: str) -> GearSpeedConfig:
        """Read a JSON object of settings (the ``--config`` file of the CLI)."""
        with open(path, encoding="utf-8-sig") as fh:  # -sig: tolerate a byte-order mark
            try:
                data = json.load(fh)
            except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                raise ValueError(f"config file {path!r} is not valid JSON: {exc}") from None
        if not isinstance(data, dict):
            raise ValueError(f"config file {path!r} must hold a JSON object of settings")
        return cls.from_kwargs(data)


__all__ = ["ACTION_MODES", "DEMAND_PRESETS", "OBSERVATION_SETS", "GearSpeedConfig"]
