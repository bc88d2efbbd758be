"""Benchmark: period-1 continuation of both models over [0.05, 3] with branch switching at the
first period-doubling point.

    python benchmarks/bench_continuation.py [--repeats 3] [--omega-min 0.05] [--omega-max 3]

Each run: ``continue_orbits(model, 0.05, 3.0, max_switches=1, max_period=2)`` (pseudo-arclength,
bifurcation location by bisection, one period-2 branch), on the located map (the default) and on the
unlocated one (``located=False``), interleaved A/B within each repeat, so the ratio of the two is
taken under the same machine state. The models alternate (constant, dynamic, ...); wall and CPU time
(``time.process_time``, one thread) are printed per run with the load average (``os.getloadavg``)
before and after. numba compilation/loading is done once before the clock starts and printed
separately. Target: < 10 s for both models on one core.
"""

from __future__ import annotations

import argparse
import os
import platform
import time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--omega-min", type=float, default=0.05)
    ap.add_argument("--omega-max", type=float, default=3.0)
    args = ap.parse_args(argv)

    from gear_env.analysis.continuation import continue_orbits

    print(f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, Python {platform.python_version()}")
    t = time.perf_counter()
    for m in ("constant", "dynamic"):  # compile / load the kernels
        for located in (True, False):
            continue_orbits(m, 1.0, 1.05, max_switches=0, located=located)
    print(f"numba compile/load (excluded): {time.perf_counter() - t:.1f} s")
    rows: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    for rep in range(args.repeats):
        for located in (True, False) if rep % 2 == 0 else (False, True):  # fmt: skip
            tot_w = tot_c = 0.0
            load0 = os.getloadavg()[0]
            name = "located" if located else "unlocated"
            for m in ("constant", "dynamic") if rep % 2 == 0 else ("dynamic", "constant"):
                w0, c0 = time.perf_counter(), time.process_time()
                r = continue_orbits(m, args.omega_min, args.omega_max, max_switches=1, max_period=2, located=located)
                wall, cpu = time.perf_counter() - w0, time.process_time() - c0
                tot_w += wall
                tot_c += cpu
                pts = sum(len(b.omega) for b in r.branches)
                kinds = {}
                for bp in r.bifurcations:
                    kinds[bp.type] = kinds.get(bp.type, 0) + 1
                first_pd = next((bp.omega for bp in r.bifurcations if bp.type == "period-doubling"), float("nan"))
                print(f"  repeat {rep} {name:9s} {m:8s}: wall {wall:5.2f} s, CPU {cpu:5.2f} s; "
                      f"{len(r.branches)} branches, "
                  f"{pts} points, bifurcations {kinds}; first period doubling at {first_pd:.5f}; "
                  f"complete={r.complete}")  # fmt: skip
            load1 = os.getloadavg()[0]
            rows[located].append((tot_w, tot_c))
            print(f"repeat {rep} {name}: both models wall {tot_w:.2f} s, CPU {tot_c:.2f} s "
              f"(load average {load0:.2f} -> {load1:.2f})")  # fmt: skip
    for located in (True, False):
        ws = sorted(r[0] for r in rows[located])
        cs = sorted(r[1] for r in rows[located])
        print(f"{'located' if located else 'unlocated'} map, both models: wall {ws[0]:.2f}-{ws[-1]:.2f} s, "
              f"CPU {cs[0]:.2f}-{cs[-1]:.2f} s over {len(ws)} repeats")  # fmt: skip
    ratios = sorted(a[1] / b[1] for a, b in zip(rows[True], rows[False], strict=True))
    print(f"CPU time located / unlocated, per repeat: {ratios[0]:.2f}-{ratios[-1]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
