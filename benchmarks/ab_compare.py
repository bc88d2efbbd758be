"""A/B speed of this tree against another git ref (default ``main``), interleaved in one run.

The other ref's ``gear_env`` is exported with ``git archive`` to a temporary folder; then child
processes run the same workloads alternately on the two trees (A B B A A B ...), each child on the
same one core. The workloads are those of the three benchmarks, called from their own code
(``bench_simulator.throughput``, ``bench_env.bench_single / bench_vector / bench_kernel``):

* ``sim-dynamic``, ``sim-constant``: ``GearSimulator.advance`` mesh periods/s (omega 1.2, N 192);
* ``sim-short``: ``GearSimulator.advance(1)`` calls/s (constant model, omega 1.2, N 192);
* ``lanes-64``, ``scalar-8``: the SIMD lanes kernel at 64 systems, the scalar batch kernel at 8
  (the default control step, env-steps/s), as ``bench_batch_kernels.py`` times them;
* ``env-single``, ``env-vec-4``, ``env-vec-8``, ``env-vec-12``, ``env-vec-16``, ``env-vec-64``: the environments,
  env-steps/s
  (``GearSpeedEnv()``'s defaults, or each side's ``--a-env``/``--b-env`` id with ``--a-cfg``/``--b-cfg``
  settings, so that a setting of this tree is timed against another tree's, e.g. a step count against
  the code of an issue's date:
  ``--ref ad98ae5 --a-env GearSpeedDemand-v0 --b-env GearSpeedDemand-v1 --b-cfg '{"steps_per_period": 72}'``).

``--policy SPEC`` replaces the random set-points of the env-* workloads by a policy's (``pretrained``, a script
name, a policy file: ``agents.registry``): its actions are recorded once on side B's environment (the start each
workload makes, ``bench_env.record_policy_actions``) and replayed on both sides, so both time the same set-points,
those an agent chooses (quiet speeds, few contact changes), whatever their numerical differences:
``--ref ad98ae5 --a-env GearSpeedDemand-v0 --b-env GearSpeedDemand-v1 --b-cfg '{"correct_kinks": true}'
--policy pretrained``.

Rates are per CPU second of the child (robust against other jobs on the machine). Each child
warms up first (its compile is not timed; the numba cache, one folder per source hash, is kept
between runs in $NUMBA_CACHE_DIR, default a folder in the temp dir). Prints, per workload, the
median of the B/A ratios over the rounds and their range, with the load average.

    python benchmarks/ab_compare.py [--ref main] [--rounds 4] [--seconds 1.5] [--only sim-dynamic ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

WORKLOADS = (
    "sim-dynamic",
    "sim-constant",
    "sim-short",
    "lanes-64",
    "scalar-8",
    "env-single",
    "env-vec-4",
    "env-vec-8",
    "env-vec-12",
    "env-vec-16",
    "env-vec-64",
)

_CHILD = r"""
import json, sys, time
import numpy as np
sys.path.insert(0, {bench!r})
import bench_env as E
import bench_simulator as S
secs = {seconds!r}
only = {only!r}
env_id = {env_id!r}
cfg = json.loads({cfg!r})
acts = {{n: np.load(p, allow_pickle=False) for n, p in {actions!r}.items()}}

def run(name, warm):
    t = 0.05 if warm else secs
    if name == "sim-short":
        return S.throughput_short("constant", 1.2, 192, 200 if warm else 2000, repeats=1 if warm else 5)
    if name.startswith("sim-"):
        return S.throughput(name[4:], 1.2, 10 if warm else 60, 192, repeats=1 if warm else 5)[1]
    if name == "lanes-64":
        return E.bench_kernel(64, t, lanes=True)
    if name == "scalar-8":
        return E.bench_kernel(8, t, lanes=False)
    if name == "env-single":
        return E.bench_single(t, env_id, acts.get(name), **cfg)
    if name.startswith("env-vec-"):
        return E.bench_vector(int(name[8:]), t, env_id, acts.get(name), **cfg)
    raise ValueError(name)

for n in only:
    run(n, True)
print(json.dumps({{n: run(n, False) for n in only}}))
"""


_RECORD = r"""
import json, sys
import numpy as np
sys.path.insert(0, {bench!r})
import bench_env as E
cfg = json.loads({cfg!r})
for name, path in {paths!r}.items():
    n = 0 if name == "env-single" else int(name[8:])
    acts = E.record_policy_actions({spec!r}, {env_id!r}, n, 4096 if n == 0 else 512, **cfg)
    np.save(path, acts)
    print(name, acts.shape, "mean |a|", float(np.abs(acts).mean()), flush=True)
"""


def _record(tree: Path, spec: str, env_id: str, cfg: str, names: list[str], tmp: Path, cwd: str) -> dict[str, str]:
    """Record policy ``spec``'s actions on ``env_id`` (settings ``cfg``) for the env-* workloads ``names``, in a child
    on ``tree`` (side B); returns workload -> .npy path."""
    paths = {n: str(tmp / f"actions-{n}.npy") for n in names}
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), str(ROOT)]))  # ROOT: the agents package
    code = _RECORD.format(bench=str(HERE), cfg=cfg, paths=paths, spec=spec, env_id=env_id)
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"recording the actions of policy {spec!r} on {env_id} failed:\n{out.stderr[-3000:]}")
    print("actions of policy", spec, "recorded on side B:", "; ".join(out.stdout.strip().splitlines()))
    return paths


def _child(
    tree: Path,
    only: list[str],
    seconds: float,
    cpu: int,
    cwd: str,
    env_id: str | None = None,
    cfg: str = "{}",
    actions: dict[str, str] | None = None,
) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    code = _CHILD.format(
        bench=str(HERE), seconds=seconds, only=list(only), env_id=env_id, cfg=cfg, actions=dict(actions or {})
    )
    cmd = [sys.executable, "-c", code]
    if hasattr(os, "sched_setaffinity"):
        cmd = ["taskset", "-c", str(cpu), *cmd]
    out = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, check=False)  # cwd: no gear_env
    if out.returncode != 0:
        raise SystemExit(f"child on {tree} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", default="main", help="git ref of side A (default main); side B is this tree")
    ap.add_argument("--rounds", type=int, default=4, help="A/B pairs per workload (default 4)")
    ap.add_argument("--seconds", type=float, default=1.5, help="CPU seconds per measurement (default 1.5)")
    ap.add_argument("--only", nargs="+", choices=WORKLOADS, default=list(WORKLOADS), help="workloads to run")
    ap.add_argument("--cpu", type=int, default=None, help="core to pin the children to (default: the last)")
    ap.add_argument("--tree", default=str(ROOT), help="folder holding side B's gear_env (default: this tree)")
    for side in ("a", "b"):
        who = f"env-* workloads of side {side.upper()}"
        ap.add_argument(f"--{side}-env", metavar="ID", help=f"{who}: this registered id")
        ap.add_argument(f"--{side}-cfg", metavar="JSON", default="{}", help=f"{who}: these settings (a JSON object)")
    ap.add_argument("--policy", metavar="SPEC", help="env-* workloads: replay the actions of this policy (recorded on "
                    "side B's environment, which needs --b-env) instead of random ones")  # fmt: skip
    args = ap.parse_args(argv)
    if args.policy and not args.b_env:
        ap.error("--policy needs --b-env (the registered id whose policy actions are recorded)")
    for side in ("a", "b"):
        try:
            if not isinstance(json.loads(getattr(args, f"{side}_cfg")), dict):
                raise ValueError("not an object")
        except ValueError as exc:
            ap.error(f"--{side}-cfg must be a JSON object of environment settings: {exc}")
    os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(tempfile.gettempdir()) / "gear-env-ab-cache"))
    cpu = args.cpu if args.cpu is not None else (os.cpu_count() or 1) - 1
    with tempfile.TemporaryDirectory() as tmp:
        tree_a, cwd = Path(tmp) / "a", Path(tmp) / "cwd"
        tree_a.mkdir()
        cwd.mkdir()
        arch = subprocess.run(
            ["git", "-C", str(ROOT), "archive", args.ref, "gear_env"], capture_output=True, check=True
        )
        subprocess.run(["tar", "-x", "-C", str(tree_a)], input=arch.stdout, check=True)
        trees = {"A": tree_a, "B": Path(args.tree)}
        env_names = [n for n in args.only if n.startswith("env-")]
        actions = (
            _record(trees["B"], args.policy, args.b_env, args.b_cfg, env_names, Path(tmp), str(cwd))
            if args.policy and env_names
            else {}
        )
        print(f"A = {args.ref} ({tree_a}), B = {args.tree}; {args.rounds} rounds, {args.seconds} s each")
        for side in ("a", "b"):
            what = getattr(args, f"{side}_env") or "GearSpeedEnv()"
            print(f"  env-* of {side.upper()}: {what} {getattr(args, f'{side}_cfg')}")
        print("load before:", os.getloadavg())
        ratios: dict[str, list[float]] = {n: [] for n in args.only}
        for r in range(args.rounds):
            order = ("A", "B") if r % 2 == 0 else ("B", "A")
            res = {
                side: _child(
                    trees[side],
                    args.only,
                    args.seconds,
                    cpu,
                    str(cwd),
                    getattr(args, f"{side.lower()}_env"),
                    getattr(args, f"{side.lower()}_cfg"),
                    actions,
                )  # fmt: skip
                for side in order
            }
            for n in args.only:
                ratios[n].append(res["B"][n] / res["A"][n])
            print(f"round {r + 1}: " + ", ".join(f"{n} {ratios[n][-1]:.3f}" for n in args.only), flush=True)
        print("load after:", os.getloadavg())
        print("B/A speed ratio (> 1: B faster): median [min, max]")
        for n in args.only:
            v = np.array(ratios[n])
            print(f"  {n:13s} {np.median(v):.3f} [{v.min():.3f}, {v.max():.3f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
