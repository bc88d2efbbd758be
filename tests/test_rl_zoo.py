"""rl-zoo3 on the gear task: train with agents/hyperparams/ppo.yml, replay with enjoy, tune with Optuna.

The tests that train run rl-zoo3's own command line (``python -m rl_zoo3.train`` / ``rl_zoo3.enjoy``)
in subprocesses, as a user types it, on a few thousand environment steps. They are marked slow (each
takes 20-60 s or more on the 2-core VM: Python start-ups with torch, numba cache loads, a short
training); .ci/run runs them explicitly (``pytest -m slow tests/test_rl_zoo.py``).
Installed by ``pip install -e '.[zoo]'`` (in ``dev``).
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rl_zoo3", reason="rl-zoo3 is not installed (pip install -e '.[zoo]')")
optuna = pytest.importorskip("optuna", reason="optuna is not installed (pip install -e '.[zoo]')")
yaml = pytest.importorskip("yaml")

from gear_env.envs.env_config import task_config  # noqa: E402

ZOO_ENV = "GearSpeed-v1"  # the task the tests train on: the well-posed default task, as in docs/TRAINING.md

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "agents" / "hyperparams" / "ppo.yml"
# small enough for a test: 2 sub-envs x 256 steps per update, 2 epochs
SMALL = ["n_envs:2", "n_steps:256", "batch_size:128", "n_epochs:2"]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env.setdefault("OMP_NUM_THREADS", "1")
    env["MPLBACKEND"] = "Agg"
    return env


def _zoo(module: str, args: list[str], cwd: Path, timeout: float = 600) -> str:
    cmd = [sys.executable, "-m", f"rl_zoo3.{module}", "--algo", "ppo", "--env", ZOO_ENV]
    cmd += ["--gym-packages", "gear_env", "--device", "cpu", *args]
    proc = subprocess.run(cmd, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f"{' '.join(cmd)}\n--- stdout\n{proc.stdout[-3000:]}\n--- stderr\n{proc.stderr[-3000:]}"
    )
    return proc.stdout


def test_rl_zoo_hyperparams_file_matches_the_shipped_policy():
    """agents/hyperparams/ppo.yml holds, in rl-zoo3's format, an entry per task; the GearSpeed-v0 entry
    holds the shipped v0 policy's PPO values and env settings."""
    import json

    from agents.ppo import PPO_DEFAULTS
    from agents.registry import pretrained_dir

    conf = yaml.safe_load(CONF.read_text())
    assert {"GearSpeed-v0", "GearSpeed-v1", "GearSpeedDemand-v0"} <= set(conf)
    entry = conf["GearSpeed-v0"]
    shipped = json.loads((pretrained_dir() / "config.json").read_text())
    ppo = shipped["ppo"]
    for key in set(PPO_DEFAULTS) - {"net_arch", "log_std_init", "use_sde", "sde_sample_freq"}:
        assert entry[key] == pytest.approx(ppo[key]), key
    pk = eval(entry["policy_kwargs"], {})  # how rl-zoo3 reads it (a trusted file of this repository)
    assert pk == {"log_std_init": ppo["log_std_init"], "net_arch": ppo["net_arch"]}
    assert entry["n_envs"] == shipped["train"]["num_envs"]
    assert entry["n_timesteps"] == shipped["train"]["timesteps"]
    assert entry["normalize"] is True and shipped["vecnormalize"] is True
    for key, value in entry["env_kwargs"].items():
        assert shipped["env_config"][key] == value, key
    # only keys that rl-zoo3 or SB3's PPO understand (a typo would fail at the start of training)
    import inspect

    from stable_baselines3 import PPO

    zoo_keys = {"n_envs", "n_timesteps", "normalize", "policy_kwargs", "env_kwargs", "policy"}
    assert set(entry) - zoo_keys <= set(inspect.signature(PPO.__init__).parameters)


def test_rl_zoo_limit_task_entry_is_stock_sb3_ppo():
    """The GearSpeedDemandLimit-v0 entry is SB3's PPO with its defaults (the stock-learner result of the task
    page), written out so that gear-env train, whose own defaults differ, runs the same learner."""
    import inspect

    from stable_baselines3 import PPO
    from stable_baselines3.common.policies import ActorCriticPolicy

    entry = yaml.safe_load(CONF.read_text())["GearSpeedDemandLimit-v0"]
    assert (entry["n_envs"], entry["n_timesteps"], entry["normalize"]) == (8, 300000, True)
    defaults = inspect.signature(PPO.__init__).parameters
    zoo_keys = {"n_envs", "n_timesteps", "normalize", "policy_kwargs", "env_kwargs", "policy"}
    for key in set(entry) - zoo_keys:
        assert entry[key] == defaults[key].default, key
    pk = eval(entry["policy_kwargs"], {})  # how rl-zoo3 reads it (a trusted file of this repository)
    assert pk["log_std_init"] == inspect.signature(ActorCriticPolicy.__init__).parameters["log_std_init"].default
    assert pk["net_arch"] == [64, 64]  # SB3's MlpPolicy default for PPO: pi and vf [64, 64] each
    assert "env_kwargs" not in entry  # the registered task as it is


@pytest.mark.slow
def test_rl_zoo_train_then_enjoy_replays_what_gear_env_evaluates(tmp_path):
    """rl_zoo3.train reads the conf file (values in the saved config.yml) and writes a model with its
    VecNormalize statistics; rl_zoo3.enjoy replays it, and its first episode's return equals the
    return gear-env's own evaluation (agents.trained.TrainedPolicy + run_episode) gives the same
    model on the same seed."""
    from stable_baselines3 import PPO

    from agents.trained import TrainedPolicy, load_vecnormalize
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.evaluation import run_episode

    logs = tmp_path / "logs"
    out = _zoo(
        "train",
        ["--conf-file", str(CONF), "-n", "1024", "--hyperparams", *SMALL, "--eval-freq", "-1"]
        + ["--seed", "0", "--num-threads", "1", "-f", str(logs)],
        tmp_path,
    )
    run = logs / "ppo" / f"{ZOO_ENV}_1"
    assert (run / f"{ZOO_ENV}.zip").is_file(), out[-2000:]
    saved = yaml.unsafe_load((run / ZOO_ENV / "config.yml").read_text())  # rl-zoo3 writes an OrderedDict tag
    saved = dict(saved)
    entry = yaml.safe_load(CONF.read_text())[ZOO_ENV]
    assert saved["gamma"] == entry["gamma"] and saved["gae_lambda"] == entry["gae_lambda"]
    assert saved["normalize"] is True and saved["policy_kwargs"] == entry["policy_kwargs"]
    assert saved["n_envs"] == 2 and saved["n_steps"] == 256  # the command-line overrides won

    model = PPO.load(str(run / f"{ZOO_ENV}.zip"), device="cpu")
    assert model.num_timesteps >= 1024
    # rl-zoo3 pickles its statistics; gear-env never unpickles a run folder, so the owner of this
    # (self-made, trusted) run converts it once, as docs/TRAINING.md says
    from agents.runs import convert_pickled_statistics

    vn = load_vecnormalize(convert_pickled_statistics(run / ZOO_ENV / "vecnormalize.pkl"))
    cfg = task_config(ZOO_ENV)
    env = GearSpeedEnv(cfg)
    assert model.observation_space == env.observation_space
    ours = run_episode(env, TrainedPolicy(model, vn), seed=0).ret

    n = str(cfg.max_steps)  # one whole episode
    out = _zoo(
        "enjoy",
        ["-f", str(logs), "--exp-id", "1", "-n", n, "--no-render", "--deterministic", "--seed", "0"],
        tmp_path,
    )
    rewards = [float(x) for x in re.findall(r"Episode Reward: (-?[\d.]+)", out)]
    assert len(rewards) == 1, out[-2000:]
    assert rewards[0] == pytest.approx(ours, abs=0.006)  # enjoy prints 2 decimals


def _journal(path: Path):
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    return JournalStorage(JournalFileBackend(str(path)))


@pytest.mark.slow
def test_rl_zoo_optimize_two_workers_share_one_journal_study(tmp_path):
    """Two rl-zoo3 --optimize processes started at the same time (as on two machines sharing a
    folder) add their trials to one Optuna study in a journal file; the study then has both trials,
    completed, with different sampled hyper-parameters and finite objective values."""
    storage = tmp_path / "shared" / "gear_ppo.log"
    cmd_tail = ["--conf-file", str(CONF), "-n", "512", "--hyperparams", "n_envs:1", "--optimize"]
    cmd_tail += ["--n-trials", "1", "--sampler", "random", "--pruner", "none", "--n-evaluations", "1"]
    cmd_tail += ["--eval-episodes", "1", "--storage", str(storage), "--study-name", "gear-ppo", "--no-optim-plots"]
    cmd_tail += ["--num-threads", "1"]
    procs = []
    for worker in (0, 1):
        cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", ZOO_ENV]
        cmd += ["--gym-packages", "gear_env", "--device", "cpu", *cmd_tail, "--seed", str(worker)]
        cmd += ["-f", str(tmp_path / f"logs{worker}")]
        procs.append(
            (
                cmd,
                subprocess.Popen(
                    cmd, cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
                ),
            )
        )
    for cmd, p in procs:
        so, se = p.communicate(timeout=900)
        assert p.returncode == 0, f"{' '.join(cmd)}\n--- stdout\n{so[-3000:]}\n--- stderr\n{se[-3000:]}"

    study = optuna.load_study(study_name="gear-ppo", storage=_journal(storage))
    done = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) == 2
    assert all(math.isfinite(t.value) for t in done)
    assert done[0].params != done[1].params
    assert "rl_zoo3.train" in study.user_attrs["command"]
    assert study.best_value == max(t.value for t in done)  # the study maximises the mean eval return
