"""Every Python block of the README runs when saved as a script (``python block.py``), as a newcomer would."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def python_blocks(text: str) -> list[str]:
    """The bodies of the README's ```python fenced blocks, in order."""
    return [m.group(1) for m in FENCE.finditer(text)]


def test_readme_has_python_blocks():
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 3, "the README's quick start lost its Python blocks"


def test_fence_parser_finds_exact_bodies():
    text = "x\n```python\na = 1\nb = 2\n```\n```bash\nls\n```\n```python\nc = 3\n```\n"
    assert python_blocks(text) == ["a = 1\nb = 2\n", "c = 3\n"]


@pytest.mark.parametrize("index", range(len(python_blocks(README.read_text(encoding="utf-8")))))
def test_readme_block_runs_as_saved_script(index, tmp_path):
    block = python_blocks(README.read_text(encoding="utf-8"))[index]
    script = tmp_path / f"readme_block_{index}.py"
    script.write_text(block, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, (
        f"README Python block {index} failed as a script:\n{block}\n--- stderr ---\n{proc.stderr[-3000:]}"
    )
