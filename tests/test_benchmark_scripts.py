"""The benchmark and example scripts refer only to names the package has.

numba resolves a kernel's global names when it compiles, not when the script is imported, so a
script that calls a renamed kernel function imports fine and fails only when it is run (this
happened to ``benchmarks/kernel_interleave.py``). This test reads every script's syntax tree and
checks each ``from gear_env... import name`` and each ``alias.name`` where ``alias`` is a
``gear_env`` module imported as ``import gear_env.x as alias`` or ``from gear_env import x as alias``.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted([*ROOT.glob("benchmarks/*.py"), *ROOT.glob("examples/*.py"), ROOT / "train.py"])


def _missing_names(path: Path) -> list[str]:
    """``module.name`` strings that a script uses but the package does not define."""
    tree = ast.parse(path.read_text(), filename=str(path))
    aliases: dict[str, object] = {}  # local name -> gear_env module object
    missing = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "gear_env":
            mod = importlib.import_module(node.module)
            for a in node.names:
                if not hasattr(mod, a.name):
                    try:  # a submodule imported by name (from gear_env import kernels)
                        sub = importlib.import_module(f"{node.module}.{a.name}")
                    except ImportError:
                        missing.append(f"{node.module}.{a.name}")
                        continue
                    aliases[a.asname or a.name] = sub
                elif type(getattr(mod, a.name)).__name__ == "module":
                    aliases[a.asname or a.name] = getattr(mod, a.name)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "gear_env" and a.asname:
                    aliases[a.asname] = importlib.import_module(a.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            mod = aliases[node.value.id]
            if not hasattr(mod, node.attr):
                missing.append(f"{mod.__name__}.{node.attr} (line {node.lineno})")  # type: ignore[attr-defined]
    return missing


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_script_uses_only_existing_package_names(path):
    assert _missing_names(path) == []


def test_the_check_finds_a_missing_kernel_name(tmp_path):
    """The check itself can fail: a script calling a kernel function that does not exist."""
    bad = tmp_path / "bad.py"
    bad.write_text("from gear_env import kernels as K\n\ndef f():\n    return K.interval_step_t(1)\n")
    assert _missing_names(bad) == ["gear_env.sim.kernels.interval_step_t (line 4)"]
    worse = tmp_path / "worse.py"
    worse.write_text("from gear_env.sim.kernels import no_such_kernel\n")
    assert _missing_names(worse) == ["gear_env.sim.kernels.no_such_kernel"]


def test_batch_ratio_benchmark_runs_on_a_small_case():
    """bench_simulator.ratio_batch (simulate_batch from given starts vs DOP853 per omega) on two
    omegas and a few periods: both DOP853 variants found a tolerance that reaches Newmark's error
    and were timed slower than the Newmark batch."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_simulator as B
    finally:
        sys.path.pop(0)
    r = B.ratio_batch("constant", (1.2, 2.8), 3, 64)
    assert r["omegas"] == 2 and 0.0 < r["err_max"] < 1e-2
    for label in ("events", "plain"):
        x = r[label]
        assert x is not None and x["batch"] > 1.0 and x["single"] > 1.0
        assert x["t_dop"] > x["t_batch"] > 0.0
