"""Crafted files and concurrent writers of issue 25, each tried once; a table of case, expected, got, held.

    python benchmarks/crafted_cases.py            # every case, a table, exit 1 if any did not hold
    python benchmarks/crafted_cases.py --list     # the case names
    python benchmarks/crafted_cases.py --rss      # peak RSS of the memory cases, each in a fresh process

Each case builds its hostile input from the files the package ships (gear_env/data/pretrained, the
shipped policies) or from files the package writes (a sweep checkpoint, a results file), in a fresh
temporary folder, then runs the loader or the ``gear-env`` command the way a user would. A case
*holds* when the outcome is the expected one: a clean refusal (a ``ValueError`` in the API, exit code
2 and a one-line message on the CLI) naming the file or option and the field, with

* no traceback (any other exception type is a failure),
* the Python-traced memory peak (``tracemalloc``: numpy arrays, bytes read, JSON) under
  ``MEMORY_BOUND`` bytes,
* no file written outside the case's folder, and no code run (the payloads would create a marker).

``tests/test_crafted_cases.py`` runs every case as a test; CI runs this script in its slow stage.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import struct
import sys
import tempfile
import time
import tracemalloc
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MEMORY_BOUND = 64 * 2**20
"""Largest Python-traced memory peak a refused case may cost (bytes)."""
PRETRAINED = ROOT / "gear_env" / "data" / "pretrained"
POLICY_V1 = ROOT / "gear_env" / "data" / "policies" / "GearSpeed-v1"


@dataclass
class Outcome:
    """What a case did: ``kind`` is "refused" (ValueError/exit 2), "ok" (worked) or "crash"."""

    kind: str
    message: str = ""


@dataclass
class Case:
    name: str
    expected: str
    run: Callable[[Path], Outcome]
    must_contain: tuple[str, ...] = ()
    expect: str = "refused"


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------
def api(fn: Callable[[], object]) -> Outcome:
    """Run an API call: ValueError (and OSError) are refusals, anything else a crash."""
    try:
        fn()
    except (ValueError, OSError) as exc:
        return Outcome("refused", f"{type(exc).__name__}: {exc}")
    except Exception as exc:  # noqa: BLE001 - a traceback is what a case must not produce
        return Outcome("crash", f"{type(exc).__name__}: {exc}")
    return Outcome("ok")


def cli(*argv: str) -> Outcome:
    """Run ``gear-env argv`` in this process; exit 2 with one line on stderr is a refusal."""
    from gear_env.cli import main

    err, out = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            rc = main(list(argv))
    except Exception as exc:  # noqa: BLE001
        return Outcome("crash", f"{type(exc).__name__}: {exc}")
    msg = err.getvalue().strip()
    if rc == 2:
        lines = [x for x in msg.splitlines() if "error" in x]
        return Outcome("refused" if len(lines) == 1 else "crash", lines[-1] if lines else msg)
    return Outcome("ok" if rc == 0 else f"exit {rc}", msg[-300:])


def run_copy(work: Path) -> Path:
    """A copy of the shipped pretrained run folder (an earlier release's run) in ``work``."""
    dst = work / "run"
    shutil.copytree(PRETRAINED, dst)
    return dst


def rewrite_zip(path: Path, change: Callable[[dict[str, bytes]], dict[str, bytes]]) -> None:
    with zipfile.ZipFile(path) as z:
        entries = {n: z.read(n) for n in z.namelist()}
    entries = change(entries)
    with zipfile.ZipFile(path, "w") as z:
        for n, b in entries.items():
            z.writestr(n, b)


def model_data(path: Path, change: Callable[[dict], None]) -> None:
    """Change the JSON ``data`` entry of an SB3 zip."""

    def ch(e: dict[str, bytes]) -> dict[str, bytes]:
        d = json.loads(e["data"])
        change(d)
        e["data"] = json.dumps(d).encode()
        return e

    rewrite_zip(path, ch)


def add_bomb(path: Path, member: str, nbytes: int) -> None:
    """Put a deflated member of ``nbytes`` zeros (about 1/1000 of that compressed) into a zip, streamed."""
    with zipfile.ZipFile(path) as z:
        entries = {n: z.read(n) for n in z.namelist() if n != member}
    with zipfile.ZipFile(path, "w") as z:
        for n, b in entries.items():
            z.writestr(n, b)
        info = zipfile.ZipInfo(member)
        info.compress_type = zipfile.ZIP_DEFLATED
        with z.open(info, "w", force_zip64=True) as fh:
            chunk = bytes(1 << 20)
            for _ in range(nbytes >> 20):
                fh.write(chunk)


def npy_bytes(shape: tuple[int, ...], descr: str = "<f8", payload: bytes = b"") -> bytes:
    """A ``.npy`` member whose header declares ``shape`` (the data need not be there)."""
    h = repr({"descr": descr, "fortran_order": False, "shape": tuple(shape)}).encode()
    pad = (64 - (10 + len(h) + 1) % 64) % 64
    h = h + b" " * pad + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(h)) + h + payload


def set_npz_member(path: Path, name: str, data: bytes) -> None:
    def ch(e: dict[str, bytes]) -> dict[str, bytes]:
        e[f"{name}.npy"] = data
        return e

    rewrite_zip(path, ch)


def deep_json(levels: int = 100_000) -> str:
    return "[" * levels + "]" * levels


FP = {"model": "dynamic", "periods": 4, "max_period": 8}
GRID = np.array([1.0, 1.1, 1.2])


def sweep_checkpoint(work: Path) -> Path:
    """A valid sweep checkpoint (2 of 3 points done) written by the package."""
    from gear_env.analysis.checkpoint import Checkpoint
    from gear_env.analysis.results import PointResult
    from gear_env.sim.kernels import N_PC, N_STATS, NSTATE

    ck = Checkpoint(str(work / "c.ckpt.npz"), FP, GRID)
    for i, (reg, per) in enumerate((("period-1", 1), ("chaotic", 0))):
        ck.add(i, PointResult(float(GRID[i]), reg, per, 0.01, np.zeros((4, N_PC)), np.ones(N_STATS),
                              np.zeros(NSTATE), 64, 1, True, 4))  # fmt: skip
    ck.save()
    return ck.path


def load_checkpoint(path: Path) -> None:
    from gear_env.analysis.checkpoint import Checkpoint

    Checkpoint.open(str(path), FP, GRID)


def results_file(work: Path) -> Path:
    """A valid .nc results file of 3 points written by the package."""
    from gear_env.analysis.results import PointResult, assemble
    from gear_env.sim.kernels import N_PC, N_STATS, NSTATE
    from gear_env.sim.params import GearParams

    pts = [
        PointResult(
            float(w), "period-1", 1, None, np.zeros((4, N_PC)), np.ones(N_STATS), np.zeros(NSTATE), 64, 1, True, 4
        )  # fmt: skip
        for w in GRID
    ]
    res = assemble(GRID, pts, "dynamic", "forward", GearParams(), 8, 4, False)
    p = work / "r.nc"
    res.save(str(p))
    return p


def nc_attr(path: Path, name: str, value: str) -> None:
    """Rewrite one global attribute of a NetCDF-4 file (the file stays otherwise valid)."""
    import netCDF4

    with netCDF4.Dataset(path, "r+") as f:
        f.setncattr(name, value)


def shipped_policy(work: Path) -> Path:
    dst = work / "pol"
    shutil.copytree(POLICY_V1, dst)
    return dst


def policy_json(folder: Path, change: Callable[[dict], None]) -> None:
    p = folder / "policy.json"
    d = json.loads(p.read_text())
    change(d)
    p.write_text(json.dumps(d))


def load_run(run: Path) -> Callable[[], object]:
    def f() -> object:
        from agents.trained import load_trained_policy

        return load_trained_policy(run)

    return f


def load_shipped(folder: Path) -> Callable[[], object]:
    def f() -> object:
        from agents.shipped import load_policy

        return load_policy(folder)

    return f


def with_checkpoint(run: Path, steps: int = 512) -> Path:
    """Give a copy of the pretrained run a checkpoint (model + statistics + latest.json), and its
    config.json the environment settings of this release (so ``--resume`` accepts it)."""
    from agents.envs import config_to_dict, make_config

    cfg = json.loads((run / "config.json").read_text())
    cfg["env_config"] = config_to_dict(make_config(cfg["env_id"], cfg["env_config"]))
    (run / "config.json").write_text(json.dumps(cfg))
    ck = run / "checkpoints"
    ck.mkdir(exist_ok=True)
    shutil.copy(run / "model.zip", ck / f"ckpt_{steps:09d}.zip")
    shutil.copy(run / "vecnormalize.npz", ck / f"ckpt_{steps:09d}_vecnormalize.npz")
    latest = {"steps": steps, "model": f"ckpt_{steps:09d}.zip", "vecnormalize": f"ckpt_{steps:09d}_vecnormalize.npz"}
    (ck / "latest.json").write_text(json.dumps(latest))
    return ck


def resume(run: Path) -> Outcome:
    """``gear-env train --out RUN --resume`` up to a step count the checkpoint has not reached (the
    checkpoint is loaded before any training step)."""
    return cli("train", "--out", str(run), "--resume", "--timesteps", "1000", "--no-progress", "--quiet",
               "--no-tensorboard", "--eval-freq", "0", "--checkpoint-freq", "0")  # fmt: skip


# --------------------------------------------------------------------------------------------------
# the cases
# --------------------------------------------------------------------------------------------------
def _c_continuation_symlink(w: Path) -> Outcome:
    (w / "a.json").write_text('{"keep": true}')
    os.symlink(w / "a.json", w / "l.png")
    out = cli("continuation", "--omega-min", "1.0", "--omega-max", "1.1", "--json", str(w / "a.json"),
              "--plot", str(w / "l.png"), "--quiet")  # fmt: skip
    if (w / "a.json").read_text() != '{"keep": true}':
        return Outcome("crash", "a.json was overwritten")
    return out


def _c_continuation_hardlink(w: Path) -> Outcome:
    (w / "a.json").write_text('{"keep": true}')
    os.link(w / "a.json", w / "h.png")
    return cli("continuation", "--omega-min", "1.0", "--omega-max", "1.1", "--json", str(w / "a.json"),
               "--plot", str(w / "h.png"), "--quiet")  # fmt: skip


def _held_by_other(target: Path, argv: list[str], keep: str | None = None) -> Outcome:
    """Hold the output lock as another writer would, then run the command on the same output."""
    from gear_env.io import OutputLock

    with OutputLock(target):
        out = cli(*argv)
    if keep is not None and target.read_text() != keep:
        return Outcome("crash", f"{target.name} was changed by the refused writer")
    return out


def _c_two_evaluate(w: Path) -> Outcome:
    (w / "r.json").write_text("first")
    return _held_by_other(w / "r.json", ["evaluate", "--schedule", "constant:1.0", "--episodes", "1",
                                          "--json", str(w / "r.json")], keep="first")  # fmt: skip


def _c_two_continuation(w: Path) -> Outcome:
    (w / "c.json").write_text("first")
    return _held_by_other(w / "c.json", ["continuation", "--omega-min", "1.0", "--omega-max", "1.1",
                                          "--json", str(w / "c.json"), "--quiet"], keep="first")  # fmt: skip


def _c_two_evaluate_via_symlink(w: Path) -> Outcome:
    (w / "r.json").write_text("first")
    os.symlink(w / "r.json", w / "alias.json")
    return _held_by_other(w / "r.json", ["evaluate", "--schedule", "constant:1.0", "--episodes", "1",
                                          "--json", str(w / "alias.json")], keep="first")  # fmt: skip


def _c_two_train(w: Path) -> Outcome:
    from gear_env.io import OutputLock

    d = w / "D"
    d.mkdir()
    with OutputLock(d, "run folder"):
        out = cli("train", "--out", str(d), "--timesteps", "64", "--num-envs", "1", "--no-progress", "--quiet")
    if any(d.iterdir()):
        return Outcome("crash", "the refused train wrote into the folder")
    return out


def _c_two_resume(w: Path) -> Outcome:
    from gear_env.io import OutputLock

    run = run_copy(w)
    with_checkpoint(run)
    before = sorted(p.name for p in run.rglob("*"))
    with OutputLock(run, "run folder"):
        out = resume(run)
    if sorted(p.name for p in run.rglob("*")) != before:
        return Outcome("crash", "the refused resume changed the run folder")
    return out


def _c_overwrite_non_run(w: Path) -> Outcome:
    d = w / "D"
    (d / "checkpoints").mkdir(parents=True)
    (d / "checkpoints" / "mine.zip").write_bytes(b"user data")
    (d / "metrics.csv").write_text("user,data\n")
    out = cli("train", "--out", str(d), "--overwrite", "--timesteps", "64", "--num-envs", "1", "--no-progress",
              "--quiet")  # fmt: skip
    if (d / "metrics.csv").read_text() != "user,data\n" or not (d / "checkpoints" / "mine.zip").exists():
        return Outcome("crash", "user files were deleted or replaced")
    return out


def _c_model_policy_kwargs_unknown(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d["policy_kwargs"].update(squash_output=True))
    return api(load_run(run))


def _c_model_policy_kwargs_string(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d.update(policy_kwargs="dict(net_arch=[64])"))
    return api(load_run(run))


def _c_model_optimizer_kwargs(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d["policy_kwargs"].update(optimizer_kwargs={"bogus": 1}))
    return api(load_run(run))


def _c_model_n_steps(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d.update(n_steps=10**12))
    return api(load_run(run))


def _c_model_n_envs(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d.update(n_envs="x"))
    return api(load_run(run))


def _c_model_device(w: Path) -> Outcome:
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d.update(device="cuda:7"))
    return api(load_run(run))


def _c_model_tensorboard_log(w: Path) -> Outcome:
    """A tensorboard_log pointing outside is dropped on load (nothing is written there)."""
    run = run_copy(w)
    model_data(run / "model.zip", lambda d: d.update(tensorboard_log=str(w.parent / "elsewhere")))
    got: list[object] = []
    out = api(lambda: got.append(load_run(run)().model.tensorboard_log))  # type: ignore[attr-defined]
    if out.kind == "ok" and got != [None]:
        return Outcome("crash", f"tensorboard_log of the file was kept: {got}")
    return out


def _c_model_bomb(w: Path) -> Outcome:
    run = run_copy(w)
    add_bomb(run / "model.zip", "policy.pth", 600 * 2**20)
    return api(load_run(run))


def _c_vecnorm_bomb(w: Path) -> Outcome:
    run = run_copy(w)
    add_bomb(run / "vecnormalize.npz", "unused.npy", 800 * 2**20)
    return api(load_run(run))


def _c_vecnorm_giant_shape(w: Path) -> Outcome:
    run = run_copy(w)
    set_npz_member(run / "vecnormalize.npz", "obs_mean", npy_bytes((10**12,)))
    return api(load_run(run))


def _c_resume_giant_obs_var(w: Path) -> Outcome:
    run = run_copy(w)
    ck = with_checkpoint(run)
    set_npz_member(ck / "ckpt_000000512_vecnormalize.npz", "obs_var", npy_bytes((10**12,)))
    return resume(run)


def _c_checkpoint_giant_poincare(w: Path) -> Outcome:
    p = sweep_checkpoint(w)
    set_npz_member(p, "poincare", npy_bytes((10**12, 4, 9)))
    return api(lambda: load_checkpoint(p))


def _c_checkpoint_deep_fingerprint(w: Path) -> Outcome:
    p = sweep_checkpoint(w)
    buf = io.BytesIO()
    np.save(buf, np.array(deep_json()))
    set_npz_member(p, "fingerprint", buf.getvalue())
    return api(lambda: load_checkpoint(p))


def _c_checkpoint_regime(w: Path, regime: str, period: int) -> Outcome:
    p = sweep_checkpoint(w)
    buf = io.BytesIO()
    np.save(buf, np.array([regime, "chaotic"], dtype="U32"))
    set_npz_member(p, "regime", buf.getvalue())
    buf = io.BytesIO()
    np.save(buf, np.array([period, 0], np.int64))
    set_npz_member(p, "period", buf.getvalue())
    return api(lambda: load_checkpoint(p))


def _c_policy_deep_json(w: Path) -> Outcome:
    pol = shipped_policy(w)
    (pol / "policy.json").write_text(deep_json())
    return api(load_shipped(pol))


def _c_results_deep_json(w: Path) -> Outcome:
    from gear_env.analysis.results import SweepResult

    p = results_file(w)
    nc_attr(p, "config", deep_json())
    return api(lambda: SweepResult.load(str(p)))


def _c_results_bad_regime(w: Path) -> Outcome:
    from gear_env.analysis.results import SweepResult

    p = results_file(w)
    import netCDF4

    with netCDF4.Dataset(p, "r+") as f:
        f.variables["period"][0] = -7
    return api(lambda: SweepResult.load(str(p)))


def _c_policy_huge_net(w: Path) -> Outcome:
    pol = shipped_policy(w)
    policy_json(pol, lambda d: d.update(net_arch=[16384, 16384]))
    t0 = time.perf_counter()
    out = api(load_shipped(pol))
    if time.perf_counter() - t0 > 30:
        return Outcome("crash", "took more than 30 s")
    return out


def _c_policy_unknown_key(w: Path) -> Outcome:
    pol = shipped_policy(w)
    policy_json(pol, lambda d: d.update(policy_kwargs={"x": 1}))
    return api(load_shipped(pol))


def _c_policy_pt_pickle(w: Path) -> Outcome:
    import pickle

    pol = shipped_policy(w)
    marker = w / "PWNED"

    class Payload:
        def __reduce__(self):  # type: ignore[no-untyped-def]
            return (open, (str(marker), "w"))

    import torch

    torch.save({"x": Payload()}, pol / "policy.pt", pickle_module=pickle)
    out = api(load_shipped(pol))
    if marker.exists():
        return Outcome("crash", "code ran")
    return out


def _c_latest_negative(w: Path) -> Outcome:
    run = run_copy(w)
    ck = with_checkpoint(run)
    d = json.loads((ck / "latest.json").read_text())
    d["steps"] = -100
    (ck / "latest.json").write_text(json.dumps(d))
    return resume(run)


def _c_checkpoints_symlink_outside(w: Path) -> Outcome:
    run = run_copy(w)
    outside = w / "outside"
    outside.mkdir()
    with_checkpoint(run)
    shutil.move(str(run / "checkpoints"), str(outside / "checkpoints"))
    os.symlink(outside / "checkpoints", run / "checkpoints")
    before = sorted(p.name for p in (outside / "checkpoints").iterdir())
    out = resume(run)
    if sorted(p.name for p in (outside / "checkpoints").iterdir()) != before:
        return Outcome("crash", "wrote checkpoints outside the run folder")
    return out


def _c_full_disk_names_file(w: Path) -> Outcome:
    """ENOSPC while a sweep writes its checkpoint: the error names the checkpoint file."""
    import errno
    from unittest import mock

    from gear_env.analysis.checkpoint import Checkpoint

    ck = Checkpoint(str(w / "full.ckpt.npz"), FP, GRID)
    ck.add(0, _point())

    def enospc(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with mock.patch("os.fsync", enospc):
        out = api(ck.save)
    return out


def _c_full_disk_lock_names_file(w: Path) -> Outcome:
    """ENOSPC writing the lock file of an output: the error names the output."""
    import errno
    from unittest import mock

    from gear_env.io import OutputLock

    def enospc(*a: object) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with mock.patch("os.pwrite", enospc):
        return api(lambda: OutputLock(w / "x.json").acquire())


def _point():  # type: ignore[no-untyped-def]
    from gear_env.analysis.results import PointResult
    from gear_env.sim.kernels import N_PC, N_STATS, NSTATE

    return PointResult(1.0, "period-1", 1, 0.0, np.zeros((4, N_PC)), np.ones(N_STATS), np.zeros(NSTATE), 64, 1, True, 4)


def _c_schedule_fifo(w: Path) -> Outcome:
    os.mkfifo(w / "s.csv")
    return cli("evaluate", "--schedule", str(w / "s.csv"), "--episodes", "1")


def _c_schedule_dir(w: Path) -> Outcome:
    (w / "d.csv").mkdir()
    return cli("evaluate", "--schedule", str(w / "d.csv"), "--episodes", "1")


def _c_schedule_proc_mem(w: Path) -> Outcome:
    return cli("evaluate", "--schedule", "/proc/self/mem", "--episodes", "1")


def _c_env_string_action(env_id: str) -> Callable[[Path], Outcome]:
    def f(w: Path) -> Outcome:
        import gymnasium as gym

        import gear_env  # noqa: F401

        env = gym.make(env_id)
        env.reset(seed=0)
        return api(lambda: env.step(np.array(["0.1"])))

    return f


def _c_env_time_limit(value: float) -> Callable[[Path], Outcome]:
    def f(w: Path) -> Outcome:
        import gymnasium as gym

        import gear_env  # noqa: F401

        return api(lambda: gym.make("GearSpeed-v1", max_episode_steps=value))

    return f


def _c_env_no_time_limit(w: Path) -> Outcome:
    """Gymnasium's documented ``max_episode_steps=-1`` (no TimeLimit wrapper): the env truncates itself."""
    import gymnasium as gym

    import gear_env  # noqa: F401

    def run() -> None:
        env = gym.make("GearSpeed-v1", max_episode_steps=-1, max_steps=3, periods_per_step=8, warmup_periods=16)
        env.reset(seed=0)
        trunc = [env.step(env.action_space.sample())[3] for _ in range(3)]
        if trunc != [False, False, True]:
            raise RuntimeError(f"max_episode_steps=-1: expected truncation at the env's max_steps=3, got {trunc}")

    return api(run)


# --------------------------------------------------------------------------------------------------
# the second probe (an independent hostile probe after the first fixes; docs/RELIABILITY.md)
# --------------------------------------------------------------------------------------------------
def _c_params_hard_link(w: Path) -> Outcome:
    (w / "p.json").write_text("{}")
    os.link(w / "p.json", w / "l.json")
    out = cli("simulate", "--omega", "1.0", "--params", str(w / "p.json"), "--json", str(w / "l.json"))
    return out if (w / "p.json").read_text() == "{}" else Outcome("crash", "the --params file was overwritten")


def _c_output_in_input_run(w: Path) -> Outcome:
    run = run_copy(w)
    before = (run / "model.zip").read_bytes()
    out = cli("evaluate", "--policy", str(run), "--env", "GearSpeed-v0", "--json", str(run / "model.zip"))
    return out if (run / "model.zip").read_bytes() == before else Outcome("crash", "model.zip was overwritten")


def _c_folder_link_out(w: Path) -> Outcome:
    from gear_env.io import atomic_write_text, hold_outputs

    (w / "precious.txt").write_text("keep")
    (w / "D").mkdir()
    os.symlink(w / "precious.txt", w / "D" / "rl_report.md")

    def write() -> None:
        with hold_outputs({}, folders={"--out": w / "D"}):
            atomic_write_text(w / "D" / "rl_report.md", "report")

    out = api(write)
    return out if (w / "precious.txt").read_text() == "keep" else Outcome("crash", "written through the link")


def _c_steady_alias(w: Path) -> Outcome:
    from gear_env.cli.steady import main as steady

    (w / "a.json").write_text("keep")
    os.symlink(w / "a.json", w / "l.png")
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = steady(["--json", str(w / "a.json"), "--plot", str(w / "l.png")])
    lines = err.getvalue().strip().splitlines()
    return Outcome("refused" if rc == 2 and len(lines) == 1 else f"exit {rc}", lines[-1] if lines else "")


LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(8)
)


def _c_hyperparams(text: str) -> Callable[[Path], Outcome]:
    def f(w: Path) -> Outcome:
        (w / "h.yml").write_text(text)
        return cli("train", "--out", str(w / "D"), "--hyperparams", str(w / "h.yml"), "--timesteps", "64")

    return f


def _c_protocol_cache(w: Path) -> Outcome:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import demand_protocol

    seeds = range(0, 3)
    (w / "c" / "s").mkdir(parents=True)
    path = w / "c" / "s" / "oracle.json"
    rows = [dict(seed=s, delivered=0.0, shortfall=0.0, cost=0.0, settled_omega=1.0, **{"return": 1e300}) for s in seeds]
    path.write_text(json.dumps({"spec": "oracle", "seeds": [0, 3], "episodes": rows}))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        got = demand_protocol.read_cache(path, w / "c", "oracle", seeds)
    return Outcome("refused", err.getvalue().strip()) if got is None else Outcome("ok", "the injected rows were used")


def _c_make_vec_time_limit(w: Path) -> Outcome:
    import gymnasium as gym

    import gear_env  # noqa: F401

    return api(lambda: gym.make_vec("GearSpeedDemandHard-v0", num_envs=2, vectorization_mode="vector_entry_point",
                                    max_episode_steps=0))  # fmt: skip


def _c_nc_other_kind_bomb(w: Path) -> Outcome:
    import netCDF4

    from gear_env.analysis.results import SweepResult

    p = w / "other.nc"
    with netCDF4.Dataset(p, "w") as f:  # 200 MiB of zeros in about 0.2 MiB
        f.createDimension("omega", 25)
        f.createDimension("k", 2**20)
        v = f.createVariable("poincare", "f8", ("omega", "k"), zlib=True, complevel=9, chunksizes=(1, 2**20))
        for i in range(25):
            v[i, :] = np.zeros(2**20)
    return api(lambda: SweepResult.load(str(p)))


def _c_latest_drops_statistics(w: Path) -> Outcome:
    run = run_copy(w)
    ck = with_checkpoint(run)
    latest = json.loads((ck / "latest.json").read_text())
    (ck / "latest.json").write_text(json.dumps({**latest, "vecnormalize": None}))
    return resume(run)


def _c_demand_fifo(w: Path) -> Outcome:
    os.mkfifo(w / "demand.csv")
    return cli("train", "--out", str(w / "D"), "--demand", str(w / "demand.csv"), "--timesteps", "64")


def _c_hard_policy_pickle(w: Path) -> Outcome:
    pol = w / "hard"
    shutil.copytree(ROOT / "gear_env" / "data" / "policies" / "GearSpeedDemandHard-v0", pol)
    with zipfile.ZipFile(pol / "policy.pt") as z:
        entries = {i.filename: z.read(i.filename) for i in z.infolist()}
    marker = w / "PWNED"
    for name in entries:
        if name.endswith("/data.pkl"):
            entries[name] = f"cos\nsystem\n(S'touch {marker}'\ntR.".encode()
    with zipfile.ZipFile(pol / "policy.pt", "w", zipfile.ZIP_STORED) as z:
        for name, b in entries.items():
            z.writestr(name, b)
    out = api(load_shipped(pol))
    return Outcome("crash", "code ran") if marker.exists() else out


def _c_valid_pretrained(w: Path) -> Outcome:
    return api(load_run(run_copy(w)))


def _c_valid_policies(w: Path) -> Outcome:
    from agents.shipped import load_policy

    def f() -> None:
        for d in sorted((ROOT / "gear_env" / "data" / "policies").iterdir()):
            load_policy(d)

    return api(f)


def _c_valid_checkpoint_and_results(w: Path) -> Outcome:
    from gear_env.analysis.results import SweepResult

    def f() -> None:
        load_checkpoint(sweep_checkpoint(w))
        SweepResult.load(str(results_file(w)))

    return api(f)


CASES: list[Case] = [
    Case("continuation --plot symlink to --json", "exit 2, a.json kept", _c_continuation_symlink, ("same file",)),
    Case("continuation --plot hard link to --json", "exit 2", _c_continuation_hardlink, ("same file",)),
    Case("two evaluate --json f", "second refused, first's file kept", _c_two_evaluate, ("another process",)),
    Case("two continuation --json f", "second refused", _c_two_continuation, ("another process",)),
    Case("evaluate --json via a symlink to a locked f", "refused", _c_two_evaluate_via_symlink, ("another process",)),
    Case("two train --out D", "second refused, D untouched", _c_two_train, ("another process",)),
    Case("two train --resume on one run", "second refused, run untouched", _c_two_resume, ("another process",)),
    Case(
        "train --overwrite on a non-run folder",
        "exit 2, user files kept",
        _c_overwrite_non_run,
        ("not a gear-env run folder",),
    ),  # fmt: skip
    Case(
        "model.zip policy_kwargs unknown key",
        "corrupt model file",
        _c_model_policy_kwargs_unknown,
        ("policy_kwargs.squash_output",),
    ),  # fmt: skip
    Case(
        "model.zip policy_kwargs a string", "corrupt model file", _c_model_policy_kwargs_string, ("policy_kwargs",)
    ),  # fmt: skip
    Case(
        "model.zip optimizer_kwargs bogus key",
        "corrupt model file",
        _c_model_optimizer_kwargs,
        ("optimizer_kwargs.bogus",),
    ),  # fmt: skip
    Case("model.zip n_steps = 10**12", "corrupt model file", _c_model_n_steps, ("data.n_steps",)),
    Case('model.zip n_envs = "x"', "corrupt model file", _c_model_n_envs, ("data.n_envs",)),
    Case('model.zip device = "cuda:7"', "corrupt model file", _c_model_device, ("data.device",)),
    Case("model.zip tensorboard_log outside", "loads, log folder dropped", _c_model_tensorboard_log, (), "ok"),
    Case("model.zip policy.pth bomb (600 MB)", "refused before inflating", _c_model_bomb, ("policy.pth", "declares")),
    Case("vecnormalize.npz unused 800 MB member", "refused before inflating", _c_vecnorm_bomb, ("unused.npy",)),
    Case(
        "vecnormalize obs_mean shape (10**12,)", "refused before allocating", _c_vecnorm_giant_shape, ("obs_mean",)
    ),  # fmt: skip
    Case("resume checkpoint obs_var shape (10**12,)", "exit 2", _c_resume_giant_obs_var, ("obs_var", "shape")),
    Case(
        "sweep checkpoint poincare (10**12, 4, 9)",
        "refused before allocating",
        _c_checkpoint_giant_poincare,
        ("poincare",),
    ),  # fmt: skip
    Case("sweep checkpoint fingerprint 100,000 deep", "refused", _c_checkpoint_deep_fingerprint, ("nested",)),
    Case('sweep checkpoint regime "xxxx"', "refused", lambda w: _c_checkpoint_regime(w, "xxxx", 0), ("regime[0]",)),
    Case("sweep checkpoint period -7", "refused", lambda w: _c_checkpoint_regime(w, "period-1", -7), ("period[0]",)),
    Case(
        "sweep checkpoint period 10**12",
        "refused",
        lambda w: _c_checkpoint_regime(w, "period-1", 10**12),
        ("period[0]",),
    ),  # fmt: skip
    Case("policy.json 100,000 deep", "refused", _c_policy_deep_json, ("nested",)),
    Case(".nc config attribute 100,000 deep", "refused", _c_results_deep_json, ("nested",)),
    Case(".nc period -7", "refused", _c_results_bad_regime, ("period[0]",)),
    Case("policy.json net_arch [16384, 16384]", "refused before building", _c_policy_huge_net, ("net_arch",)),
    Case("policy.json unknown key", "refused", _c_policy_unknown_key, ("policy_kwargs",)),
    Case("policy.pt torch pickle payload", "refused, no code run", _c_policy_pt_pickle, ("policy.pt",)),
    Case("latest.json steps = -100", "exit 2", _c_latest_negative, ("latest.json", "steps:")),
    Case(
        "train --resume, checkpoints/ symlink outside",
        "exit 2, nothing written outside",
        _c_checkpoints_symlink_outside,
        ("leaves the folder",),
    ),  # fmt: skip
    Case("full disk writing a sweep checkpoint", "names the file", _c_full_disk_names_file, ("full.ckpt.npz",)),
    Case("full disk writing a lock file", "names the file", _c_full_disk_lock_names_file, ("x.json",)),
    Case("--schedule FIFO", "exit 2, FIFO named", _c_schedule_fifo, ("FIFO",)),
    Case("--schedule directory", "exit 2, directory named", _c_schedule_dir, ("directory",)),
    Case("--schedule /proc/self/mem", "exit 2, cannot read", _c_schedule_proc_mem, ("/proc/self/mem",)),
    Case('GearSpeed-v1 step(np.array(["0.1"]))', "ValueError", _c_env_string_action("GearSpeed-v1"), ("action",)),
    Case(
        'GearSpeedDemand-v0 step(np.array(["0.1"]))',
        "ValueError",
        _c_env_string_action("GearSpeedDemand-v0"),
        ("action",),
    ),  # fmt: skip
    Case("gym.make(max_episode_steps=-2)", "ValueError", _c_env_time_limit(-2), ("max_episode_steps",)),
    Case("gym.make(max_episode_steps=-1): no wrapper, the env truncates", "ends", _c_env_no_time_limit, (), "ok"),
    Case("gym.make(max_episode_steps=nan)", "ValueError", _c_env_time_limit(float("nan")), ("max_episode_steps",)),
    Case("simulate --json hard link to its --params", "exit 2, params kept", _c_params_hard_link, ("--params",)),
    Case(
        "evaluate --json RUN/model.zip, RUN the --policy",
        "exit 2, model kept",
        _c_output_in_input_run,
        ("model.zip of the input --policy",),
    ),  # fmt: skip
    Case("output folder: a link in it to a file outside", "refused", _c_folder_link_out, ("out of the output folder",)),
    Case("steady map --plot symlink to --json", "exit 2", _c_steady_alias, ("same file",)),
    Case(
        "--hyperparams 100,000-deep YAML",
        "exit 2",
        _c_hyperparams("GearSpeed-v1: " + "[" * 100_000 + "]" * 100_000),
        ("nested deeper",),
    ),  # fmt: skip
    Case(
        "--hyperparams billion laughs",
        "exit 2",
        _c_hyperparams(LAUGHS + "GearSpeed-v1:\n  env_kwargs:\n    demand: *i\n"),
        ("aliases expand",),
    ),  # fmt: skip
    Case("demand_protocol --cache with injected returns", "refused, recomputed", _c_protocol_cache, ("return",)),
    Case("gym.make_vec(max_episode_steps=0)", "ValueError", _c_make_vec_time_limit, ("max_episode_steps",)),
    Case(".nc of another kind, 200 MiB zlib zeros", "refused before inflating", _c_nc_other_kind_bomb, ("format",)),
    Case("latest.json vecnormalize null", "exit 2", _c_latest_drops_statistics, ("vecnormalize",)),
    Case("train --demand FIFO", "exit 2, FIFO named", _c_demand_fifo, ("demand.csv", "FIFO")),
    Case(
        "GearSpeedDemandHard-v0 policy.pt pickle payload", "refused, no code run", _c_hard_policy_pickle, ("policy.pt",)
    ),
    Case("shipped pretrained run (earlier release) loads", "loads", _c_valid_pretrained, (), "ok"),
    Case("shipped policies load", "loads", _c_valid_policies, (), "ok"),
    Case("a checkpoint and a results file of this release load", "loads", _c_valid_checkpoint_and_results, (), "ok"),
]


def _files_outside(work: Path, before: set[str]) -> list[str]:
    """Files that appeared in the case's parent folder but outside its own folder."""
    return sorted(set(os.listdir(work.parent)) - before - {work.name})


def run_case(case: Case, base: Path) -> tuple[Outcome, bool, str]:
    """(outcome, held, why) of one case in a fresh folder under ``base``."""
    work = Path(tempfile.mkdtemp(prefix="case-", dir=base))
    before = set(os.listdir(base))
    tracemalloc.start()
    try:
        out = case.run(work)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    why = []
    if out.kind != case.expect:
        why.append(f"expected {case.expect}, got {out.kind}")
    if case.expect == "refused":
        if "\n" in out.message:
            why.append("message is not one line")
        for s in case.must_contain:
            if s not in out.message:
                why.append(f"message lacks {s!r}")
    if peak > MEMORY_BOUND:
        why.append(f"traced memory peak {peak / 2**20:.0f} MiB")
    outside = _files_outside(work, before)
    if outside:
        why.append(f"wrote outside its folder: {outside}")
    shutil.rmtree(work, ignore_errors=True)
    return out, not why, "; ".join(why)


def warm_up(load: bool = True) -> None:
    """Import what the cases use (so the memory peaks measure the cases, not first imports); with
    ``load``, also load the pretrained run and a results file once (SB3, torch and netCDF import more
    on their first use)."""
    import gymnasium  # noqa: F401
    import stable_baselines3  # noqa: F401
    import torch  # noqa: F401
    import xarray  # noqa: F401

    import agents.ppo  # noqa: F401
    import agents.shipped  # noqa: F401
    import agents.trained  # noqa: F401
    import gear_env.cli  # noqa: F401
    from gear_env.analysis.results import SweepResult

    if not load:
        return
    load_run(PRETRAINED)()  # SB3 and torch import more on their first load
    with tempfile.TemporaryDirectory() as d:
        SweepResult.load(str(results_file(Path(d))))


RSS_CASES = (
    "shipped pretrained run (earlier release) loads",
    "model.zip policy.pth bomb (600 MB)",
    "vecnormalize.npz unused 800 MB member",
    "vecnormalize obs_mean shape (10**12,)",
    "sweep checkpoint poincare (10**12, 4, 9)",
    "policy.json net_arch [16384, 16384]",
)
"""Cases whose whole-process memory is measured by ``--rss`` (the first is the baseline: a valid load)."""


def _one(name: str) -> int:
    """Run one case in this (fresh) process and print its outcome and peak RSS (``--one NAME``)."""
    import resource

    warm_up(load=False)
    case = next(c for c in CASES if c.name == name)
    with tempfile.TemporaryDirectory(prefix="crafted-") as base:
        out = case.run(Path(base))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"kind": out.kind, "message": out.message[:200], "maxrss_mib": rss}))
    return 0


def rss_table() -> int:
    """Each of :data:`RSS_CASES` in a fresh process: peak resident memory (imports included)."""
    import subprocess

    print("| case | outcome | peak RSS (MiB) |\n|---|---|---:|")
    for name in RSS_CASES:
        r = subprocess.run([sys.executable, __file__, "--one", name], capture_output=True, text=True, check=False)
        d = json.loads(r.stdout.strip().splitlines()[-1])
        print(f"| {name} | {d['kind']} | {d['maxrss_mib']:.0f} |")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if "--list" in args:
        for c in CASES:
            print(c.name)
        return 0
    if "--one" in args:
        return _one(args[args.index("--one") + 1])
    if "--rss" in args:
        return rss_table()
    os.environ.setdefault("MPLBACKEND", "Agg")
    warm_up()
    rows = []
    with tempfile.TemporaryDirectory(prefix="crafted-") as base:
        for c in CASES:
            t0 = time.perf_counter()
            out, held, why = run_case(c, Path(base))
            got = f"{out.kind}: {out.message}" if out.message else out.kind
            rows.append((c.name, c.expected, got, held, why, time.perf_counter() - t0))
    w = max(len(r[0]) for r in rows)
    print(f"| {'case':{w}} | expected | got | held |")
    print(f"|{'-' * (w + 2)}|---|---|---|")
    for name, exp, got, held, why, _dt in rows:
        g = got if len(got) <= 150 else got[:147] + "..."
        print(f"| {name:{w}} | {exp} | {g} | {'yes' if held else 'NO: ' + why} |")
    n_held = sum(r[3] for r in rows)
    print(f"\n{n_held} of {len(rows)} cases held ({sum(r[5] for r in rows):.0f} s)")
    return 0 if n_held == len(rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
