"""Issue #24: the environments' ``tol`` setting (error-controlled integration instead of fixed steps).

The single and the vector env give identical numbers with it (lanes of any count); its observations are closer
to a fine fixed-step reference than the default 64 steps are; bad values are refused naming the field."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gear_env  # noqa: F401  (registers the ids)
from gear_env.envs.vector_env import GearSpeedVectorEnv

ACTIONS = np.array([0.2, 0.35, 0.35, -0.1, 0.5, 0.5], np.float32)


def _single(seed: int, **kw) -> tuple[np.ndarray, np.ndarray]:
    env = gym.make("GearSpeedDemand-v0", **kw)
    o, _ = env.reset(seed=seed)
    obs, rew = [o], []
    for a in ACTIONS:
        o, r, *_ = env.step(np.array([a], np.float32))
        obs.append(o)
        rew.append(r)
    return np.array(obs), np.array(rew)


@pytest.mark.parametrize("n", [2, 9])  # 9 rows: above the SIMD lanes' threshold of the fixed-step path
def test_single_and_vector_env_are_identical_with_tol(n):
    seeds = [11 + i for i in range(n)]
    from gear_env.envs.env_config import task_config

    vec = GearSpeedVectorEnv(n, task_config("GearSpeedDemand-v0", {"tol": 1e-3}))
    o, _ = vec.reset(seed=seeds)
    obs, rew = [o], []
    for a in ACTIONS:
        o, r, *_ = vec.step(np.full((n, 1), a, np.float32))
        obs.append(o)
        rew.append(r)
    obs, rew = np.stack(obs, 1), np.stack(rew, 1)
    for i in (0, n - 1):
        so, sr = _single(seeds[i], tol=1e-3)
        np.testing.assert_array_equal(obs[i], so)
        np.testing.assert_array_equal(rew[i], sr)


def test_tol_observations_are_closer_to_a_fine_reference_than_64_steps():
    """Force RMS, peak and bearing deflection features over six steps on three episodes, against 1024 steps."""
    errs = {}
    for seed in (1, 2, 3):
        ref, _ = _single(seed, steps_per_period=1024)
        for name, kw in (("64", {}), ("tol", {"tol": 1e-5})):
            o, _ = _single(seed, **kw)
            errs.setdefault(name, []).append(np.max(np.abs(o[:, 2:5] - ref[:, 2:5])))
    assert max(errs["tol"]) < max(errs["64"]), errs


def test_bad_tol_is_refused_naming_the_field():
    for bad in (0.0, 0.5, float("nan"), "1e-4", True):
        with pytest.raises(ValueError, match="tol must be"):
            gym.make("GearSpeed-v1", tol=bad)
