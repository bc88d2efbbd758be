"""Issue #26: the evaluation never gives a wrong number silently. ``gear-env evaluate`` and ``report`` take
``--env``, default to a run folder's own task (its config.json) and refuse a policy trained on another task
unless told; the CLI defaults to GearSpeed-v1; ``agents.compare`` scores a model against the oracle in one
call and refuses a model whose spaces do not fit the task."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.ppo import TrainOptions, train
from gear_env.cli import build_parser
from gear_env.cli import main as cli_main

FAST_ENV = {"steps_per_period": 32, "periods_per_step": 8, "max_steps": 16, "warmup_periods": 16}
TINY_PPO = {"n_steps": 32, "batch_size": 64, "n_epochs": 1, "net_arch": [8, 8]}


@pytest.fixture(scope="module")
def v0_run(tmp_path_factory):
    """A tiny run trained on GearSpeed-v0 (its config.json says so)."""
    out = tmp_path_factory.mktemp("runs") / "v0run"
    opts = dict(out=str(out), env_id="GearSpeed-v0", env_config=FAST_ENV, timesteps=128, num_envs=2, seed=1)
    opts.update(eval_freq=0, checkpoint_freq=0, ppo=TINY_PPO, progress_bar=False, tensorboard=False, verbose=0)
    train(TrainOptions(**opts))
    assert json.loads((out / "config.json").read_text())["env_id"] == "GearSpeed-v0"
    return out


def _config(tmp_path):
    path = tmp_path / "fast.json"
    path.write_text(json.dumps({"max_steps": 3, "steps_per_period": 32}))
    return str(path)


def test_evaluate_defaults_to_the_run_folders_own_task(v0_run, tmp_path, capsys):
    js = tmp_path / "e.json"
    argv = ["evaluate", "--policy", str(v0_run), "--episodes", "1", "--config", _config(tmp_path), "--json", str(js)]
    assert cli_main(argv) == 0
    assert "--env GearSpeed-v0: the task the run folder(s) were trained on" in capsys.readouterr().out
    assert json.loads(js.read_text())["config"]["action_mode"] == "delta"  # v0's actions, not v1's


def test_evaluate_and_report_refuse_a_run_of_another_task_unless_told(v0_run, tmp_path, capsys):
    base = ["--policy", str(v0_run), "--episodes", "1", "--config", _config(tmp_path)]
    assert cli_main(["evaluate", "--env", "GearSpeed-v1", *base]) == 2
    err = capsys.readouterr().err
    assert "trained on GearSpeed-v0" in err and "--allow-other-env" in err
    assert cli_main(["report", "--env", "GearSpeed-v1", *base, "--out", str(tmp_path / "rep")]) == 2
    assert "trained on GearSpeed-v0" in capsys.readouterr().err
    assert not (tmp_path / "rep").exists()  # refused before any output
    assert cli_main(["evaluate", "--env", "GearSpeed-v1", "--allow-other-env", *base]) == 0


def test_cli_defaults_to_gearspeed_v1(tmp_path):
    from gear_env.cli.common import choose_env
    from gear_env.cli.train import options_from_args

    assert choose_env(None, ["oracle", "pretrained", "constant:1.2"]) == "GearSpeed-v1"
    parser = build_parser()
    for cmd in (["evaluate", "--policy", "oracle"], ["report", "--policy", "oracle", "--out", "x"]):
        assert parser.parse_args(cmd).env is None  # resolved by choose_env: the run folders', else v1
    args = parser.parse_args(["train", "--out", str(tmp_path / "r")])
    assert options_from_args(args).env_id == "GearSpeed-v1"


def test_run_folders_of_different_tasks_need_env(v0_run, tmp_path):
    from gear_env.cli.common import choose_env

    other = tmp_path / "v1run"
    other.mkdir()
    cfg = json.loads((v0_run / "config.json").read_text())
    (other / "config.json").write_text(json.dumps({**cfg, "env_id": "GearSpeed-v1"}))
    with pytest.raises(ValueError, match="different tasks"):
        choose_env(None, [str(v0_run), f"mine={other}"])
    assert choose_env("GearSpeed-v0", [str(v0_run), str(other)]) == "GearSpeed-v0"


def test_compare_is_one_call_and_refuses_a_model_of_another_layout():
    from gymnasium import spaces

    from agents import compare

    class Holder:  # holds omega 1.25 on v1 (action = set-point on [-1, 1] over omega 0.1-3.0)
        observation_space = spaces.Box(-1, 1, (10,), np.float32)
        action_space = spaces.Box(-1, 1, (1,), np.float32)

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            a = np.full((len(np.atleast_2d(obs)), 1), 2 * (1.25 - 0.1) / 2.9 - 1, np.float32)
            return a, state

    rep = compare(Holder(), env_id="GearSpeed-v1", episodes=1, seed=9001, settings={"max_steps": 6})
    assert list(rep.episodes) == ["model", "oracle", "fixed-best"] and rep.reference == "oracle"
    assert "% of oracle" in rep.to_markdown()
    assert np.isfinite(rep.percent_of_reference("model"))
    wrong = Holder()
    wrong.observation_space = spaces.Box(-1, 1, (15,), np.float32)
    with pytest.raises(ValueError, match="observation_space"):
        compare(wrong, env_id="GearSpeed-v1", episodes=1)
