"""The CleanRL-style PPO example (examples/cleanrl_ppo.py): Gymnasium's own wrappers on the registered task,
then gear-env's evaluation on the oracle's seeds."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
TINY = ["--total-timesteps", "128", "--num-steps", "64", "--num-minibatches", "4", "--eval-episodes", "2", "--quiet"]


@pytest.fixture(scope="module")
def mod():
    spec = importlib.util.spec_from_file_location("cleanrl_ppo", ROOT / "examples" / "cleanrl_ppo.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_cleanrl_trains_and_is_scored_against_the_oracle(mod, tmp_path):
    out = tmp_path / "r.json"
    assert mod.main([*TINY, "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["env_id"] == "GearSpeed-v1" and res["eval_seeds"] == [9001, 9002]
    assert set(res["returns"]) == {"cleanrl-ppo", "oracle", "fixed-best"}
    assert all(len(v) == 2 and np.all(np.isfinite(v)) for v in res["returns"].values())
    assert res["pct_of_oracle"]["oracle"] == pytest.approx(100.0)
    assert [r["global_step"] for r in res["log"]] == [64, 128]
    # the oracle's returns are those of gear-env's own evaluation on the same seeds
    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    cfg = task_config("GearSpeed-v1")
    rep = evaluate_policies({"oracle": resolve_policy("oracle", cfg)}, cfg, episodes=2, seed=9001)
    assert [e.ret for e in rep.episodes["oracle"]] == res["returns"]["oracle"]


def test_cleanrl_refuses_to_overwrite_a_result(mod, tmp_path):
    out = tmp_path / "r.json"
    out.write_text("mine")
    with pytest.raises(SystemExit, match="exists"):
        mod.main([*TINY, "--json", str(out)])
    assert out.read_text() == "mine"


def test_cleanrl_frozen_policy_shapes_and_bounds(mod):
    agent = mod.build_agent(11, 1)
    pol = mod.FrozenPolicy(agent, np.zeros(11), np.ones(11))
    a, _ = pol.predict(np.zeros(11, np.float32))
    assert a.shape == (1,) and a.dtype == np.float32
    b, _ = pol.predict(np.random.default_rng(0).normal(size=(5, 11)) * 100)
    assert b.shape == (5, 1) and np.all(np.abs(b) <= 1.0)
    assert np.array_equal(pol.predict(np.ones(11))[0], pol.predict(np.ones(11))[0])  # deterministic


def test_cleanrl_bad_sizes_are_refused_before_training(mod):
    with pytest.raises(SystemExit, match="num-minibatches"):
        mod.main(["--num-steps", "10", "--num-minibatches", "3"])
    with pytest.raises(SystemExit, match="total-timesteps"):
        mod.main(["--total-timesteps", "0"])
