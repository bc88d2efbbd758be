"""Issue 25: every crafted file and concurrent writer of ``benchmarks/crafted_cases.py`` as a test.

A case holds when it ends as expected (a one-line refusal naming the file or option and the field,
or a normal load for the valid files of earlier releases), without a traceback, with the
Python-traced memory peak under ``MEMORY_BOUND`` and nothing written outside its folder. The
decompression bombs (600 and 800 MB streamed into a zip) and the 100,000-deep NetCDF attribute take
seconds to *build*, so they run with ``-m slow`` (and in CI's slow stage through the script).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import crafted_cases as cc  # noqa: E402

SLOW = {
    "model.zip policy.pth bomb (600 MB)",
    "vecnormalize.npz unused 800 MB member",
    ".nc config attribute 100,000 deep",
    ".nc of another kind, 200 MiB zlib zeros",
}


@pytest.fixture(scope="module", autouse=True)
def _warm(tmp_path_factory):
    import matplotlib

    matplotlib.use("Agg")
    cc.warm_up()


@pytest.mark.parametrize(
    "case", [pytest.param(c, id=c.name, marks=[pytest.mark.slow] if c.name in SLOW else []) for c in cc.CASES]
)
def test_crafted_case_holds(case, tmp_path):
    out, held, why = cc.run_case(case, tmp_path)
    assert held, f"{case.name}: {why} ({out.kind}: {out.message})"


def test_every_case_has_a_distinct_name():
    names = [c.name for c in cc.CASES]
    assert len(names) == len(set(names))
