"""Cold start: seconds of numba compile before the first results, from an empty cache.

Each measurement is a fresh subprocess with an empty ``NUMBA_CACHE_DIR`` (a new temporary folder):

* ``v1``: ``gym.make("GearSpeed-v1")``, ``reset()`` and one ``step`` (what a new user waits for;
  the target of issue #18 is 30 s on the 2-vCPU VM);
* ``env``: the same for ``GearSpeed-v0``;
* ``vec``: ``gym.make_vec("GearSpeed-v1", num_envs=8, vectorization_mode="vector_entry_point")``,
  ``reset()`` and one ``step`` (the SIMD lanes kernel);
* ``v1vec``: ``vec`` after ``v1`` in the same process (only the vector env's part is timed: what
  the vector env compiles beyond the kernels that the single env compiled; its "import" column
  includes the single env);
* ``sim``: ``GearSimulator(...).advance(2)`` and ``simulate(...)`` for both backlash models.

With ``--ref REF`` the same is measured, interleaved (A B B A ...), on the ``gear_env`` of another
git ref exported to a temporary folder, and the ratio B/A printed. Compiling is CPU-bound and
single-threaded: wall seconds grow with the load of the machine (printed with them), CPU seconds
(user + sys) much less, so both are printed: the first call's CPU seconds (measured in the child)
and the whole child process's (imports included, from ``os.wait4``); the summary compares CPU.

    python benchmarks/bench_cold_start.py [--rounds 1] [--ref main] [--only v1 env sim vec v1vec]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

_ENV_CHILD = r"""
import time
t0 = time.perf_counter()
import gymnasium as gym
import gear_env
t1 = time.perf_counter()
c1 = time.process_time()
e = gym.make("ENV_ID")
e.reset(seed=0)
e.step(e.action_space.sample())
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {time.process_time() - c1:.3f}")
"""

_VEC_CHILD = r"""
import time
t0 = time.perf_counter()
import gymnasium as gym
import gear_env
t1 = time.perf_counter()
if SINGLE_FIRST:
    e = gym.make("GearSpeed-v1")
    e.reset(seed=0)
    e.step(e.action_space.sample())
    t1 = time.perf_counter()
c1 = time.process_time()
v = gym.make_vec("GearSpeed-v1", num_envs=8, vectorization_mode="vector_entry_point")
v.reset(seed=0)
v.step(v.action_space.sample())
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {time.process_time() - c1:.3f}")
"""

_CHILDREN = {
    "env": _ENV_CHILD.replace("ENV_ID", "GearSpeed-v0"),
    "vec": _VEC_CHILD.replace("SINGLE_FIRST", "False"),
    "v1vec": _VEC_CHILD.replace("SINGLE_FIRST", "True"),
    "v1": _ENV_CHILD.replace("ENV_ID", "GearSpeed-v1"),
    "sim": r"""
import time
t0 = time.perf_counter()
from gear_env import GearSimulator, simulate
t1 = time.perf_counter()
c1 = time.process_time()
for m in ("constant", "dynamic"):
    GearSimulator(model=m, omega=1.2).advance(2)
    simulate(1.2, m, periods=1, transient=0)
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {time.process_time() - c1:.3f}")
""",
}


def cold(tree: Path, what: str, cwd: Path) -> tuple[float, float, float, float]:
    """(import seconds, first-call wall seconds, first-call CPU seconds, CPU seconds of the whole
    child) of child ``what`` on the package in ``tree``, empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(tree))
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            proc = subprocess.Popen([sys.executable, "-c", _CHILDREN[what]], env=env, cwd=cwd, stdout=out, stderr=err)
            _pid, code, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(code)
            out.seek(0)
            err.seek(0)
            stdout, stderr = out.read(), err.read()
    if proc.returncode != 0:
        raise SystemExit(f"{what} on {tree} failed:\n{stderr[-3000:]}")
    a, b, c = stdout.split()[-3:]
    return float(a), float(b), float(c), usage.ru_utime + usage.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=1, help="measurements per tree and child (default 1)")
    ap.add_argument("--ref", default=None, help="also measure this git ref's gear_env (A), interleaved")
    ap.add_argument("--only", nargs="+", choices=sorted(_CHILDREN), default=["v1", "sim"])
    ap.add_argument("--tree", default=str(ROOT), help="folder holding the gear_env to measure (default: this tree)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp) / "cwd"  # no gear_env in the children's working folder
        cwd.mkdir()
        trees = {"B": Path(args.tree)}
        if args.ref:
            tree_a = Path(tmp) / "a"
            tree_a.mkdir()
            arch = subprocess.run(
                ["git", "-C", str(ROOT), "archive", args.ref, "gear_env"], capture_output=True, check=True
            )
            subprocess.run(["tar", "-x", "-C", str(tree_a)], input=arch.stdout, check=True)
            trees = {"A": tree_a, "B": Path(args.tree)}
        print(f"trees: {', '.join(f'{k} = {v}' for k, v in trees.items())}; {os.cpu_count()} CPUs")
        res: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for r in range(args.rounds):
            order = sorted(trees) if r % 2 == 0 else sorted(trees, reverse=True)
            for what in args.only:
                for side in order:
                    load = os.getloadavg()[0]
                    t = time.perf_counter()
                    imp, first, first_cpu, cpu = cold(trees[side], what, cwd)
                    wall = time.perf_counter() - t
                    res.setdefault((side, what), []).append((first, first_cpu))
                    print(
                        f"{side} {what:3s}: import {imp:5.2f} s, first call (compile) {first:6.1f} s wall "
                        f"{first_cpu:6.1f} s CPU; process {wall:6.1f} s wall {cpu:6.1f} s CPU; "
                        f"load {load:.1f} -> {os.getloadavg()[0]:.1f}",
                        flush=True,
                    )
        for what in args.only:
            line = ", ".join(
                f"{s} {min(r[0] for r in res[(s, what)]):.1f} s wall, "
                f"{np.median([r[1] for r in res[(s, what)]]):.1f} s CPU"
                for s in sorted(trees)
            )
            ratio = ""
            if "A" in trees:
                cpu = {s: np.median([r[1] for r in res[(s, what)]]) for s in trees}
                ratio = f"  (CPU B/A {cpu['B'] / cpu['A']:.3f})"
            print(f"{what}: first-call compile, best wall and median CPU: {line}{ratio}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
