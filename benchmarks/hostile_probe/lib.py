"""The probe's plumbing: a working folder, real subprocesses with their exit code, first error line and peak RSS.

Nothing here hard-codes a path: :func:`configure` names the working folder (the base runs, the numba
cache, the payload marker and one sub-folder per case live there), and the package under test is the
one ``python -c "import gear_env"`` finds in the current environment (``PYTHONPATH`` is inherited, never
set here).
"""

from __future__ import annotations

import importlib.util
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

PY = sys.executable
HERE = Path(__file__).resolve().parent
BENCHMARKS = HERE.parent


class _Config:
    """The working folder and what derives from it; set once by :func:`configure`."""

    out: Path | None = None

    def folder(self) -> Path:
        if self.out is None:
            raise RuntimeError("hostile_probe.lib.configure(out) was not called")
        return self.out


CFG = _Config()


def configure(out: Path) -> None:
    """Use ``out`` (an existing folder) as the working folder: base runs, cache, payload marker, cases."""
    out = Path(out).resolve()
    bad = set(str(out)) & set("'\"\\\n $`;&|<>()*?[]{}!#~")
    if bad:
        raise ValueError(
            f"--out {str(out)!r}: the payload marker path is written into pickles and YAML; "
            f"use a folder path without {''.join(sorted(bad))!r}"
        )
    CFG.out = out


def package_dir(name: str = "gear_env") -> Path:
    """The folder of the package ``name`` importable here (without importing it)."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"package {name!r} is not importable in this environment")
    return Path(next(iter(spec.submodule_search_locations))).resolve()


def data_dir() -> Path:
    """``gear_env/data`` of the package under test (the shipped pretrained run and policies)."""
    return package_dir("gear_env") / "data"


def gear_env_cmd() -> list[str]:
    """The ``gear-env`` console script beside this interpreter, else ``python -m gear_env.cli``."""
    script = Path(PY).parent / "gear-env"
    if script.is_file():
        return [str(script)]
    return [PY, "-c", "import sys; from gear_env.cli import main; sys.exit(main())"]


def sub_env() -> dict[str, str]:
    """The subprocess environment: the caller's, with a numba cache in the working folder and a headless backend."""
    return {**os.environ, "GEAR_ENV_CACHE": str(CFG.folder() / "cache"), "MPLBACKEND": "Agg"}


def payload_mark() -> Path:
    return CFG.folder() / "PWNED"


def payload(tag: str) -> bytes:
    """A protocol-0 pickle that runs ``touch <out>/PWNED_tag`` when unpickled."""
    return f"cos\nsystem\n(S'touch {payload_mark()}_{tag}'\ntR.".encode()


def touch_cmd(tag: str) -> str:
    """The shell command a YAML/eval payload would run (creates the marker of ``tag``)."""
    return f"touch {payload_mark()}_{tag}"


def pwned(tag: str) -> bool:
    return Path(f"{payload_mark()}_{tag}").exists()


def run(argv, cwd, timeout=240, env=None, preexec=None):
    """rc, stderr first error line, traceback?, peak RSS (MiB), seconds."""
    t0 = time.time()
    with open(Path(cwd) / ".stderr", "wb") as ef, open(Path(cwd) / ".stdout", "wb") as of:
        p = subprocess.Popen(
            [str(a) for a in argv],
            cwd=cwd,
            env=env or sub_env(),
            stdout=of,
            stderr=ef,
            stdin=subprocess.DEVNULL,
            preexec_fn=preexec,
        )
        rc: int | str | None = None
        rss = 0.0
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                rc = os.waitstatus_to_exitcode(status)
                rss = ru.ru_maxrss / 1024
                p.returncode = rc
                break
            if time.time() - t0 > timeout:
                p.kill()
                pid, status, ru = os.wait4(p.pid, 0)
                p.returncode = -9
                rc = "TIMEOUT"
                rss = ru.ru_maxrss / 1024
                break
            time.sleep(0.05)
    err = (Path(cwd) / ".stderr").read_text(errors="replace")
    lines = [x for x in err.splitlines() if x.strip()]
    errl = [x for x in lines if "rror" in x or "refus" in x]
    first = (errl[0] if errl else (lines[0] if lines else ""))[:240]
    return {
        "rc": rc,
        "err": first,
        "tb": "Traceback" in err,
        "rss": round(rss),
        "s": round(time.time() - t0, 1),
        "nerr": len(errl),
        "stderr": err,
    }


def ge(cwd, *args, **kw):
    return run([*gear_env_cmd(), *map(str, args)], cwd, **kw)


SNIP = """
import sys
try:
{body}
except (ValueError, OSError) as e:
    print(f"error: {{type(e).__name__}}: {{e}}".splitlines()[0], file=sys.stderr); sys.exit(2)
print("ok")
"""


def py(cwd, body, **kw):
    body = "\n".join("    " + ln for ln in body.strip("\n").splitlines())
    return run([PY, "-c", SNIP.format(body=body)], cwd, **kw)


TRAIN_R = [
    "train",
    "--out",
    "R",
    "--timesteps",
    "256",
    "--num-envs",
    "1",
    "--eval-freq",
    "0",
    "--checkpoint-freq",
    "128",
    "--ppo",
    "n_steps=128",
    "--ppo",
    "batch_size=64",
    "--no-tensorboard",
    "--no-progress",
    "--quiet",
]
TRAIN_D = [
    "train",
    "--out",
    "D",
    "--env",
    "GearSpeedDemandHard-v0",
    "--distill",
    "1",
    "--distill-set",
    "episodes=2",
    "--distill-set",
    "epochs=1",
    "--num-envs",
    "1",
    "--eval-freq",
    "0",
    "--checkpoint-freq",
    "128",
    "--ppo",
    "n_steps=128",
    "--ppo",
    "batch_size=64",
    "--no-tensorboard",
    "--no-progress",
    "--quiet",
]


def warm_cache() -> None:
    """``gear-env compile --jobs 1`` into the working folder's numba cache, once, before any case.

    The cases probe the package's own inputs and outputs; with a cold cache, a case run under a file-size
    limit would fail in numba's cache write instead (an ``OSError`` naming no file of the user's)."""
    CFG.folder().mkdir(parents=True, exist_ok=True)
    r = run([*gear_env_cmd(), "compile", "--jobs", "1"], CFG.folder(), timeout=3600)
    if r["rc"] != 0:
        raise RuntimeError(f"gear-env compile failed: exit {r['rc']}: {r['stderr'][-500:]}")


def base() -> Path:
    """Two small real runs made once per working folder: R (PPO, GearSpeed-v1, 256 steps) and D (a distilled
    GearSpeedDemandHard-v0 run); the cases copy them."""
    b = CFG.folder() / "base"
    b.mkdir(exist_ok=True)
    for name, argv in (("R", TRAIN_R), ("D", TRAIN_D)):
        if not (b / name / "model.zip").is_file():
            shutil.rmtree(b / name, ignore_errors=True)
            r = run([*gear_env_cmd(), *argv], b, timeout=1800)
            if r["rc"] != 0:
                raise RuntimeError(f"could not make the base run {name}: exit {r['rc']}: {r['stderr'][-500:]}")
    return b


def copy_pretrained(w):
    d = Path(w) / "run"
    shutil.copytree(data_dir() / "pretrained", d)
    return d


def copy_run(w, name="R"):
    d = Path(w) / name
    shutil.copytree(base() / name, d, symlinks=True)
    return d


def zip_entries(p):
    with zipfile.ZipFile(p) as z:
        return {i.filename: z.read(i.filename) for i in z.infolist()}


def write_zip(p, entries, compress=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(p, "w", compression=compress) as z:
        for n, b in entries.items():
            z.writestr(n, b)


def edit_data(p, fn):
    import json

    e = zip_entries(p)
    d = json.loads(e["data"])
    fn(d)
    e["data"] = json.dumps(d).encode()
    write_zip(p, e)


def torch_payload_zip(src, dst, tag):
    """Copy a torch zip (stored), replacing its data.pkl by a payload."""
    with zipfile.ZipFile(src) as z:
        ent = {i.filename: z.read(i.filename) for i in z.infolist()}
    for k in list(ent):
        if k.endswith("/data.pkl"):
            ent[k] = payload(tag)
    write_zip(dst, ent, compress=zipfile.ZIP_STORED)


def deep(n=100_000):
    return "[" * n + "]" * n


def bomb_zip_member(z: zipfile.ZipFile, name: str, nbytes: int):
    """Write a member of nbytes zeros, deflated, streaming (cheap in memory)."""
    zi = zipfile.ZipInfo(name)
    zi.compress_type = zipfile.ZIP_DEFLATED
    with z.open(zi, "w", force_zip64=True) as fh:
        chunk = b"\0" * (1 << 20)
        for _ in range(nbytes >> 20):
            fh.write(chunk)


def ulimit_f(kb):
    def f():
        resource.setrlimit(resource.RLIMIT_FSIZE, (kb * 1024, kb * 1024))

    return f


def wait_lock(folder, timeout=200):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if any(p.name.endswith(".lock") for p in Path(folder).iterdir()):
            return True
        time.sleep(0.2)
    return False


def two_writers(w, argv_a, argv_b, lockdir=None, timeout=200):
    """Start A, wait for its lock, run B; kill A. Returns B's result and A's state."""
    lockdir = lockdir or w
    with open(Path(w) / ".a_err", "wb") as ef:
        a = subprocess.Popen([str(x) for x in argv_a], cwd=w, env=sub_env(), stdout=subprocess.DEVNULL, stderr=ef)
    ok = wait_lock(lockdir, timeout)
    if not ok:
        a.kill()
        a.wait()
        return {
            "rc": "NOLOCK",
            "err": (Path(w) / ".a_err").read_text()[-200:],
            "tb": False,
            "rss": 0,
            "s": 0,
            "nerr": 0,
        }
    alive = a.poll() is None
    r = run(argv_b, w)
    r["a_alive_at_b"] = alive and a.poll() is None
    a.send_signal(signal.SIGKILL)
    a.wait()
    return r
