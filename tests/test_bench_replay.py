"""``benchmarks/ab_compare.py --policy``: a policy's actions recorded from the start that the env workloads make, and
replayed there (``bench_env.record_policy_actions``, ``bench_single(actions=...)``, ``bench_vector(actions=...)``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import ab_compare  # noqa: E402
import bench_env  # noqa: E402


@pytest.mark.parametrize("num_envs", [0, 3])
def test_recorded_actions_are_the_policys_and_replay(num_envs):
    env_id = "GearSpeedDemand-v0"
    acts = bench_env.record_policy_actions("sensor-servo", env_id, num_envs, 4)
    assert acts.shape == ((4, 1) if num_envs == 0 else (4, num_envs, 1)) and acts.dtype == np.float32
    assert np.isfinite(acts).all() and (np.abs(acts) <= 1.0).all()
    again = bench_env.record_policy_actions("sensor-servo", env_id, num_envs, 4)
    np.testing.assert_array_equal(acts, again)  # deterministic from reset(seed=0)
    # the recording follows the policy: the servo's first action from the same observation
    import gymnasium as gym

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config

    pol = resolve_policy("sensor-servo", task_config(env_id, {}), env_id=env_id)
    obs0, _ = gym.make(env_id).reset(seed=0)
    np.testing.assert_array_equal(acts.reshape(len(acts), -1)[0, 0], np.asarray(pol.predict(obs0, True)[0]).ravel()[0])
    rate = (
        bench_env.bench_single(0.02, env_id, acts)
        if num_envs == 0
        else bench_env.bench_vector(num_envs, 0.02, env_id, acts)
    )
    assert rate > 0.0


def test_ab_compare_policy_needs_the_b_env():
    with pytest.raises(SystemExit):
        ab_compare.main(["--policy", "pretrained", "--only", "env-single"])


def test_a_policy_told_the_scenario_is_recorded_in_the_single_env_only():
    single = bench_env.record_policy_actions("fixed-best", "GearSpeedDemand-v0", 0, 3)
    assert single.shape == (3, 1) and np.isfinite(single).all()
    with pytest.raises(ValueError, match="num_envs=0"):
        bench_env.record_policy_actions("fixed-best", "GearSpeedDemand-v0", 2, 3)
