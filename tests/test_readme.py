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


def _subcommand_options() -> dict[str, set[str]]:
    """Every ``gear-env`` sub-command with the option strings its parser accepts."""
    import argparse

    from gear_env.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {s for a in p._actions for s in a.option_strings} for name, p in sub.choices.items()}


COMMAND = re.compile(r"gear-env (\w[\w-]*)((?:[^`\n|]|\\\n)*)")


def readme_flags(text: str) -> list[tuple[str, str]]:
    """(sub-command, --flag) pairs the README names after ``gear-env <sub-command>``."""
    pairs = []
    for m in COMMAND.finditer(text.replace("\\\n", " ")):
        for flag in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", m.group(2)):
            pairs.append((m.group(1), flag))
    return pairs


def test_flag_reader_finds_flags_of_each_command():
    text = "`gear-env sweep --points 3 [--json out.json]` and\n    gear-env train --out x \\\n    --resume\n"
    assert readme_flags(text) == [("sweep", "--points"), ("sweep", "--json"), ("train", "--out"), ("train", "--resume")]


def test_every_command_and_flag_the_readme_names_exists():
    options = _subcommand_options()
    text = README.read_text(encoding="utf-8")
    missing = [
        f"gear-env {c} {f}" for c, f in readme_flags(text) if c not in options or f not in options[c] | {"--help"}
    ]
    assert not missing, "the README names commands/flags that do not exist: " + ", ".join(sorted(set(missing)))
