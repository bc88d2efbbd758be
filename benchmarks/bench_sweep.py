"""Benchmark: the 300-point bifurcation diagrams of both models on 1 and 2 local workers.

    python benchmarks/bench_sweep.py [--points 300] [--transient 300] [--periods 200] [--lyapunov-cost] [--json FILE]

Each sweep: omega in [0.05, 3], forward, 300 transient + 200 recorded mesh periods per omega,
classification (with confirmation windows) and the largest Lyapunov exponent included.

* 1 worker: the two sweeps run serially in this process (``sweep(..., workers=1)``).
* 2 workers: both sweeps share a local process pool (``sweep_many(..., workers=2)``); the pool
  is started and its workers have loaded the numba kernels before the clock starts (that
  one-off start-up is printed separately). numba compilation is kept out of all timings.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--transient", type=int, default=300)
    ap.add_argument("--periods", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--lyapunov-cost", action="store_true", help="also time the serial sweeps without Lyapunov")
    ap.add_argument("--steps-study", action="store_true", help="only print the low-omega steps-per-period study")
    ap.add_argument("--lyapunov-study", action="store_true", help="only print finite-time Lyapunov estimates")
    ap.add_argument("--json", metavar="FILE", help="also write a JSON record (benchmarks/make_tables.py reads it)")
    args = ap.parse_args(argv)
    from bench_record import Record, check_json_target

    check_json_target(args.json)
    rec = Record("bench_sweep", argv)
    if args.steps_study:
        return steps_study()
    if args.lyapunov_study:
        return lyapunov_study()

    from gear_env.analysis import sweep, sweep_many
    from gear_env.analysis.executors import local_pool, start_workers
    from gear_env.analysis.sweep import warm_numba_cache

    grid = np.linspace(0.05, 3.0, args.points)
    common = dict(transient=args.transient, periods=args.periods, lyapunov=True)
    print(f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, Python {platform.python_version()}")
    print(f"grid: {args.points} points in [0.05, 3], transient {args.transient}, recorded {args.periods}")
    t = time.perf_counter()
    warm_numba_cache()
    print(f"numba compile/load (excluded): {time.perf_counter() - t:.1f} s")

    serial = {}
    t_serial = 0.0
    cpu0 = time.process_time()
    for model in ("constant", "dynamic"):
        t = time.perf_counter()
        serial[model] = sweep(grid, model=model, workers=1, progress=False, **common)
        dt = time.perf_counter() - t
        t_serial += dt
        print(f"1 worker  {model:8s}: {dt:6.1f} s   {serial[model].summary()}")
    cpu = time.process_time() - cpu0
    print(f"1 worker  both    : {t_serial:6.1f} s wall, {cpu:6.1f} s CPU (wall > CPU: other load on the machine)")

    if args.lyapunov_cost:
        t_nol = 0.0
        for model in ("constant", "dynamic"):
            t = time.perf_counter()
            sweep(grid, model=model, progress=False, transient=args.transient, periods=args.periods, lyapunov=False)
            t_nol += time.perf_counter() - t
        print(f"1 worker  both, no Lyapunov: {t_nol:6.1f} s (Lyapunov adds {100 * (t_serial / t_nol - 1):.0f} %)")

    t = time.perf_counter()
    pool = local_pool(args.workers, warm_numba_cache)
    start_workers(pool, args.workers)
    print(f"pool start-up with {args.workers} workers (excluded): {time.perf_counter() - t:.1f} s")
    pids = list(getattr(pool, "_processes", {}) or {})
    cpu_before = {pid: _proc_cpu(pid) for pid in pids}
    try:
        t = time.perf_counter()
        par = sweep_many(
            [dict(omegas=grid, model=m, **common) for m in ("constant", "dynamic")],
            workers=args.workers, executor=pool, progress=False,
        )  # fmt: skip
        t_par = time.perf_counter() - t
        cpu_workers = [_proc_cpu(pid) - cpu_before[pid] for pid in pids]
    finally:
        pool.shutdown()
    for model, r in zip(("constant", "dynamic"), par):
        agree = np.mean([a == b for a, b in zip(r.regime, serial[model].regime)])
        print(f"{args.workers} workers {model:8s}: {r.summary()}; regime agrees with serial at {100 * agree:.1f} %")
    print(f"{args.workers} workers both    : {t_par:6.1f} s")
    print(f"speed-up 1 -> {args.workers} workers: {t_serial / t_par:.2f} (wall clock)")
    what = f"{args.points} points x 2 models, {args.transient} + {args.periods} periods, classification + Lyapunov"
    rec.add(f"sweep: {what}, 1 worker", "s wall", [t_serial])
    rec.add(f"sweep: the same on {args.workers} workers", "s wall", [t_par])
    rec.add(f"sweep speed-up 1 -> {args.workers} workers (wall clock)", "x", [t_serial / t_par])
    if cpu_workers and all(c > 0 for c in cpu_workers):
        busiest = max(cpu_workers)
        print(
            "worker CPU seconds: "
            + ", ".join(f"{c:.1f}" for c in cpu_workers)
            + f"; CPU-bound speed-up (serial CPU / busiest worker CPU): {cpu / busiest:.2f}"
        )
        rec.add(f"sweep speed-up 1 -> {args.workers} workers (serial CPU / busiest worker CPU)", "x", [cpu / busiest])
    if args.json:
        rec.write(args.json)
    return 0


def _proc_cpu(pid: int) -> float:
    """User + system CPU seconds of a process (Linux /proc), 0 if unavailable."""
    import os

    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def lyapunov_study() -> int:
    """Finite-time Lyapunov estimates over 200, 1000, 4000 mesh periods after 500 on the attractor."""
    from gear_env.analysis import largest_lyapunov
    from gear_env.sim.simulator import GearSimulator

    print("model     omega   lam(200)  lam(1000) lam(4000)  [per unit natural time]")
    for model, w in [("constant", 0.526), ("constant", 0.469), ("constant", 1.71), ("constant", 2.274),
                     ("dynamic", 2.162), ("dynamic", 1.879)]:  # fmt: skip
        sim = GearSimulator(None, model, None, w)  # default steps, as largest_lyapunov
        sim.advance(500)
        x = sim.state
        vals = [largest_lyapunov(w, model, state=x, periods=n) for n in (200, 1000, 4000)]
        print(f"{model:8s} {w:6.3f}  " + "  ".join(f"{v:+.4f}" for v in vals))
    return 0


def steps_study() -> int:
    """Amplitudes at low omega against the Newmark steps per mesh period (dynamic model)."""
    from gear_env.sim.simulator import GearSimulator

    print("omega  steps  amp_U      amp_Delta  amp_force  contact_loss")
    for w in (0.05, 0.1, 0.2, 0.3, 0.5):
        for n in (128, 256, 512, 1024, 2048):
            sim = GearSimulator(None, "dynamic", n, w)
            sim.advance(50 if w < 0.2 else 200)
            st = sim.advance(20)
            print(
                f"{w:5.2f} {n:6d}  {st.amplitude('U'):.6f}   {st.amplitude('delta'):.6f}   "
                f"{st.amplitude('force'):.6f}   {st.separation_fraction:.4f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
