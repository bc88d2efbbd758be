"""Issue 15: nothing a user has is lost or overwritten, and every input is bounded before work.

Real faults where the machine allows them: device nodes made with mknod (as root; a FIFO
otherwise), a tiny tmpfs that fills up (as root; an injected ENOSPC otherwise), two concurrent
writers, kill -9 of a subprocess.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gear_env.cli import main as cli
from gear_env.io import OutputLock, atomic_write_text, check_outputs, read_json

ROOT = Path(__file__).resolve().parents[1]
TINY_SWEEP = [
    "sweep", "--omega-min", "1.0", "--omega-max", "1.2", "--points", "3", "--transient", "1", "--periods", "4",
    "--steps-per-period", "8", "--no-lyapunov", "--quiet",
]  # fmt: skip


def _node(tmp_path: Path) -> Path:
    """A device node (a copy of /dev/null, made with mknod as root), else a FIFO."""
    p = tmp_path / "node"
    if os.geteuid() == 0:
        os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    else:
        os.mkfifo(p)
    return p


def _is_node(p: Path) -> bool:
    m = os.lstat(p).st_mode
    return stat.S_ISCHR(m) or stat.S_ISFIFO(m)


# --------------------------------------------------------------------------------------------------
# 1. non-regular outputs
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "command",
    [
        ["simulate", "--omega", "1.2", "--periods", "2", "--transient", "0", "--steps-per-period", "8", "--json"],
        [*TINY_SWEEP, "--json"],
        ["evaluate", "--schedule", "constant:1.2", "--episodes", "1", "--json"],
    ],
)
def test_device_and_directory_outputs_are_refused_before_work(tmp_path, capsys, command):
    node = _node(tmp_path)
    assert cli([*command, str(node)]) == 2
    err = capsys.readouterr().err
    assert "not a regular file" in err and "--json" in err
    assert _is_node(node)  # still the device (or FIFO), not replaced by a regular file
    assert cli([*command, str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_atomic_write_never_replaces_a_device(tmp_path):
    node = _node(tmp_path)
    with pytest.raises(OSError, match="not a regular file"):
        atomic_write_text(node, "x")
    assert _is_node(node)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]  # no temporary file left
    # a symbolic link to a regular file is written through, the link stays
    (tmp_path / "real.txt").write_text("old")
    (tmp_path / "link.txt").symlink_to(tmp_path / "real.txt")
    atomic_write_text(tmp_path / "link.txt", "new")
    assert (tmp_path / "link.txt").is_symlink() and (tmp_path / "real.txt").read_text() == "new"


# --------------------------------------------------------------------------------------------------
# 6. an output equal to an input or to another output
# --------------------------------------------------------------------------------------------------
def test_outputs_equal_to_inputs_or_each_other_are_refused(tmp_path, capsys):
    sched = tmp_path / "s.csv"
    sched.write_text("0,1.0\n10,1.2\n")
    cfg = tmp_path / "c.json"
    cfg.write_text("{}")
    link = tmp_path / "hard.csv"
    os.link(sched, link)
    cases = [
        ["evaluate", "--schedule", str(sched), "--json", str(sched)],
        ["evaluate", "--schedule", str(sched), "--markdown", str(link)],  # the same file by another name
        ["evaluate", "--schedule", "constant:1", "--config", str(cfg), "--json", str(cfg)],
        [*TINY_SWEEP, "--out", str(tmp_path / "x.nc"), "--json", str(tmp_path / "x.nc")],
        ["simulate", "--omega", "1", "--json", str(tmp_path / "a"), "--plot", str(tmp_path / "a")],
    ]
    for argv in cases:
        assert cli(argv) == 2, argv
        err = capsys.readouterr().err
        assert "is the same file as" in err, (argv, err)
    assert sched.read_text() == "0,1.0\n10,1.2\n" and cfg.read_text() == "{}"
    assert not (tmp_path / "x.nc").exists() and not (tmp_path / "a").exists()


def test_check_outputs_accepts_distinct_new_files(tmp_path):
    check_outputs({"--json": tmp_path / "a.json", "--plot": tmp_path / "a.png"}, {"--config": tmp_path / "none"})
    with pytest.raises(ValueError, match="output folder .* does not exist"):
        check_outputs({"--json": tmp_path / "missing" / "a.json"})


# --------------------------------------------------------------------------------------------------
# 2, 3. the sweep's checkpoint is kept until the result is saved; never discarded silently
# --------------------------------------------------------------------------------------------------
@pytest.fixture
def tiny_disk(tmp_path):
    """A 32 KiB tmpfs (root), or None where mounting is not allowed."""
    d = tmp_path / "tiny"
    d.mkdir()
    if os.geteuid() != 0:
        yield None
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=32k", "tmpfs", str(d)], capture_output=True)
    if r.returncode != 0:
        yield None
        return
    try:
        yield d
    finally:
        subprocess.run(["umount", "-l", str(d)], capture_output=True)


def test_a_full_disk_keeps_every_point_and_resume_writes_without_recomputing(tmp_path, tiny_disk, monkeypatch, capsys):
    import importlib

    from gear_env.analysis.results import SweepResult

    sw = importlib.import_module("gear_env.analysis.sweep")  # the module (the package exports the function)

    ckpt = tmp_path / "sweep.ckpt.npz"
    if tiny_disk is not None:  # a real full disk: the NetCDF result does not fit in 32 KiB
        out = tiny_disk / "sweep.nc"
        (tiny_disk / "filler").write_bytes(b"\0" * 16 * 1024)
    else:  # no tmpfs here: inject the error a full disk gives

        def full(self, path):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))

        out = tmp_path / "sweep.nc"
        monkeypatch.setattr(SweepResult, "save", full)
    argv = [*TINY_SWEEP, "--out", str(out), "--checkpoint", str(ckpt)]
    assert cli(argv) == 2
    cap = capsys.readouterr()
    assert "could not write" in cap.err and "--resume" in cap.out
    assert ckpt.is_file() and not out.exists()
    with np.load(ckpt) as z:
        assert len(z["index"]) == 3  # every finished point is in the checkpoint
    monkeypatch.undo()
    # rerun with --resume into a folder with room: no point is computed again
    monkeypatch.setattr(sw, "run_point", lambda *a, **k: pytest.fail("a finished point was recomputed"))
    good = tmp_path / "ok.nc"
    assert cli([*TINY_SWEEP, "--out", str(good), "--checkpoint", str(ckpt), "--resume"]) == 0
    assert good.is_file() and not ckpt.exists()  # deleted only after the result was saved
    assert not list(tmp_path.glob(".*.lock"))  # the locks are gone too


def test_an_existing_checkpoint_is_not_discarded_without_restart(tmp_path, capsys):
    out = tmp_path / "s.nc"
    ckpt = tmp_path / "s.nc.ckpt.npz"
    ckpt.write_bytes(b"finished points of an earlier, killed sweep")
    assert cli([*TINY_SWEEP, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--resume" in err and "--restart" in err
    assert ckpt.read_bytes() == b"finished points of an earlier, killed sweep"
    assert cli([*TINY_SWEEP, "--out", str(out), "--restart"]) == 0
    assert out.is_file() and not ckpt.exists()


# --------------------------------------------------------------------------------------------------
# 4. two writers of the same output
# --------------------------------------------------------------------------------------------------
HOLD = (
    "import sys, time; from gear_env.io import OutputLock; lock = OutputLock(sys.argv[1]).acquire(); "
    "print('held', flush=True); time.sleep(60)"
)


def _holder(path: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen([sys.executable, "-c", HOLD, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    assert p.stdout is not None and p.stdout.readline().strip() == "held"
    return p


def test_a_second_sweep_with_the_same_out_is_refused(tmp_path, capsys):
    out = tmp_path / "s.nc"
    holder = _holder(out)  # another process is writing s.nc
    try:
        assert cli([*TINY_SWEEP, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "being written by another process" in err and f"pid {holder.pid}" in err
        assert not out.exists()
    finally:
        holder.kill()  # kill -9: the lock dies with its holder
        holder.wait()
    with OutputLock(out):
        pass


def test_two_concurrent_sweeps_one_wins_the_other_is_refused(tmp_path):
    out = tmp_path / "s.nc"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "gear_env", *TINY_SWEEP, "--out", str(out)]
    a = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
    b = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
    ra, rb = a.wait(timeout=600), b.wait(timeout=600)
    errs = a.stderr.read() + b.stderr.read()  # type: ignore[union-attr]
    assert sorted([ra, rb]) in ([0, 0], [0, 2]), errs
    if sorted([ra, rb]) == [0, 2]:
        assert "being written by another process" in errs
    from gear_env.analysis.results import SweepResult

    assert len(SweepResult.load(str(out)).omega) == 3


# --------------------------------------------------------------------------------------------------
# 9, 10, 12, 13. bounds and clear errors (exit 2 naming the argument)
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["simulate", "--omega", "1", "--periods", "99999999999999999999"], "--periods"),
        (["simulate", "--omega", "1", "--transient", "1000000000000"], "--transient"),
        (["simulate", "--omega", "nan"], "--omega"),
        (["sweep", "--points", "100000000000"], "--points"),
        (["sweep", "--workers", "99999999999999999999"], "--workers"),
        (["train", "--out", "x", "--num-envs", "10000000"], "--num-envs"),
        (["evaluate", "--schedule", "constant:1", "--seed", "-1"], "--seed"),
    ],
)
def test_out_of_range_numbers_are_usage_errors_naming_the_flag(argv, flag, capsys):
    assert cli(argv) == 2
    assert flag in capsys.readouterr().err


def test_memory_is_estimated_before_allocating(capsys):
    assert cli(["simulate", "--omega", "1", "--periods", "10000000"]) == 2
    err = capsys.readouterr().err
    assert "--periods 10000000" in err and "GiB" in err


def test_json_inputs_are_bounded_before_parsing(tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match=r"deep.json.*nested deeper than 64"):
        read_json(deep, "--config")
    assert cli(["evaluate", "--schedule", "constant:1", "--config", str(deep)]) == 2
    assert "deep.json" in capsys.readouterr().err
    assert cli(["evaluate", "--schedule", str(deep)]) == 2
    err = capsys.readouterr().err
    assert "deep.json" in err and "nested deeper" in err
    big_int = tmp_path / "int.json"
    big_int.write_text('{"max_steps": ' + "9" * 5000 + "}")
    assert cli(["evaluate", "--schedule", "constant:1", "--config", str(big_int)]) == 2
    err = capsys.readouterr().err
    assert "int.json" in err and "digits" in err
    huge = tmp_path / "huge.csv"
    with open(huge, "wb") as fh:  # a sparse 1 GB file: refused from its size, never read
        fh.truncate(1 << 30)
    assert cli(["evaluate", "--schedule", str(huge)]) == 2
    assert "huge.csv" in capsys.readouterr().err


def test_random_policy_specs_are_checked():
    from agents.registry import resolve_policy

    for spec in ("random:nan", "random:-1", "random:1.5", "constant:inf"):
        with pytest.raises(ValueError, match=f"policy spec '{spec}'"):
            resolve_policy(spec, None)
    assert resolve_policy("random:7", None).predict(np.zeros(10))[0].shape == (1,)


def test_gear_params_unknown_field_is_a_value_error():
    from gear_env.sim.params import GearParams

    with pytest.raises(ValueError, match=r"unknown GearParams field\(s\) \['stiffness'\]"):
        GearParams(stiffness=1)
    with pytest.raises(ValueError, match="positional"):
        GearParams(*range(40))
    assert GearParams(kappa=0.3).kappa == 0.3


# --------------------------------------------------------------------------------------------------
# 15. kill -9 of the main process of a parallel sweep: its workers end too
# --------------------------------------------------------------------------------------------------
def _session_pids(sid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                fields = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != "Z":
                out.append(int(d))
    return out


@pytest.mark.slow
def test_kill_9_of_a_parallel_sweep_leaves_no_worker_running(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    ckpt = tmp_path / "p.ckpt.npz"
    cmd = [sys.executable, "-m", "gear_env", "sweep", "--points", "400", "--transient", "50", "--periods", "8",
           "--no-lyapunov", "--quiet", "--workers", "2", "--chunks", "40", "--checkpoint", str(ckpt)]  # fmt: skip
    main = subprocess.Popen(cmd, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        while not ckpt.exists():  # the workers are computing once the first chunk is saved
            assert main.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() - t0 < 300, "no chunk finished within 300 s"
            time.sleep(0.2)
        assert len(_session_pids(main.pid)) >= 3  # main, (forkserver), two workers
        main.kill()
        main.wait()
        deadline = time.monotonic() + 20
        while _session_pids(main.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _session_pids(main.pid) == [], "worker processes outlived the killed sweep"
    finally:
        for pid in _session_pids(main.pid):
            os.kill(pid, 9)
    # and the checkpoint it left is not discarded by a rerun without --resume
    r = subprocess.run(
        [*cmd[:-2], "--checkpoint", str(ckpt), "--workers", "1"], env=env, capture_output=True, text=True
    )
    assert r.returncode == 2 and "--restart" in r.stderr and ckpt.is_file()


def test_lifeline_ends_a_worker_whose_main_process_is_gone():
    code = (
        "import os, sys, time; from gear_env.analysis.lifeline import exit_with_parent;"
        "exit_with_parent(int(sys.argv[1]), interval=0.05); time.sleep(30); sys.exit(0)"
    )
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a pid that no longer exists
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-c", code, str(dead.pid)], env=env, timeout=30)
    assert r.returncode == 1 and time.monotonic() - t0 < 20


def test_read_json_names_the_file(tmp_path):
    p = tmp_path / "c.json"
    p.write_text("{bad")
    with pytest.raises(ValueError, match=r"--config '.*c.json' is not valid JSON"):
        read_json(p, "--config")
    p.write_text(json.dumps({"a": [1, 2, {"b": 3}]}))
    assert read_json(p, "--config") == {"a": [1, 2, {"b": 3}]}
