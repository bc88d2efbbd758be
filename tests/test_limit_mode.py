"""``action_mode="limit"``: the action is a speed limit and the drive follows the demand under it."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env.envs import env_kernels as EK
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig, task_config
from gear_env.envs.env_terms import ACTION_CODES

SHORT = {"periods_per_step": 8, "warmup_periods": 16, "max_steps": 30}


def _decode(cfg, w0, a, demand, mode="limit"):
    w0 = np.asarray(w0, float)
    out = np.empty(len(w0))
    d = np.broadcast_to(np.asarray(demand, float), w0.shape).copy()
    EK.decode_actions(w0, np.asarray(a, float), d, cfg.TERMS.settings_vector(cfg), ACTION_CODES[mode], out)
    return out


def test_limit_is_the_target_set_point_capped_at_the_demand():
    """Limit mode decodes min(demand, L(a)) exactly as target mode decodes the set-point L(a) when L <= demand,
    and as the set-point at the demand when L > demand (filter and rate limit alike)."""
    rng = np.random.default_rng(1)
    for alpha in (1.0, 0.3):
        cfg = task_config("GearSpeedDemand-v0", {"reference_filter": alpha, "action_mode": "limit"})
        w0 = rng.uniform(0.1, 3.0, 500)
        a = rng.uniform(-1.2, 1.2, 500)
        d = rng.uniform(1.2, 1.8, 500)
        lim = cfg.omega_min + 0.5 * (np.clip(a, -1, 1) + 1) * (cfg.omega_max - cfg.omega_min)
        a_d = 2 * (d - cfg.omega_min) / (cfg.omega_max - cfg.omega_min) - 1
        as_target = _decode(cfg, w0, np.where(lim <= d, a, a_d), d, mode="target")
        np.testing.assert_allclose(_decode(cfg, w0, a, d), as_target, rtol=0, atol=1e-12)
        # never above the demand when it starts at or below it, and never faster than the rate limit
        out = _decode(cfg, w0, a, d)
        assert np.all(out[w0 <= d] <= d[w0 <= d] + 1e-12)
        assert np.all(np.abs(out - w0) <= cfg.max_domega + 1e-12)


def test_limit_mode_needs_a_demand():
    with pytest.raises(ValueError, match=r'action_mode "limit".*needs a demand'):
        GearSpeedConfig(action_mode="limit")
    with pytest.raises(ValueError, match=r"action_mode must be one of"):
        GearSpeedConfig(action_mode="cap")


def test_full_limit_follows_the_demand_in_the_environment():
    """With the limit at its top the delivered speed tracks the demand at the rate limit: after the rise it
    equals the demand of every step (the info's omega against the info's demand)."""
    env = GearSpeedEnv(task_config("GearSpeedDemand-v0", {**SHORT, "action_mode": "limit", "reference_filter": 1.0}))
    env.reset(seed=3, options={"omega": 1.2})
    gap = []
    for _ in range(SHORT["max_steps"]):
        _, _, term, trunc, info = env.step(np.array([1.0], np.float32))
        gap.append(info["demand"] - info["omega"])
        if term or trunc:
            break
    gap = np.array(gap)
    assert np.all(gap >= -1e-12)  # never above the demand
    assert np.mean(np.abs(gap) < 1e-12) > 0.5  # on it most of the time (behind only while catching up)


def test_action_range_maps_the_actions_onto_the_band():
    """``action_range=(lo, hi)``: in target mode the set-point of action a is lo + (a + 1)/2 (hi - lo); the
    default (None) is [omega_min, omega_max], bit for bit as before."""
    cfg = task_config("GearSpeed-v1", {"reference_filter": 1.0, "max_domega": 2.9, "action_range": (1.1, 1.8)})
    a = np.linspace(-1, 1, 21)
    np.testing.assert_allclose(_decode(cfg, np.full(21, 1.5), a, 0.0, "target"), 1.1 + 0.5 * (a + 1) * 0.7, atol=1e-12)
    base = task_config("GearSpeed-v1", {"reference_filter": 1.0, "max_domega": 2.9})
    assert base.action_range is None
    want = base.omega_min + 0.5 * (a + 1) * (base.omega_max - base.omega_min)
    assert np.array_equal(_decode(base, np.full(21, 1.5), a, 0.0, "target"), want)


@pytest.mark.parametrize("bad", [(1.8, 1.1), (0.0, 1.0), (1.0, 3.5), (1.2, 1.2), "x", (1.0,)])
def test_bad_action_range_names_the_field(bad):
    with pytest.raises(ValueError, match=r"action_range"):
        task_config("GearSpeed-v1", {"action_range": bad})


def test_scripts_and_schedules_speak_the_action_range():
    """A constant-speed script and a schedule hold their speed when the actions are rescaled."""
    from agents.registry import resolve_policy
    from gear_env.envs.schedules import SpeedSchedule
    from gear_env.evaluation import evaluate_policies

    cfg = task_config("GearSpeed-v1", {**SHORT, "action_range": (1.0, 1.6)})
    pols = {"const": resolve_policy("constant:1.3", cfg), "sched": SpeedSchedule.constant(1.3, config=cfg)}
    rep = evaluate_policies(pols, cfg, episodes=1, seed=5)
    for name in pols:
        assert abs(rep.episodes[name][0].settled_omega - 1.3) < 1e-6, name
