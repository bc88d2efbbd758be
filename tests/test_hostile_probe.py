"""The case list of ``benchmarks/hostile_probe`` (issue 25's second probe) is well formed; no case is run here.

The probe itself (271 subprocesses, about half an hour) is run by hand:
``python -m benchmarks.hostile_probe`` from the repository root.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.hostile_probe import lib  # noqa: E402
from benchmarks.hostile_probe.__main__ import main, table  # noqa: E402
from benchmarks.hostile_probe.cases import CASES  # noqa: E402


def test_the_case_list_has_unique_names_each_with_a_group_an_expected_text_and_a_function():
    assert len(CASES) == 271  # the table in docs/RELIABILITY.md ("Second probe") has this many rows
    names = [name for name, _, _, _ in CASES]
    assert len(set(names)) == len(names), sorted({n for n in names if names.count(n) > 1})
    for name, expected, group, fn in CASES:
        assert isinstance(name, str) and name.strip(), name
        assert isinstance(expected, str) and expected.strip(), name
        assert isinstance(group, str) and group.strip(), name
        assert callable(fn), name


def test_the_list_option_names_every_case_without_running_any(capsys):
    assert main(["--list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == len(CASES)
    assert main(["--list", "--select", "A alias"]) == 0
    sel = capsys.readouterr().out.splitlines()
    assert 0 < len(sel) < len(CASES) and all("[A alias]" in ln for ln in sel)
    assert main(["--select", "no case has this text"]) == 2


def test_the_table_has_one_row_per_case_and_escapes_bars():
    row = {"i": 3, "group": "A", "name": "a|b", "expected": "exit 2", "rc": 2, "err": "x", "rss": 100}
    text = table(
        [
            {**row, "held": True, "skipped": False, "note": ""},
            {**row, "held": False, "skipped": True, "note": "not root"},
        ]
    )
    lines = text.splitlines()
    assert len(lines) == 4 and "a/b" in lines[2] and lines[2].endswith("| True |")
    assert lines[3].endswith("| skipped: not root |")


def test_the_payload_marker_lives_in_the_working_folder_and_odd_paths_are_refused(tmp_path):
    lib.configure(tmp_path)
    try:
        assert str(tmp_path.resolve()) in lib.payload("x").decode()
        assert lib.payload_mark().parent == tmp_path.resolve()
    finally:
        lib.CFG.out = None
    with pytest.raises(ValueError, match="--out"):
        lib.configure(tmp_path / "a b")
