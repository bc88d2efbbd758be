"""PPO training runs (agents/ppo.py, train.py, gear-env train): run folders, resume, errors, pretrained."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from agents.ppo import TrainOptions, train
from agents.registry import resolve_policy
from agents.runs import RunFolder, RunFolderError
from gear_env.envs.env_config import GearSpeedConfig
from gear_env.evaluation import evaluate_policies

# a cheap environment (coarse integration, short steps/episodes) and a tiny PPO: ~1 s per run
FAST_ENV = {"steps_per_period": 32, "periods_per_step": 8, "max_steps": 16, "warmup_periods": 16}
TINY_PPO = {"n_steps": 32, "batch_size": 64, "n_epochs": 2, "net_arch": [16, 16]}


def _opts(out, **kw):
    base = dict(
        out=str(out),
        env_id="GearSpeed-v0",  # these tests check v0's delta-mode actions (TrainOptions' default is GearSpeed-v1)
        env_config=FAST_ENV,
        timesteps=256,
        num_envs=4,
        seed=1,
        eval_freq=128,
        eval_episodes=2,
        checkpoint_freq=128,
        ppo=TINY_PPO,
        progress_bar=False,
        tensorboard=False,
        verbose=0,
    )
    base.update(kw)
    return TrainOptions(**base)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "r1"
    summary = train(_opts(out))
    assert summary["timesteps"] == 256 and summary["finished"]
    return out


def test_training_writes_a_complete_run_folder_that_loads(run_dir):
    for name in ("model.zip", "vecnormalize.npz", "config.json", "env_config.json", "metrics.csv", "metrics.json"):
        assert (run_dir / name).is_file(), name
    cfg = RunFolder(run_dir).read_config()
    assert cfg["env_config"] == GearSpeedConfig.from_kwargs(FAST_ENV).to_dict()
    assert cfg["ppo"]["n_steps"] == 32 and cfg["ppo"]["gamma"] == pytest.approx(0.999)
    assert cfg["train"]["num_envs"] == 4 and "stable_baselines3" in cfg["versions"]
    assert cfg["observation_space"]["shape"] == [10]
    # env_config.json is a plain settings object that the environment accepts as is
    GearSpeedConfig.from_kwargs(json.loads((run_dir / "env_config.json").read_text()))
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert [r["timesteps"] for r in metrics["evaluations"]] == [128, 256]
    assert metrics["summary"]["wall_seconds"] > 0
    steps, model_path, vn_path = RunFolder(run_dir).latest_checkpoint()
    assert steps == 256 and model_path.is_file() and vn_path.is_file()
    # the policy loads, normalises observations with frozen statistics and plays an episode
    pol = resolve_policy(str(run_dir), FAST_ENV)
    assert pol.vecnorm.training is False and pol.vecnorm.norm_reward is False
    mean_before = pol.vecnorm.obs_rms.mean.copy()
    rep = evaluate_policies({"ppo": pol}, FAST_ENV, episodes=1, seed=0)
    assert rep.episodes["ppo"][0].steps == 16
    assert np.array_equal(pol.vecnorm.obs_rms.mean, mean_before)
    # the best evaluation and any checkpoint load the same way
    assert resolve_policy(str(run_dir / "best_model.zip"), FAST_ENV).vecnorm is not None
    assert resolve_policy(str(run_dir / "checkpoints" / "ckpt_000000256.zip"), FAST_ENV).model.num_timesteps == 256


def test_a_setpoint_policy_drives_the_delta_mode_environment(tmp_path):
    out = tmp_path / "setpoint"
    train(_opts(out, env_config={**FAST_ENV, "action_mode": "target"}, eval_freq=0, checkpoint_freq=0))
    pol = resolve_policy(str(out), FAST_ENV)  # evaluated on the delta-mode environment
    assert pol.action_adapter is not None
    rep = evaluate_policies({"p": pol}, FAST_ENV, episodes=1, seed=0)
    assert np.all(np.abs(np.diff(rep.episodes["p"][0].omega)) <= 0.05 + 1e-9)


def test_resume_continues_the_step_count(run_dir, tmp_path):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(run_dir, out)
    summary = train(_opts(out, timesteps=512, resume=True))
    assert summary["timesteps"] == 512
    assert RunFolder(out).latest_checkpoint()[0] == 512
    assert summary["sessions"] == 2
    metrics = json.loads((out / "metrics.json").read_text())
    assert [r["timesteps"] for r in metrics["evaluations"]] == [128, 256, 384, 512]
    from stable_baselines3 import PPO

    assert PPO.load(str(out / "model.zip")).num_timesteps == 512


def test_resume_with_an_incompatible_config_is_refused(run_dir):
    with pytest.raises(RunFolderError, match=r"incompatible configuration.*max_steps"):
        train(_opts(run_dir, env_config={**FAST_ENV, "max_steps": 20}, timesteps=512, resume=True))
    with pytest.raises(RunFolderError, match=r"num_envs 4 vs 2"):
        train(_opts(run_dir, num_envs=2, timesteps=512, resume=True))
    with pytest.raises(ValueError, match="already reaches --timesteps"):
        train(_opts(run_dir, timesteps=256, resume=True))
    with pytest.raises(RunFolderError, match="already holds a run"):
        train(_opts(run_dir))


def test_a_model_for_another_observation_layout_is_refused(run_dir):
    # a demand profile adds an observation entry: 11 features instead of 10
    with pytest.raises(ValueError, match=r"another observation layout.*shape \(10,\) vs \(11,\)"):
        resolve_policy(str(run_dir), {**FAST_ENV, "demand": "steps"})


def test_missing_and_corrupt_run_folders_give_clear_errors(run_dir, tmp_path):
    import shutil

    with pytest.raises(RunFolderError, match="does not exist"):
        resolve_policy(str(tmp_path / "nothing"), FAST_ENV)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(RunFolderError, match="config.json is missing"):
        resolve_policy(str(empty), FAST_ENV)
    bad = tmp_path / "bad"
    shutil.copytree(run_dir, bad)
    (bad / "model.zip").write_bytes(b"not a zip")
    with pytest.raises(RunFolderError, match="corrupt model file"):
        resolve_policy(str(bad), FAST_ENV)
    shutil.copy(run_dir / "model.zip", bad / "model.zip")
    (bad / "vecnormalize.npz").write_bytes(b"\x80\x04garbage")
    with pytest.raises(RunFolderError, match="corrupt normalisation statistics"):
        resolve_policy(str(bad), FAST_ENV)
    (bad / "config.json").write_text("{not json")
    with pytest.raises(RunFolderError, match="cannot read config.json"):
        resolve_policy(str(bad), FAST_ENV)
    with pytest.raises(RunFolderError, match="no checkpoint"):
        RunFolder(empty).latest_checkpoint()
    assert zipfile.is_zipfile(run_dir / "model.zip")  # the original is untouched


def test_ctrl_c_leaves_a_usable_checkpoint(tmp_path, monkeypatch):
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    import agents.ppo as ppo

    class Interrupt(BaseCallback):
        def _on_step(self) -> bool:
            if self.model.num_timesteps >= 160:
                raise KeyboardInterrupt
            return True

    orig = ppo._callbacks
    monkeypatch.setattr(ppo, "_callbacks", lambda *a: CallbackList([orig(*a), Interrupt()]))
    out = tmp_path / "int"
    with pytest.raises(KeyboardInterrupt):
        train(_opts(out, timesteps=1024))
    steps, model_path, _ = RunFolder(out).latest_checkpoint()
    assert steps == 160
    with pytest.raises(RunFolderError, match="training did not finish.*--resume"):
        resolve_policy(str(out), FAST_ENV)
    assert resolve_policy(str(model_path), FAST_ENV).model.num_timesteps == 160
    assert json.loads((out / "metrics.json").read_text())["summary"]["interrupted"] is True
    monkeypatch.setattr(ppo, "_callbacks", orig)
    summary = train(_opts(out, timesteps=384, resume=True))
    assert summary["timesteps"] >= 384


def test_train_command_line_and_exit_codes(tmp_path, capsys):
    from gear_env.cli import main as cli_main

    cfg = tmp_path / "env.json"
    cfg.write_text(json.dumps(FAST_ENV))
    out = tmp_path / "cli"
    args = ["--out", str(out), "--config", str(cfg), "--timesteps", "128", "--num-envs", "2", "--eval-freq", "0"]
    args += ["--no-progress", "--no-tensorboard", "--quiet", "--seed", "3"]
    args += [f"--ppo={k}={json.dumps(v)}" for k, v in TINY_PPO.items()]
    assert cli_main(["train", *args]) == 0
    assert (out / "model.zip").is_file()
    assert RunFolder(out).read_config()["train"]["seed"] == 3
    # the same code behind train.py: a usage error is exit 2 with a message
    from gear_env.cli.train import main as train_main

    assert train_main(["--out", str(out), "--config", str(tmp_path / "missing.json")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert train_main(["--out", str(out), "--ppo", "gamma_typo=0.9"]) == 2
    assert "unknown PPO hyper-parameter" in capsys.readouterr().err


def test_pretrained_policy_loads_and_runs():
    from agents.registry import pretrained_dir

    if not (pretrained_dir() / "model.zip").is_file():
        pytest.fail("the pretrained policy is missing from gear_env/data/pretrained/")
    size = sum(p.stat().st_size for p in pretrained_dir().iterdir() if p.is_file())
    assert size < 1_000_000
    pol = resolve_policy("pretrained", GearSpeedConfig())
    cfg = GearSpeedConfig.from_kwargs(steps_per_period=32, max_steps=12)
    rep = evaluate_policies({"pretrained": pol}, cfg, episodes=1, seed=0)
    ep = rep.episodes["pretrained"][0]
    assert ep.steps == 12 and np.isfinite(ep.ret)


def test_training_without_tensorboard_writes_nothing_to_the_system_temp_dir(tmp_path, monkeypatch):
    """Issue #26: every learn() without TensorBoard left an empty SB3-<date> folder in the system temp
    directory. Training now logs into the run folder with no outputs."""
    import tempfile

    systmp = tmp_path / "systmp"
    systmp.mkdir()
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(systmp))
    assert tempfile.gettempdir() == str(systmp)
    train(_opts(tmp_path / "run", timesteps=128, eval_freq=0, checkpoint_freq=0))
    assert not [p.name for p in systmp.iterdir() if p.name.startswith("SB3-")]


def test_gear_env_train_resume_keeps_the_stored_evaluation_episodes(run_dir):
    """``gear-env train --resume`` without ``--eval-episodes`` evaluates on the run's stored number of episodes
    (here 2), not the CLI default; an explicit value still wins."""
    import argparse

    from gear_env.cli.train import DEFAULT_EVAL_EPISODES, add_arguments, options_from_args

    p = argparse.ArgumentParser()
    add_arguments(p)
    assert RunFolder(run_dir).read_config()["train"]["eval_episodes"] == 2 != DEFAULT_EVAL_EPISODES
    resume = ["--out", str(run_dir), "--resume"]
    assert options_from_args(p.parse_args(resume)).eval_episodes == 2
    assert options_from_args(p.parse_args([*resume, "--eval-episodes", "5"])).eval_episodes == 5
