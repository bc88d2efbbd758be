"""The first-call compile is announced once, only when the numba cache has no code of the kernel."""

from __future__ import annotations

import gear_env._numba_cache as NC


def test_announces_once_on_an_empty_cache(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("GEAR_ENV_QUIET", raising=False)
    monkeypatch.setattr(NC, "_CHECKED", set())
    assert NC.announce_compile("env_kernels", "the environment's kernels", "a minute", cache_dir=str(tmp_path))
    err = capsys.readouterr().err
    assert "compiling the environment's kernels" in err and "gear-env compile" in err
    assert not NC.announce_compile("env_kernels", "the environment's kernels", "a minute", cache_dir=str(tmp_path))
    assert capsys.readouterr().err == ""


def test_silent_when_the_cache_holds_the_kernel(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("GEAR_ENV_QUIET", raising=False)
    monkeypatch.setattr(NC, "_CHECKED", set())
    sub = tmp_path / "gear_env_0123"
    sub.mkdir()
    (sub / "env_kernels.post_step-10.py311.nbi").write_bytes(b"")
    assert NC.cache_has("env_kernels", str(tmp_path))
    assert not NC.cache_has("drivers", str(tmp_path))
    assert not NC.announce_compile("env_kernels", "x", "y", cache_dir=str(tmp_path))
    assert capsys.readouterr().err == ""


def test_quiet_switch(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GEAR_ENV_QUIET", "1")
    monkeypatch.setattr(NC, "_CHECKED", set())
    assert not NC.announce_compile("drivers", "x", "y", cache_dir=str(tmp_path))
    assert capsys.readouterr().err == ""


def test_a_new_process_with_an_empty_cache_announces_the_env_compile(tmp_path):
    """What a user sees: the line appears before the (long) compile of the first gym.make().reset()."""
    import os
    import subprocess
    import sys

    code = (
        "import gear_env.envs.env_core as C, gear_env.envs.env_config as E; "
        "C.GearSpeedCore(E.GearSpeedConfig(), 1, single=True)"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    env.pop("GEAR_ENV_QUIET", None)
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stderr.count("gear-env: compiling the environment's kernels") == 1
