"""Speed schedules for the GearSpeed tasks: hand-written omega(t) profiles used as policies.

A :class:`SpeedSchedule` is a piecewise-linear omega(t) with t in environment steps (held constant
after the last point, and before the first). It behaves like a stable-baselines3 model:
``predict(obs, state=None, episode_start=None, deterministic=True) -> (actions, state)``, so it
works with ``stable_baselines3.common.evaluation.evaluate_policy``, with
:func:`gear_env.evaluation.evaluate_policies`, and in a plain Gymnasium loop.

The action drives omega towards the schedule's value at the end of the coming step: in ``delta``
action mode from the omega decoded from the observation (entry 0), in ``target`` mode directly.
The environment's rate limit (``max_domega`` per step) still applies, so a steep schedule is
followed as fast as the motor allows.

**Which task.** The action a schedule produces depends on the task (a change of omega on
``GearSpeed-v0``, a filtered speed reference on ``GearSpeed-v1``), so a schedule is bound to one:
``config=`` takes a task id (``"GearSpeed-v1"``), an environment made by ``gym.make`` (its own
settings), a :class:`~gear_env.envs.env_config.GearSpeedConfig` or a dict of settings. A schedule built
without ``config=`` is unbound: :func:`gear_env.evaluation.evaluate_policies` (and ``gear-env
evaluate``) bind it to the task they run, and :meth:`SpeedSchedule.predict` refuses to act until it is
bound (:meth:`SpeedSchedule.bind`). A bound schedule run on a task whose actions mean something else
(another action mode, rate limit or reference filter) is refused too.

Files (:meth:`SpeedSchedule.from_file`):

* CSV: two columns ``time,omega`` (time in env steps >= 0, omega = Omega/omega_n), one point per
  row; an optional header row; ``#`` comments and blank lines ignored.
* JSON: ``[[t, omega], ...]``, ``{"points": [[t, omega], ...]}`` or ``{"time": [...], "omega": [...]}``.

Times must be non-decreasing (a repeated time makes a step change); omegas must lie in the env's
[omega_min, omega_max]. Errors name the file, the row and the problem.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .env_config import GearSpeedConfig
from .env_terms import action_bounds

MAX_SCHEDULE_BYTES = 16 * 1024 * 1024
"""Largest schedule file read (bytes); a larger one is refused before it is read."""

ACTION_FIELDS = (
    "action_mode", "max_domega", "reference_filter", "omega_min", "omega_max", "action_range", "limit_rate"
)  # fmt: skip
"""The settings that decide what an action means: a schedule bound to one task runs on another only if
they agree."""


def _as_config(config: Any) -> GearSpeedConfig | None:
    """``config=`` of a schedule -> a GearSpeedConfig (None stays None: unbound).

    Accepts a GearSpeedConfig, a dict of settings, a registered task id or an environment (anything with
    ``unwrapped.config``, e.g. from ``gym.make``)."""
    if config is None or isinstance(config, GearSpeedConfig):
        return config
    if isinstance(config, str):
        from .env_config import task_config

        return task_config(config)
    inner = getattr(getattr(config, "unwrapped", None), "config", None)
    if isinstance(inner, GearSpeedConfig):
        return inner
    return GearSpeedConfig.from_kwargs(config)


def _validate_points(
    points: Any, cfg: GearSpeedConfig, where: str, row_names: Sequence[str] | None = None
) -> np.ndarray:
    """Check (t, omega) points and return an (m, 2) float array; errors name ``where`` and the row."""
    if points is None or len(points) == 0:
        raise ValueError(f"{where}: the schedule is empty (need at least one (time, omega) point)")
    out = np.empty((len(points), 2))
    for i, pt in enumerate(points):
        row = row_names[i] if row_names is not None else f"point {i}"
        if isinstance(pt, (str, bytes)) or not isinstance(pt, Sequence) or len(pt) != 2:
            raise ValueError(f"{where}, {row}: expected two values (time, omega), got {pt!r}")
        vals = []
        for name, v in zip(("time", "omega"), pt):
            try:
                if isinstance(v, bool):
                    raise TypeError
                x = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"{where}, {row}: {name} {v!r} is not a number") from None
            if not math.isfinite(x):
                raise ValueError(f"{where}, {row}: {name} {v!r} is not finite")
            vals.append(x)
        t, w = vals
        if t < 0:
            raise ValueError(f"{where}, {row}: time {t:g} is negative (times are env steps >= 0)")
        if i > 0 and t < out[i - 1, 0]:
            raise ValueError(
                f"{where}, {row}: time {t:g} is smaller than the previous time {out[i - 1, 0]:g} "
                "(times must be non-decreasing)"
            )
        if not cfg.omega_min <= w <= cfg.omega_max:
            raise ValueError(
                f"{where}, {row}: omega {w:g} is outside the env range [{cfg.omega_min:g}, {cfg.omega_max:g}]"
            )
        out[i] = (t, w)
    return out


class SpeedSchedule:
    """A piecewise-linear speed schedule omega(t), t in env steps, usable as a policy.

    Args:
        points: (time, omega) pairs, times non-decreasing and >= 0, omegas in the env range.
        config: the task the actions are meant for (omega range, max_domega, action mode, reference
            filter): a task id, an env from ``gym.make``, a ``GearSpeedConfig`` or a dict of settings.
            None (the default): unbound until :meth:`bind` (evaluate_policies binds it to its task).
        name: label for tables and plots.

    Use the constructors :meth:`constant`, :meth:`ramp`, :meth:`piecewise`, :meth:`from_file`
    and :meth:`from_spec`.
    """

    def __init__(
        self,
        points: Any,
        config: GearSpeedConfig | Mapping[str, Any] | str | Any | None = None,
        name: str | None = None,
    ):
        cfg = _as_config(config)
        self.bound = cfg is not None
        self.config = cfg if cfg is not None else GearSpeedConfig()  # the omega range is the same for every task
        self.points = _validate_points(points, self.config, name or "schedule")
        self.name = name or "schedule"
        self._counters = np.zeros(0, np.int64)

    def bind(self, config: Any) -> SpeedSchedule:
        """This schedule for the task ``config`` (task id, env, GearSpeedConfig or dict).

        Unbound: returns a bound copy (this object stays unbound, so it can be bound to other tasks).
        Bound: returns ``self`` if ``config`` gives actions the same meaning (:data:`ACTION_FIELDS`), else
        raises ``ValueError`` naming the settings that differ."""
        cfg = _as_config(config)
        if cfg is None:
            raise ValueError("SpeedSchedule.bind: config must name a task (task id, env, GearSpeedConfig or dict)")
        if not self.bound:
            out = SpeedSchedule.__new__(SpeedSchedule)
            out.bound, out.config, out.name = True, cfg, self.name
            out.points = _validate_points(self.points.tolist(), cfg, self.name)
            out._counters = np.zeros(0, np.int64)
            return out
        diff = [
            f"{k} {getattr(self.config, k)!r} vs {getattr(cfg, k)!r}"
            for k in ACTION_FIELDS
            if getattr(self.config, k) != getattr(cfg, k)
        ]
        if diff:
            raise ValueError(
                f"schedule {self.name!r} was built for a task whose actions mean something else than on this one "
                f"({'; '.join(diff)}): build it with config= the task it runs on (e.g. config=env or "
                f"config='GearSpeed-v1'), or without config= to let the evaluation bind it"
            )
        return self

    # ------------------------------------------------------------------ constructors
    @classmethod
    def constant(cls, omega: float, config: Any = None) -> SpeedSchedule:
        """Hold ``omega`` for the whole episode."""
        return cls([(0.0, omega)], config, name=f"constant {float(omega):g}")

    @classmethod
    def ramp(cls, omega_start: float, omega_end: float, steps: float, config: Any = None) -> SpeedSchedule:
        """Linear from ``omega_start`` (t = 0) to ``omega_end`` (t = ``steps``), then held."""
        if not (isinstance(steps, (int, float, np.integer, np.floating)) and math.isfinite(steps) and steps > 0):
            raise ValueError(f"ramp steps must be a number > 0, got {steps!r}")
        return cls(
            [(0.0, omega_start), (float(steps), omega_end)],
            config,
            name=f"ramp {float(omega_start):g}->{float(omega_end):g}/{float(steps):g}",
        )

    @classmethod
    def piecewise(cls, points: Any, config: Any = None, name: str | None = None) -> SpeedSchedule:
        """Piecewise linear through (time, omega) points."""
        return cls(points, config, name=name or "piecewise")

    @classmethod
    def from_file(cls, path: str | os.PathLike, config: Any = None) -> SpeedSchedule:
        """Load a CSV (``.csv``/``.txt``) or JSON (``.json``) file of (time, omega) points."""
        bound_cfg = _as_config(config)
        cfg = bound_cfg if bound_cfg is not None else GearSpeedConfig()
        p = os.fspath(path)
        where = f"schedule file {p!r}"
        from ..io import read_limited

        # a FIFO, directory, device or /proc file is refused by name (never waited on); size from stat first
        raw = read_limited(p, "schedule file", MAX_SCHEDULE_BYTES)
        try:
            if p.lower().endswith(".json"):
                points, rows = cls._read_json(raw, where)
            else:
                points, rows = cls._read_csv(raw, where)
        except UnicodeDecodeError as exc:  # e.g. UTF-16 or a binary file
            raise ValueError(f"{where} is not UTF-8 text ({exc})") from None
        except csv.Error as exc:
            raise ValueError(f"{where}: unreadable CSV ({exc})") from None
        sched = cls.__new__(cls)
        sched.bound = bound_cfg is not None
        sched.config = cfg
        sched.points = _validate_points(points, cfg, where, rows)
        sched.name = os.path.splitext(os.path.basename(p))[0]
        sched._counters = np.zeros(0, np.int64)
        return sched

    @staticmethod
    def _read_csv(raw: bytes, where: str) -> tuple[list[Any], list[str]]:
        import io

        points: list[Any] = []
        rows: list[str] = []
        text = raw.decode("utf-8-sig")  # -sig: tolerate a byte-order mark (Excel)
        for lineno, rec in enumerate(csv.reader(io.StringIO(text, newline="")), start=1):
            cells = [c.strip() for c in rec]
            if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
                continue
            if not points and not rows and _is_header(cells):
                continue
            points.append(cells if len(cells) != 2 else (cells[0], cells[1]))
            rows.append(f"row {lineno}")
        return points, rows

    @staticmethod
    def _read_json(raw: bytes, where: str) -> tuple[list[Any], list[str]]:
        from ..io import parse_json_text

        data = parse_json_text(raw.decode("utf-8-sig"), where)
        if isinstance(data, Mapping):
            if "points" in data:
                data = data["points"]
            elif "time" in data and "omega" in data:
                t, w = data["time"], data["omega"]
                if not isinstance(t, list) or not isinstance(w, list) or len(t) != len(w):
                    raise ValueError(f"{where}: 'time' and 'omega' must be lists of equal length")
                data = list(zip(t, w))
            else:
                raise ValueError(
                    f"{where}: expected a list of [time, omega] pairs, or an object with 'points' or 'time'/'omega'"
                )
        if not isinstance(data, list):
            raise ValueError(f"{where}: expected a list of [time, omega] pairs, got {type(data).__name__}")
        return data, [f"point {i}" for i in range(len(data))]

    @classmethod
    def from_spec(cls, spec: str, config: Any = None) -> SpeedSchedule:
        """A schedule from a command-line spec: a file path, or a built-in:

        ``constant:W``, ``ramp:W0:W1:STEPS``, ``piecewise:T0=W0,T1=W1,...``.
        """
        if not isinstance(spec, str) or not spec:
            raise ValueError(f"schedule spec must be a non-empty string, got {spec!r}")
        kind, _, rest = spec.partition(":")
        try:
            if kind == "constant" and rest:
                return cls.constant(float(rest), config)
            if kind == "ramp" and rest:
                a, b, n = rest.split(":")
                return cls.ramp(float(a), float(b), float(n), config)
            if kind == "piecewise" and rest:
                pts = [tuple(float(x) for x in item.split("=")) for item in rest.split(",")]
                return cls.piecewise(pts, config, name=spec)
        except ValueError as exc:
            if "schedule" in str(exc) or "ramp" in str(exc) or "omega" in str(exc):
                raise
            raise ValueError(
                f"bad schedule spec {spec!r}: use constant:W, ramp:W0:W1:STEPS, piecewise:T0=W0,T1=W1 or a file ({exc})"
            ) from None
        return cls.from_file(spec, config)

    # ------------------------------------------------------------------ evaluation
    def omega_at(self, t: float | np.ndarray) -> float | np.ndarray:
        """Scheduled omega at env step(s) t (held constant outside the points)."""
        out = np.interp(np.asarray(t, float), self.points[:, 0], self.points[:, 1])
        return out if np.ndim(t) else float(out)

    def action(self, obs: np.ndarray, t: np.ndarray | int) -> np.ndarray:
        """Actions (n, 1) for observations (n, n_obs) before step index ``t`` (per row)."""
        if not self.bound:
            raise ValueError(
                f"schedule {self.name!r} is not bound to a task, so it does not know what its actions mean "
                "(a change of omega on GearSpeed-v0, a speed reference on GearSpeed-v1): build it with config=env "
                "or config='GearSpeed-v1', call .bind(env), or run it through gear_env.evaluation.evaluate_policies"
            )
        cfg = self.config
        lo, hi = cfg.omega_min, cfg.omega_max
        obs = np.asarray(obs, float).reshape(-1, np.shape(obs)[-1])
        target = np.asarray(self.omega_at(np.asarray(t, float) + 1.0), float).reshape(-1)
        if cfg.action_mode != "delta":  # a set-point (target) or a limit the drive follows the demand under
            if cfg.reference_filter != 1.0:  # the set-point whose filtered step lands on the target
                w = lo + 0.5 * (obs[:, 0] + 1.0) * (hi - lo)
                target = np.clip(w + (target - w) / cfg.reference_filter, lo, hi)
            alo, ahi = action_bounds(cfg)
            a = 2.0 * (target - alo) / (ahi - alo) - 1.0
            if cfg.action_mode == "limit_rate":  # move the observed speed limit towards the scheduled speed
                x = obs[:, cfg.TERMS.observation_names(cfg).index("speed_limit")]
                limit = lo + 0.5 * (x + 1.0) * (hi - lo)
                a = (np.clip(target, alo, ahi) - limit) / cfg.limit_rate
        else:
            w = lo + 0.5 * (obs[:, 0] + 1.0) * (hi - lo)
            diff = target - w
            diff = np.where(np.abs(diff) < 1e-6 * (hi - lo), 0.0, diff)  # float32 observation round-off
            a = diff / cfg.max_domega
        return np.clip(a, -1.0, 1.0).astype(np.float32).reshape(-1, 1)

    def reset(self) -> None:
        """Forget the step counters (start of new episodes in a plain loop)."""
        self._counters = np.zeros(0, np.int64)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """SB3-style prediction for a batch of observations (or one).

        Keeps one step counter per env index: taken from ``state`` if given (SB3 passes back what
        it got), else from the schedule itself; reset to 0 where ``episode_start`` is True.
        Returns (actions (n, 1) float32 (shape (1,) for a single observation), new counters).
        """
        obs = np.asarray(observation)
        single = obs.ndim == 1
        obs2 = obs.reshape(1, -1) if single else obs
        n = obs2.shape[0]
        if state is not None:
            counters = np.asarray(state, np.int64).reshape(-1).copy()
        else:
            counters = self._counters.copy()
        if counters.shape != (n,):
            counters = np.zeros(n, np.int64)
        if episode_start is not None:
            counters[np.asarray(episode_start, bool).reshape(-1)[:n]] = 0
        actions = self.action(obs2, counters)
        counters = counters + 1
        self._counters = counters.copy()
        return (actions[0] if single else actions), counters

    def __repr__(self) -> str:
        return f"SpeedSchedule({self.name!r}, points={self.points.tolist()})"


def _is_header(cells: Sequence[str]) -> bool:
    try:
        [float(c) for c in cells]
        return False
    except ValueError:
        return all(any(ch.isalpha() for ch in c) for c in cells if c)


__all__ = ["SpeedSchedule"]
