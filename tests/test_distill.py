"""Issue #23: the DAgger warm start from the privileged episode oracle (agents/distill.py, ``train --distill``)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.distill import check_distill, teacher_for  # noqa: E402
from agents.ppo import TrainOptions, train  # noqa: E402
from agents.trained import load_trained_policy  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FAST = {"steps_per_period": 32, "periods_per_step": 8, "max_steps": 16, "warmup_periods": 16}
ENV = "GearSpeedDemand-v0"


def _env() -> dict[str, str]:
    """The test's environment (NUMBA_CACHE_DIR included: the subprocess loads the compiled kernels) + the repo."""
    import os

    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}


def _opts(out: Path, **kw) -> TrainOptions:
    base = dict(out=str(out), env_id=ENV, env_config=FAST, timesteps=0, num_envs=2, eval_episodes=2, distill=3,
                distill_params={"episodes": 6, "epochs": 30}, progress_bar=False, tensorboard=False, verbose=0,
                ppo={"n_steps": 32, "batch_size": 32, "n_epochs": 1})  # fmt: skip
    return TrainOptions(**{**base, **kw})


def _teacher_gap(run: Path, seeds) -> float:
    """Mean |student action - teacher action| over the states the teacher visits on ``seeds``."""
    from agents.envs import make_config
    from gear_env.envs.env import GearSpeedEnv

    cfg = make_config(ENV, FAST)
    env, teacher = GearSpeedEnv(cfg), teacher_for(ENV, cfg)
    student = load_trained_policy(run, model_file="best_model.zip")
    gaps = []
    for s in seeds:
        obs, _ = env.reset(seed=s)
        teacher.observe_episode(env.episode)
        state, start = None, np.array([True])
        for _ in range(cfg.max_steps):
            a, state = teacher.predict(obs[None], state, start)
            b, _ = student.predict(obs[None], None, start, deterministic=True)
            start = np.array([False])
            gaps.append(abs(float(a[0, 0]) - float(b[0, 0])))
            obs, *_rest, term, trunc, _info = env.step(a[0])
            if term or trunc:
                break
    return float(np.mean(gaps))


def test_bad_settings_name_the_field():
    with pytest.raises(ValueError, match="distill .DAgger iterations. must be an integer in"):
        check_distill(-1, {})
    with pytest.raises(ValueError, match="unknown distillation setting.*'episods'"):
        check_distill(2, {"episods": 3})
    with pytest.raises(ValueError, match="distill_episodes must be an integer in \\[1, "):
        check_distill(2, {"episodes": 0})
    with pytest.raises(ValueError, match="distill_learning_rate"):
        check_distill(2, {"learning_rate": float("nan")})
    with pytest.raises(ValueError, match=r"distill_quantile must be null \(squared error\) or a number in \(0, 1\)"):
        check_distill(2, {"quantile": 1.0})
    with pytest.raises(ValueError, match="timesteps must be an integer in \\[1, "):
        TrainOptions(out="x", timesteps=0)  # 0 means "distillation only": refused without a distillation


def test_the_student_learns_the_teacher_and_the_run_is_ordinary(tmp_path):
    out = tmp_path / "d"
    summary = train(_opts(out))
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["distill"]["iterations"] == 3 and cfg["distill"]["episodes"] == 6
    rows = json.loads((out / "metrics.json").read_text())["evaluations"]
    assert [r["timesteps"] for r in rows] == [96, 192, 288]  # 3 iterations x 6 episodes x 16 steps
    assert summary["timesteps"] == 288 and summary["finished"]
    # a fresh actor is far from the teacher; the distilled one is close, on training episodes it never drove
    # (seeds 0-17 drove the distillation; 500-503 are new)
    fresh = tmp_path / "fresh"
    train(_opts(fresh, distill_params={"episodes": 6, "epochs": 1, "learning_rate": 1e-9}))
    assert _teacher_gap(out, range(500, 504)) < 0.5 * _teacher_gap(fresh, range(500, 504))
    # the run folder is an ordinary one: the CLI evaluates it
    r = subprocess.run(
        [sys.executable, "-m", "gear_env", "evaluate", "--env", ENV, "--policy", str(out), "--episodes", "2",
         "--seed", "800000", "--config", str(out / "env_config.json")],
        capture_output=True, text=True, cwd=tmp_path, env=_env(),
    )  # fmt: skip
    assert r.returncode == 0, r.stderr


def test_the_quantile_loss_is_minimised_by_the_labels_quantile():
    """With ``quantile`` q the fit is the labels' q-quantile (pinball loss), without it their mean: a constant
    fitted by gradient descent to skewed labels lands on numpy's quantile / mean."""
    import torch

    from agents.distill import _loss

    labels = torch.as_tensor(np.random.default_rng(0).exponential(1.0, 4000), dtype=torch.float32)
    for q, want in ((None, float(labels.mean())), (0.3, float(np.quantile(labels.numpy(), 0.3))),
                    (0.8, float(np.quantile(labels.numpy(), 0.8)))):  # fmt: skip
        c = torch.zeros((), requires_grad=True)
        opt = torch.optim.Adam([c], lr=0.02)
        for _ in range(1500):
            opt.zero_grad()
            _loss(c.expand(len(labels)), labels, q).backward()
            opt.step()
        assert float(c) == pytest.approx(want, abs=0.02), q
    assert abs(np.quantile(labels.numpy(), 0.3) - float(labels.mean())) > 0.5  # the three targets differ


def test_distillation_is_deterministic_under_a_seed(tmp_path):
    import torch

    def weights(p: Path) -> list[np.ndarray]:
        return [t.detach().numpy().copy() for t in load_trained_policy(p).model.policy.parameters()]

    train(_opts(tmp_path / "a", distill=2))
    train(_opts(tmp_path / "b", distill=2))
    for x, y in zip(weights(tmp_path / "a"), weights(tmp_path / "b"), strict=True):
        np.testing.assert_array_equal(x, y)
    assert torch.get_num_threads() == 1


def test_resume_continues_a_distilled_run_with_ppo(tmp_path):
    out = tmp_path / "d"
    train(_opts(out, distill=2))
    stored = json.loads((out / "config.json").read_text())
    summary = train(_opts(out, distill=2, resume=True, timesteps=192 + 64))
    assert summary["timesteps"] == 256  # one PPO rollout (2 envs x 32 steps) after the 192 distillation steps
    assert json.loads((out / "config.json").read_text()) == stored


def test_tasks_without_a_scenario_distill_from_their_steady_map_oracle(tmp_path):
    """GearSpeed-v1 has no episode scenario: the teacher is its steady-map oracle, and the student learns it."""
    out = tmp_path / "v1"
    train(_opts(out, env_id="GearSpeed-v1", distill=2, distill_params={"episodes": 4, "epochs": 30}))
    rows = json.loads((out / "metrics.json").read_text())["evaluations"]
    assert [r["timesteps"] for r in rows] == [64, 128]


def test_cli_refuses_an_unknown_setting_before_any_work(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "gear_env", "train", "--env", ENV, "--out", str(tmp_path / "x"), "--distill", "2",
         "--distill-set", "epocs=3"],
        capture_output=True, text=True, env=_env(),
    )  # fmt: skip
    assert r.returncode == 2 and "unknown distillation setting(s) ['epocs']" in r.stderr, r.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_the_own_learner_loop_of_the_docs_runs(tmp_path):
    """docs/TRAINING.md's DAgger loop with Gymnasium + torch only runs as written (3 rounds, 60 episodes)."""
    text = (ROOT / "docs" / "TRAINING.md").read_text()
    block = text.split("**With your own learner.**", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    script = tmp_path / "own_loop.py"
    script.write_text(block)
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path,
                       env=_env(), timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    losses = [float(line.rsplit(" ", 1)[1]) for line in r.stdout.splitlines() if line.startswith("round ")]
    assert len(losses) == 3 and all(0 <= v < 0.1 for v in losses), r.stdout


DISTILL = "agents.distill.DistillCallback"


def test_the_zoo_entry_is_the_distillation_recipe_for_gear_env_train_too(tmp_path):
    """agents/hyperparams/ppo.yml's GearSpeedDemand-v0 entry names agents.distill.DistillCallback; gear-env train
    --hyperparams turns it into --distill 12 (distillation only); any other callback is refused."""
    from agents.hyperparams import load_zoo_entry
    from gear_env.cli.train import add_arguments, options_from_args

    conf = ROOT / "agents" / "hyperparams" / "ppo.yml"
    assert load_zoo_entry(conf, ENV)["distill"] == {"iterations": 12}
    import argparse

    p = argparse.ArgumentParser()
    add_arguments(p)
    opts = options_from_args(p.parse_args(["--out", str(tmp_path / "r"), "--env", ENV, "--hyperparams", str(conf)]))
    assert (opts.distill, opts.timesteps, opts.ppo["net_arch"]) == (12, 0, [128, 128])
    # the student learns a speed limit over [1.15, 1.8] without a reference filter (docs/RESULTS.md)
    limit = {"action_mode": "limit", "action_range": [1.15, 1.8], "reference_filter": 1.0}
    assert {k: opts.env_config[k] for k in limit} == limit
    hard = load_zoo_entry(conf, "GearSpeedDemandHard-v0")
    assert hard["env_kwargs"] == {} and hard["distill"] == {"iterations": 12, "quantile": 0.4, "eval_episodes": 64}
    hard_args = ["--out", str(tmp_path / "h"), "--env", "GearSpeedDemandHard-v0", "--hyperparams", str(conf)]
    opts = options_from_args(p.parse_args(hard_args))
    # the shipped Hard recipe: its kept round chosen on 64 in-training evaluation episodes
    assert (opts.distill, opts.distill_params, opts.eval_episodes) == (12, {"quantile": 0.4}, 64)
    assert options_from_args(p.parse_args([*hard_args, "--eval-episodes", "8"])).eval_episodes == 8  # explicit wins
    assert options_from_args(p.parse_args(hard_args[:4])).eval_episodes == 16  # without the entry: the default
    for value in ("2.5", "0", "true", "'64'"):
        odd = tmp_path / "odd.yml"
        odd.write_text(f"{ENV}:\n  callback:\n    - {DISTILL}:\n        eval_episodes: {value}\n")
        with pytest.raises(ValueError, match=r"eval_episodes must be an integer in \[1, 100000\]"):
            options_from_args(p.parse_args(["--out", str(tmp_path / "o"), "--env", ENV, "--hyperparams", str(odd)]))
    bad = tmp_path / "bad.yml"
    bad.write_text(f"{ENV}:\n  callback: stable_baselines3.common.callbacks.CheckpointCallback\n")
    with pytest.raises(ValueError, match="runs only agents.distill.DistillCallback"):
        load_zoo_entry(bad, ENV)


@pytest.mark.slow
def test_rl_zoo_trains_the_distillation_through_the_callback(tmp_path):
    """rl_zoo3.train with the DistillCallback (2 rounds of 3 episodes): the saved model is the distilled actor."""
    conf = tmp_path / "tiny.yml"
    conf.write_text(f"""{ENV}:
  n_envs: 2
  n_timesteps: 4096
  policy: 'MlpPolicy'
  normalize: true
  n_steps: 64
  batch_size: 64
  policy_kwargs: "dict(log_std_init=-1.5, net_arch=[32, 32])"
  callback:
    - agents.distill.DistillCallback:
        iterations: 2
        episodes: 3
        eval_episodes: 2
""")
    r = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", ENV, "--gym-packages", "gear_env",
         "--conf-file", str(conf), "--device", "cpu", "--seed", "0", "--eval-freq", "-1", "-f", str(tmp_path / "logs")],
        capture_output=True, text=True, cwd=tmp_path, env=_env(),
        timeout=900,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "[distill] done: 600 environment steps" in r.stdout and "[distill] kept round" in r.stdout
    from stable_baselines3 import PPO

    model = PPO.load(str(tmp_path / "logs" / "ppo" / f"{ENV}_1" / f"{ENV}.zip"), device="cpu")
    assert model.num_timesteps == 602  # 600 distilled + the one step (2 envs) at which it stopped: no PPO update


def test_under_a_dead_time_the_teacher_predicts_from_the_students_actions(tmp_path):
    """GearSpeedDemandHard-v0 (one step of dead time): with ``sent`` the teacher's predicted omega (its Smith
    predictor) is the one the environment reaches while another policy drives; the recipe runs there."""
    from agents.distill import sent
    from agents.envs import make_config
    from gear_env.envs.env import GearSpeedEnv

    cfg = make_config("GearSpeedDemandHard-v0", FAST)
    env, teacher = GearSpeedEnv(cfg), teacher_for("GearSpeedDemandHard-v0", cfg)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=3)
    teacher.observe_episode(env.episode)
    state, start = None, np.array([True])
    misses = 0
    for _ in range(cfg.max_steps):
        label, state = teacher.predict(obs[None], state, start)
        start = np.array([False])
        ahead = float(state["omega_ahead"][0])
        act = float(rng.uniform(-1, 1))
        misses += abs(act - float(label[0, 0])) > 0.1  # the driver does not follow the teacher
        state = sent(state, act)
        obs, _r, term, trunc, info = env.step(np.array([act], np.float32))
        assert info["omega"] == pytest.approx(ahead, abs=1e-6)
    assert misses > cfg.max_steps // 2
    out = tmp_path / "hard"
    train(_opts(out, env_id="GearSpeedDemandHard-v0", distill=2, distill_params={"episodes": 4, "epochs": 5}))
    assert json.loads((out / "config.json").read_text())["env_id"] == "GearSpeedDemandHard-v0"
