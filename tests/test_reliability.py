"""Faults and reproducibility: cold numba caches compiled by two processes at once, identical
numbers across processes, atomic writes that survive a crash, clear errors for unwritable output."""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from gear_env import simulate
from gear_env.io import atomic_write, atomic_write_text

SCRIPT = textwrap.dedent(
    """
    import json, sys
    from gear_env import simulate
    tr = simulate(1.7, model=sys.argv[1], periods=5, transient=20, steps_per_period=32)
    print(json.dumps(tr.poincare("delta").tolist()))
    """
)


def _run_pair(tmp_path, cache_dir):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", SCRIPT, model], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for model in ("dynamic", "dynamic")
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (_out, err) in zip(procs, outs):
        assert p.returncode == 0, err
    return [json.loads(o) for o, _ in outs]


def test_cold_cache_two_processes_and_cross_process_determinism(tmp_path):
    """Two processes compile into the same empty numba cache at once; both work, and agree
    bit-for-bit with each other, with a warm-cache process and with this process."""
    cache = tmp_path / "numba-cache"
    first = _run_pair(tmp_path, cache)
    assert first[0] == first[1]
    warm = _run_pair(tmp_path, cache)
    assert warm[0] == first[0]
    here = simulate(1.7, model="dynamic", periods=5, transient=20, steps_per_period=32).poincare("delta").tolist()
    assert here == first[0]


def test_atomic_write_keeps_old_file_on_crash(tmp_path):
    target = tmp_path / "result.json"
    atomic_write_text(target, json.dumps({"v": 1}))

    def crashing_writer(tmp):
        with open(tmp, "w") as fh:
            fh.write('{"v": 2, "trunc')  # half-written
        raise KeyboardInterrupt  # killed mid-write

    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, crashing_writer)
    assert json.loads(target.read_text()) == {"v": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]  # no temp debris


def test_missing_or_readonly_output_folder_gives_clear_error(tmp_path, monkeypatch):
    with pytest.raises(OSError, match="does not exist"):
        atomic_write_text(tmp_path / "nope" / "x.json", "{}")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    if os.access(ro, os.W_OK):  # root ignores permissions: emulate a read-only mount
        real_access = os.access
        monkeypatch.setattr(os, "access", lambda p, m: False if str(p) == str(ro) else real_access(p, m))
    try:
        with pytest.raises(PermissionError, match="not writable"):
            atomic_write_text(ro / "x.json", "{}")
    finally:
        ro.chmod(0o700)


def test_full_disk_error_is_reported_with_path(tmp_path, monkeypatch):
    def full(tmp):
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="could not write .*x.json.*No space left"):
        atomic_write(tmp_path / "x.json", full)
    assert not (tmp_path / "x.json").exists()


def test_same_numbers_twice_in_process():
    a = simulate(2.0, model="constant", periods=10, transient=10, steps_per_period=32)
    b = simulate(2.0, model="constant", periods=10, transient=10, steps_per_period=32)
    assert np.array_equal(a.data, b.data)


def test_atomic_write_gives_normal_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "r.json", "{}")
    finally:
        os.umask(old)
    assert (tmp_path / "r.json").stat().st_mode & 0o777 == 0o644
