"""RLlib on the gear task: the native vector env through gym.make_vec, and examples/rllib_train.py.

RLlib (``ray[rllib]``) pins its own Gymnasium version (1.2.2 for ray 2.60; the package's default
environment has 1.4), so these tests run in a separate virtual environment with the ``rllib`` extra:
.ci/run creates it (``.ci-venv-rllib``) and runs this file there. In an environment without RLlib
the training test is skipped; the make_vec test runs everywhere.

The training test starts a local Ray instance (2 CPUs), trains PPO for 1,024 env steps with one
remote EnvRunner of 4 sub-environments, and compares with the shipped SB3 policy on 2 seeds
(~1-2 min on the 2-core VM: Ray's start-up dominates), so it is marked slow.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.env_config import task_config
from gear_env.envs.vector_env import GearSpeedVectorEnv

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "GearSpeed-v1"  # the task RLlib trains on here (the example's default)
HAS_RLLIB = importlib.util.find_spec("ray") is not None and importlib.util.find_spec("ray.rllib") is not None


def _example():
    spec = importlib.util.spec_from_file_location("rllib_train", ROOT / "examples" / "rllib_train.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["rllib_train"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_rllib_make_vec_builds_the_native_vector_env():
    """What RLlib's EnvRunner calls (gym.make_vec with mode vector_entry_point, the id prefixed with
    its module so Ray workers import it) gives GearSpeedVectorEnv, whose sub-env i reproduces a
    single env seeded seed + i exactly, on the installed Gymnasium (1.4 here, 1.2.2 with RLlib)."""
    venv = gym.make_vec(f"gear_env:{ENV_ID}", num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(venv.unwrapped, GearSpeedVectorEnv)
    cfg = task_config(ENV_ID)
    assert venv.num_envs == 3 and venv.config == cfg
    obs, _ = venv.reset(seed=7)
    act = np.array([[0.3], [-0.2], [0.9]], np.float32)
    obs2, rew, *_ = venv.step(act)
    for i in range(3):
        env = GearSpeedEnv(cfg)
        o, _ = env.reset(seed=7 + i)
        assert np.array_equal(o, obs[i])
        o2, r, *_ = env.step(act[i])
        assert np.array_equal(o2, obs2[i]) and r == rew[i]
    venv.close()


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One short RLlib training run through the example's command line (JSON + checkpoint)."""
    mod = _example()
    d = tmp_path_factory.mktemp("rllib")
    out, ckpt = d / "rllib.json", d / "ckpt"
    args = ["--timesteps", "1000", "--num-env-runners", "1", "--num-envs-per-runner", "4"]
    args += ["--rollout-fragment-length", "128", "--eval-episodes", "2", "--eval-seed", "0", "--num-cpus", "2"]
    assert mod.main([*args, "--checkpoint", str(ckpt), "--out", str(out)]) == 0
    return mod, json.loads(out.read_text()), ckpt, out


@pytest.mark.slow
@pytest.mark.skipif(
    not HAS_RLLIB, reason="RLlib is not installed (pip install -e '.[rllib]'; .ci/run uses .ci-venv-rllib)"
)
class TestRLlibTrainAndCompare:
    def test_rllib_trains_on_the_native_vector_env(self, run):
        mod, res, _, _ = run
        r = res["rllib"]
        assert res["format"] == "gear-env-rllib/1" and res["env_id"] == ENV_ID == mod.ENV_ID
        # every EnvRunner (here one remote actor) stepped the package's own vector env
        assert r["vector_env_classes"] == ["gear_env.envs.vector_env.GearSpeedVectorEnv"]
        assert r["ppo"]["train_batch_size_per_learner"] == 4 * 128
        # RLlib's PPO takes the SB3 agent's values from agents/hyperparams/ppo.yml
        from agents.hyperparams import load_zoo_entry

        sb3 = load_zoo_entry(ROOT / "agents" / "hyperparams" / "ppo.yml", ENV_ID)["ppo"]
        assert r["ppo"]["gamma"] == sb3["gamma"] and r["ppo"]["lambda_"] == sb3["gae_lambda"]
        assert r["ppo"]["lr"] == sb3["learning_rate"] and r["ppo"]["num_epochs"] == sb3["n_epochs"]
        assert r["timesteps"] == 1024 and r["iterations"] == 2  # whole updates of 512 steps
        assert [h["env_steps"] for h in r["history"]] == [512, 1024]
        assert res["ray"]["nodes"] == 1 and res["ray"]["resources"]["CPU"] == 2.0
        assert res["versions"]["gymnasium"] == gym.__version__

    def test_rllib_and_sb3_evaluated_on_the_same_seeds(self, run):
        """Both policies have one episode per evaluation seed; the SB3 numbers equal an independent
        evaluation of the shipped policy on those seeds (bit for bit)."""
        from agents.registry import resolve_policy
        from gear_env.evaluation import evaluate_policies

        mod, res, _, _ = run
        assert res["eval_seeds"] == [0, 1]
        assert set(res["policies"]) == {"rllib-ppo", "sb3-pretrained"}
        for s in res["policies"].values():
            assert s["episodes"] == 2 and len(s["returns"]) == 2 and s["diverged"] == 0
        cfg = mod.eval_config(ENV_ID, mod.ENV_CONFIG)
        pol = resolve_policy("pretrained", cfg, env_id=ENV_ID)
        again = evaluate_policies({"p": pol}, cfg, episodes=2, seed=0).to_json_dict()
        assert again["policies"]["p"]["returns"] == res["policies"]["sb3-pretrained"]["returns"]

    def test_rllib_checkpoint_reproduces_the_reported_returns(self, run):
        """The policy read back from the RLlib checkpoint, evaluated on the same seeds, gives exactly
        the returns of the JSON; its deterministic actions are in [-1, 1] with shape (n, 1)."""
        from gear_env.evaluation import evaluate_policies

        mod, res, ckpt, _ = run
        pol = mod.RLlibPolicy(mod.load_module(ckpt))
        cfg = mod.eval_config(ENV_ID, mod.ENV_CONFIG)
        obs = np.stack([GearSpeedEnv(cfg).reset(seed=s)[0] for s in range(3)])
        act, _ = pol.predict(obs)
        assert act.shape == (3, 1) and act.dtype == np.float32 and np.all(np.abs(act) <= 1.0)
        again = evaluate_policies({"r": pol}, cfg, episodes=2, seed=0).to_json_dict()
        assert again["policies"]["r"]["returns"] == res["policies"]["rllib-ppo"]["returns"]

    def test_rllib_example_refuses_to_overwrite(self, run):
        mod, _, _, out = run
        before = out.read_bytes()
        with pytest.raises(SystemExit) as e:
            mod.main(["--timesteps", "1", "--out", str(out)])
        assert e.value.code == 2 and out.read_bytes() == before


def test_rllib_gymnasium_vector_env_closes_after_a_failed_init():
    """RLlib's gymnasium (1.2.2) closes vector envs from ``VectorEnv.__del__``, also when __init__
    raised before setting any attribute: close() must then do nothing, not raise AttributeError."""
    with pytest.raises(ValueError, match="num_envs"):
        GearSpeedVectorEnv(num_envs=0)
    env = GearSpeedVectorEnv.__new__(GearSpeedVectorEnv)  # the state __del__ sees after that error
    env.close()
    assert env.closed
