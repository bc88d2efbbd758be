"""``gear-env compile`` fills the numba cache ahead of time, in parallel processes."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from gear_env.cli import main
from gear_env.envs.warmup import GROUPS, check_groups, compile_kernels


def test_list_and_bad_input(capsys):
    assert main(["compile", "--list"]) == 0
    out = capsys.readouterr().out
    assert all(g in out for g in GROUPS)
    assert main(["compile", "--only", "gpu"]) == 2
    err = capsys.readouterr().err
    assert "unknown kernel group 'gpu'; groups: tangent, simulator, simd-dynamic, simd-constant" in err
    assert main(["compile", "--jobs", "0"]) == 2
    assert "--jobs must be >= 1" in capsys.readouterr().err
    with pytest.raises(ValueError, match="jobs must be an integer >= 1"):
        compile_kernels(["simulator"], jobs=0)
    assert check_groups(None) == list(GROUPS)
    assert check_groups(["simd-constant", "simd-constant"]) == ["simd-constant"]


def test_a_failing_group_is_reported(monkeypatch):
    """A worker that fails (here: an unknown group slipped past the check) is named with its error."""
    monkeypatch.setattr("gear_env.envs.warmup.check_groups", lambda groups: list(groups))
    with pytest.raises(RuntimeError, match=r"(?s)failed for nope \(exit 1\):.*unknown kernel group 'nope'"):
        compile_kernels(["nope"], jobs=1)


_CHILD = r"""
import json
from gear_env import GearSimulator, simulate_batch
from gear_env.sim import kernels as K, batch_kernels as BK
GearSimulator(model="dynamic", omega=1.2).advance(2)
GearSimulator(model="constant", omega=0.8).record(1)
simulate_batch([0.9, 1.3], model="dynamic", periods=2, transient=1)
print(json.dumps({f.__name__: len(f.stats.cache_misses) for f in
                  (K.integrate_stats, K.integrate_record, BK._lanes_dynamic)}))
"""


@pytest.mark.slow
def test_compiled_cache_serves_later_processes(tmp_path):
    """From an empty cache: after ``gear-env compile --only simulator simd-dynamic`` a new process
    at other omegas and step counts loads every kernel it calls from the disk cache (no compile)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    cp = subprocess.run(
        [sys.executable, "-m", "gear_env", "compile", "--only", "simulator", "simd-dynamic", "--jobs", "2"],
        env=env, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert cp.returncode == 0, cp.stdout + cp.stderr
    assert "[2/2]" in cp.stdout and "done in" in cp.stdout
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {
        "integrate_stats": 0,
        "integrate_record": 0,
        "_lanes_dynamic": 0,
    }
