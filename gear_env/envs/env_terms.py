"""The GearSpeed environments' terms, declared once.

Everything an environment of the GearSpeed family exposes by name is one entry of one table here:

* :data:`SETTINGS` - configuration fields (name, default, check, allowed range, meaning);
* :data:`REWARDS` - reward terms; each brings its weight setting (``w_<name>`` unless named) and
  optional parameter settings, and appears in ``info`` as ``reward_<name>``; the reward is their
  sum, in table order;
* :data:`COSTS` - cost terms for safe-RL libraries (non-negative), ``info["cost_<name>"]``, summed
  into ``info["cost"]`` (a task without cost terms has neither key);
* :data:`INFOS` - the other ``info`` columns (features, bookkeeping, episode totals);
* :data:`OBSERVATIONS` - the observation features, in order, with their bounds.

From these follow: the fields of the config dataclass (:func:`gear_env.envs.env_config.table_config`), the
column and slot numbers the numba kernels use (:data:`R`, :data:`C`, :data:`IX`, :data:`P`,
:data:`F`: module-level namedtuples of ints, which numba freezes as constants), the ``info`` keys
and their types, the index lists the kernel sums the reward and the cost over, the observation
names and bounds of ``env.observation_names`` / ``observation_space``, and the Markdown tables of
docs/ENVIRONMENT.md (:func:`markdown`, checked by tests/test_env_terms.py).

An entry belongs to every task unless its ``tasks`` names some; :func:`task` gives the view of one
task (``TASKS``). The formulas live in one place, ``env_kernels.post_step``, one line per term,
written against the slots: ``I[r, R.chaos] = -S[P.w_chaos] * chaos``. Adding a reward term is one
entry here plus that line (docs/ENVIRONMENT.md, "Adding a term").

Pure Python, no numba: this module is imported by the kernels, the config and the docs tool.
"""

from __future__ import annotations

import math
import re
import sys
from collections import namedtuple
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

TASKS = ("GearSpeed-v0",)
"""Task ids of the family (``gym.make`` ids)."""

ALL: tuple[str, ...] = ()
"""``tasks=ALL`` (the default): the entry belongs to every task."""


# ---------------------------------------------------------------------------------------- checks
Check = Callable[[str, Any, Any], Any]
"""``check(label, value, config) -> normalised value``; ``label`` is ``"<ConfigClass>.<field>"``,
``config`` the object being validated (fields before this one already normalised). Raises
``ValueError`` naming the label and the allowed range."""


def check_real(label: str, value: Any, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> float:
    """Validate a real number in [lo, hi] (or open ends) and return it as float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{label} must be a real number, got {value!r}")
    v = float(value)
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"{label} must be in {rng}, got {value!r}")
    return v


def check_int(label: str, value: Any, lo: int, hi: int) -> int:
    """Validate an integer in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{label} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def check_choice(label: str, value: Any, choices: Sequence[str]) -> str:
    """Validate one of ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{label} must be one of {list(choices)}, got {value!r}")
    return value


def _real_check(lo: float, hi: float, lo_open: bool, hi_open: bool, label: str, v: Any, cfg: Any) -> float:
    return check_real(label, v, lo, hi, lo_open, hi_open)


def _int_check(lo: int, hi: int, label: str, v: Any, cfg: Any) -> int:
    return check_int(label, v, lo, hi)


def _choice_check(choices: tuple[str, ...], label: str, v: Any, cfg: Any) -> str:
    return check_choice(label, v, choices)


# the checks are partials of module-level functions, so a table (and a core holding it) pickles
def real(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> Check:
    """Check of a real setting in [lo, hi] (``lo_open``/``hi_open``: open ends)."""
    return partial(_real_check, lo, hi, lo_open, hi_open)


def integer(lo: int, hi: int) -> Check:
    """Check of an integer setting in [lo, hi]."""
    return partial(_int_check, lo, hi)


def choice(*choices: str) -> Check:
    """Check of a setting that is one of ``choices``."""
    return partial(_choice_check, choices)


def boolean(label: str, v: Any, cfg: Any) -> bool:
    """Check of a True/False setting."""
    if not isinstance(v, (bool, np.bool_)):
        raise ValueError(f"{label} must be True or False, got {v!r}")
    return bool(v)


WEIGHT_MAX = 1e6
"""Largest reward or cost weight."""


# ---------------------------------------------------------------------------------------- entries
@dataclass(frozen=True)
class Setting:
    """A configuration field.

    Args:
        name: field name (a keyword of ``gym.make``).
        default: default value (immutable).
        check: :data:`Check` that validates and normalises the value.
        range: the allowed values, for the docs table.
        doc: meaning (one line, units).
        shown: the default as the docs table shows it (default: the value).
        kernel: if given, the setting is copied into the kernels' settings vector ``S`` at slot
            ``P.<name>`` as ``float(kernel(value))`` (``float`` for a plain number).
        tasks: tasks that have this field (``ALL``: every task).
    """

    name: str
    default: Any
    check: Check
    range: str
    doc: str
    kernel: Callable[[Any], float] | None = None
    tasks: tuple[str, ...] = ALL
    shown: str = ""


@dataclass(frozen=True)
class Term:
    """A reward or cost term: ``info["reward_<name>"]`` (or ``"cost_<name>"``).

    Args:
        name: short name (a Python identifier).
        default: default weight (>= 0; the sign of a penalty is in the formula).
        formula: the term as written in the docs (the code is one line of ``env_kernels.post_step``).
        doc: when it applies, what it pays for.
        weight: name of the weight setting (default ``w_<name>``).
        weight_doc: meaning of the weight in the docs table (default "weight of the <name> term").
        params: further settings the formula uses (documented with the term, copied to ``S``).
        tasks: tasks that have this term (``ALL``: every task).
    """

    name: str
    default: float
    formula: str
    doc: str
    weight: str = ""
    weight_doc: str = ""
    params: tuple[Setting, ...] = ()
    tasks: tuple[str, ...] = ALL

    @property
    def weight_name(self) -> str:
        """The config field of the weight."""
        return self.weight or f"w_{self.name}"

    def settings(self) -> tuple[Setting, ...]:
        """The weight setting followed by the term's parameters."""
        w = Setting(
            self.weight_name,
            float(self.default),
            real(0.0, WEIGHT_MAX),
            "[0, 1e6]",
            self.weight_doc or f"weight of the {self.name} term",
            kernel=float,
            tasks=self.tasks,
        )
        return (w, *self.params)


@dataclass(frozen=True)
class Info:
    """An ``info`` column that is not a term: name, Python type of the value, meaning (units)."""

    name: str
    dtype: type
    doc: str
    tasks: tuple[str, ...] = ALL


@dataclass(frozen=True)
class Observation:
    """An observation feature (one float32 entry of the observation vector).

    Args:
        name: feature name (``env.observation_names``).
        low, high: bounds of the observation Box.
        doc: meaning (how it is scaled).
        when: None (always) or a predicate of the config that says whether the entry is present.
        tasks: tasks that have it (``ALL``: every task).
    """

    name: str
    low: float
    high: float
    doc: str
    when: Callable[[Any], bool] | None = None
    tasks: tuple[str, ...] = ALL


# ---------------------------------------------------------------------------------------- the table
FEATURE_CLIP = 10.0
"""Upper bound of the log-scaled and per-period features."""
STATE_CLIP = 1e6
"""Bound of the hidden-state entries of ``observation="full"`` (the kernels' divergence limit)."""
MIN_STATIC_MESH_FORCE = 1e-6
"""Smallest static mesh force F_s [k_m0 b0] the env accepts (the default pair has 0.0275)."""
ACTION_MODES = ("delta", "target", "limit", "limit_rate")
ACTION_CODES = {"delta": 0, "target": 1, "limit": 2, "limit_rate": 2}
"""The action mode as the kernels take it (``env_kernels.decode_actions``): 0 delta, 1 target, 2 limit. In
``limit_rate`` mode the environment first turns the action into the limit it sets (:func:`limit_after`), which
the kernel then decodes as a limit-mode action."""
CORE_OBSERVATIONS = (
    "speed_limit", "force_level", "force_level_known", "steady_force_level", "steady_force_level_known",
    "mean_force_level", "mean_force_level_count",
)  # fmt: skip
"""Observation entries written by the environment's core (``env_core.GearSpeedCore``: ``_show_limit`` and
``_add_levels``) rather than by ``env_kernels.post_step``: the speed limit the core keeps and the force level
computed from the observation (after any sensor noise)."""
LIMIT_MODES = ("limit", "limit_rate")
"""Action modes in which the drive follows the demand under a speed limit (they need a demand)."""
OBSERVATION_SETS = ("sensors", "full")
DEMAND_PRESETS = ("steps", "ramp", "random")
THROUGHPUT_MODES = ("all", "delivered")
BACKLASH_MODELS = ("constant", "dynamic")  # params.MODELS (checked by the config)


def _scheme(label: str, v: Any, cfg: Any) -> str | None:
    from ..sim.params import SCHEMES  # lazy: keeps this module free of numba

    if v is None:
        return None
    if not isinstance(v, str) or v not in SCHEMES:
        raise ValueError(f"{label} must be None or one of {list(SCHEMES)}, got {v!r}")
    return v


def _params(label: str, v: Any, cfg: Any) -> Any:
    from ..sim.params import C_FS, SCHEMES, GearParams, refuse_extensions  # lazy: keeps this module free of numba

    scheme = None if cfg.scheme is None else SCHEMES[cfg.scheme]
    if v is None:
        v = GearParams()
    elif isinstance(v, Mapping):
        given = dict(v)
        v = GearParams.from_dict(given)
        for i, name in enumerate(("newmark_beta", "velocity_correction")):
            if scheme is not None and name in given and getattr(v, name) != scheme[i]:
                raise ValueError(
                    f"{label}.{name} = {getattr(v, name)!r} conflicts with scheme={cfg.scheme!r} ({name} "
                    f"{scheme[i]!r}; the Fox-Goodwin ids set it): leave {name} out of params or give the "
                    f"scheme's, choose the scheme by name ({', '.join(repr(n) for n in SCHEMES)}), or pass "
                    f"scheme=None to take params.{name} as given"
                )
    elif not isinstance(v, GearParams):
        raise ValueError(f"{label} must be a GearParams, a dict of its fields or None, got {v!r}")
    if scheme is not None and (v.newmark_beta, v.velocity_correction) != scheme:
        # the task's scheme, whatever pair is passed
        v = v.replace(newmark_beta=scheme[0], velocity_correction=scheme[1])
    if not v.consts[C_FS] >= MIN_STATIC_MESH_FORCE:  # features and rewards are forces / F_s: F_s = 0 gives inf
        raise ValueError(
            f"{label} must load the mesh (T_p, T_g > 0): the env scales forces by the static mesh "
            f"force F_s, got F_s = {v.consts[C_FS]:g} k_m0 b0 (need >= {MIN_STATIC_MESH_FORCE:g})"
        )
    refuse_extensions(v, label)
    return v


def _omega_max(label: str, v: Any, cfg: Any) -> float:
    w = check_real(label, v, 0.0, 20.0, lo_open=True)
    if w <= cfg.omega_min:
        raise ValueError(f"{label} must be > omega_min ({cfg.omega_min:g}), got {v!r}")
    return w


def _max_domega(label: str, v: Any, cfg: Any) -> float:
    try:
        return check_real(label, v, 0.0, cfg.omega_max - cfg.omega_min, lo_open=True)
    except ValueError as exc:
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not 0 < v < math.inf:
            raise
        # a positive number above the bound, which two other settings make: name them (a user who set omega_max
        # to 0.125 with the default max_domega 0.05 is told which of the three to change)
        raise ValueError(
            f"{exc} (the bound is omega_max - omega_min = {cfg.omega_max:g} - {cfg.omega_min:g}: lower max_domega or "
            "widen [omega_min, omega_max])"
        ) from None


def _steps(label: str, v: Any, cfg: Any) -> int | str:
    """An integer in [16, 1024], or "auto": with Fox-Goodwin's beta 48, 64 or 80 steps per mesh period per
    sub-environment by the contact loss of its previous interval (``gear_env.sim.integration.contact_steps``, the
    rule calibrated for that scheme; 32 or 64 with ``correct_kinks``), with any other beta 64 (the tasks' count)."""
    if isinstance(v, str) and v == "auto":
        return "auto"
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 1024:
        raise ValueError(f'{label} must be an integer in [16, 1024] or "auto", got {v!r}')
    return int(v)


def _locate(label: str, v: Any, cfg: Any) -> bool:
    """A bool; True only with fixed steps (``tol`` locates the contact changes itself)."""
    b = boolean(label, v, cfg)
    if b and cfg.tol is not None:
        raise ValueError(f"{label} applies to fixed steps; tol={cfg.tol!r} locates contact changes itself: leave one")
    return b


def _correct(label: str, v: Any, cfg: Any) -> bool:
    """A bool; True only with fixed steps and without ``locate_contacts`` (two ways to treat the same steps)."""
    b = _locate(label, v, cfg)
    if b and cfg.locate_contacts:
        raise ValueError(f"{label} and locate_contacts treat the same steps two ways: set one of them")
    return b


def _tol(label: str, v: Any, cfg: Any) -> float | None:
    """None (fixed steps) or the error per mesh period in b0 units, in [1e-8, 0.1]."""
    from ..sim.params import NEWMARK_BETA  # lazy: keeps this module free of numba

    if v is None:
        return None
    if cfg.params.newmark_beta != NEWMARK_BETA:
        raise ValueError(
            f"{label} (error control) takes only the paper's Newmark beta (params.newmark_beta = {NEWMARK_BETA}, "
            f"params.velocity_correction = False), got {cfg.params.newmark_beta:.6g} (scheme={cfg.scheme!r}); leave "
            f'tol None (fixed steps) or pass scheme="paper"'
        )
    return check_real(label, v, 1e-8, 0.1)


def _initial_omega(label: str, v: Any, cfg: Any) -> Any:
    lo, hi = cfg.omega_min, cfg.omega_max
    if v is None:
        return None
    if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
        return check_real(label, v, lo, hi)
    if isinstance(v, Sequence) and not isinstance(v, str) and len(v) == 2:
        a = check_real(f"{label}[0]", v[0], lo, hi)
        b = check_real(f"{label}[1]", v[1], lo, hi)
        if b < a:
            raise ValueError(f"{label} must be (lo, hi) with lo <= hi, got {v!r}")
        return (a, b)
    raise ValueError(f"{label} must be None, a number or a pair (lo, hi) in [{lo:g}, {hi:g}], got {v!r}")


def _demand(label: str, v: Any, cfg: Any) -> Any:
    if v is None:
        if cfg.action_mode in LIMIT_MODES:
            raise ValueError(
                f'action_mode "{cfg.action_mode}" sets a speed limit under which the drive follows the demand: it '
                "needs a demand "
                '(demand is None; give demand="random", "steps", "ramp" or a list of (t, omega) points)'
            )
        return None
    if isinstance(v, str):
        return check_choice(label, v, DEMAND_PRESETS)
    if not isinstance(v, Sequence) or len(v) == 0:
        raise ValueError(
            f"{label} must be None, one of {list(DEMAND_PRESETS)} or a non-empty list of "
            f"(t_steps, omega) points, got {v!r}"
        )
    pts: list[tuple[float, float]] = []
    for i, pt in enumerate(v):
        if not isinstance(pt, Sequence) or isinstance(pt, str) or len(pt) != 2:
            raise ValueError(f"{label}[{i}] must be a (t_steps, omega) pair, got {pt!r}")
        t = check_real(f"{label}[{i}][0] (time in steps)", pt[0], 0.0, 1e9)
        w = check_real(f"{label}[{i}][1] (omega)", pt[1], cfg.omega_min, cfg.omega_max)
        if pts and t < pts[-1][0]:
            raise ValueError(f"{label} times must be non-decreasing; point {i} has t={t:g} < {pts[-1][0]:g}")
        pts.append((t, w))
    return tuple(pts)


def _action_range(label: str, v: Any, cfg: Any) -> Any:
    """None (the whole speed range) or a (lo, hi) band inside [omega_min, omega_max]."""
    if v is None:
        return None
    from .tasks import pair

    owner, name = label.rsplit(".", 1)
    lo, hi = pair(owner, name, v, cfg.omega_min, cfg.omega_max)
    if not hi > lo:
        raise ValueError(f"{label} must be a band (lo, hi) with lo < hi, got {v!r}")
    return (lo, hi)


def action_bounds(cfg: Any) -> tuple[float, float]:
    """The speeds (omega) that the actions -1 and +1 mean in target and limit modes (in limit_rate mode the
    band the speed limit moves in): ``action_range`` or [omega_min, omega_max]."""
    r = cfg.action_range
    return (float(cfg.omega_min), float(cfg.omega_max)) if r is None else (float(r[0]), float(r[1]))


def _limit_rate(label: str, v: Any, cfg: Any) -> float:
    """A positive change of the speed limit per step, at most the width of the action range."""
    lo, hi = action_bounds(cfg)
    return check_real(label, v, 0.0, hi - lo, lo_open=True)


def _action_delay(label: str, v: Any, cfg: Any) -> int:
    """An actuator dead time in [0, 10] steps; none in limit_rate mode (not supported there)."""
    n = integer(0, 10)(label, v, cfg)
    if n and cfg.action_mode == "limit_rate":
        raise ValueError(
            f'{label} must be 0 with action_mode "limit_rate" (a dead time is not supported in that mode), got {v!r}'
        )
    return n


def limit_after(cfg: Any, limit: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """``limit_rate`` mode: the speed limit (omega) after actions in [-1, 1] move ``limit`` by
    ``action x limit_rate``, clipped to the action range (:func:`action_bounds`)."""
    lo, hi = action_bounds(cfg)
    a = np.clip(np.asarray(actions, float), -1.0, 1.0)
    return np.clip(np.asarray(limit, float) + a * cfg.limit_rate, lo, hi)


def limit_action(cfg: Any, limit: np.ndarray) -> np.ndarray:
    """The limit-mode action in [-1, 1] that means the speed limit ``limit`` (omega) over the action range."""
    lo, hi = action_bounds(cfg)
    return np.clip(2.0 * (np.asarray(limit, float) - lo) / (hi - lo) - 1.0, -1.0, 1.0)


def _demand_segments(label: str, v: Any, cfg: Any) -> tuple[int, int]:
    from .tasks import int_pair  # lazy: tasks imports params

    owner, name = label.rsplit(".", 1)
    return int_pair(owner, name, v, 1, 1_000_000)


def _demand_range(label: str, v: Any, cfg: Any) -> Any:
    """None (the whole speed range) or a (lo, hi) band inside [omega_min, omega_max]."""
    if v is None:
        return None
    from .tasks import pair

    owner, name = label.rsplit(".", 1)
    return pair(owner, name, v, cfg.omega_min, cfg.omega_max)


def _plant_family(label: str, v: Any, cfg: Any) -> Any:
    from .tasks import PlantFamily, from_value

    return from_value(PlantFamily, label, v)


def _wear(label: str, v: Any, cfg: Any) -> Any:
    """A WearChange (or None); the family's e_m1 range times every wear factor must stay valid."""
    from .tasks import PlantFamily, WearChange, from_value

    w = from_value(WearChange, label, v)
    if w is not None:
        fam = cfg.plant_family if cfg.plant_family is not None else PlantFamily(load=(1.0, 1.0), e_m1=(1.0, 1.0))
        levels = cfg.duty_cycle.levels if cfg.duty_cycle is not None else (1.0,)
        lo, hi = min(w.factors), max(w.factors)
        try:
            worn = PlantFamily(load=fam.load, e_m1=(fam.e_m1[0] * lo, fam.e_m1[1] * hi))
        except ValueError as exc:
            raise ValueError(f"{label} factors {list(w.factors)} take the family's e_m1 out of range: {exc}") from None
        worn.check(cfg.params, levels, MIN_STATIC_MESH_FORCE)
    return w


def _duty_cycle(label: str, v: Any, cfg: Any) -> Any:
    """A DutyCycle (or None); with a plant family or a duty cycle, every corner of the family box under
    every duty level must give valid parameters (refused here, before any training starts)."""
    from .tasks import DutyCycle, PlantFamily, from_value

    d = from_value(DutyCycle, label, v)
    if cfg.plant_family is not None or d is not None:
        fam = cfg.plant_family if cfg.plant_family is not None else PlantFamily(load=(1.0, 1.0), e_m1=(1.0, 1.0))
        fam.check(cfg.params, d.levels if d is not None else (1.0,), MIN_STATIC_MESH_FORCE)
    return d


def _throughput(label: str, v: Any, cfg: Any) -> str:
    check_choice(label, v, THROUGHPUT_MODES)
    if v == "delivered" and cfg.demand is None:
        raise ValueError(f'{label} "delivered" pays omega up to the demand: it needs a demand (demand is None)')
    return v


def _is_delivered(v: Any) -> float:
    return 1.0 if v == "delivered" else 0.0


def _not_none(v: Any) -> float:
    return 1.0 if v is not None else 0.0


def _has_demand(cfg: Any) -> bool:
    return cfg.demand is not None


def _full_state(cfg: Any) -> bool:
    return cfg.observation == "full"


def _has_memory(cfg: Any) -> bool:
    return cfg.memory_steps > 0.0


def _has_delay(cfg: Any) -> bool:
    return cfg.action_delay > 0


def _has_force_level(cfg: Any) -> bool:
    return bool(cfg.force_level)


def _has_level_window(cfg: Any) -> bool:
    return cfg.level_window > 0


def _level_window(label: str, v: Any, cfg: Any) -> int:
    """0 (off) or the averaging window in [1, 1000] env steps of the mean force level; needs ``force_level``."""
    n = integer(0, 1000)(label, v, cfg)
    if n and not cfg.force_level:
        raise ValueError(f"{label} > 0 needs force_level=True (it averages the force level), got {v!r}")
    return n


def _has_limit_state(cfg: Any) -> bool:
    return cfg.action_mode == "limit_rate"


TROUBLE_CONTACT = 0.02
"""A step is *troubled* (for the memory features) when its contact-loss fraction exceeds this, it has an
impact (either side) or its motion is non-periodic (c > 0.5): the edge seeker's test
(benchmarks/demand_gap.py)."""


SETTINGS: tuple[Setting, ...] = (
    # physics
    Setting("scheme", None, _scheme, 'None, "paper", "fox-goodwin", "fox-goodwin-vc"',
            "Newmark scheme: sets `params.newmark_beta` and `params.velocity_correction`: beta 1/4 (paper), 1/12 "
            "(fox-goodwin) or 1/12 with the damping forces' velocity corrected (fox-goodwin-vc, the Fox-Goodwin ids' "
            "setting: the same cost per step, 10x less error over the period-1 orbits at 64 steps), over those of a "
            "`GearParams` passed in `params` (a dict that names others is refused); None: `params` as given"),
    Setting("params", None, _params, "`GearParams` or dict", "physical parameters (SI); the torques must give a "
            "static mesh force >= 1e-6 N (features are relative to it)", shown="Table 1"),
    Setting("model", "dynamic", choice(*BACKLASH_MODELS), '"dynamic", "constant"', "backlash model"),
    Setting("steps_per_period", 64, _steps, '[16, 1024], "auto"',
            "Newmark steps per mesh period (with `params.newmark_beta` < 1/4, kept: where omega is too low for that "
            "beta at this count, the sub-environment takes the nearest stable beta for that step, "
            '`gear_env.sim.linear.stable_beta`); "auto": with beta 1/12, 48, 64 or 80 per sub-environment and step '
            "by its contact loss (time out of drive-side contact) in the step before (<= 0.2, <= 0.5, more; 80 only "
            "for period-1 motion; `gear_env.sim.integration.contact_steps`; with `correct_kinks` 32 or 64: the kinks "
            "that 80 steps bought down are corrected), with any other beta 64"),
    Setting("tol", None, _tol, "None, [1e-8, 0.1]",
            "error per mesh period (b0 units) instead of `steps_per_period`: every mesh period integrated with "
            "contact changes located and N, 2N steps Richardson-extrapolated, N chosen per period "
            "(`GearSimulator(tol=)`); None: fixed steps"),
    Setting("locate_contacts", False, _locate, "bool",
            "locate the contact changes inside the Newmark steps (a step whose contact region changes is taken again "
            "split at the crossing, `gear_env.sim.kernels.located_step_t`): fixed steps only (not with `tol`, which "
            "locates them itself); single and vector env alike"),
    Setting("correct_kinks", False, _correct, "bool",
            "correct a Newmark step whose contact region changes for the kink of the backlash force inside it, "
            "without a solve (`gear_env.sim.kernels.kink_correct_t`): more accurate than `locate_contacts` at "
            "omega >= 0.3 and cheaper; fixed steps only, not with `tol` or `locate_contacts`; single and vector env "
            "alike"),
    Setting("randomize_params", False, boolean, "bool", "per-episode jitter of kappa, xi_m, xi_p, xi_g, T_p, T_g"),
    Setting("randomize_scale", 0.1, real(0.0, 0.5), "[0, 0.5]",
            "relative jitter (uniform factors in [1-s, 1+s], seeded)"),
    # control
    Setting("periods_per_step", 24, integer(1, 1000), "[1, 1000]", "mesh periods per env step", kernel=float),
    Setting("omega_min", 0.1, real(0.0, 20.0, lo_open=True), "(0, 20]", "smallest admissible omega", kernel=float),
    Setting("omega_max", 3.0, _omega_max, "(omega_min, 20]", "largest admissible omega", kernel=float),
    Setting("max_domega", 0.05, _max_domega, "(0, max-min]", "largest omega change per step", kernel=float),
    Setting("action_mode", "delta", choice(*ACTION_MODES), '"delta", "target", "limit", "limit_rate"',
            "meaning of the action: a change of omega (delta), a speed set-point over [omega_min, omega_max] "
            "(target), or a speed limit over that range under which the drive follows the demand (limit: "
            "set-point min(demand, limit); needs a demand), or a change of that speed limit (limit_rate: the "
            "limit moves by action x `limit_rate` per step, starts each episode at the bottom of the action "
            "range and is observed as `speed_limit`; needs a demand)"),
    Setting("action_range", None, _action_range, "None, (lo, hi) in [omega_min, omega_max]",
            "the speeds that the actions -1 and +1 mean in target and limit modes, linear between (None: "
            "[omega_min, omega_max]); the observation keeps scaling omega over [omega_min, omega_max]"),
    Setting("limit_rate", 0.03, _limit_rate, "(0, width of the action range]",
            "limit_rate mode: change of the speed limit per step for the action +-1 (omega units); no effect "
            "in other modes"),
    Setting("reference_filter", 1.0, real(0.0, 1.0, lo_open=True), "(0, 1]",
            "target and limit modes: fraction of the set-point error the drive's reference closes per step "
            "(first-order filter before the rate limit; 1: none; no effect in delta mode)", kernel=float),
    # episode
    Setting("max_steps", 200, integer(1, 1_000_000), "[1, 1e6]", "episode length (truncation)", kernel=float),
    Setting("initial_omega", None, _initial_omega, "None, number, (lo, hi)",
            "initial omega (None: uniform over the range)"),
    Setting("warmup_periods", 48, integer(0, 100_000), "[0, 1e5]", "mesh periods before the first observation"),
    Setting("demand", None, _demand, 'None, "steps", "ramp", "random", [(t, omega), ...]',
            'required omega over the episode (t in env steps, piecewise linear); "random": a new level uniform '
            "over `demand_range` every `demand_segment_steps` steps, drawn per episode", kernel=_not_none),
    Setting("demand_segment_steps", (10, 30), _demand_segments, "(lo, hi), 1 <= lo <= hi",
            'steps a level of the "random" demand is held (uniform integers)'),
    Setting("demand_range", None, _demand_range, "None, (lo, hi) in [omega_min, omega_max]",
            'band of the "random" demand levels (uniform over it; None: [omega_min, omega_max])'),
    Setting("plant_family", None, _plant_family, "None, `PlantFamily` or dict",
            "per-episode gear pair: uniform factors on the load torques (`load`) and on e_m1 (`e_m1`), "
            "see gear_env/envs/tasks.py"),
    Setting("duty_cycle", None, _duty_cycle, "None, `DutyCycle` or dict",
            "load duty cycle: the load torques times a level from `levels`, changing every `segment_steps` "
            "steps (drawn per episode)"),
    Setting("wear", None, _wear, "None, `WearChange` or dict",
            "a change of the pair within the episode: at a step drawn from `at_step`, e_m1 times a factor drawn "
            "from `factors` (see gear_env/envs/tasks.py)"),
    Setting("action_delay", 0, _action_delay, "[0, 10]; 0 with limit_rate",
            "actuator dead time [env steps]: the action of step t drives step t + action_delay (the drive "
            "holds the initial speed's set-point until then)"),
    Setting("sensor_noise", 0.0, real(0.0, 1.0), "[0, 1]",
            "std of Gaussian noise added to the continuous sensor features (force, deflection, defect, "
            "contact loss and their memory copies) of the observation, clipped to their bounds; drawn per "
            "episode; info and reward keep the true values"),
    # observation
    Setting("observation", "sensors", choice(*OBSERVATION_SETS), '"sensors", "full"', "observation set"),
    Setting("poincare_window", 16, integer(9, 1000), "[9, 1000]", "Poincare samples for the defect"),
    Setting("defect_scale", 0.02, real(0.0, 100.0, lo_open=True), "(0, 100]",
            "defect [b0] that counts as fully non-periodic", kernel=float),
    Setting("memory_steps", 0.0, real(0.0, 1000.0), "[0, 1000]",
            "time constant [env steps] of the memory features (`trouble_omega`, `trouble_recency`, "
            "`prev_force_rms`, `prev_contact_loss`); 0: none (the observation carries no history)", kernel=float),
    Setting("force_level", False, boolean, "bool",
            "add the observation entries `force_level`, `force_level_known`, `steady_force_level` and "
            "`steady_force_level_known`: the sensed force RMS over the family's steady force at the step's speed "
            "(gear_env/envs/force_level.py; a scaling of what is observed, in which the pair shows directly)"),
    Setting("level_window", 0, _level_window, "[0, 1000]",
            "(with `force_level`) add `mean_force_level` and `mean_force_level_count`: the pair's q averaged over "
            "the clean steps, a running mean over the first `level_window` of them, then an exponential average "
            "of weight 1/`level_window` (it follows a pair that changes); 0: off"),
)  # fmt: skip

REWARDS: tuple[Term, ...] = (
    Term("throughput", 1.0, "w_throughput * omega_mean / omega_max (delivered: min(omega_mean, demand))",
         "paid for speed (throughput at constant torque); with `throughput=\"delivered\"` only up to the demand",
         params=(Setting("throughput", "all", _throughput, '"all", "delivered"',
                         'what is paid: all of omega, or omega delivered against the demand (needs a demand)',
                         kernel=_is_delivered),)),
    Term("chaos", 1.0, "- w_chaos * c", "non-periodic motion, c = clip(defect / defect_scale, 0, 1)"),
    Term("contact", 0.5, "- w_contact * contact_loss_fraction", "time the teeth were apart or in back contact"),
    Term("impact", 0.2, "- w_impact * (drive re-impacts + back_impact_weight * back impacts) / mesh period",
         "impacts per mesh period",
         params=(Setting("back_impact_weight", 5.0, real(0.0, WEIGHT_MAX), "[0, 1e6]",
                         "a back-side impact costs this many drive-side re-impacts", kernel=float),)),
    Term("vibration", 0.5, "- w_vibration * max(0, F_peak/F_s - 1) / 10", "force peaks above the static mesh force"),
    Term("rate", 0.02, "- w_rate * (domega / max_domega)^2", "abrupt speed changes"),
    Term("demand", 2.0, "- w_demand * max(0, demand - omega_mean) / omega_max",
         "shortfall (only with a demand profile)"),
    Term("divergence", 10.0, "- divergence_penalty", "a diverging step (all other terms are then 0)",
         weight="divergence_penalty", weight_doc="reward of a diverging step: minus this"),
)  # fmt: skip

COSTS: tuple[Term, ...] = (
    Term("nonperiodic", 1.0, "w_nonperiodic * c", "non-periodic motion (the chaos measure c in [0, 1])"),
    Term("separation", 1.0, "w_separation * contact_loss_fraction", "tooth separation and back contact"),
    Term("impacts", 1.0, "w_impacts * (drive re-impacts + back_impact_weight * back impacts) / mesh period",
         "impacts per mesh period"),
)  # fmt: skip

INFOS: tuple[Info, ...] = (
    Info("step", int, "steps taken in the episode"),
    Info("omega", float, "omega at the end of the step"),
    Info("omega_mean", float, "time mean of omega over the step, (w0 + w1)/2"),
    Info("domega", float, "change of omega in the step"),
    Info("demand", float, "required omega charged in this step (0 without a demand profile)"),
    Info("force_rms", float, "RMS of the dynamic mesh force / F_s"),
    Info("force_peak", float, "peak mesh force / F_s"),
    Info("translation_rms", float, "dynamic RMS bearing deflection [b0]"),
    Info("defect", float, "periodicity defect of the Poincare window [b0]"),
    Info("period", int, "detected period (1..8), 0 if none"),
    Info("chaos", float, "c = clip(defect / defect_scale, 0, 1)"),
    Info("nonperiodic", bool, "c > 0.5"),
    Info("contact_loss", float, "fraction of the step with the teeth apart or in back contact"),
    Info("drive_impacts", int, "drive-side re-impacts in the step"),
    Info("back_impacts", int, "back-side impacts in the step"),
    Info("step_time_s", float, "physical time of the step [s]"),
    Info("diverged", bool, "the integration diverged (the step terminates the episode)"),
    Info("episode_return", float, "sum of the rewards so far"),
    Info("episode_steps", int, "steps so far"),
    Info("episode_throughput", float, "mean omega so far"),
    Info("episode_time_s", float, "physical time so far [s]"),
    Info("episode_time_periodic_s", float, "physical time in periodic motion [s]"),
    Info("episode_time_nonperiodic_s", float, "physical time in non-periodic motion [s]"),
    Info("episode_steps_periodic", int, "steps in periodic motion"),
    Info("episode_steps_nonperiodic", int, "steps in non-periodic motion"),
    Info("episode_impacts", int, "impacts (both sides) so far"),
    Info("episode_back_impacts", int, "back-side impacts so far"),
    Info("episode_contact_loss", float, "time-weighted contact-loss fraction so far"),
)

OBSERVATIONS: tuple[Observation, ...] = (
    Observation("omega", -1.0, 1.0, "2 (omega - omega_min)/(omega_max - omega_min) - 1, at the end of the step"),
    Observation("domega", -1.0, 1.0, "change of omega in the step / max_domega"),
    Observation("force_rms", 0.0, FEATURE_CLIP, "log1p(RMS of the dynamic mesh force / F_s)"),
    Observation("force_peak", 0.0, FEATURE_CLIP, "log1p(peak mesh force / F_s)"),
    Observation("translation_rms", 0.0, FEATURE_CLIP, "log1p(dynamic RMS bearing deflection / static deflection)"),
    Observation("defect", 0.0, FEATURE_CLIP, "log1p(periodicity defect / defect_scale)"),
    Observation("period", 0.0, 1.0, "detected period n/8 (n = 1..8), 0 if none"),
    Observation("contact_loss", 0.0, 1.0, "fraction of time the teeth were apart or in back contact"),
    Observation("drive_impacts", 0.0, FEATURE_CLIP, "drive-side re-impacts per mesh period"),
    Observation("back_impacts", 0.0, FEATURE_CLIP, "back-side impacts per mesh period"),
    Observation("demand", -1.0, 1.0, "(only with a demand profile) required omega of the next step, scaled like omega",
                when=_has_demand),
    *(
        Observation(name, -STATE_CLIP, STATE_CLIP, f'(only `observation="full"`) hidden state {name} [b0]',
                    when=_full_state)
        for name in ("X_p", "Y_p", "X_g", "Y_g", "U", "dX_p", "dY_p", "dX_g", "dY_g", "dU")
    ),
    # memory (memory_steps > 0): what happened before the last step; a step is troubled when its contact loss
    # > TROUBLE_CONTACT, it has an impact or c > 0.5
    Observation("trouble_omega", -1.0, 1.0, "(only with `memory_steps` > 0) mean omega of the step where trouble "
                "last began, scaled like omega; while the trouble lasts, the lowest such omega of the spell (the "
                "edge when crossing it from above); 1 until trouble is seen in the episode", when=_has_memory),
    Observation("trouble_recency", 0.0, 1.0, "(only with `memory_steps` > 0) exp(-(steps since the last troubled "
                "step) / memory_steps): 1 on a troubled step, 0 until trouble is seen", when=_has_memory),
    Observation("prev_force_rms", 0.0, FEATURE_CLIP, "(only with `memory_steps` > 0) `force_rms` of the previous "
                "step (of the warm-up itself after a reset)", when=_has_memory),
    Observation("prev_contact_loss", 0.0, 1.0, "(only with `memory_steps` > 0) `contact_loss` of the previous step "
                "(of the warm-up itself after a reset)", when=_has_memory),
    Observation("speed_limit", -1.0, 1.0, '(only with `action_mode="limit_rate"`) the speed limit the drive '
                "followed the demand under in the step, scaled like omega; the next action moves it",
                when=_has_limit_state),
    Observation("force_level", -5.0, 5.0, "(only with `force_level`) log of the step's sensed force RMS ratio over the "
                "family's steady one at the step's mean speed: the pair's log q (gear_env/envs/force_level.py), "
                "clipped to +-5; 0 where the table does not cover the speed (0.9-2.0)", when=_has_force_level),
    Observation("force_level_known", 0.0, 1.0, "(only with `force_level`) 1 if the step's mean speed lies in the "
                "table (0.9-2.0), else 0", when=_has_force_level),
    Observation("steady_force_level", -5.0, 5.0, "(only with `force_level`) `force_level` of the last clean, steady "
                "step (no trouble, |domega| <= 0.3, speed in the table); 0 until one", when=_has_force_level),
    Observation("steady_force_level_known", 0.0, 1.0, "(only with `force_level`) 1 once such a step was seen in "
                "the episode", when=_has_force_level),
    Observation("mean_force_level", -5.0, 5.0, "(only with `level_window` > 0) log of the pair's q = "
                "exp(`force_level`) averaged over the clean steps (no trouble above thresholds raised by "
                "2 `sensor_noise`, speed in the table): running mean over the first `level_window`, then "
                "exponential of weight 1/`level_window`; "
                "averaging q, not log q, keeps it unbiased under sensor noise; 0 until one", when=_has_level_window),
    Observation("mean_force_level_count", 0.0, 1.0, "(only with `level_window` > 0) clean steps averaged so far over "
                "`level_window`, at most 1", when=_has_level_window),
    Observation("pending_action", -1.0, 1.0, "(only with `action_delay` > 0) the action already sent that drives the "
                "next step (the state of the dead time; the drive's hold action right after a reset)",
                when=_has_delay),
)  # fmt: skip


# ---------------------------------------------------------------------------------------- derived
def _check_names() -> None:
    """Names are identifiers and unique per kind (settings, info keys, observations); tasks are known."""

    def repeated_or_bad(names: Sequence[str]) -> list[str]:
        return [n for k, n in enumerate(names) if not n.isidentifier() or n in names[:k]]

    settings = [s.name for s in all_settings()]
    infos = [f"reward_{t.name}" for t in REWARDS] + [f"cost_{t.name}" for t in COSTS] + [i.name for i in INFOS]
    for kind, names in (("setting", settings), ("info key", infos), ("observation", [o.name for o in OBSERVATIONS])):
        bad = repeated_or_bad(names)
        if bad:
            raise ValueError(f"env_terms: {kind} name(s) {bad} repeated or not identifiers")
    if COSTS and "cost" in infos:
        raise ValueError("env_terms: 'cost' is the sum of the cost terms; no INFOS entry may use that name")
    entries: list[Any] = [*all_settings(), *REWARDS, *COSTS, *INFOS, *OBSERVATIONS]
    for e in entries:
        unknown = set(e.tasks) - set(TASKS)
        if unknown:
            raise ValueError(f"env_terms: {e.name!r} names unknown task(s) {sorted(unknown)}; tasks are {list(TASKS)}")


def _slots(typename: str, names: Sequence[str], start: int = 0) -> Any:
    return namedtuple(typename, names)(*range(start, start + len(names)))


def all_settings() -> tuple[Setting, ...]:
    """Every setting of the family in config-field order: :data:`SETTINGS`, then each reward and cost
    term's weight and parameters."""
    out = list(SETTINGS)
    for t in (*REWARDS, *COSTS):
        out.extend(t.settings())
    return tuple(out)


def _info_columns() -> tuple[tuple[str, type], ...]:
    cols: list[tuple[str, type]] = [(f"reward_{t.name}", float) for t in REWARDS]
    cols += [(f"cost_{t.name}", float) for t in COSTS]
    cols += [("cost", float)] if COSTS else []
    cols += [(i.name, i.dtype) for i in INFOS]
    return tuple(cols)


_check_names()
INFO_COLUMNS: tuple[tuple[str, type], ...] = _info_columns()
"""(key, type) of every column of the kernels' info matrix ``I`` (all tasks): reward terms, cost
terms, ``cost`` (if any cost term), then :data:`INFOS`."""
N_INFO = len(INFO_COLUMNS)

# slot namespaces the kernels index with (numba freezes module-level namedtuples of ints)
R = _slots("RewardColumns", [t.name for t in REWARDS])
"""Info column of each reward term: ``I[r, R.chaos]``."""
C = _slots("CostColumns", [t.name for t in COSTS], len(REWARDS))
"""Info column of each cost term: ``I[r, C.<name>]``."""
IX = _slots("InfoColumns", [k for k, _ in INFO_COLUMNS[len(REWARDS) + len(COSTS) :]], len(REWARDS) + len(COSTS))
"""Info column of every non-term key (``IX.omega``; ``IX.cost`` when a cost term exists)."""
DERIVED_SLOTS: tuple[tuple[str, Callable[[Any], float]], ...] = (
    ("action_lo", lambda cfg: action_bounds(cfg)[0]),
    ("action_hi", lambda cfg: action_bounds(cfg)[1]),
)
"""Kernel slots computed from several settings: (name, value of a validated config)."""
P = _slots("SettingSlots", [s.name for s in all_settings() if s.kernel is not None] + [n for n, _ in DERIVED_SLOTS])
"""Slot of each kernel setting in the settings vector ``S``: ``S[P.w_chaos]``; then :data:`DERIVED_SLOTS`."""
N_SETTINGS = len(P)
F = _slots("FeatureColumns", [o.name for o in OBSERVATIONS])
"""Column of each observation feature in the kernels' feature matrix (the observation gathers its entries)."""
N_FEATURES = len(F)
COST_COLUMN = IX.cost if COSTS else -1
"""Info column of ``cost`` (-1 when no cost term is declared)."""


def _in(tasks: tuple[str, ...], task_id: str) -> bool:
    return not tasks or task_id in tasks


@dataclass(frozen=True)
class TaskTerms:
    """The table as one task sees it (see :func:`task`)."""

    task_id: str
    settings: tuple[Setting, ...]
    rewards: tuple[Term, ...]
    costs: tuple[Term, ...]
    infos: tuple[Info, ...]
    observations: tuple[Observation, ...]

    # -------------------------------------------------------------- info
    @property
    def reward_keys(self) -> tuple[str, ...]:
        """``reward_<name>`` of the task's reward terms, in summation order."""
        return tuple(f"reward_{t.name}" for t in self.rewards)

    @property
    def cost_keys(self) -> tuple[str, ...]:
        """``cost_<name>`` of the task's cost terms (their sum is ``info["cost"]``)."""
        return tuple(f"cost_{t.name}" for t in self.costs)

    @property
    def info_keys(self) -> dict[str, type]:
        """``info`` keys of the task and the Python type of each value, in column order."""
        keep = set(self.reward_keys) | set(self.cost_keys) | {i.name for i in self.infos}
        if self.costs:
            keep.add("cost")
        return {k: t for k, t in INFO_COLUMNS if k in keep}

    def info_columns(self) -> np.ndarray:
        """Columns of the kernels' info matrix that make up the task's ``info`` (int64)."""
        keys = self.info_keys
        return np.array([j for j, (k, _) in enumerate(INFO_COLUMNS) if k in keys], np.int64)

    def reward_columns(self) -> np.ndarray:
        """Info columns the reward is summed over, in order (int64)."""
        return np.array([getattr(R, t.name) for t in self.rewards], np.int64)

    def cost_columns(self) -> np.ndarray:
        """Info columns ``info["cost"]`` is summed over, in order (int64)."""
        return np.array([getattr(C, t.name) for t in self.costs], np.int64)

    # -------------------------------------------------------------- config
    @property
    def field_names(self) -> tuple[str, ...]:
        """Config fields of the task, in order."""
        return tuple(s.name for s in self.settings)

    def settings_vector(self, cfg: Any) -> np.ndarray:
        """The kernels' settings vector ``S`` (float64, slots :data:`P`) of a validated config; slots of
        settings the task does not have are 0 (the terms that use them are not summed)."""
        S = np.zeros(N_SETTINGS)
        for s in self.settings:
            if s.kernel is not None:
                S[getattr(P, s.name)] = float(s.kernel(getattr(cfg, s.name)))
        for name, value in DERIVED_SLOTS:
            S[getattr(P, name)] = float(value(cfg))
        return S

    # -------------------------------------------------------------- observation
    def observation_entries(self, cfg: Any) -> tuple[Observation, ...]:
        """The observation features present under ``cfg``, in order."""
        return tuple(o for o in self.observations if o.when is None or o.when(cfg))

    def observation_names(self, cfg: Any) -> tuple[str, ...]:
        """Names of the observation entries under ``cfg``."""
        return tuple(o.name for o in self.observation_entries(cfg))

    def observation_columns(self, cfg: Any) -> np.ndarray:
        """Feature columns (:data:`F`) the observation gathers, in order (int64)."""
        return np.array([getattr(F, o.name) for o in self.observation_entries(cfg)], np.int64)

    def observation_bounds(self, cfg: Any) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) float32 bounds of the observation Box under ``cfg``."""
        obs = self.observation_entries(cfg)
        return np.array([o.low for o in obs], np.float32), np.array([o.high for o in obs], np.float32)

    # -------------------------------------------------------------- docs
    def markdown(self, which: str) -> str:
        """A Markdown table of the task's ``"settings"``, ``"rewards"``, ``"costs"``, ``"info"`` or
        ``"observations"`` (the tables of docs/ENVIRONMENT.md)."""

        def row(*cells: Any) -> str:
            return "| " + " | ".join(str(c) for c in cells) + " |"

        if which == "settings":
            lines = [row("setting", "default", "range", "meaning"), row("---", "---", "---", "---")]
            lines += [row(s.name, s.shown or _fmt(s.default), s.range, s.doc) for s in self.settings]
        elif which in ("rewards", "costs"):
            prefix, terms = ("reward", self.rewards) if which == "rewards" else ("cost", self.costs)
            lines = [row("info key", "term", "weight (default)", "meaning"), row("---", "---", "---", "---")]
            lines += [
                row(f"{prefix}_{t.name}", f"`{t.formula}`", f"{t.weight_name} ({_fmt(t.default)})", t.doc)
                for t in terms
            ]
            if which == "costs" and terms:
                lines.append(row("cost", "sum of the cost terms", "", "non-negative, for safe-RL libraries"))
        elif which == "info":
            lines = [row("key", "type", "meaning"), row("---", "---", "---")]
            lines += [row(i.name, i.dtype.__name__, i.doc) for i in self.infos]
        elif which == "observations":
            lines = [row("#", "name", "meaning", "range"), row("---", "---", "---", "---")]
            lines += [
                row(k, o.name, o.doc, f"[{_fmt(o.low)}, {_fmt(o.high)}]") for k, o in enumerate(self.observations)
            ]
        else:
            raise ValueError(f"which must be settings, rewards, costs, info or observations, got {which!r}")
        return "\n".join(lines)


def _fmt(v: Any) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if v is None:
        return "None"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def task(task_id: str) -> TaskTerms:
    """The table entries of one task of :data:`TASKS`."""
    if task_id not in TASKS:
        raise ValueError(f"task_id must be one of {list(TASKS)}, got {task_id!r}")
    return TaskTerms(
        task_id,
        tuple(s for s in all_settings() if _in(s.tasks, task_id)),
        tuple(t for t in REWARDS if _in(t.tasks, task_id)),
        tuple(t for t in COSTS if _in(t.tasks, task_id)),
        tuple(i for i in INFOS if _in(i.tasks, task_id)),
        tuple(o for o in OBSERVATIONS if _in(o.tasks, task_id)),
    )


# ---------------------------------------------------------------------------------------- docs tool
_MARK = re.compile(r"<!-- table:(?P<task>[\w.-]+):(?P<which>\w+) -->\n.*?<!-- /table -->", re.S)


def update_docs(text: str) -> str:
    """Replace every ``<!-- table:TASK:WHICH -->`` ... ``<!-- /table -->`` block of ``text`` by the
    table generated from the declarations (see :meth:`TaskTerms.markdown`)."""

    def sub(m: re.Match[str]) -> str:
        body = task(m["task"]).markdown(m["which"])
        return f"<!-- table:{m['task']}:{m['which']} -->\n{body}\n<!-- /table -->"

    return _MARK.sub(sub, text)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gear_env.envs.env_terms FILE.md``: rewrite the generated tables of a Markdown file."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m gear_env.envs.env_terms docs/ENVIRONMENT.md", file=sys.stderr)
        return 2
    from pathlib import Path

    from ..io import atomic_write_text

    path = Path(args[0])
    old = path.read_text(encoding="utf-8")
    new = update_docs(old)
    if new != old:
        atomic_write_text(path, new)
    print(f"{path}: {'updated' if new != old else 'up to date'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
