"""Faults: processes killed with SIGKILL while they write a sweep checkpoint or a results file,
stable-baselines3 ``SubprocVecEnv`` workers (warm and cold numba cache), and read-only or full
output folders for every file the user keeps (``SweepResult.save``, ``gear-env simulate --json``,
``gear-env evaluate --json``)."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
import pytest

from gear_env import io as gio
from gear_env.analysis import SweepResult, sweep
from gear_env.cli import main as cli_main

GRID = np.linspace(0.9, 1.3, 6)
FAST = dict(model="constant", transient=20, periods=12, progress=False, steps_per_period=32, lyapunov=False)

KILL_SCRIPT = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from gear_env import io as gio
    import gear_env.analysis.checkpoint as C
    from gear_env.analysis import sweep

    GRID = np.linspace(0.9, 1.3, 6)
    FAST = dict(model="constant", transient=20, periods=12, progress=False, steps_per_period=32, lyapunov=False)
    real = gio.atomic_write
    calls = [0]

    def hanging_after(n):
        def atomic_write(path, writer):
            calls[0] += 1
            if calls[0] <= n:
                return real(path, writer)

            def half(tmp):  # write the new file completely, cut it in half, then hang before the rename
                writer(tmp)
                with open(tmp, "r+b") as fh:
                    fh.truncate(200)
                print("WRITING", flush=True)
                time.sleep(600)

            return real(path, half)
        return atomic_write

    if __name__ == "__main__":
        mode, path = sys.argv[1], sys.argv[2]
        if mode == "checkpoint":  # a serial sweep that saves after every point; the 3rd save is killed
            C.MIN_INTERVAL = 0.0
            C.atomic_write = hanging_after(2)
            sweep(GRID, checkpoint=path, **FAST)
        else:  # save a 2-point result, then get killed while overwriting it with a 6-point one
            sweep(GRID[:2], **FAST).save(path)
            gio.atomic_write = hanging_after(0)
            sweep(GRID, **FAST).save(path)
        print("NOT KILLED", flush=True)
    """
)


def run_and_kill(tmp_path, mode: str, target) -> None:
    script = tmp_path / "victim.py"
    script.write_text(KILL_SCRIPT)
    proc = subprocess.Popen(
        [sys.executable, str(script), mode, str(target)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line = proc.stdout.readline()
        assert line.strip() == "WRITING", (line, proc.stderr.read() if proc.poll() is not None else "")
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(timeout=60) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def test_sweep_killed_while_writing_its_checkpoint_resumes_identically(tmp_path):
    ck = tmp_path / "sweep.ckpt.npz"
    run_and_kill(tmp_path, "checkpoint", ck)
    with np.load(ck) as z:  # the previous checkpoint, complete
        assert z["index"].tolist() == [0, 1]
    debris = [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert len(debris) == 1  # SIGKILL leaves the half-written temp file; it is never read
    calls: list[int] = []
    resumed = sweep(GRID, checkpoint=str(ck), _on_point=calls.append, **FAST)
    assert len(calls) == len(GRID) - 2  # only the unfinished points ran
    full = sweep(GRID, **FAST)
    np.testing.assert_array_equal(resumed.poincare, full.poincare)
    np.testing.assert_array_equal(resumed.final_states, full.final_states)
    assert resumed.regime == full.regime
    assert not ck.exists()  # removed after success


def test_results_file_killed_mid_overwrite_keeps_the_previous_result(tmp_path):
    out = tmp_path / "result.nc"
    run_and_kill(tmp_path, "results", out)
    r = SweepResult.load(str(out))  # checksum verified: the complete old file
    expected = sweep(GRID[:2], **FAST)
    np.testing.assert_array_equal(r.omega, GRID[:2])
    np.testing.assert_array_equal(r.poincare, expected.poincare)


# ---------------------------------------------------------------------------------- SubprocVecEnv
SUBPROC_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import numpy as np

    KW = dict(max_steps=4, periods_per_step=4, warmup_periods=8, steps_per_period=32)

    def make():
        import gymnasium as gym
        import gear_env  # registers GearSpeed-v0 in the worker

        return gym.make("GearSpeed-v0", **KW)

    if __name__ == "__main__":
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

        n = int(sys.argv[1])
        acts = np.random.default_rng(0).uniform(-1, 1, (6, n, 1)).astype(np.float32)
        out = {}
        for name, cls in (("subproc", SubprocVecEnv), ("dummy", DummyVecEnv)):
            venv = cls([make] * n)
            venv.seed(7)
            rows = [venv.reset().tolist()]
            for a in acts:
                obs, rew, done, _ = venv.step(a)
                # DummyVecEnv keeps rewards in a float32 buffer, SubprocVecEnv passes the float64 ones on
                rows.append([obs.tolist(), rew.astype(np.float32).tolist(), done.tolist()])
            venv.close()
            out[name] = rows
        print(json.dumps(out))
    """
)


def run_subproc_vec_env(tmp_path, n: int, cache_dir: str | None):
    script = tmp_path / "subproc.py"
    script.write_text(SUBPROC_SCRIPT)
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    proc = subprocess.run([sys.executable, str(script), str(n)], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["subproc"] == out["dummy"]  # bit-identical, every step
    # and the first observations equal single envs seeded 7 + i in this process
    from gear_env.envs.env import GearSpeedEnv

    first = [
        GearSpeedEnv(max_steps=4, periods_per_step=4, warmup_periods=8, steps_per_period=32).reset(seed=7 + i)[0]
        for i in range(n)
    ]
    np.testing.assert_array_equal(np.array(out["subproc"][0], np.float32), np.stack(first))
    return out


def test_subproc_vec_env_two_workers_matches_dummy_vec_env(tmp_path):
    run_subproc_vec_env(tmp_path, 2, None)  # the shared (warm) cache


@pytest.mark.slow
def test_subproc_vec_env_three_workers_from_a_cold_numba_cache(tmp_path):
    """Three workers compile the env kernels into an empty cache at the same time (~30-60 s)."""
    cache = tmp_path / "cold-cache"
    run_subproc_vec_env(tmp_path, 3, str(cache))
    assert any(cache.rglob("*.nbi"))  # they did write the cache
    run_subproc_vec_env(tmp_path, 3, str(cache))  # and read it back


# ---------------------------------------------------------------------------------- unwritable output
@pytest.fixture(scope="module")
def small_result():
    return sweep(GRID[:2], **FAST)


def read_only_folder(tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    if os.access(ro, os.W_OK):  # root ignores permissions: emulate a read-only mount
        real_access = os.access
        monkeypatch.setattr(os, "access", lambda p, m, **k: False if str(p) == str(ro) else real_access(p, m, **k))
    return ro


def read_only_mount(monkeypatch):
    """EROFS from creating the temp file, as a read-only file system gives even to root."""

    def erofs(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", erofs)


def full_disk(monkeypatch):
    """ENOSPC when the data is flushed (where a full disk shows up for buffered writes)."""

    def enospc(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(gio.os, "fsync", enospc)


FAULTS = {
    "read-only folder": ("not writable", lambda tp, mp: read_only_folder(tp, mp)),
    "read-only mount": ("Read-only file system", lambda tp, mp: read_only_mount(mp) or tp),
    "full disk": ("No space left", lambda tp, mp: full_disk(mp) or tp),
}


def simulate_json(path):
    return ["simulate", "--omega", "1.2", "--periods", "2", "--transient", "0", "--steps-per-period", "16"] + [
        "--json",
        str(path),
    ]


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_sweep_result_save_reports_unwritable_output(tmp_path, monkeypatch, small_result, fault):
    word, setup = FAULTS[fault]
    old = tmp_path / "old.nc"
    small_result.save(str(old))
    before = old.read_bytes()
    folder = setup(tmp_path, monkeypatch)
    target = folder / "old.nc" if folder != tmp_path else old
    try:
        with pytest.raises(OSError, match=word) as exc:
            small_result.save(str(target))
        assert "old.nc" in str(exc.value) or "ro" in str(exc.value)
    finally:
        monkeypatch.undo()
        (tmp_path / "ro").chmod(0o700) if (tmp_path / "ro").exists() else None
    assert old.read_bytes() == before  # the previous file is untouched
    assert not [p for p in tmp_path.rglob("*.tmp")]  # and no debris is left


@pytest.mark.parametrize("fault", sorted(FAULTS))
@pytest.mark.parametrize("command", ["simulate", "evaluate"])
def test_cli_json_output_reports_unwritable_output(tmp_path, monkeypatch, capsys, fault, command):
    word, setup = FAULTS[fault]
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"max_steps": 2, "periods_per_step": 2, "warmup_periods": 4, "steps_per_period": 16}))
    folder = setup(tmp_path, monkeypatch)
    out = folder / "out.json"
    if command == "simulate":
        argv = simulate_json(out)
    else:
        argv = ["evaluate", "--schedule", "constant:1.2", "--episodes", "1", "--config", str(cfg), "--json", str(out)]
    try:
        rc = cli_main(argv)
    finally:
        monkeypatch.undo()
        (tmp_path / "ro").chmod(0o700) if (tmp_path / "ro").exists() else None
    err = capsys.readouterr().err
    assert rc == 2
    assert f"gear-env {command}: error:" in err and word in err, err
    assert "Traceback" not in err
    assert not out.exists() and not [p for p in tmp_path.rglob("*.tmp")]
