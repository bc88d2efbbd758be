"""The core install (``pip install gear-env``: no torch, stable-baselines3 or pandas) imports the package and
runs the environments, schedules, the evaluation and the scripted baselines; what needs the ``rl`` extra says
so. Run in a subprocess whose import system refuses those packages, as if they were not installed."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

BLOCK = textwrap.dedent(
    """
    import sys

    BLOCKED = ("torch", "stable_baselines3", "pandas", "rl_zoo3", "tensorboard", "xarray")

    class Block:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {name!r} (blocked: core install)", name=name)
            return None

    for m in list(sys.modules):
        if m.split(".")[0] in BLOCKED:
            del sys.modules[m]
    sys.meta_path.insert(0, Block())
    """
)


def run_core(code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    script = tmp_path / "core.py"
    script.write_text(BLOCK + textwrap.dedent(code), encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )


def test_the_blocker_blocks(tmp_path):
    proc = run_core("import torch\n", tmp_path)
    assert proc.returncode != 0 and "blocked: core install" in proc.stderr


def test_core_runs_the_environments_schedules_and_evaluation_without_torch(tmp_path):
    proc = run_core(
        """
        import gymnasium as gym
        import numpy as np

        import gear_env
        from gear_env import simulate
        from gear_env.evaluation import evaluate_policies
        from gear_env.envs.schedules import SpeedSchedule
        from agents.registry import resolve_policy

        assert simulate(1.2, periods=5, transient=5).amplitude("U") > 0
        for env_id in ("GearSpeed-v1", "GearSpeedDemand-v0"):
            env = gym.make(env_id, max_episode_steps=2)
            obs, info = env.reset(seed=0)
            obs, r, term, trunc, info = env.step(np.zeros(1, np.float32))
            assert np.isfinite(r) and info["cost"] >= 0
        venv = gym.make_vec("GearSpeed-v1", num_envs=2, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        venv.step(np.zeros((2, 1), np.float32))
        cfg = gear_env.envs.env_config.task_config("GearSpeed-v1", {"max_steps": 3})
        rep = evaluate_policies(
            {"s": SpeedSchedule.constant(1.2), "h": resolve_policy("hill-climber", cfg)}, cfg, episodes=1
        )
        assert "| s |" in rep.to_markdown()
        try:
            resolve_policy("pretrained", cfg, env_id="GearSpeed-v1")
        except ImportError as exc:
            assert "gear-env[rl]" in str(exc), exc
        else:
            raise AssertionError("the pretrained policy loaded without torch")
        try:
            import gear_env.envs.sb3_adapter  # noqa: F401
        except ImportError as exc:
            assert "gear-env[rl]" in str(exc), exc
        else:
            raise AssertionError("the SB3 adapter imported without stable-baselines3")
        import sys
        assert not any(m.split(".")[0] in ("torch", "stable_baselines3", "pandas") for m in sys.modules)
        print("core ok")
        """,
        tmp_path,
    )
    assert proc.returncode == 0 and "core ok" in proc.stdout, proc.stderr[-3000:]
