"""Issue 25: the building blocks of the reading layer (gear_env/untrusted.py), the output lock and the
run-folder rule of ``--overwrite``, each against an independent expectation."""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

from gear_env.errors import FileFormatError
from gear_env.io import OutputLock, hold_outputs, parse_json_text
from gear_env.untrusted import ArraySpec, inside, open_zip, read_member, read_npz, read_regular

PRETRAINED = Path(__file__).resolve().parents[1] / "gear_env" / "data" / "pretrained"


def _lying_zip(declared: int, real: bytes) -> bytes:
    """A zip whose one deflated member declares ``declared`` bytes but inflates to ``real``."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("m", real)
    raw = bytearray(buf.getvalue())
    # patch the uncompressed size in the local header (offset 22) and the central directory (offset 24)
    struct.pack_into("<I", raw, 22, declared)
    cd = raw.rfind(b"PK\x01\x02")
    struct.pack_into("<I", raw, cd + 24, declared)
    return bytes(raw)


def test_a_member_is_never_inflated_beyond_its_declared_size():
    real = bytes(50 * 2**20)  # 50 MB of zeros, ~50 KB deflated
    raw = _lying_zip(1000, real)
    assert len(raw) < 200_000
    z = open_zip(raw, "archive", max_member=4096, max_total=4096, path="lying.zip")
    with pytest.raises(FileFormatError, match="lying.zip.*m.*corrupt member"):
        read_member(z, "m", "lying.zip")  # CRC mismatch after at most 1001 bytes


def test_declared_sizes_are_checked_before_inflating():
    raw = _lying_zip(10**9, b"x" * 10)
    with pytest.raises(FileFormatError, match="m: declares 1,000,000,000 bytes"):
        open_zip(raw, "archive", path="big.zip")


def test_npz_header_shape_is_checked_before_allocating(tmp_path):
    p = tmp_path / "a.npz"
    np.savez(p, x=np.arange(4.0))
    assert np.array_equal(read_npz(p, "stats", {"x": ArraySpec("f", 1, 10)})["x"], np.arange(4.0))
    with pytest.raises(FileFormatError, match="x: shape \\(4,\\) has 4 elements; the limit is 3"):
        read_npz(p, "stats", {"x": ArraySpec("f", 1, 3)})
    with pytest.raises(FileFormatError, match="x: dtype float64 not allowed"):
        read_npz(p, "stats", {"x": ArraySpec("i", 1, 10)})
    with pytest.raises(FileFormatError, match="y.npy: stats lacks this member"):
        read_npz(p, "stats", {"x": ArraySpec("f", 1, 10), "y": ArraySpec("f", 1, 10)})
    np.savez(p, x=np.arange(4.0), extra=np.zeros(2))
    with pytest.raises(FileFormatError, match="extra.npy: unknown member"):
        read_npz(p, "stats", {"x": ArraySpec("f", 1, 10)})


def test_json_numbers_depth_and_size_are_bounded():
    assert parse_json_text("[1.5, 2]", "x") == [1.5, 2]
    with pytest.raises(ValueError, match="a number of 65 characters"):
        parse_json_text("1." + "1" * 63, "x")
    with pytest.raises(ValueError, match="nested deeper than 64"):
        parse_json_text("[" * 65 + "]" * 65, "x")


def test_special_files_are_refused_by_name_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "f")
    with pytest.raises(FileFormatError, match="FIFO"):
        read_regular(tmp_path / "f", "schedule file", 100)
    with pytest.raises(FileFormatError, match="is a directory"):
        read_regular(tmp_path, "schedule file", 100)
    with pytest.raises(FileFormatError, match="does not exist"):
        read_regular(tmp_path / "nope", "schedule file", 100)
    (tmp_path / "big").write_bytes(b"x" * 101)
    with pytest.raises(FileFormatError, match="101 bytes; the limit is 100"):
        read_regular(tmp_path / "big", "schedule file", 100)


def test_paths_that_leave_a_folder_are_refused(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "out").mkdir()
    os.symlink(tmp_path / "out", tmp_path / "run" / "checkpoints")
    assert inside(tmp_path / "run", tmp_path / "run" / "a", "a") == tmp_path / "run" / "a"
    with pytest.raises(FileFormatError, match="checkpoints: leaves the folder"):
        inside(tmp_path / "run", tmp_path / "run" / "checkpoints", "checkpoints")
    with pytest.raises(FileFormatError, match="leaves the folder"):
        inside(tmp_path / "run", tmp_path / "run" / ".." / "x", "x")


def test_a_locked_output_is_refused_under_any_name(tmp_path):
    (tmp_path / "a.json").write_text("1")
    os.symlink(tmp_path / "a.json", tmp_path / "sym.json")
    os.link(tmp_path / "a.json", tmp_path / "hard.json")
    with OutputLock(tmp_path / "a.json"):
        for alias in ("a.json", "sym.json", "hard.json"):
            with pytest.raises(ValueError, match="being written by another process"):
                OutputLock(tmp_path / alias, "--json").acquire()
        OutputLock(tmp_path / "b.json").acquire().release()  # another output is free
    with OutputLock(tmp_path / "hard.json"):  # released: free again, by any name
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "hard.json", "sym.json"]  # no lock left


def test_hold_outputs_refuses_aliases_within_one_command(tmp_path):
    (tmp_path / "a.json").write_text("1")
    os.link(tmp_path / "a.json", tmp_path / "h.png")
    with pytest.raises(ValueError, match="--plot .* is the same file as the output --json"):
        hold_outputs({"--json": tmp_path / "a.json", "--plot": tmp_path / "h.png"})
    with pytest.raises(ValueError, match="exists and is not a folder"):
        hold_outputs({}, folders={"--out": tmp_path / "a.json"})
    with hold_outputs({"--json": tmp_path / "new.json"}, folders={"--out": tmp_path / "d"}):
        assert (tmp_path / "d").is_dir()
        with pytest.raises(ValueError, match="--out .* being written"):
            hold_outputs({}, folders={"--out": tmp_path / "d"})


def test_run_folder_rule_of_overwrite(tmp_path):
    from agents.runs import RUN_MARKER, RunFolder, is_run_folder

    old = tmp_path / "old"
    shutil.copytree(PRETRAINED, old)  # a run folder of an earlier release: no marker
    assert not (old / RUN_MARKER).exists() and is_run_folder(old)
    user = tmp_path / "user"
    (user / "checkpoints").mkdir(parents=True)
    (user / "metrics.csv").write_text("mine\n")
    assert not is_run_folder(user)
    (user / "config.json").write_text(json.dumps({"format": "something-else"}))
    assert not is_run_folder(user)
    (user / "config.json").write_text(json.dumps({"format": "gear-env-run/1"}))
    assert not is_run_folder(user)  # a stub naming the format is not a run config (issue 25, second probe)
    shutil.copy(PRETRAINED / "config.json", user / "config.json")
    assert is_run_folder(user)  # a run config beside metrics: an earlier release's run
    only_cfg = tmp_path / "cfg"
    only_cfg.mkdir()
    (only_cfg / "config.json").write_text(json.dumps({"format": "gear-env-run/1"}))
    assert not is_run_folder(only_cfg)
    RunFolder(only_cfg).mark()
    assert is_run_folder(only_cfg)


def test_the_model_zip_of_an_earlier_release_passes_the_checks():
    from agents.trained import check_model_zip

    raw, data = check_model_zip(PRETRAINED / "model.zip")
    assert raw == (PRETRAINED / "model.zip").read_bytes()
    assert data["policy_kwargs"] == {"net_arch": [64, 64], "log_std_init": -2.0} and data["n_steps"] == 256
