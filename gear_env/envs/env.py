"""``GearSpeed-v0``: schedule the meshing frequency of a spur gear-bearing pair.

The physics, features and reward live in :mod:`gear_env.envs.env_core` (shared with the vector env);
the configuration in :mod:`gear_env.envs.env_config`.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .env_config import GearSpeedConfig
from .env_core import INFO_KEYS, REWARD_KEYS, SENSOR_NAMES, TERMS, GearSpeedCore, check_options, check_seed


def _check_make_time_limit() -> bool:
    """Check ``gym.make(ID, max_episode_steps=...)``; True when the value is Gymnasium's ``-1``.

    Gymnasium applies the value only after the env is built, so it is read from the ``make`` call that is
    building this env. A positive integer is the time limit; ``-1`` is Gymnasium's documented "no
    ``TimeLimit`` wrapper" (the env then truncates at its own ``max_steps``, so episodes still end);
    anything else (0, other negatives, NaN, a bool, a float) is refused with a ValueError here, where
    Gymnasium would silently drop the limit or raise its own TypeError."""
    import sys

    from gymnasium.envs import registration

    frame: Any = sys._getframe(1)
    for _ in range(8):
        if frame is None:
            return False
        if frame.f_code is registration.make.__code__:
            v = frame.f_locals.get("max_episode_steps")
            if v is None:
                return False
            return check_time_limit(v) == -1
        frame = frame.f_back
    return False


MAX_TIME_LIMIT = 10**9
"""Largest ``max_episode_steps`` accepted (steps)."""


def check_time_limit(v: Any) -> int:
    """``v`` if it is a valid ``max_episode_steps``: a Python integer in [1, :data:`MAX_TIME_LIMIT`] or -1.

    Refused with a ValueError: 0, other negatives, NaN, bools, floats, strings, numpy integers (Gymnasium's
    ``make`` raises its own TypeError for those) and values beyond the bound."""
    if isinstance(v, bool) or not isinstance(v, int) or not (1 <= v <= MAX_TIME_LIMIT or v == -1):
        raise ValueError(
            f"max_episode_steps must be a Python integer in [1, {MAX_TIME_LIMIT}] (the episode's time limit) or -1 "
            f"(no TimeLimit wrapper: the env truncates at its own max_steps), got {v!r}; omit it for the task's own "
            "episode length"
        )
    return v


def check_action(action: Any, n: int | None = None) -> np.ndarray:
    """Validate actions in [-1, 1] and return them as float64 (shape (n,) or (1,)).

    Accepts shape (1,) (or a scalar) for one env, (n, 1) or (n,) for n envs. NaN, inf or any other
    shape raises ``ValueError`` naming the action. Finite values outside [-1, 1] are clipped.
    """
    if n is None and type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        v = float(action[0])  # fast path: what SB3 and the samplers pass
        if not math.isfinite(v):
            raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
        return np.array([min(max(v, -1.0), 1.0)])
    try:
        if np.iscomplexobj(action):  # a cast would silently drop the imaginary part
            raise TypeError
        raw = action if isinstance(action, np.ndarray) else np.asarray(action)
        if raw.dtype.kind in "SUVb" or (
            raw.dtype.kind == "O" and any(isinstance(x, (str, bytes, bool, np.bool_)) for x in raw.flat)
        ):
            raise TypeError  # text is refused, also when it spells a number ("0.1"), and so are bools (not 1.0)
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be a float array of shape (1,) in [-1, 1], got {action!r}") from None
    if n is None:
        if a.shape not in ((1,), ()):
            raise ValueError(f"action must have shape (1,), got shape {a.shape}: {action!r}")
        a = a.reshape(1)
    else:
        if a.shape not in ((n, 1), (n,)):
            raise ValueError(f"actions must have shape ({n}, 1), got shape {a.shape}")
        a = a.reshape(n)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
    return np.clip(a, -1.0, 1.0)


class GearSpeedEnv(gym.Env):
    """Schedule the meshing frequency of a spur gear-bearing pair with backlash.

    ## Description

    A pinion and a gear on elastic bearings mesh with a time-varying stiffness, a static
    transmission error and backlash (constant or centre-distance dependent "dynamic" backlash); see
    docs/MODEL.md. The agent sets the meshing frequency omega = Omega/omega_n (proportional to
    speed, hence throughput at constant torque) like a motor drive: each step lasts
    ``periods_per_step`` mesh periods (default 24) during which omega ramps linearly in time to the
    new value, at most ``max_domega`` (default 0.05) per step. The simulator state carries over
    between steps, so hysteresis and coexisting attractors are part of the task. Over
    omega in [0.1, 3] the default gear pair is period-1 in ~[0.1, 0.3] and [0.6, 1.6], non-periodic
    (period doubling, torus, chaos) in ~[0.35, 0.55] and [1.65, 2.55], and period-1 but impacting
    (73 % contact loss) in [2.6, 3]. The agent must find the fast, quiet window from the sensors.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``. ``action_mode="delta"`` (default): new omega = omega +
    a * max_domega. ``action_mode="target"``: target omega = omega_min + (a + 1)/2 (omega_max -
    omega_min), approached at most max_domega per step; with ``reference_filter`` = alpha < 1 the
    drive's reference first closes the fraction alpha of the error (a first-order filter):
    new omega = omega + clip(alpha (target - omega), +-max_domega). ``action_mode="limit"`` (with a
    demand): the same value is a speed limit and the target is min(demand of the step, limit).
    ``action_range=(lo, hi)`` maps the actions of target and limit modes onto [lo, hi] instead of
    [omega_min, omega_max]. Always clipped to [omega_min, omega_max].
    NaN/inf or a wrong shape raise ``ValueError``.

    ## Observation Space

    ``Box(float32)`` of sensor-like features of the last step (``observation="sensors"``):

    {observations}

    F_s is the static mesh force. The periodicity defect is ``min_{p=1..8} max_k |P_{k+p} - P_k|``
    over the last ``poincare_window`` (16) Poincare samples P_k = (Delta, dU/omega) [b0], one per
    mesh period: ~0 for period-p motion, large for quasi-periodic or chaotic motion.

    ## Rewards

    Per step, with c = clip(defect / defect_scale, 0, 1) (defect_scale = 0.02 b0), F_peak the
    largest mesh force of the step and F_s the static one, the reward is the sum of the terms (each
    in ``info``; on a diverging step only ``reward_divergence`` is not 0):

    {rewards}

    The terms, their weights and the info keys are declared in :mod:`gear_env.envs.env_terms`. With the
    default model the best constant speed is omega ~1.2 (docs/ENVIRONMENT.md has the steady reward
    curve).

    ## Starting State

    The static equilibrium (drive-side contact), then ``warmup_periods`` (48) mesh periods at the
    initial omega, drawn uniformly from ``initial_omega`` (default [omega_min, omega_max]; the
    ``reset(options={"omega": w})`` option fixes it). The first observation describes the last
    ``periods_per_step`` warm-up periods.

    ## Episode End

    Truncation after ``max_steps`` (200) steps. Termination only if the integration diverges
    (non-finite state or Newton failure): reward -divergence_penalty, ``info["diverged"] = True``,
    the observation repeats the last finite one.

    ## Info

    The same keys on every step (and on reset): the reward terms above, then

    {info}

    ## Arguments

    ``gym.make("GearSpeed-v0", **settings)`` or ``GearSpeedEnv(config=None, render_mode=None,
    **settings)``; the settings are the fields of :class:`GearSpeedConfig` (e.g. ``params``,
    ``model``, ``periods_per_step``, ``max_domega``, ``action_mode``, ``demand``,
    ``randomize_params``, reward weights). Unknown settings raise ``ValueError``.

    ## Tasks

    One class, nine registered tasks (``gear_env.envs.tasks.TASK_SETTINGS``; docs/ENVIRONMENT.md says why):
    ``GearSpeed-v0`` (the defaults), ``GearSpeed-v1`` (speed-reference actions, 48-period control
    step, 0.1 per step, 100 steps), ``GearSpeedDemand-v0`` (as v1, plus a gear pair drawn per
    episode from a family, a load duty cycle and a random operator demand; throughput paid only up to
    the demand) and ``GearSpeedDemandHard-v0`` (as GearSpeedDemand-v0, with noisy sensors, a one-step
    actuator dead time and a wear change of the pair within the episode), plus ``GearSpeedDemandLimit-v0``
    (Demand-v0 with a rate-limited speed-limit action) and the Fox-Goodwin ids ``GearSpeed-v2``,
    ``GearSpeedDemand-v1``, ``GearSpeedDemandLimit-v1``, ``GearSpeedDemandHard-v1`` (the four before them with
    ``scheme="fox-goodwin-vc"``: Newmark beta 1/12 with the velocity correction, the same cost per step, 10x less
    integration error; ``gear_env.envs.tasks.FOX_GOODWIN_TASKS``). ``self.episode`` is the
    episode's scenario (an oracle may read it; the agent does not see it). ``info["cost"]`` (>= 0) sums
    the cost terms for safe-RL libraries.

    ## Version History

    * v0: initial version (delta actions, 24 mesh periods per step, 200 steps). Unchanged by v1,
      except the new ``info`` keys ``cost`` and ``cost_*`` and its registration with
      ``max_episode_steps=200``.
    * v1: the default task made well-posed for stock PPO: ``action_mode="target"`` (a speed reference,
      approached at the acceleration limit), ``periods_per_step=48`` and ``max_domega=0.1`` (the same
      acceleration as v0, half the decisions), ``max_steps=100`` (the same physical episode).
      Revised in place in gear-env 0.4.0 (same id; its issue was still open): ``reference_filter=0.1``, the
      drive's first-order reference filter, with which stock PPO holds the window instead of cycling through
      it. ``gym.make("GearSpeed-v1", reference_filter=1.0)`` is the 0.3.0 task.
    * GearSpeedDemand-v0: the first version of the demand task (family: load x0.4-1.5, ``e_m1``
      x0.25-2; demand band ``demand_range=(1.2, 1.8)``; both settled before the first release).
      Changed in place in gear-env 0.4.0 (issue #16 open): ``reference_filter=0.1`` (was 1.0) and
      ``memory_steps=20`` (was 0: the observation gains ``trouble_omega``, ``trouble_recency``,
      ``prev_force_rms``, ``prev_contact_loss``); the shipped policy was retrained on it.
    * GearSpeed-v2, GearSpeedDemand-v1, GearSpeedDemandLimit-v1, GearSpeedDemandHard-v1 (issue #24): GearSpeed-v1,
      GearSpeedDemand-v0, GearSpeedDemandLimit-v0 and GearSpeedDemandHard-v0 integrated with Newmark beta 1/12 and
      the velocity correction (``scheme="fox-goodwin-vc"``); the older ids are unchanged.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(self, config: GearSpeedConfig | dict | None = None, render_mode: str | None = None, **kwargs: Any):
        self._no_time_limit_wrapper = _check_make_time_limit()
        super().__init__()
        self.config = GearSpeedConfig.from_kwargs(config, **kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self._core = GearSpeedCore(self.config, 1, single=True)
        self._row0 = np.zeros(1, np.int64)  # the core's row of this env (read-only: passed every step)
        self._row0.flags.writeable = False
        lo, hi = self._core.observation_bounds()
        self.observation_space = spaces.Box(lo, hi, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.observation_names: tuple[str, ...] = self._core.observation_names
        """Name of each observation entry (the ``OBSERVATIONS`` entries of :mod:`gear_env.envs.env_terms`)."""
        self.obs_names = list(self.observation_names)  # older name, kept
        self._needs_reset = True
        self._wrapper_truncates = False  # set at reset (see _adopt_time_limit)
        self._history: list[tuple[float, float, float, float]] = []  # (omega, chaos, contact loss, force peak)
        self._renderer: Any = None

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``options={"omega": w}`` fixes the initial meshing frequency.

        ``seed``: None or an integer >= 0; ``options``: None or a dict (only key ``"omega"``);
        anything else raises ``ValueError`` before the env changes.
        """
        seed = check_seed(seed)  # an np.int64 becomes an int (Gymnasium's seeding takes only int)
        check_options(options, ("omega",))
        super().reset(seed=seed)
        self._adopt_time_limit()
        self._core.reset_rows(np.array([0]), [self.np_random], options)
        self._needs_reset = False
        info = self._core.info_row(0)
        self._history = [(info["omega"], info["chaos"], info["contact_loss"], info["force_peak"])]
        if self.render_mode == "human":
            self.render()
        return self._core.obs[0].copy(), info

    def step(self, action: Any):
        """Advance one control step (``periods_per_step`` mesh periods)."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (and after an episode ended)")
        a = check_action(action)
        reward, terminated, truncated = self._core.step_rows(self._row0, a)
        info = self._core.info_row(0)
        self._history.append((info["omega"], info["chaos"], info["contact_loss"], info["force_peak"]))
        term, trunc = bool(terminated[0]), bool(truncated[0]) and not self._wrapper_truncates
        if term or trunc:
            self._needs_reset = True
        if self.render_mode == "human":
            self.render()
        return self._core.obs[0].copy(), float(reward[0]), term, trunc, info

    def render(self):
        """``rgb_array``: an (H, W, 3) uint8 frame; ``human``: draw in a matplotlib window."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from .render import EnvRenderer

        if self._renderer is None:
            self._renderer = EnvRenderer(self.config, human=self.render_mode == "human")
        return self._renderer.draw(
            np.array(self._history, float).reshape(-1, 4), self._core.hist[0].copy(), self.render_mode == "rgb_array"
        )

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ extras
    @property
    def omega(self) -> float:
        """Current meshing frequency Omega/omega_n."""
        return float(self._core.omega[0])

    @property
    def state(self) -> np.ndarray:
        """Copy of the hidden simulator state (10 values, b0 units)."""
        return self._core.X[0].copy()

    def _adopt_time_limit(self) -> None:
        """Who truncates: made by ``gym.make`` (registered with ``max_episode_steps``), Gymnasium's
        ``TimeLimit`` wrapper does, so ``gym.make(ID, max_episode_steps=N)`` ends episodes at N; the
        env's own ``max_steps`` then only sizes the demand profile and the duty cycle (held at their last
        values beyond it). An explicit ``max_steps`` keyword keeps truncating at its value; one above the
        registered limit is refused (the wrapper would cut first): pass ``max_episode_steps`` instead."""
        self._wrapper_truncates = False
        spec = self.spec
        if self._no_time_limit_wrapper or spec is None or spec.id not in gym.registry:
            return
        reg = gym.spec(spec.id)
        if reg.max_episode_steps is None:
            return
        given = (spec.kwargs or {}).get("max_steps")
        default = (reg.kwargs or {}).get("max_steps", GearSpeedConfig().max_steps)
        if given is None or given == default:
            self._wrapper_truncates = True
        elif given > reg.max_episode_steps:
            raise ValueError(
                f"gym.make({spec.id!r}, max_steps={given}) asks for longer episodes than the registered time limit "
                f"({reg.max_episode_steps} steps): use gym.make({spec.id!r}, max_episode_steps={given})"
            )

    @property
    def episode(self) -> Any:
        """The current episode's scenario (:class:`gear_env.envs.tasks.Episode`: plant, duty cycle, demand);
        what an oracle may know, never part of the observation."""
        return self._core.episodes[0]

    def __getstate__(self):
        d = self.__dict__.copy()
        d["_renderer"] = None
        return d


def _doc_tables(doc: str) -> str:
    """Fill the ``{observations}``, ``{rewards}`` and ``{info}`` tables of the class docstring from the table."""
    for which in ("observations", "rewards", "info"):
        table = TERMS.markdown(which).replace("\n", "\n    ")
        doc = doc.replace("{" + which + "}", table)
    return doc


GearSpeedEnv.__doc__ = _doc_tables(GearSpeedEnv.__doc__ or "")


__all__ = ["GearSpeedConfig", "GearSpeedEnv", "INFO_KEYS", "REWARD_KEYS", "SENSOR_NAMES", "check_action"]
