"""Issue 15 items 5, 8, 11, 13: run folders never run code when loaded, --overwrite leaves no stale
checkpoint, PPO settings are checked before training. The payloads are harmless: each one, if it
were unpickled, would only create a marker file."""

from __future__ import annotations

import base64
import json
import pickle
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.ppo import TrainOptions, rollout_total, train
from agents.registry import resolve_policy
from agents.runs import RunFolder, RunFolderError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from crafted_cases import rewrite_zip  # noqa: E402  (the crafted cases' zip rewriter, written once)

FAST_ENV = {"steps_per_period": 32, "periods_per_step": 8, "max_steps": 16, "warmup_periods": 16}
TINY_PPO = {"n_steps": 32, "batch_size": 64, "n_epochs": 2, "net_arch": [16, 16]}


def _opts(out, **kw):
    base = dict(
        out=str(out), env_config=FAST_ENV, timesteps=256, num_envs=4, seed=1, eval_freq=128, eval_episodes=2,
        checkpoint_freq=128, ppo=TINY_PPO, progress_bar=False, tensorboard=False, verbose=0,
    )  # fmt: skip
    base.update(kw)
    return TrainOptions(**base)


class Payload:
    """Unpickling this creates ``marker`` (and nothing else)."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sec") / "run"
    train(_opts(out, timesteps=512))
    return out


@pytest.fixture
def copy(run_dir, tmp_path):
    dst = tmp_path / "copy"
    shutil.copytree(run_dir, dst)
    return dst


def _pickled(marker: Path) -> dict:
    return {":type:": "<class 'x'>", ":serialized:": base64.b64encode(pickle.dumps(Payload(marker))).decode()}


def test_a_pickled_statistics_file_is_never_loaded(copy, tmp_path):
    marker = tmp_path / "pwned"
    (copy / "vecnormalize.npz").unlink()
    (copy / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    with pytest.raises(RunFolderError, match="pickled statistics.*no longer loads pickles"):
        resolve_policy(str(copy), FAST_ENV)
    assert not marker.exists()
    # an .npz whose arrays are pickled objects is refused too (allow_pickle=False)
    with open(copy / "vecnormalize.npz", "wb") as fh:
        np.savez(fh, format=np.array([Payload(marker)], dtype=object))
    with pytest.raises(RunFolderError, match="corrupt normalisation statistics"):
        resolve_policy(str(copy), FAST_ENV)
    assert not marker.exists()


def test_pickled_entries_of_a_model_zip_are_never_unpickled(copy, tmp_path):
    marker = tmp_path / "pwned"

    def swap_policy_class(entries):  # a known entry: replaced by gear-env's own object, never read
        data = json.loads(entries["data"])
        data["policy_class"] = _pickled(marker)
        entries["data"] = json.dumps(data).encode()
        return entries

    rewrite_zip(copy / "model.zip", swap_policy_class)
    pol = resolve_policy(str(copy), FAST_ENV)
    assert pol.predict(np.zeros(10, np.float32))[0].shape == (1,)
    assert not marker.exists()

    def add_entry(entries):  # an unknown pickled entry: the whole file is refused
        data = json.loads(entries["data"])
        data["evil"] = _pickled(marker)
        entries["data"] = json.dumps(data).encode()
        return entries

    rewrite_zip(copy / "model.zip", add_entry)
    with pytest.raises(RunFolderError, match=r"pickled entries \['evil'\]"):
        resolve_policy(str(copy), FAST_ENV)
    assert not marker.exists()


def test_a_pickle_in_the_network_weights_is_refused(copy, tmp_path):
    marker = tmp_path / "pwned"

    def evil_weights(entries):
        entries["policy.pth"] = pickle.dumps(Payload(marker))
        return entries

    rewrite_zip(copy / "model.zip", evil_weights)
    with pytest.raises(RunFolderError, match="corrupt model file"):
        resolve_policy(str(copy), FAST_ENV)
    assert not marker.exists()


def test_resume_loads_only_checkpoint_files_of_the_run_and_never_unpickles(copy, tmp_path, capsys):
    marker = tmp_path / "pwned"
    latest = copy / "checkpoints" / "latest.json"
    good = json.loads(latest.read_text())
    outside = tmp_path / "elsewhere.zip"
    shutil.copy(copy / "model.zip", outside)
    for name in ("../../elsewhere.zip", str(outside), "ckpt_000000512.zip/../../model.zip"):
        latest.write_text(json.dumps({**good, "model": name}))
        with pytest.raises(RunFolderError, match="only checkpoint files"):
            RunFolder(copy).latest_checkpoint()
    latest.write_text(json.dumps(good))
    ckpt = copy / "checkpoints" / good["model"]

    def add_entry(entries):
        data = json.loads(entries["data"])
        data["evil"] = _pickled(marker)
        entries["data"] = json.dumps(data).encode()
        return entries

    rewrite_zip(ckpt, add_entry)
    with pytest.raises(RunFolderError, match="pickled entries"):
        train(_opts(copy, timesteps=640, resume=True))
    assert not marker.exists()
    # a truncated checkpoint: exit 2 with a message, no traceback
    data = (copy / "model.zip").read_bytes()
    ckpt.write_bytes(data[: len(data) // 2])
    from gear_env.cli import main as cli

    cfgs = ["--no-progress", "--no-tensorboard", "--quiet"]
    assert cli(["train", "--out", str(copy), "--resume", "--timesteps", "640", *cfgs]) == 2
    assert "corrupt model file" in capsys.readouterr().err
    assert not marker.exists()


def test_resume_says_which_checkpoint_it_continues(copy, capsys):
    train(_opts(copy, timesteps=640, resume=True, verbose=1))
    out = capsys.readouterr().out
    assert "from checkpoint" in out and "ckpt_000000512.zip" in out and "at 512 steps" in out


def test_overwrite_of_a_longer_run_leaves_no_stale_checkpoint(copy):
    assert RunFolder(copy).latest_checkpoint()[0] == 512
    train(_opts(copy, timesteps=256, overwrite=True))
    run = RunFolder(copy)
    steps, mpath, vpath = run.latest_checkpoint()
    assert steps == 256 and mpath.is_file() and vpath.is_file()
    names = sorted(p.name for p in run.checkpoint_dir.glob("ckpt_*.zip"))
    assert names == ["ckpt_000000128.zip", "ckpt_000000256.zip"]  # nothing of the 512-step run
    summary = train(_opts(copy, timesteps=384, resume=True))
    assert summary["timesteps"] == 384 and run.latest_checkpoint()[0] == 384


def test_timesteps_are_rounded_up_to_whole_rollouts_with_a_message(tmp_path, capsys):
    opts = _opts(tmp_path / "r", timesteps=10, eval_freq=0, checkpoint_freq=0, verbose=1)
    assert rollout_total(opts) == 128  # n_steps 32 x 4 envs
    summary = train(opts)
    assert summary["timesteps"] == 128
    assert "--timesteps 10 is rounded up to 128" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("n_steps", 0), ("n_steps", -1), ("n_steps", 1.5), ("batch_size", 0), ("batch_size", 1), ("n_epochs", 0),
        ("net_arch", "x"), ("net_arch", [-1]), ("net_arch", [0]), ("gamma", float("nan")), ("gamma", 2),
        ("ent_coef", float("inf")), ("max_grad_norm", float("nan")), ("log_std_init", float("inf")),
        ("learning_rate", float("nan")), ("gae_lambda", -1), ("clip_range", -1), ("use_sde", "yes"),
    ],
)  # fmt: skip
def test_ppo_values_are_checked_before_training(tmp_path, key, value):
    with pytest.raises(ValueError, match=f"PPO hyper-parameter {key}"):
        _opts(tmp_path / "never", ppo={**TINY_PPO, key: value})
    assert not (tmp_path / "never").exists()


def test_num_envs_and_timesteps_are_bounded(tmp_path):
    with pytest.raises(ValueError, match=r"num_envs must be an integer in \[1, 1024\]"):
        _opts(tmp_path, num_envs=10_000_000)
    with pytest.raises(ValueError, match="timesteps must be an integer"):
        _opts(tmp_path, timesteps=10**13)


def test_resume_refuses_a_checkpoint_index_that_drops_the_statistics(copy):
    """Issue 25, second probe: latest.json with ``"vecnormalize": null`` resumed a normalising run with fresh
    statistics (silently another policy's input scale)."""
    latest = copy / "checkpoints" / "latest.json"
    latest.write_text(json.dumps({**json.loads(latest.read_text()), "vecnormalize": None}))
    with pytest.raises(RunFolderError, match="vecnormalize: names no statistics"):
        train(_opts(copy, timesteps=640, resume=True))
