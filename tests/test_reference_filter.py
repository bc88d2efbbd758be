"""The drive's reference filter (``reference_filter``, target mode): validation, step response, baselines."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gear_env.envs import env_kernels as EK
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import GearSpeedConfig, task_config

SHORT = {"periods_per_step": 8, "warmup_periods": 16, "max_steps": 40}


def _decode(cfg, w0, a):
    out = np.empty(len(w0))
    w0 = np.asarray(w0, float)
    EK.decode_actions(w0, np.asarray(a, float), np.zeros_like(w0), cfg.TERMS.settings_vector(cfg), 1, out)
    return out


def _setpoint_action(cfg, target):
    return 2.0 * (target - cfg.omega_min) / (cfg.omega_max - cfg.omega_min) - 1.0


@pytest.mark.parametrize("bad", [0, 0.0, -0.1, 1.5, math.nan, math.inf, "0.5", True, None])
def test_bad_reference_filter_names_the_field_and_range(bad):
    with pytest.raises(ValueError, match=r"reference_filter must (be in \(0, 1\]|be a real number)"):
        GearSpeedConfig(action_mode="target", reference_filter=bad)


@pytest.mark.parametrize("alpha", [0.2, 0.5, 0.85])
def test_step_response_is_first_order_then_rate_limited(alpha):
    """A constant set-point T: while |alpha (T - w)| <= max_domega, w_{k+1} - T = (1 - alpha)(w_k - T)
    (geometric, ratio 1 - alpha); further away, every step moves exactly max_domega towards T."""
    cfg = task_config("GearSpeed-v1", {"reference_filter": alpha})
    T, dmax = 1.25, cfg.max_domega
    a = np.array([_setpoint_action(cfg, T)])
    for w0 in (3.0, 0.1):
        w = [w0]
        for _ in range(80):
            w.append(float(_decode(cfg, [w[-1]], a)[0]))
        w = np.array(w)
        far = np.abs(alpha * (T - w[:-1])) > dmax
        assert far[0] and not far[-1]
        np.testing.assert_allclose(np.abs(np.diff(w))[far], dmax, rtol=0, atol=1e-12)
        near = ~far & (np.abs(w[:-1] - T) > 1e-9)
        np.testing.assert_allclose((w[1:] - T)[near], (1 - alpha) * (w[:-1] - T)[near], rtol=0, atol=1e-12)
        assert abs(w[-1] - T) < 1e-6


def test_no_filter_is_the_plain_rate_limited_setpoint():
    """reference_filter = 1 (the setting's default; GearSpeed-v1 before release 0.4.0) decodes exactly as
    before: clip(T, w - dmax, w + dmax)."""
    cfg = task_config("GearSpeed-v1", {"reference_filter": 1.0})
    assert GearSpeedConfig().reference_filter == 1.0
    rng = np.random.default_rng(0)
    w0 = rng.uniform(0.1, 3.0, 200)
    a = rng.uniform(-1, 1, 200)
    T = cfg.omega_min + 0.5 * (a + 1) * (cfg.omega_max - cfg.omega_min)
    want = np.clip(np.clip(T, w0 - cfg.max_domega, w0 + cfg.max_domega), cfg.omega_min, cfg.omega_max)
    assert np.array_equal(_decode(cfg, w0, a), want)


def test_no_effect_in_delta_mode():
    cfg = GearSpeedConfig(reference_filter=0.3)  # action_mode "delta"
    w0, a = np.array([1.0, 2.0]), np.array([0.5, -1.0])
    out = np.empty(2)
    EK.decode_actions(w0, a, np.zeros(2), cfg.TERMS.settings_vector(cfg), 0, out)
    np.testing.assert_allclose(out, w0 + a * cfg.max_domega, rtol=0, atol=1e-15)


def test_scripted_policies_invert_the_filter():
    """fixed-best and a schedule command the set-point whose filtered step lands on their target, so they
    follow the same omega path as without the filter (full rate, then hold)."""
    from agents.baselines import ConstantSpeed
    from gear_env.envs.schedules import SpeedSchedule

    paths = {}
    for alpha in (1.0, 0.3):
        cfg = task_config("GearSpeed-v1", {**SHORT, "reference_filter": alpha})
        for name, pol in (
            ("constant", ConstantSpeed(1.25, cfg)),
            ("schedule", SpeedSchedule.from_spec("constant:1.25", cfg)),
        ):
            env = GearSpeedEnv(cfg)
            obs, info = env.reset(seed=0, options={"omega": 2.0})
            w = [info["omega"]]
            for t in range(15):
                act = pol.predict(obs)[0] if name == "constant" else pol.action(obs[None], t)[0]
                obs, _, _, _, info = env.step(act)
                w.append(info["omega"])
            paths[name, alpha] = np.array(w)
    for name in ("constant", "schedule"):
        np.testing.assert_allclose(paths[name, 0.3], paths[name, 1.0], rtol=0, atol=1e-5)
        assert abs(paths[name, 0.3][-1] - 1.25) < 1e-5 and abs(paths[name, 0.3][1] - 1.9) < 1e-5
