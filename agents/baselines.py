"""Scripted speed policies for the GearSpeed tasks with the SB3 ``predict`` interface.

Every policy here reads only the observation (omega is observation[0], scaled linearly from
[omega_min, omega_max] to [-1, 1]; the vibration features follow ``gear_env.envs.env_core.SENSOR_NAMES``)
and returns actions for either action mode of the environment, so PPO models, these baselines,
the oracle and the schedules of ``gear_env.envs.schedules`` are all evaluated by the same code
(``gear_env.evaluation.evaluate_policies``).

**Which task.** What an action means depends on the task (a change of omega on GearSpeed-v0, a filtered
speed reference on GearSpeed-v1), so a policy is built for one: ``config=`` takes a GearSpeedConfig or a
dict of settings of :data:`agents.envs.GEAR_ENV_ID` (GearSpeed-v1). A policy built without ``config=``
follows the task it runs on: ``evaluate_policies`` / ``run_episode`` call :meth:`ScriptedPolicy.bind`
with the environment's config, which rebuilds it for that task; until then it acts for GearSpeed-v1. A
policy built with ``config=`` and run on a task whose actions mean something else is refused.

* :class:`ConstantSpeed` - go to a fixed omega at the maximum rate and hold it ("constant:1.2";
  "constant-best" uses the omega of the best steady reward, found by :func:`best_constant_omega`).
* :class:`SlowRamp` - ramp towards a target omega at a fraction of the maximum rate ("ramp").
* :class:`HillClimber` - greedy: raise omega while the sensors show periodic, contact-free,
  impact-free motion; back off when the periodicity defect, contact loss or impacts rise, and do
  not climb again above the lowest speed where trouble was seen ("hill-climber").
"""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np

from .envs import control_parameters
from .policy import BasePolicy

OBS_OMEGA = 0
OBS_DEFECT = 5  # log1p(periodicity defect / defect_scale)
OBS_CONTACT = 7  # contact-loss fraction of the step
OBS_DRIVE_IMPACTS = 8  # drive-side re-impacts per mesh period
OBS_BACK_IMPACTS = 9  # back-side impacts per mesh period
OBS_DEMAND = 10  # demand of the next step, scaled like omega (only with a demand)


class ScriptedPolicy(BasePolicy):
    """Base class: converts a desired omega per environment into actions for the configured mode.

    Subclasses implement ``_targets(omega, obs, state) -> (target omega (n,), state)``.
    ``predict`` accepts one observation (shape (obs_dim,)) or a batch (n, obs_dim) and returns
    float32 actions of shape (1,) or (n, 1) in [-1, 1], plus the recurrent-style ``state``
    (per-environment memory; reset where ``episode_start`` is True)."""

    name = "scripted"

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        self = super().__new__(cls)
        self._ctor = (args, kwargs)  # the constructor's arguments: bind() rebuilds an unbound policy with them
        return self

    def __init__(self, config: Any = None):
        self.config = config
        self.bound = config is not None  # built for a task; unbound ones follow the task they run on (bind)
        cp = control_parameters(config)
        self.omega_min = float(cp["omega_min"])
        self.omega_max = float(cp["omega_max"])
        self.max_domega = float(cp["max_domega"])
        self.action_mode = str(cp["action_mode"])
        self.action_low, self.action_high = float(cp["action_low"]), float(cp["action_high"])
        self.reference_filter = float(cp.get("reference_filter", 1.0))
        self.max_steps = int(cp["max_steps"])
        self.has_demand = bool(cp.get("has_demand", False))
        self.action_delay = int(cp.get("action_delay", 0))
        self.sensor_noise = float(cp.get("sensor_noise", 0.0))
        self.limit_rate = float(cp.get("limit_rate", 0.0))
        self.limit_column = int(cp.get("limit_column", -1))
        self._decoder = None  # the environment's own action decoder, built on the first need (omega_after)

    def bind(self, config: Any) -> ScriptedPolicy:
        """This policy for the task whose (GearSpeedConfig) ``config`` it runs on.

        Built without ``config=``: returns ``self`` if ``config`` is the default task's configuration, else
        the policy rebuilt with the same arguments and ``config=config``. Built with ``config=``: returns
        ``self`` if ``config`` gives actions the same meaning (``gear_env.envs.schedules.ACTION_FIELDS`` and the
        actuator dead time), else raises ``ValueError`` naming the settings that differ."""
        from gear_env.envs.schedules import ACTION_FIELDS

        from .envs import GEAR_ENV_ID, make_config

        mine, theirs = make_config(GEAR_ENV_ID, self.config), make_config(GEAR_ENV_ID, config)
        if not self.bound:
            if mine == theirs:
                return self
            args, kwargs = self._ctor
            sig = inspect.signature(type(self).__init__)
            if "config" not in sig.parameters:
                raise TypeError(f"{type(self).__name__} takes no config=, so it cannot be rebuilt for a task")
            call = sig.bind_partial(None, *args, **kwargs)  # None: self
            call.arguments["config"] = theirs
            return type(self)(*call.args[1:], **call.kwargs)
        fields = (*ACTION_FIELDS, "action_delay")
        diff = [
            f"{k} {getattr(mine, k)!r} vs {getattr(theirs, k)!r}"
            for k in fields
            if getattr(mine, k) != getattr(theirs, k)
        ]
        if diff:
            raise ValueError(
                f"policy {self.name!r} was built for a task whose actions mean something else than on this one "
                f"({'; '.join(diff)}): build it with config= the task it runs on (e.g. config=env.unwrapped.config), "
                "or without config= to let the evaluation bind it"
            )
        return self

    # ---- conversions ----------------------------------------------------------------------------
    def omega_from_obs(self, obs: np.ndarray) -> np.ndarray:
        """Meshing frequency (n,) from observations (n, obs_dim)."""
        x = np.asarray(obs, float)[:, OBS_OMEGA]
        return self.omega_min + 0.5 * (x + 1.0) * (self.omega_max - self.omega_min)

    def action_to(self, omega: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Action (n,) that moves omega towards ``target`` as fast as the rate limit allows."""
        target = np.clip(np.asarray(target, float), self.omega_min, self.omega_max)
        if self.action_mode == "delta":
            a = (target - omega) / self.max_domega
        else:  # target or limit mode (the limit caps the set-point at the demand): the environment filters and
            # rate-limits the move itself
            if self.reference_filter != 1.0:  # the set-point whose filtered step lands on the target
                target = np.clip(omega + (target - omega) / self.reference_filter, self.omega_min, self.omega_max)
            a = 2.0 * (target - self.action_low) / (self.action_high - self.action_low) - 1.0
        return np.clip(a, -1.0, 1.0)

    # ---- the policy interface (BasePolicy.predict wraps this) -------------------------------------
    def predict_batch(
        self, observations: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """Actions (n, 1) for observations (n, obs_dim); ``state`` carries per-environment memory."""
        obs = np.asarray(observations, dtype=np.float64)
        if not np.all(np.isfinite(obs)):
            raise ValueError(f"observation must be a finite array of shape (obs_dim,) or (n, obs_dim), got {obs.shape}")
        n = obs.shape[0]
        state = self._state(state, n, episode_start)
        omega = self.omega_from_obs(obs)
        if not self.action_delay:
            target, state = self._targets(omega, obs, state)
            a = self.action_to(omega, target)
            if self.action_mode == "limit_rate":
                a = self.rate_action(obs, a)
            return a.astype(np.float32).reshape(n, 1), state
        # actuator dead time (a Smith predictor): the actions already sent drive the next steps, so the
        # target is decided from what is sensed now and commanded from the omega those actions will leave
        fresh = state["sent"] == 0
        if fresh.any():  # the drive holds the initial speed until the first action arrives
            state["pending"][fresh] = self.action_to(omega[fresh], omega[fresh])[:, None]
        ahead = self.omega_after(omega, state["pending"], _obs_demand(self, obs) if self.has_demand else None)
        state["omega_ahead"] = ahead
        target, state = self._targets(omega, obs, state)
        a = self.action_to(ahead, target).astype(np.float32).astype(float)  # as the environment receives it
        state["pending"] = np.concatenate([state["pending"][:, 1:], a[:, None]], axis=1)
        state["sent"] = state["sent"] + 1
        return a.astype(np.float32).reshape(n, 1), state

    def rate_action(self, obs: np.ndarray, limit_actions: np.ndarray) -> np.ndarray:
        """limit_rate mode: the actions (n,) that move the observed speed limit (entry ``speed_limit``) so that the
        drive does what the limit-mode actions ``limit_actions`` (n,) would make it do, as far as ``limit_rate``
        allows in a step. A limit L at or above the coming demand d means "follow the demand": then any limit in
        [d, L] does the same, and the one nearest the present limit is taken (the limit is not pulled down to a
        low demand, which it would have to climb back from at ``limit_rate`` per step); below d, L itself."""
        want = self.action_low + 0.5 * (np.asarray(limit_actions, float) + 1.0) * (self.action_high - self.action_low)
        x = np.asarray(obs, float)[:, self.limit_column]
        have = self.omega_min + 0.5 * (x + 1.0) * (self.omega_max - self.omega_min)
        d = _obs_demand(self, obs)
        want = np.where(want >= d, np.clip(have, np.minimum(d, want), want), want)
        return np.clip((want - have) / self.limit_rate, -1.0, 1.0)

    def omega_after(self, omega: np.ndarray, actions: np.ndarray, demand: np.ndarray | None = None) -> np.ndarray:
        """Omega (n,) after the actions (n, k) drive k steps from ``omega``, decoded by the environment's own
        kernel (``gear_env.envs.env_kernels.decode_actions``: delta, target or limit mode, reference filter, rate
        limit). ``demand`` (n,): the demand those steps follow in limit mode (taken as constant over them)."""
        if self._decoder is None:
            from gear_env.envs.env_kernels import decode_actions
            from gear_env.envs.env_terms import ACTION_CODES

            from .envs import GEAR_ENV_ID, make_config

            c = make_config(GEAR_ENV_ID, self.config)
            self._decoder = (decode_actions, c.TERMS.settings_vector(c), ACTION_CODES[c.action_mode])
        decode, S, mode = self._decoder
        w = np.array(omega, float)
        d = np.full_like(w, self.omega_max) if demand is None else np.asarray(demand, float).reshape(w.shape)
        for a in np.asarray(actions, float).T:
            out = np.empty_like(w)
            decode(w, np.ascontiguousarray(a), d, S, mode, out)
            w = out
        return w

    def _state(self, state: Any, n: int, episode_start: np.ndarray | None) -> Any:
        """Fresh state when None or of another batch size; reset rows where an episode starts."""
        fresh = self._initial(n)
        if state is None or not isinstance(state, dict) or len(next(iter(state.values()), [])) != n:
            return fresh
        if episode_start is not None:
            es = np.asarray(episode_start, bool).reshape(-1)
            if es.shape == (n,) and es.any():
                state = {k: v.copy() for k, v in state.items()}
                for k in state:
                    state[k][es] = fresh[k][es]
        return state

    def initial_state(self, n: int) -> dict[str, np.ndarray]:
        """Per-environment memory at the start of an episode (subclasses extend it)."""
        return {"t": np.zeros(n, np.int64)}

    def _initial(self, n: int) -> dict[str, np.ndarray]:
        """:meth:`initial_state`; with an actuator dead time also the actions on their way to the drive
        (``pending``), how many were sent, and the omega they will leave (``omega_ahead``)."""
        st = self.initial_state(n)
        if self.action_delay:
            st.update(pending=np.zeros((n, self.action_delay)), sent=np.zeros(n, np.int64), omega_ahead=np.zeros(n))
        return st

    def _targets(self, omega: np.ndarray, obs: np.ndarray, state: dict) -> tuple[np.ndarray, dict]:
        raise NotImplementedError


def _obs_demand(policy: ScriptedPolicy, obs: np.ndarray) -> np.ndarray:
    """The demand of the coming step (n,) from observations (n, obs_dim) of a task with a demand."""
    x = np.asarray(obs, float)[:, OBS_DEMAND]
    return policy.omega_min + 0.5 * (x + 1.0) * (policy.omega_max - policy.omega_min)


class ConstantSpeed(ScriptedPolicy):
    """Go to ``omega`` at the maximum rate and hold it."""

    def __init__(self, omega: float, config: Any = None, name: str | None = None):
        super().__init__(config)
        w = float(omega)
        if not np.isfinite(w) or not self.omega_min <= w <= self.omega_max:
            raise ValueError(f"constant speed omega must be in [{self.omega_min:g}, {self.omega_max:g}], got {omega!r}")
        self.omega = w
        self.name = name or f"constant:{w:g}"

    def _targets(self, omega, obs, state):
        state["t"] = state["t"] + 1
        return np.full_like(omega, self.omega), state


class SlowRamp(ScriptedPolicy):
    """Ramp from wherever the episode starts towards ``target`` at ``rate_fraction`` of the
    maximum rate (default a quarter: 0.0125 per step with the defaults), then hold."""

    def __init__(self, target: float, config: Any = None, rate_fraction: float = 0.25, name: str | None = None):
        super().__init__(config)
        if not 0.0 < float(rate_fraction) <= 1.0:
            raise ValueError(f"ramp rate_fraction must be in (0, 1], got {rate_fraction!r}")
        w = float(target)
        if not np.isfinite(w) or not self.omega_min <= w <= self.omega_max:
            raise ValueError(f"ramp target must be in [{self.omega_min:g}, {self.omega_max:g}], got {target!r}")
        self.target = w
        self.rate = float(rate_fraction) * self.max_domega
        self.name = name or f"ramp:{w:g}:{rate_fraction:g}"

    def _targets(self, omega, obs, state):
        state["t"] = state["t"] + 1
        step = np.clip(self.target - omega, -self.rate, self.rate)
        return omega + step, state


class HillClimber(ScriptedPolicy):
    """Greedy vibration-feedback controller.

    Each step, the motion counts as *clean* when the periodicity defect is below ``defect_tol``
    (in units of the environment's defect_scale), the contact-loss fraction below ``contact_tol``
    and there were no impacts. Clean: raise omega by ``climb`` x max rate, but not above
    ``ceiling - margin`` (the ceiling is the lowest omega at which trouble was seen in this
    episode). Not clean: remember the ceiling and back off at the full rate. With a demand
    (GearSpeedDemand-v0) it never climbs above the demand, forgets the ceiling when the demand changes
    and raises it by ``forget`` per clean step, so it re-probes a window that moved. Greedy by design: it
    stays in the first clean window it finds above (or below) its start.
    """

    name = "hill-climber"

    def __init__(
        self,
        config: Any = None,
        climb: float = 0.5,
        margin: float | None = None,
        defect_tol: float = 0.5,
        contact_tol: float = 0.02,
        forget: float | None = None,
    ):
        super().__init__(config)
        # with a demand the window moves (load changes) and the demand changes: the ceiling is raised
        # again by `forget` per clean step, so the climber re-probes (none without a demand: v0 as before)
        self.forget = (0.05 * self.max_domega if self.has_demand else 0.0) if forget is None else float(forget)
        self.climb = float(climb)
        self.margin = 2.0 * self.max_domega if margin is None else float(margin)
        self.defect_obs_tol = float(np.log1p(defect_tol))
        self.contact_tol = float(contact_tol)

    def initial_state(self, n: int) -> dict[str, np.ndarray]:
        return {"t": np.zeros(n, np.int64), "ceiling": np.full(n, np.inf), "demand": np.full(n, np.nan)}

    def clean(self, obs: np.ndarray) -> np.ndarray:
        """(n,) bool: the last step showed periodic, contact-free, impact-free motion."""
        return (
            (obs[:, OBS_DEFECT] <= self.defect_obs_tol)
            & (obs[:, OBS_CONTACT] <= self.contact_tol)
            & (obs[:, OBS_DRIVE_IMPACTS] <= 0.0)
            & (obs[:, OBS_BACK_IMPACTS] <= 0.0)
        )

    def _targets(self, omega, obs, state):
        ok = self.clean(obs)
        state["t"] = state["t"] + 1
        ceiling = state["ceiling"]
        if self.has_demand:  # a new demand level: probe afresh (the window may have moved meanwhile)
            d_raw = obs[:, OBS_DEMAND]
            ceiling = np.where(d_raw != state["demand"], np.inf, ceiling)
            state["demand"] = d_raw.copy()
        ceiling = np.where(ok, ceiling + self.forget, np.minimum(ceiling, omega))
        state["ceiling"] = ceiling
        up = np.minimum(omega + self.climb * self.max_domega, ceiling - self.margin)
        hold_or_up = np.maximum(up, np.minimum(omega, ceiling - self.margin))
        if self.has_demand:  # no faster than the demand; down to it at once
            d = _obs_demand(self, obs)
            hold_or_up = np.minimum(hold_or_up, d)
        target = np.where(ok, hold_or_up, omega - self.max_domega)
        return target, state


__all__ = ["ConstantSpeed", "HillClimber", "ScriptedPolicy", "SlowRamp"]
