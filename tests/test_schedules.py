"""Speed schedules: interpolation, actions, SB3 compatibility, file validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gear_env.envs.env import GearSpeedEnv
from gear_env.envs.schedules import SpeedSchedule

FAST = dict(max_steps=30, periods_per_step=8, warmup_periods=16)


def test_interpolation_and_hold():
    s = SpeedSchedule.piecewise([(0, 1.0), (10, 2.0), (10, 0.5), (20, 0.5)])
    assert s.omega_at(5) == pytest.approx(1.5)
    assert s.omega_at(-3) == 1.0 and s.omega_at(100) == 0.5
    assert s.omega_at(10) == 0.5  # repeated time = step change
    r = SpeedSchedule.ramp(0.5, 1.5, 20)
    assert r.omega_at(np.array([0, 10, 20, 40])).tolist() == pytest.approx([0.5, 1.0, 1.5, 1.5])


@pytest.mark.parametrize("mode", ["delta", "target"])
def test_constant_schedule_reaches_and_holds_its_speed(mode):
    cfg = dict(FAST, action_mode=mode)
    env = GearSpeedEnv(**cfg)
    sched = SpeedSchedule.constant(1.2, cfg)
    obs, _ = env.reset(seed=0, options={"omega": 2.0})
    start = np.ones(1, bool)
    for _ in range(30):
        a, _ = sched.predict(obs, episode_start=start)
        start = np.zeros(1, bool)
        obs, r, te, tr, info = env.step(a)
        if te or tr:
            break
    assert info["omega"] == pytest.approx(1.2, abs=1e-6)
    # the approach took the rate limit: (2.0 - 1.2) / 0.05 = 16 steps
    assert info["episode_steps"] == 30


def test_ramp_follows_the_schedule_within_the_rate_limit():
    cfg = FAST
    env = GearSpeedEnv(**cfg)
    sched = SpeedSchedule.ramp(1.0, 1.5, 20, cfg)
    obs, _ = env.reset(seed=0, options={"omega": 1.0})
    sched.reset()
    omegas = []
    for _ in range(25):
        a, _ = sched.predict(obs)
        obs, *_, info = env.step(a)
        omegas.append(info["omega"])
    # slope 0.025/step < max_domega: followed exactly (up to float32 observation round-off)
    np.testing.assert_allclose(omegas[:20], 1.0 + 0.025 * np.arange(1, 21), atol=1e-5)
    assert omegas[-1] == pytest.approx(1.5, abs=1e-5)


def test_predict_is_batch_aware_and_resets_per_env():
    s = SpeedSchedule.ramp(1.0, 2.0, 10, "GearSpeed-v0")
    obs = np.zeros((2, 10), np.float32)
    obs[:, 0] = 2 * (1.0 - 0.1) / 2.9 - 1  # omega = 1.0
    a, state = s.predict(obs, episode_start=np.array([True, True]))
    assert a.shape == (2, 1) and a.dtype == np.float32 and state.tolist() == [1, 1]
    a, state = s.predict(obs, state=state, episode_start=np.array([False, True]))
    assert state.tolist() == [2, 1]
    # env 0 is at step 1 (target 1.2: clipped to +1), env 1 restarted (target 1.1 -> 0.1/0.05 = 2 -> 1)
    single, st = s.predict(obs[0], episode_start=np.array([True]))
    assert single.shape == (1,)


def test_works_with_sb3_evaluate_policy():
    from stable_baselines3.common.evaluation import evaluate_policy

    from gear_env.envs.sb3_adapter import SB3VecEnvAdapter

    cfg = dict(FAST, max_steps=10)
    venv = SB3VecEnvAdapter(2, seed=0, **cfg)
    mean, std = evaluate_policy(SpeedSchedule.constant(1.2, cfg), venv, n_eval_episodes=4)
    assert np.isfinite(mean) and np.isfinite(std)


def test_csv_and_json_files(tmp_path):
    c = tmp_path / "s.csv"
    c.write_text("# comment\ntime,omega\n0,0.8\n\n50,1.2\n")
    s = SpeedSchedule.from_file(c)
    assert s.points.tolist() == [[0, 0.8], [50, 1.2]] and s.name == "s"
    for data in ([[0, 0.8], [50, 1.2]], {"points": [[0, 0.8], [50, 1.2]]}, {"time": [0, 50], "omega": [0.8, 1.2]}):
        j = tmp_path / "s.json"
        j.write_text(json.dumps(data))
        assert SpeedSchedule.from_file(j).points.tolist() == [[0, 0.8], [50, 1.2]]
    assert SpeedSchedule.from_spec(str(c)).points.tolist() == [[0, 0.8], [50, 1.2]]
    assert SpeedSchedule.from_spec("constant:1.2").omega_at(7) == 1.2
    assert SpeedSchedule.from_spec("ramp:0.5:1.5:10").omega_at(5) == pytest.approx(1.0)
    assert SpeedSchedule.from_spec("piecewise:0=1,10=2").omega_at(5) == pytest.approx(1.5)


@pytest.mark.parametrize(
    "text, match",
    [
        ("time,omega\n", "empty"),
        ("", "empty"),
        ("0,1.0\nabc,1.2\n", r"row 2: time 'abc' is not a number"),
        ("0,1.0\n5,fast\n", r"row 2: omega 'fast' is not a number"),
        ("0,1.0\n10,1.2\n5,1.3\n", r"row 3: time 5 is smaller than the previous time 10"),
        ("-1,1.0\n", r"row 1: time -1 is negative"),
        ("0,1.0\n5,4.0\n", r"row 2: omega 4 is outside the env range"),
        ("0,1.0,3\n", r"row 1: expected two values"),
        ("0,nan\n", r"row 1: omega 'nan' is not finite"),
    ],
)
def test_bad_csv_files_name_file_row_and_problem(tmp_path, text, match):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match) as exc:
        SpeedSchedule.from_file(p)
    assert "bad.csv" in str(exc.value)


@pytest.mark.parametrize(
    "text, match",
    [
        ("[]", "empty"),
        ("{not json", "not valid JSON"),
        ('{"speeds": []}', "expected a list"),
        ("[[0, 1.0], [3, 0.01]]", r"point 1: omega 0.01 is outside"),
        ('[[0, 1.0], [3, "x"]]', r"point 1: omega 'x' is not a number"),
        ('{"time": [0, 1], "omega": [1.0]}', "equal length"),
    ],
)
def test_bad_json_files(tmp_path, text, match):
    p = tmp_path / "bad.json"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        SpeedSchedule.from_file(p)


def test_missing_file_and_bad_specs(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        SpeedSchedule.from_file(tmp_path / "nope.csv")
    with pytest.raises(ValueError, match="bad schedule spec"):
        SpeedSchedule.from_spec("ramp:1:2")
    with pytest.raises(ValueError, match="outside the env range"):
        SpeedSchedule.from_spec("constant:9")
    with pytest.raises(ValueError, match="steps"):
        SpeedSchedule.ramp(1.0, 2.0, 0)


def test_standalone_example_runs(tmp_path, capsys, monkeypatch):
    import runpy
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "standalone_schedule.py"
    png = tmp_path / "run.png"
    monkeypatch.setattr(sys, "argv", [str(script), "--steps", "12", "--plot", str(png)])
    runpy.run_path(str(script), run_name="__main__")
    out = capsys.readouterr().out
    assert "episode: return" in out and "step  12" in out
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_unbound_schedule_refuses_to_act_and_evaluation_binds_it_to_its_task():
    """Issue #26: a schedule built without config= and run on GearSpeed-v1 produced v0 (delta) actions
    silently. Unbound it now refuses in a plain loop, and the evaluation binds it to the task it runs:
    the same return as the schedule built for that task."""
    import gymnasium as gym

    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    pts = [(0, 0.6), (5, 1.25)]
    unbound = SpeedSchedule.piecewise(pts)
    assert not unbound.bound
    with pytest.raises(ValueError, match="not bound to a task"):
        unbound.predict(np.zeros(10, np.float32))
    cfg = task_config("GearSpeed-v1", {"max_steps": 8})
    rep = evaluate_policies({"unbound": unbound, "bound": SpeedSchedule.piecewise(pts, cfg)}, cfg, episodes=1, seed=3)
    assert rep.episodes["unbound"][0].ret == rep.episodes["bound"][0].ret
    assert rep.episodes["unbound"][0].omega == rep.episodes["bound"][0].omega
    assert not unbound.bound  # binding made a copy: the same schedule can run on another task
    # config=env takes the env's own settings; a schedule bound to v0 is refused on v1
    env = gym.make("GearSpeed-v1")
    assert SpeedSchedule.piecewise(pts, env).config == env.unwrapped.config
    with pytest.raises(ValueError, match="action_mode"):
        evaluate_policies({"v0": SpeedSchedule.piecewise(pts, "GearSpeed-v0")}, cfg, episodes=1)
    with pytest.raises(ValueError, match="env id must be one of"):
        SpeedSchedule.constant(1.2, "GearSpeed-v9")
