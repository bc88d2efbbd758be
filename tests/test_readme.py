"""Every Python block of the README and of the getting-started page runs when saved as a script
(``python block.py``), as a newcomer would; the README stays a front page (short, no lab notebook) and its
two commands are the ones CI runs."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
GETTING_STARTED = ROOT / "docs" / "GETTING_STARTED.md"
PAGES = (README, GETTING_STARTED)
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
BASH = re.compile(r"^```bash\n(.*?)^```", re.S | re.M)


def python_blocks(text: str) -> list[str]:
    """The bodies of the README's ```python fenced blocks, in order."""
    return [m.group(1) for m in FENCE.finditer(text)]


def test_readme_has_python_blocks():
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 3, "the README's examples lost their Python blocks"
    assert len(python_blocks(GETTING_STARTED.read_text(encoding="utf-8"))) >= 3


def test_readme_is_a_front_page():
    """<= 150 lines, and no dates, load averages or run logs (they belong in docs/BENCHMARKS.md)."""
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    assert not re.findall(r"\b20\d\d-\d\d-\d\d\b", text), "a date in the README"
    assert "load average" not in text and not re.search(r"\bload \d", text), "a load average in the README"


def test_readme_commands_are_the_ones_ci_runs():
    """The README's two commands: install + demo (the `dev` extra, which CI installs too) and the tests,
    which .ci/run runs verbatim."""
    cmds = [b.strip() for b in BASH.findall(README.read_text(encoding="utf-8"))]
    assert len(cmds) == 2, cmds
    install, tests = cmds
    assert "pip install -e '.[dev]'" in install and install.endswith("gear-env demo")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "pip install -q -e '.[dev]'" in ci
    assert any(line.strip() == tests for line in ci.splitlines()), f"{tests!r} is not a line of .ci/run"


def test_fence_parser_finds_exact_bodies():
    text = "x\n```python\na = 1\nb = 2\n```\n```bash\nls\n```\n```python\nc = 3\n```\n"
    assert python_blocks(text) == ["a = 1\nb = 2\n", "c = 3\n"]


BLOCKS = [(page, i) for page in PAGES for i in range(len(python_blocks(page.read_text(encoding="utf-8"))))]


@pytest.mark.parametrize("page,index", BLOCKS, ids=[f"{p.stem}-{i}" for p, i in BLOCKS])
def test_readme_block_runs_as_saved_script(page, index, tmp_path):
    block = python_blocks(page.read_text(encoding="utf-8"))[index]
    script = tmp_path / f"{page.stem}_block_{index}.py"
    script.write_text(block, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, (
        f"{page.name} Python block {index} failed as a script:\n{block}\n--- stderr ---\n{proc.stderr[-3000:]}"
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
    text = "\n".join(p.read_text(encoding="utf-8") for p in PAGES)
    missing = [
        f"gear-env {c} {f}" for c, f in readme_flags(text) if c not in options or f not in options[c] | {"--help"}
    ]
    assert not missing, "the README names commands/flags that do not exist: " + ", ".join(sorted(set(missing)))
