"""Issue 25: hypothesis mutates the valid files the package ships and writes (bytes, JSON fields,
archive members) and every loader must either load the file or refuse it with a ValueError: never
another exception (a traceback), never code from the file (a pickle payload that would create a
marker file), Python-traced memory under ``MEMORY_BOUND``, nothing written outside the folder.

The default run draws a few examples per file kind (``derandomize=True``: the same ones every run);
``-m slow`` draws many more (the counts are in docs/RELIABILITY.md).
"""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import sys
import tempfile
import tracemalloc
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import crafted_cases as cc  # noqa: E402

MEMORY_BOUND = cc.MEMORY_BOUND
FAST, SLOW = 8, 150  # examples per file kind: default run, -m slow


class Payload:
    """Unpickling this creates ``marker`` (and nothing else)."""

    def __init__(self, marker: str):
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


# ---------------------------------------------------------------------------------------- mutations
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70) | st.floats(allow_nan=False) | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            yield from _paths(v, (*prefix, i))


@st.composite
def json_mutation(draw, doc):
    """``doc`` with one field replaced, deleted, or an unknown key added."""
    doc = json.loads(json.dumps(doc))
    paths = [p for p in _paths(doc) if p]
    path = draw(st.sampled_from(paths))
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    how = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
    if how == "replace":
        parent[path[-1]] = draw(json_values)
    elif how == "delete" and isinstance(parent, dict):
        del parent[path[-1]]
    elif isinstance(parent, dict):
        parent[draw(st.text(min_size=1, max_size=8))] = draw(json_values)
    else:
        parent.append(draw(json_values))
    return doc


@st.composite
def byte_mutation(draw, data: bytes):
    """``data`` with bytes flipped, a cut, or garbage inserted."""
    b = bytearray(data)
    how = draw(st.sampled_from(["flip", "flip", "truncate", "insert"]))
    if how == "flip":
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(b) - 1))
            b[i] = draw(st.integers(0, 255))
    elif how == "truncate":
        b = b[: draw(st.integers(0, len(b) - 1))]
    else:
        i = draw(st.integers(0, len(b)))
        b[i:i] = draw(st.binary(min_size=1, max_size=64))
    return bytes(b)


@st.composite
def member_mutation(draw, entries: dict[str, bytes], marker: str):
    """Archive members changed: one dropped, replaced by a pickle payload or by mutated bytes, or an extra one."""
    e = dict(entries)
    name = draw(st.sampled_from(sorted(e)))
    how = draw(st.sampled_from(["drop", "payload", "bytes", "extra", "header"]))
    if how == "drop":
        del e[name]
    elif how == "payload":
        e[name] = pickle.dumps(Payload(marker))
    elif how == "bytes":
        e[name] = draw(byte_mutation(e[name])) if e[name] else b"x"
    elif how == "extra":
        e[draw(st.sampled_from(["extra.npy", "x.pth", "data.pkl", name + "2"]))] = draw(st.binary(max_size=256))
    elif name.endswith(".npy"):  # a .npy header declaring another shape
        shape = tuple(draw(st.lists(st.sampled_from([0, 1, 3, 10, 10**6, 10**12]), max_size=3)))
        e[name] = cc.npy_bytes(shape, draw(st.sampled_from(["<f8", "<i8", "|O", "<U32", "|b1"])))
    else:
        e[name] = b""
    return e


def _write_zip(path: Path, entries: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w") as z:
        for n, b in entries.items():
            z.writestr(n, b)


def _entries(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n: z.read(n) for n in z.namelist()}


# ---------------------------------------------------------------------------------------- the check
def _check(work: Path, load: Callable[[], object], marker: Path) -> None:
    """``load()`` works or raises ValueError/OSError; no code ran; memory bounded; nothing outside ``work``."""
    before = set(os.listdir(work.parent))
    tracemalloc.start()
    try:
        load()
    except (ValueError, OSError) as exc:
        assert "\n" not in str(exc), f"not one line: {exc!r}"
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert not marker.exists(), "code from the file ran"
    assert peak <= MEMORY_BOUND, f"traced memory peak {peak / 2**20:.0f} MiB"
    assert set(os.listdir(work.parent)) - before == set(), "wrote outside the folder"


@pytest.fixture(scope="module")
def base():
    cc.warm_up()
    d = Path(tempfile.mkdtemp(prefix="fuzz-"))
    yield d
    shutil.rmtree(d, ignore_errors=True)


def _fresh(base: Path) -> Path:
    w = Path(tempfile.mkdtemp(dir=base))
    return w


SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=list(HealthCheck), database=None)
MODEL_DATA = json.loads(_entries(cc.PRETRAINED / "model.zip")["data"])
POLICY_META = json.loads((cc.POLICY_V1 / "policy.json").read_text())
CONFIG = json.loads((cc.PRETRAINED / "config.json").read_text())


def _model_data_case(base: Path, doc) -> None:
    w = _fresh(base)
    run = cc.run_copy(w)
    e = _entries(run / "model.zip")
    e["data"] = json.dumps(doc).encode()
    _write_zip(run / "model.zip", e)
    _check(w, cc.load_run(run), w / "PWNED")


def _run_archive_case(base: Path, name: str, draw_entries) -> None:
    """A run folder whose archive ``name`` (model.zip, vecnormalize.npz) has mutated members."""
    w = _fresh(base)
    run = cc.run_copy(w)
    _write_zip(run / name, draw_entries(_entries(run / name), str(w / "PWNED")))
    _check(w, cc.load_run(run), w / "PWNED")


def _policy_case(base: Path, doc=None, pt=None) -> None:
    w = _fresh(base)
    pol = cc.shipped_policy(w)
    if doc is not None:
        (pol / "policy.json").write_text(json.dumps(doc))
    if pt is not None:
        (pol / "policy.pt").write_bytes(pt)
    _check(w, cc.load_shipped(pol), w / "PWNED")


def _config_case(base: Path, doc) -> None:
    w = _fresh(base)
    run = cc.run_copy(w)
    (run / "config.json").write_text(json.dumps(doc))
    _check(w, cc.load_run(run), w / "PWNED")


def _checkpoint_case(base: Path, mutate) -> None:
    w = _fresh(base)
    p = cc.sweep_checkpoint(w)
    mutate(p, str(w / "PWNED"))
    _check(w, lambda: cc.load_checkpoint(p), w / "PWNED")


def _latest_case(base: Path, doc) -> None:
    from agents.runs import RunFolder

    w = _fresh(base)
    run = cc.run_copy(w)
    ck = cc.with_checkpoint(run)
    (ck / "latest.json").write_text(json.dumps(doc))
    _check(w, lambda: RunFolder(run).latest_checkpoint(), w / "PWNED")


LATEST = {"steps": 512, "model": "ckpt_000000512.zip", "vecnormalize": "ckpt_000000512_vecnormalize.npz"}
POLICY_PT = (cc.POLICY_V1 / "policy.pt").read_bytes()


def _run_all(n: int, base: Path) -> None:
    """One hypothesis run per file kind, ``n`` examples each."""

    def run(strategy, test) -> None:
        settings(max_examples=n, **SETTINGS)(given(strategy)(test))()

    run(json_mutation(MODEL_DATA), lambda doc: _model_data_case(base, doc))

    def archive(name: str):
        return lambda data: _run_archive_case(base, name, lambda e, m: data.draw(member_mutation(e, m)))

    run(st.data(), archive("model.zip"))
    run(st.data(), archive("vecnormalize.npz"))
    run(json_mutation(POLICY_META), lambda doc: _policy_case(base, doc=doc))
    run(byte_mutation(POLICY_PT), lambda pt: _policy_case(base, pt=pt))
    run(
        st.data(),
        lambda data: _policy_case(
            base, pt=_zip_bytes(data.draw(member_mutation(_entries_bytes(POLICY_PT), str(base / "PWNED"))))
        ),
    )
    run(json_mutation(CONFIG), lambda doc: _config_case(base, doc))
    run(json_mutation(LATEST), lambda doc: _latest_case(base, doc))

    def ck_members(data) -> None:
        def mutate(p: Path, marker: str) -> None:
            _write_zip(p, data.draw(member_mutation(_entries(p), marker)))

        _checkpoint_case(base, mutate)

    run(st.data(), ck_members)

    def ck_bytes(data) -> None:
        def mutate(p: Path, marker: str) -> None:
            p.write_bytes(data.draw(byte_mutation(p.read_bytes())))

        _checkpoint_case(base, mutate)

    run(st.data(), ck_bytes)
    assert not (base / "PWNED").exists()


def _entries_bytes(raw: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(raw)) as z:
        return {n: z.read(n) for n in z.namelist()}


def _zip_bytes(entries: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for n, b in entries.items():
            z.writestr(n, b)
    return buf.getvalue()


def test_mutated_files_load_or_are_refused_cleanly(base):
    _run_all(FAST, base)


@pytest.mark.slow
def test_mutated_files_load_or_are_refused_cleanly_many(base):
    _run_all(SLOW, base)


def test_the_unmutated_files_load(base):
    """The mutations start from files that load (else every example would be a refusal)."""
    w = _fresh(base)
    cc.load_run(cc.run_copy(w))()
    cc.load_shipped(cc.shipped_policy(w))()
    cc.load_checkpoint(cc.sweep_checkpoint(w))
    from agents.runs import RunFolder

    run = w / "run"
    cc.with_checkpoint(run)
    assert RunFolder(run).latest_checkpoint()[0] == 512
    assert np.isfinite(cc.load_run(run)().normalize(np.zeros(10)).sum())
