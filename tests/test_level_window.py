"""``level_window``: the ``mean_force_level`` entries (the pair's q averaged over clean steps, as the
``filtered-follow`` script estimates it), checked against the documented definition written out step by step
(the single and vector env agree bit for bit: tests/test_limit_rate.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the tasks)
from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import task_config
from gear_env.envs.env_terms import TROUBLE_CONTACT
from gear_env.envs.force_level import H_OMEGAS, LOG_H, TROUBLE_DEFECT

SHORT = {"periods_per_step": 8, "warmup_periods": 16, "max_steps": 40, "force_level": True, "level_window": 4}


def test_bad_level_window_is_refused_with_its_field_and_range():
    with pytest.raises(ValueError, match=r"level_window > 0 needs force_level=True"):
        task_config("GearSpeedDemandHard-v0", {"level_window": 8})
    for bad in (-1, 1001, 2.5, True):
        with pytest.raises(ValueError, match=r"level_window"):
            task_config("GearSpeedDemandHard-v0", {"force_level": True, "level_window": bad})
    names = GearSpeedEnv(task_config("GearSpeedDemandHard-v0", {"force_level": True})).observation_names
    assert "mean_force_level" not in names  # 0 (the default) adds nothing


def test_mean_force_level_follows_its_definition_step_by_step():
    """From the noisy observation itself: a step counts when its mean speed is in the table and it shows no
    trouble (contact loss and defect above their thresholds raised by 2 sensor_noise, or an impact); q = expm1(
    force_rms) / h(speed) is averaged, a running mean over the first level_window counted steps, then
    exponentially with weight 1/level_window; the entry is log of the mean (0 before any), the count entry
    min(count, window)/window; both restart with the episode."""
    cfg = task_config("GearSpeedDemandHard-v0", SHORT)
    env = GearSpeedEnv(cfg)
    n = env.observation_names
    c = {k: n.index(k) for k in n}
    win, margin = SHORT["level_window"], 2.0 * cfg.sensor_noise
    span = cfg.omega_max - cfg.omega_min
    lo, hi = cfg.action_range if cfg.action_range is not None else (cfg.omega_min, cfg.omega_max)
    counted, ema_steps = 0, 0
    for seed in range(6):
        obs, _ = env.reset(seed=seed, options={"omega": 1.0})
        q, count = 0.0, 0
        rng = np.random.default_rng(seed)
        for _t in range(SHORT["max_steps"] + 1):
            x = [float(v) for v in obs]
            w_end = cfg.omega_min + 0.5 * (x[c["omega"]] + 1.0) * span
            w_mid = w_end - 0.5 * x[c["domega"]] * cfg.max_domega
            trouble = (
                x[c["contact_loss"]] > TROUBLE_CONTACT + margin
                or x[c["drive_impacts"]] + x[c["back_impacts"]] > 0
                or x[c["defect"]] > TROUBLE_DEFECT + margin
            )
            if H_OMEGAS[0] <= w_mid <= H_OMEGAS[-1] and not trouble:
                sensed = math.expm1(x[c["force_rms"]]) / math.exp(float(np.interp(w_mid, H_OMEGAS, LOG_H)))
                count += 1
                q += (sensed - q) / min(count, win)
                counted += 1
                ema_steps += count > win
            want = min(max(math.log(max(q, 1e-6)), -5.0), 5.0) if count else 0.0
            assert x[c["mean_force_level"]] == pytest.approx(want, abs=2e-5)
            assert x[c["mean_force_level_count"]] == pytest.approx(min(count, win) / win, abs=1e-7)
            target = rng.uniform(0.95, 1.3)  # set-points in and near the quiet window of most pairs
            obs, _, term, trunc, _ = env.step(np.array([2.0 * (target - lo) / (hi - lo) - 1.0], np.float32))
            if term or trunc:
                break
    assert counted > 20 and ema_steps > 5  # both phases ran, so the test could fail
