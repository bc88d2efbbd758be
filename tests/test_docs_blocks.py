"""Issue #26, item 7: the Python blocks of the docs pages beyond the README and the getting-started page
(tests/test_readme.py runs those) are executed too. Every block parses; every import statement in it runs;
each block runs as a script, with the placeholder names of an API synopsis defined first (``PRELUDE``),
unless ``NOT_RUN`` names it with the reason (code to paste into a module, placeholders that are not Python
values). A new block must run or be listed, so a renamed function or a wrong import path fails a test."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
COVERED = {"GETTING_STARTED.md"}  # tests/test_readme.py runs every block of it (and of README.md)
PAGES = sorted(p for p in (ROOT / "docs").rglob("*.md") if p.name not in COVERED)
BLOCKS = [(p, i, b) for p in PAGES for i, b in enumerate(FENCE.findall(p.read_text(encoding="utf-8")))]
IDS = [f"{p.stem}-{i}" for p, i, _ in BLOCKS]

PRELUDE = {
    "SIMULATOR-0": "import numpy as np\nstarts = np.zeros((3, 10))  # the user's (n, 10) initial states\n",
    "SIMULATOR-1": "from gear_env import GearParams\nparams = GearParams()  # the user's parameters\n",
}
"""Names an API synopsis leaves to the reader, defined before it runs."""
SLOW = {
    "ANALYSIS-0": "a 300-point sweep with Lyapunov exponents, saved to netCDF",
    "TRAINING-0": "three DAgger rounds of 20 GearSpeedDemand-v0 episodes",
}
NOT_RUN = {
    "ANALYSIS-1": "continuation over omega 0.05-3.0 (minutes); tests/test_continuation*.py run continue_orbits",
    "ENVIRONMENT-1": "lines to paste into gear_env/envs/env_terms.py and env_kernels.py (how to add a reward term)",
    "ENVIRONMENT-2": "lines to paste into env_terms.py and env_kernels.py (how to add a cost term)",
    "ENVIRONMENT-3": "a class declaration to paste into gear_env/envs/env_config.py",
    "GEOMETRY-0": "a synopsis whose SpurPair(..., crack=...) elides the arguments; tests/test_geometry.py",
}


def test_every_block_is_run_or_listed_with_a_reason():
    ids = set(IDS)
    assert set(NOT_RUN) <= ids and set(PRELUDE) <= ids and set(SLOW) <= ids, "a listed block no longer exists"
    assert len(BLOCKS) >= 10


@pytest.mark.parametrize("page,index,block", BLOCKS, ids=IDS)
def test_block_parses_and_its_imports_run(page, index, block):
    tree = ast.parse(block, filename=f"{page.name} block {index}")
    imports = [ast.unparse(n) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
    if "env_terms.py" in block or "env_config.py" in NOT_RUN.get(f"{page.stem}-{index}", ""):
        return  # lines of a module, not a script: names are the module's own
    for stmt in imports:
        exec(compile(stmt, f"{page.name} block {index}", "exec"), {})  # a wrong import path raises here


def _run(page, index, block, tmp_path):
    key = f"{page.stem}-{index}"
    script = tmp_path / f"{key}.py"
    script.write_text(PRELUDE.get(key, "") + block, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1200
    )
    assert proc.returncode == 0, (
        f"{page.name} Python block {index} failed as a script:\n--- stderr ---\n{proc.stderr[-3000:]}"
    )


RUN = [(p, i, b) for (p, i, b), k in zip(BLOCKS, IDS, strict=True) if k not in NOT_RUN and k not in SLOW]
RUN_SLOW = [(p, i, b) for (p, i, b), k in zip(BLOCKS, IDS, strict=True) if k in SLOW]


@pytest.mark.parametrize("page,index,block", RUN, ids=[f"{p.stem}-{i}" for p, i, _ in RUN])
def test_block_runs_as_a_script(page, index, block, tmp_path):
    _run(page, index, block, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("page,index,block", RUN_SLOW, ids=[f"{p.stem}-{i}" for p, i, _ in RUN_SLOW])
def test_slow_block_runs_as_a_script(page, index, block, tmp_path):
    _run(page, index, block, tmp_path)


def test_the_import_check_can_fail():
    with pytest.raises(ImportError):
        exec("from gear_env.envs.tasks import task_config", {})  # the path ENVIRONMENT.md once named
