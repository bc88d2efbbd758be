"""Configuration of the ``GearSpeed-v0`` environment: a frozen, validated dataclass.

Every field has a default; ``GearSpeedConfig.from_kwargs`` (used by ``gym.make``) rejects unknown
keys with the list of valid ones, and ``__post_init__`` rejects out-of-range values with a message
naming the field and its allowed range.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from ..sim.params import MODELS, GearParams
from . import env_terms as ET
from .env_terms import ACTION_MODES, DEMAND_PRESETS, MIN_STATIC_MESH_FORCE, OBSERVATION_SETS

assert tuple(MODELS) == ET.BACKLASH_MODELS

_C = TypeVar("_C", bound="TableConfig")


class TableConfig:
    """Base of the configs whose fields come from a task's entries in :mod:`gear_env.envs.env_terms`.

    Subclasses are made with :func:`table_config`; validation runs field by field in table order
    (each setting's ``check`` sees the fields before it already normalised).
    """

    TERMS: ET.TaskTerms  # set by table_config

    if TYPE_CHECKING:  # the fields are generated from the table

        def __init__(self, **settings: Any) -> None: ...

        def __getattr__(self, name: str) -> Any: ...

    def __post_init__(self) -> None:
        cls = type(self).__name__
        for st in self.TERMS.settings:
            object.__setattr__(self, st.name, st.check(f"{cls}.{st.name}", getattr(self, st.name), self))

    @classmethod
    def field_names(cls) -> list[str]:
        """Names of all settings."""
        return [f.name for f in fields(cls)]  # type: ignore[arg-type]  # a dataclass made by table_config

    @classmethod
    def from_kwargs(cls: type[_C], config: Any = None, **kwargs: Any) -> _C:
        """Build from a config (or dict) plus keyword overrides; unknown keys raise ``ValueError``."""
        base: dict[str, Any] = {}
        if isinstance(config, cls):
            base = {name: getattr(config, name) for name in cls.field_names()}
        elif isinstance(config, Mapping):
            base = dict(config)
        elif config is not None:
            raise ValueError(f"config must be a {cls.__name__}, a dict or None, got {type(config).__name__}")
        base.update(kwargs)
        valid = cls.field_names()
        unknown = sorted(set(base) - set(valid))
        if unknown:
            raise ValueError(f"unknown {cls.__name__} key(s) {unknown}; valid keys: {valid}")
        return cls(**base)

    def replace(self: _C, **changes: Any) -> _C:
        """A copy with some settings changed (validated again)."""
        return type(self).from_kwargs(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (``params`` as a dict of SI values). A setting of :data:`OMITTED_AT_NONE` is left out while
        None, so that a run folder's config written before it existed compares equal, and a config file of an older
        id does not carry a ``scheme: null`` over a Fox-Goodwin id's scheme."""
        out: dict[str, Any] = {}
        for name in self.field_names():
            v = getattr(self, name)
            if v is None and name in OMITTED_AT_NONE:
                continue
            if isinstance(v, GearParams) or hasattr(v, "to_dict"):  # GearParams, PlantFamily, DutyCycle
                v = v.to_dict()
            elif isinstance(v, tuple):
                v = [list(p) if isinstance(p, tuple) else p for p in v]
            out[name] = v
        return out

    @classmethod
    def from_json(cls: type[_C], path: str) -> _C:
        """Read a JSON object of settings (the ``--config`` file of the CLI)."""
        from ..io import read_json

        data = read_json(path, "config file", max_bytes=1024 * 1024)  # size, depth, numbers bounded; BOM tolerated
        if not isinstance(data, dict):
            raise ValueError(f"config file {path!r} must hold a JSON object of settings")
        return cls.from_kwargs(data)


OMITTED_AT_NONE = frozenset({"scheme"})
"""Settings that :meth:`TableConfig.to_dict` leaves out while None."""


def table_config(task_id: str) -> Callable[[type[_C]], type[_C]]:
    """Class decorator: a frozen dataclass whose fields are the settings of ``task_id`` in
    :mod:`gear_env.envs.env_terms` (names, defaults and order from the table, checks in ``__post_init__``)."""

    def make(cls: type[_C]) -> type[_C]:
        terms = ET.task(task_id)
        ann = dict(cls.__dict__.get("__annotations__", {}))
        for st in terms.settings:
            if st.name in cls.__dict__:
                raise TypeError(f"{cls.__name__}.{st.name} is declared in env_terms; do not redeclare it")
            ann[st.name] = "Any"
            setattr(cls, st.name, st.default)
        cls.__annotations__ = ann
        cls.TERMS = terms
        return dataclass(frozen=True)(cls)

    return make


@table_config("GearSpeed-v0")
class GearSpeedConfig(TableConfig):
    """Settings of :class:`gear_env.envs.env.GearSpeedEnv` (all keyword arguments of ``gym.make``).

    The fields, their defaults, checks and meaning are the ``GearSpeed-v0`` entries of
    :mod:`gear_env.envs.env_terms` (``SETTINGS`` and the reward terms' weights); the table is in
    docs/ENVIRONMENT.md. Every field has a default; :meth:`from_kwargs` (used by ``gym.make``)
    rejects unknown keys with the list of valid ones, and ``__post_init__`` rejects out-of-range
    values with a message naming the field and its allowed range.

    Physics:
        params: :class:`GearParams` or a dict of its fields (SI units); default Table 1.
        model: backlash model, ``"dynamic"`` (default) or ``"constant"``.
        steps_per_period: Newmark steps per mesh period, in [16, 1024]; default 64 (the env's fast
            preset, same regime boundaries as the simulator's 128; see docs/ENVIRONMENT.md); or ``"auto"``: with
            Fox-Goodwin's beta 48, 64 or 80 per sub-environment and step by its contact loss in the step before
            (``gear_env.sim.integration.contact_steps``; 32 or 64 with ``correct_kinks``), with any other beta 64.
        scheme: None (``params.newmark_beta`` and ``velocity_correction`` as given), ``"paper"`` (beta 1/4),
            ``"fox-goodwin"`` (beta 1/12) or ``"fox-goodwin-vc"`` (beta 1/12 with the velocity correction, the
            Fox-Goodwin ids' setting): sets ``params.newmark_beta`` and ``params.velocity_correction``.
        tol: None (default: fixed steps) or the error per mesh period in b0 units, in [1e-8, 0.1]:
            every mesh period is then integrated with contact changes located and Richardson-extrapolated
            N and 2N steps, N chosen per period per system (as ``GearSimulator(tol=)``);
            ``steps_per_period`` is then unused. The single and the vector env stay identical.
        locate_contacts: False (default) or True: a Newmark step whose contact region changes is taken again split
            at the crossing (``gear_env.sim.kernels.located_step_t``); fixed steps only. The single and the
            vector env stay identical.
        correct_kinks: False (default) or True: a Newmark step whose contact region changes is corrected for the
            kink of the backlash force inside it, without a solve (``gear_env.sim.kernels.kink_correct_t``); fixed
            steps only, not with ``locate_contacts``. The single and the vector env stay identical.
        randomize_params: if True, every episode multiplies kappa, the three damping ratios and
            the two torques by independent factors uniform in [1 - s, 1 + s], s = ``randomize_scale``.
        randomize_scale: relative jitter s, in [0, 0.5].

    Control:
        periods_per_step: mesh periods per environment step, in [1, 1000] (default 24).
        omega_min, omega_max: admissible meshing frequency Omega/omega_n, 0 < min < max <= 20.
        max_domega: largest change of omega in one step, in (0, omega_max - omega_min].
        action_mode: ``"delta"`` (action = change of omega in units of max_domega) or ``"target"``
            (action maps linearly onto [omega_min, omega_max]; the change is rate-limited).
        reference_filter: target mode: the fraction alpha in (0, 1] of the set-point error the drive's
            reference closes per step before the rate limit (first-order filter; 1 = none, the default).

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

    # ------------------------------------------------------------------ derived quantities
    @property
    def warmup_total(self) -> int:
        """Mesh periods actually simulated before the first observation."""
        return max(self.warmup_periods, self.periods_per_step, self.poincare_window)

    def demand_points(self) -> np.ndarray | None:
        """The demand profile as an (m, 2) array of (t in steps, omega), or None."""
        d = self.demand
        if d is None or d == "random":  # "random": drawn per episode (gear_env.envs.tasks.random_demand)
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


def task_config(env_id: str, settings: Mapping[str, Any] | None = None) -> Any:
    """The validated ``GearSpeedConfig`` of a registered task, with ``settings`` overriding its defaults."""
    from .tasks import TASK_SETTINGS

    if env_id not in TASK_SETTINGS:
        raise ValueError(f"env id must be one of {list(TASK_SETTINGS)}, got {env_id!r}")
    return GearSpeedConfig.from_kwargs({**TASK_SETTINGS[env_id], **dict(settings or {})})


__all__ = [
    "ACTION_MODES",
    "DEMAND_PRESETS",
    "MIN_STATIC_MESH_FORCE",
    "OBSERVATION_SETS",
    "GearSpeedConfig",
    "TableConfig",
    "table_config",
    "task_config",
]
