"""Issue 25: two writers on one output, as two real processes, for every command that writes.

Writer A starts; as soon as it holds its output lock (the ``.<name>.lock`` file beside the output
appears), A is frozen (SIGSTOP; it keeps its lock) and writer B starts the same command on the same
output. B must be refused at once (exit 2, "is being written by another process"); then A resumes,
must finish normally and its output must be complete (it loads), so nothing is lost. ``evaluate``
runs by default; every command with ``-m slow``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    return env


def _gear_env(*argv: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "gear_env", *argv], cwd=cwd, env=_env(), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _json_ok(p: Path) -> None:
    json.loads(p.read_text())


def _nc_ok(p: Path) -> None:
    from gear_env.analysis.results import SweepResult

    assert len(SweepResult.load(str(p))) == 24


def _run_ok(p: Path) -> None:
    from agents.runs import RunFolder

    run = RunFolder(p)
    run.read_config()
    assert (p / "model.zip").is_file() and run.read_metrics()["summary"]["finished"]


FAST_TRAIN = ["--set", "steps_per_period=32", "--set", "periods_per_step=8", "--set", "max_steps=16",
              "--set", "warmup_periods=16"]  # fmt: skip
COMMANDS = {
    "evaluate": (["evaluate", "--schedule", "constant:1.0", "--episodes", "30", "--json", "{out}"], "r.json", _json_ok),
    "simulate": (["simulate", "--omega", "1.0", "--transient", "150000", "--periods", "8", "--json", "{out}"],
                 "s.json", _json_ok),  # fmt: skip
    "sweep": (["sweep", "--points", "24", "--omega-min", "0.8", "--omega-max", "1.6", "--transient", "400",
               "--periods", "40", "--no-lyapunov", "--quiet", "--out", "{out}"], "w.nc", _nc_ok),  # fmt: skip
    "continuation": (["continuation", "--omega-min", "0.5", "--omega-max", "2.5", "--time-limit", "20", "--quiet",
                      "--json", "{out}"], "c.json", _json_ok),  # fmt: skip
    "stability": (["stability", "--points", "60", "--no-cache", "--json", "{out}"], "m.json", _json_ok),
    "train": (["train", "--out", "{out}", "--timesteps", "2048", "--num-envs", "2", "--ppo", "n_steps=64",
               "--ppo", "batch_size=64", "--ppo", "n_epochs=1", "--eval-freq", "0", "--checkpoint-freq", "1024",
               "--eval-episodes", "2", "--no-progress", "--quiet", "--no-tensorboard", *FAST_TRAIN], "D", _run_ok),
}  # fmt: skip


@pytest.mark.parametrize(
    "command", [pytest.param(c, marks=[] if c == "evaluate" else [pytest.mark.slow]) for c in COMMANDS]
)
def test_a_second_writer_is_refused_and_the_first_loses_nothing(command, tmp_path):
    argv, name, check = COMMANDS[command]
    out = tmp_path / name
    args = [a.replace("{out}", str(out)) for a in argv]
    a = _gear_env(*args, cwd=tmp_path)
    lock = tmp_path / f".{name}.lock"
    t0 = time.monotonic()
    # The lock file is created before it is flocked; the holder's pid is written only once the flock is
    # held, so wait for the pid (stopping A between open and flock once let B take the lock).
    while a.poll() is None and time.monotonic() - t0 < 120:
        try:
            if lock.read_text().strip() == str(a.pid):
                break
        except FileNotFoundError:
            pass
        time.sleep(0.05)
    assert a.poll() is None, f"writer A ended before B could start: {a.communicate()}"
    # Freeze A while B runs: a stopped process keeps its flock, so B meets a held lock however fast
    # A's work is on this machine (a fast A once finished before B had started, and B rightly ran).
    os.kill(a.pid, signal.SIGSTOP)
    try:
        b = _gear_env(*args, cwd=tmp_path)
        b_out, b_err = b.communicate(timeout=300)
    finally:
        os.kill(a.pid, signal.SIGCONT)
    a_out, a_err = a.communicate(timeout=600)
    assert b.returncode == 2, (b_out, b_err)
    assert "being written by another process" in b_err and b_err.count("\n") == 1, b_err
    assert a.returncode in ((0, 1) if command == "continuation" else (0,)), (a_out, a_err)  # 1: time limit hit
    check(out)
    assert not lock.exists()
