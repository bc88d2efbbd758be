"""Benchmark of the simulator core, on one core, in one run.

Prints:
1. first-call compile time (fresh NUMBA_CACHE_DIR, in a subprocess) separately from the cached
   start-up (second subprocess, same cache directory) and the warm in-process call;
2. simulated mesh periods per second for both backlash models at the default steps per period;
3. the speed-up over SciPy ``solve_ivp`` (DOP853) at equal accuracy on the same work: same omega,
   same start state, same number of mesh periods. The Newmark error at the default step count is
   measured against a fine reference (gear_env.sim.reference, rtol 1e-12 with event location); then
   the loosest DOP853 tolerance whose error is no larger is searched (``rtol`` in half decades, both
   straight through the contact kinks and with event location), and both are timed back to back
   (median of 3 paired ratios, robust to the VM's speed drift);
4. the same work at the tests' accuracy bound (1e-3 b0): the smallest N (32 ... 256) and the
   loosest DOP853 tolerance that reach it, and their paired ratio;
5. with ``--work-precision``: errors and times of Newmark at N = 48 ... 384 and DOP853 at
   rtol = 1e-1 ... 1e-7, and the paired ratio of the smallest N and the loosest rtol that reach an error
   of 1e-3 (the accuracy the tests require) and 1e-4.

    python benchmarks/bench_simulator.py [--work-precision] [--json FILE]    (pins itself to one core)
    python benchmarks/bench_simulator.py --quick
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

_CHILD = r"""
import time, sys
t0 = time.perf_counter()
import gear_env
from gear_env import GearSimulator, simulate
t1 = time.perf_counter()
for m in ("constant", "dynamic"):
    GearSimulator(model=m, omega=1.2).advance(2)
    simulate(1.2, m, periods=1, transient=0)
t2 = time.perf_counter()
for m in ("constant", "dynamic"):
    GearSimulator(model=m, omega=1.2).advance(2)
    simulate(1.2, m, periods=1, transient=0)
t3 = time.perf_counter()
print(f"{t1 - t0:.4f} {t2 - t1:.4f} {t3 - t2:.6f}")
"""


def compile_times() -> tuple[list[float], list[float]]:
    """(fresh-cache [import, first call, warm call], cached [import, first call, warm call]) in s."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        runs = []
        for _ in range(2):
            out = subprocess.run(
                [sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, check=True
            ).stdout.split()
            runs.append([float(v) for v in out])
    return runs[0], runs[1]


def throughput(model: str, omega: float, periods: int, n_steps: int, repeats: int = 10) -> tuple[float, float]:
    """Mesh periods per second of GearSimulator.advance(periods), warm: (wall clock, CPU time).

    Best of ``repeats`` chunks, so that other jobs on the machine disturb the figure as little as
    possible (the best chunk is the one that had the core to itself).
    """
    from gear_env import GearSimulator

    sim = GearSimulator(model=model, omega=omega, steps_per_period=n_steps)
    sim.advance(50)
    best_w = best_c = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        c = time.process_time()
        sim.advance(periods)
        best_c = min(best_c, time.process_time() - c)
        best_w = min(best_w, time.perf_counter() - t)
    return periods / best_w, periods / best_c


def throughput_short(model: str, omega: float, n_steps: int, calls: int = 2000, repeats: int = 5) -> float:
    """Mesh periods per CPU second of ``GearSimulator.advance(1)`` called ``calls`` times (a caller that sets
    omega every period: the per-call cost shows), best of ``repeats``."""
    from gear_env import GearSimulator

    sim = GearSimulator(model=model, omega=omega, steps_per_period=n_steps)
    sim.advance(50)
    best = np.inf
    for _ in range(repeats):
        c = time.process_time()
        for _ in range(calls):
            sim.advance(1)
        best = min(best, time.process_time() - c)
    return calls / best


def throughput_batch(model: str, omegas, periods: int, n_steps: int, repeats: int = 5) -> float:
    """Mesh periods per second (all systems together, CPU time) of ``simulate_batch``: one system
    per omega stepped together with SIMD; best of ``repeats``."""
    from gear_env import simulate_batch

    simulate_batch(omegas, model=model, periods=2, transient=0, steps_per_period=n_steps)  # compile/load
    best = np.inf
    for _ in range(repeats):
        c = time.process_time()
        simulate_batch(omegas, model=model, periods=periods, transient=0, steps_per_period=n_steps)
        best = min(best, time.process_time() - c)
    return len(omegas) * periods / best


def _timeit(fn, min_time: float = 0.3) -> float:
    """Best-of CPU time of fn() [s] (process time: robust to other jobs on the machine)."""
    best = np.inf
    total = 0.0
    n = 0
    while total < min_time or n < 3:
        t = time.process_time()
        fn()
        dt = time.process_time() - t
        best = min(best, dt)
        total += dt
        n += 1
    return best


def paired_ratio(fast, slow, rounds: int = 3) -> tuple[float, float, float]:
    """Median over ``rounds`` of t(slow) / t(fast), the two timed back to back in each round.

    The machine is a shared VM whose speed drifts by up to 2x over minutes; timing the two sides
    minutes apart (as a plain best-of each would) puts that drift into the ratio. Here each round
    times ``slow()`` once (CPU time) right next to the best of several ``fast()`` calls.
    Returns (median ratio, median slow time, median fast time) in s.
    """
    ratios, ts, tf = [], [], []
    for _ in range(rounds):
        t = time.process_time()
        slow()
        t_slow = time.process_time() - t
        t_fast = _timeit(fast, 0.05)
        ratios.append(t_slow / t_fast)
        ts.append(t_slow)
        tf.append(t_fast)
    return float(np.median(ratios)), float(np.median(ts)), float(np.median(tf))


def ratio_vs_solve_ivp(model: str, omega: float, periods: int, n_steps: int) -> dict:
    """Equal-accuracy comparison on one piece of work; returns the measured numbers."""
    from gear_env import GearParams, GearSimulator
    from gear_env.sim.reference import reference_poincare

    p = GearParams()
    sim = GearSimulator(p, model, 512, omega)
    sim.advance(300)
    start = sim.state
    fine = reference_poincare(omega, model, p, 0, periods, start, rtol=1e-12, atol=1e-13).states

    def newmark():
        return GearSimulator(p, model, n_steps, omega, start).advance(periods)

    err_nm = float(np.max(np.abs(newmark().poincare[:, :10] - fine)))
    t_nm = _timeit(newmark)
    t0 = time.process_time()
    reference_poincare(omega, model, p, 0, periods, start)  # the tests' reference (rtol 1e-11, events)
    t_ref = time.process_time() - t0
    res = {"omega": omega, "model": model, "periods": periods, "err_newmark": err_nm, "t_newmark": t_nm}
    res["t_ref"] = t_ref
    for label, events in (("plain", False), ("events", True)):
        found = None
        for k in range(2, 25):  # rtol = 1e-1, 3.2e-2, 1e-2, ... 1e-12 (half decades)
            rtol = 10.0 ** (-k / 2)

            def run(rtol=rtol, events=events):
                return reference_poincare(
                    omega, model, p, 0, periods, start, rtol=rtol, atol=rtol * 1e-2, events=events
                )

            r = run()
            err = float(np.max(np.abs(r.states - fine)))
            if err <= err_nm:
                found = (rtol, err, r.nfev, run)
                break
        if found is None:
            res[label] = None
        else:
            rtol, err, nfev, run = found
            ratio, t, _ = paired_ratio(newmark, run)
            res[label] = {"rtol": rtol, "err": err, "time": t, "nfev": nfev, "ratio": ratio}
    return res


def ratio_at_bound(model: str, omega: float, periods: int, eps: float = 1e-3) -> dict | None:
    """Both integrators at one error bound on the same work: the smallest Newmark N (32 ... 256,
    steps of <= 25 %, i.e. error steps of <= 1.6x) and the loosest DOP853 rtol (events and plain,
    half decades from 1e-1, error steps of ~3x) whose Poincare error is <= ``eps`` b0, and their
    paired ratio. None if no N reaches it."""
    from gear_env import GearParams, GearSimulator
    from gear_env.sim.reference import reference_poincare

    p = GearParams()
    sim = GearSimulator(p, model, 512, omega)
    sim.advance(300)
    start = sim.state
    fine = reference_poincare(omega, model, p, 0, periods, start, rtol=1e-12, atol=1e-13).states
    nm = None
    for n in (32, 40, 48, 56, 64, 72, 80, 96, 112, 128, 160, 192, 224, 256):  # steps of <= 25 %

        def run_nm(n=n):
            return GearSimulator(p, model, n, omega, start).advance(periods)

        err = float(np.max(np.abs(run_nm().poincare[:, :10] - fine)))
        if err <= eps:
            nm = (n, err, run_nm)
            break
    if nm is None:
        return None
    out: dict = {"n": nm[0], "err_newmark": nm[1]}
    for label, events in (("events", True), ("plain", False)):
        for k in range(2, 25):
            rtol = 10.0 ** (-k / 2)

            def run(rtol=rtol, events=events):
                return reference_poincare(
                    omega, model, p, 0, periods, start, rtol=rtol, atol=rtol * 1e-2, events=events
                )

            err = float(np.max(np.abs(run().states - fine)))
            if err <= eps:
                ratio, _, _ = paired_ratio(nm[2], run)
                out[label] = {"rtol": rtol, "err": err, "ratio": ratio}
                break
        else:
            out[label] = None
    return out


BATCH_OMEGAS = (*np.round(np.linspace(0.7, 1.55, 10), 3), *np.round(np.linspace(2.5, 2.95, 6), 3))
"""The fresh-start work of ``ratio_batch``: 16 omegas in the period-1 bands of both models."""


def ratio_batch(model: str, omegas, periods: int, n_steps: int) -> dict:
    """The work of a fresh-start diagram: ``periods`` mesh periods at each of ``omegas``, each from
    its own attractor state. Newmark runs all of them in one ``simulate_batch`` call (SIMD across
    systems) and, for comparison, one ``GearSimulator`` after the other; DOP853 runs each omega at
    the loosest rtol (half decades) whose error is no larger than Newmark's at that omega. Returns
    the paired ratios (sum of the DOP853 times over the Newmark time)."""
    from gear_env import GearParams, GearSimulator, simulate_batch
    from gear_env.sim.reference import reference_poincare

    p = GearParams()
    starts, fines = [], []
    for w in omegas:
        sim = GearSimulator(p, model, 512, float(w))
        sim.advance(300)
        starts.append(sim.state)
        fines.append(reference_poincare(float(w), model, p, 0, periods, starts[-1], rtol=1e-12, atol=1e-13).states)
    S = np.stack(starts)

    def batch():
        return simulate_batch(list(omegas), model, periods, 0, n_steps, initial_states=S)

    def single():
        for w, s0 in zip(omegas, starts, strict=True):
            GearSimulator(p, model, n_steps, float(w), s0).advance(periods)

    errs = [float(np.max(np.abs(r.poincare[:, :10] - f))) for r, f in zip(batch(), fines, strict=True)]
    out: dict = {"omegas": len(omegas), "err_max": max(errs)}
    for label, events in (("events", True), ("plain", False)):
        runs = []
        for w, s0, f, e in zip(omegas, starts, fines, errs, strict=True):
            for k in range(2, 25):
                rtol = 10.0 ** (-k / 2)

                def run(w=float(w), s0=s0, rtol=rtol, events=events):
                    return reference_poincare(w, model, p, 0, periods, s0, rtol=rtol, atol=rtol * 1e-2, events=events)

                if float(np.max(np.abs(run().states - f))) <= e:
                    runs.append(run)
                    break
            else:
                runs = None
                break
        if runs is None:
            out[label] = None
            continue

        def dop853(runs=runs):
            for r in runs:
                r()

        r_batch, t_dop, t_batch = paired_ratio(batch, dop853)
        r_single, _, t_single = paired_ratio(single, dop853)
        out[label] = {"batch": r_batch, "single": r_single, "t_dop": t_dop, "t_batch": t_batch, "t_single": t_single}
    return out


def work_precision(model: str, omega: float, periods: int, fine_steps: int = 512) -> dict:
    """Work-precision data of both integrators on one piece of work (same omega, start state and
    periods): Newmark at several step counts and DOP853 (events and plain) at rtol 1e-1 ... 1e-7.

    Returns {"newmark": [(N, error, CPU s, run)], "events": [(rtol, error, CPU s, run)],
    "plain": [...]}, ``run`` re-running that integration. Errors are the max Poincare-state
    deviation (b0 units) from the rtol 1e-12 reference; the CPU times are single runs (for the
    table; ratios are re-timed in pairs by :func:`paired_ratio`).
    """
    from gear_env import GearParams, GearSimulator
    from gear_env.sim.reference import reference_poincare

    p = GearParams()
    sim = GearSimulator(p, model, fine_steps, omega)
    sim.advance(300)
    start = sim.state
    fine = reference_poincare(omega, model, p, 0, periods, start, rtol=1e-12, atol=1e-13).states
    out: dict = {"newmark": [], "events": [], "plain": []}
    for n in (48, 64, 96, 128, 192, 256, 384):

        def nm(n=n):
            return GearSimulator(p, model, n, omega, start).advance(periods)

        err = float(np.max(np.abs(nm().poincare[:, :10] - fine)))
        out["newmark"].append((n, err, _timeit(nm, 0.1), nm))
    for label, events in (("events", True), ("plain", False)):
        for k in range(1, 8):
            rtol = 10.0**-k

            def run(rtol=rtol, events=events):
                return reference_poincare(
                    omega, model, p, 0, periods, start, rtol=rtol, atol=rtol * 1e-2, events=events
                )

            t = time.process_time()
            r = run()
            dt = time.process_time() - t
            out[label].append((rtol, float(np.max(np.abs(r.states - fine))), dt, run))
    return out


def first_reaching(rows: list, eps: float) -> tuple | None:
    """The first row (smallest N, loosest rtol) whose error is <= eps, or None."""
    return next((r for r in rows if r[1] <= eps), None)


def print_work_precision(model: str, omega: float, periods: int) -> None:
    wp = work_precision(model, omega, periods)
    print(f"{model:8s} omega={omega}: {periods} periods")
    print("    Newmark N    : " + "  ".join(f"{n}: {e:.1e} / {t * 1e3:.2f} ms" for n, e, t, _ in wp["newmark"]))
    for label in ("events", "plain"):
        cells = "  ".join(f"{r:.0e}: {e:.1e} / {t * 1e3:.0f} ms" for r, e, t, _ in wp[label])
        print(f"    DOP853 {label:6s}: {cells}")
    for eps in (1e-3, 1e-4):
        a = first_reaching(wp["newmark"], eps)
        cells = []
        for label in ("events", "plain"):
            b = first_reaching(wp[label], eps)
            if a is None or b is None:
                cells.append(f"{label}: not reached")
            else:
                ratio, _, _ = paired_ratio(a[3], b[3])
                cells.append(f"{label} rtol {b[0]:.0e} -> {ratio:,.0f}x")
        head = "no N reached it" if a is None else f"Newmark N={a[0]}"
        print(f"    error <= {eps:.0e}: {head}; DOP853 " + "; ".join(cells))


def machine() -> str:
    try:
        cpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines()[:10]
    except OSError:
        cpu = [platform.processor()]
    return "\n".join([f"python {platform.python_version()} ({platform.platform()})", *cpu])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="simulator benchmark (one core)")
    ap.add_argument("--quick", action="store_true", help="fewer periods (smoke test)")
    ap.add_argument("--no-pin", action="store_true", help="do not pin to one CPU")
    ap.add_argument(
        "--batch-ratio",
        action="store_true",
        help="also the ratio on a fresh-start diagram's work (16 omegas, simulate_batch vs DOP853 per omega)",
    )
    ap.add_argument(
        "--work-precision",
        action="store_true",
        help="also print work-precision data (Newmark N ladder vs DOP853 rtol ladder)",
    )
    ap.add_argument("--json", metavar="FILE", help="also write a JSON record (benchmarks/make_tables.py reads it)")
    args = ap.parse_args(argv)
    from bench_record import Record, check_json_target

    check_json_target(args.json)
    rec = Record("bench_simulator", argv)
    if not args.no_pin and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    import numba

    from gear_env import default_steps_per_period

    print("== machine")
    print(machine())
    print(f"numba {numba.__version__}, numpy {np.__version__}")
    print("\n== compile time (subprocess, fresh NUMBA_CACHE_DIR), both models, simulate + GearSimulator")
    fresh, cached = compile_times()
    print(
        f"fresh cache : import {fresh[0]:.2f} s, first calls (compile + cache write) {fresh[1]:.2f} s, "
        f"warm calls {fresh[2] * 1e3:.2f} ms"
    )
    print(
        f"cached      : import {cached[0]:.2f} s, first calls (load from disk cache) {cached[1]:.2f} s, "
        f"warm calls {cached[2] * 1e3:.2f} ms"
    )
    rec.add("first calls of simulate + GearSimulator, both models, from an empty numba cache", "s", [fresh[1]])
    rec.add("the same from the disk cache", "s", [cached[1]])

    periods = 2000 if args.quick else 10000
    omegas = (0.45, 1.2, 2.8)
    n = default_steps_per_period(omegas[0])
    assert all(default_steps_per_period(w) == n for w in omegas)
    print(f"\n== throughput, default {n} steps per mesh period, one core, GearSimulator.advance({periods}), best of 10")
    for model in ("constant", "dynamic"):
        rates = [throughput(model, w, periods, n) for w in omegas]
        for k, clock in enumerate(("wall", "CPU ")):
            rr = [r[k] for r in rates]
            cells = "  ".join(f"omega={w}: {r:9,.0f}" for w, r in zip(omegas, rr, strict=True))
            ns_step = 1e9 / (np.mean(rr) * n)
            print(f"{model:8s} {clock} {cells}  mesh periods/s (mean {np.mean(rr):,.0f}; {ns_step:.0f} ns/step)")
        rec.add(
            f"simulator, {model} model, {n} steps/period (omega {', '.join(map(str, omegas))}; CPU)",
            "mesh periods/s",
            [r[1] for r in rates],
        )
        batch_w = np.linspace(0.45, 2.8, 16)
        rb = throughput_batch(model, batch_w, periods // 10, n)
        mean_cpu = np.mean([r[1] for r in rates])
        print(
            f"{model:8s} CPU  simulate_batch, 16 omegas in 0.45-2.8 stepped together (SIMD): {rb:9,.0f} mesh periods/s "
            f"({rb / mean_cpu:.2f}x one trajectory after the other)"
        )
        rec.add(f"simulate_batch, 16 runs stepped together (SIMD), {model} model", "mesh periods/s", [rb])
        rec.add(f"simulate_batch / one run after the other, {model} model", "x", [rb / mean_cpu])

    print("\n== speed-up over solve_ivp (DOP853) at equal accuracy, same start state and periods")
    work = [("dynamic", 1.2), ("dynamic", 2.8), ("constant", 1.2), ("constant", 2.8)]
    if args.quick:
        work = work[:2]
    vs_ivp: dict[str, list[float]] = {"plain": [], "events": []}
    at_bound: dict[str, list[float]] = {"plain": [], "events": []}
    for model, w in work:
        r = ratio_vs_solve_ivp(model, w, 20 if args.quick else 50, n)
        print(
            f"{model:8s} omega={w}: {r['periods']} periods, Newmark N={n}: error {r['err_newmark']:.2e}, "
            f"{r['t_newmark'] * 1e3:.2f} ms CPU"
        )
        print(
            f"    reference (DOP853 + events, rtol 1e-11): {r['t_ref'] * 1e3:8.1f} ms CPU "
            f"-> Newmark is {r['t_ref'] / r['t_newmark']:,.0f}x faster"
        )
        for label in ("plain", "events"):
            s = r[label]
            what = "DOP853 straight through kinks" if label == "plain" else "DOP853 + event location    "
            if s is None:
                print(f"    {what}: no rtol >= 1e-12 reached the Newmark error")
            else:
                print(
                    f"    {what}: rtol {s['rtol']:.1e} -> error {s['err']:.2e}, {s['time'] * 1e3:8.1f} ms CPU, "
                    f"{s['nfev']} RHS evals -> Newmark is {s['ratio']:,.0f}x faster"
                )
                vs_ivp[label].append(s["ratio"])
    print("\n== the same work at the tests' accuracy bound (1e-3 b0): smallest N and loosest rtol reaching it")
    for model, w in work:
        r = ratio_at_bound(model, w, 20 if args.quick else 50)
        if r is None:
            print(f"{model:8s} omega={w}: no N <= 256 reached 1e-3")
            continue
        cells = []
        for label in ("events", "plain"):
            s = r[label]
            cells.append(
                f"DOP853 {label} rtol {s['rtol']:.1e} (error {s['err']:.1e}) -> {s['ratio']:,.0f}x"
                if s
                else f"DOP853 {label}: not reached"
            )
        print(f"{model:8s} omega={w}: Newmark N={r['n']} (error {r['err_newmark']:.1e}); " + "; ".join(cells))
        for label in ("events", "plain"):
            if r[label]:
                at_bound[label].append(r[label]["ratio"])
    cases = ", ".join(f"{m} {w}" for m, w in work)
    for label, what in (("events", "DOP853 with event location"), ("plain", "DOP853 straight through kinks")):
        if vs_ivp[label]:
            rec.add(f"Newmark ({n} steps) vs {what} at equal accuracy ({cases})", "x", vs_ivp[label])
        if at_bound[label]:
            rec.add(f"the same, both at the tests' accuracy bound 1e-3 b0, vs {what}", "x", at_bound[label])
    if args.batch_ratio:
        print(
            f"\n== a fresh-start diagram's work: {len(BATCH_OMEGAS)} omegas in the period-1 bands "
            f"({BATCH_OMEGAS[0]}-{BATCH_OMEGAS[9]}, {BATCH_OMEGAS[10]}-{BATCH_OMEGAS[-1]}), default {n} steps, "
            "each DOP853 run at the loosest rtol reaching Newmark's error at that omega"
        )
        for model in ("dynamic", "constant"):
            r = ratio_batch(model, BATCH_OMEGAS, 20 if args.quick else 50, n)
            for label in ("events", "plain"):
                x = r[label]
                if x is None:
                    print(f"{model:8s} DOP853 {label}: some omega reached no rtol >= 1e-12")
                    continue
                print(
                    f"{model:8s} DOP853 {label:6s} {x['t_dop'] * 1e3:7.0f} ms; Newmark simulate_batch "
                    f"{x['t_batch'] * 1e3:5.2f} ms -> {x['batch']:,.0f}x; one GearSimulator after the other "
                    f"{x['t_single'] * 1e3:5.2f} ms -> {x['single']:,.0f}x "
                    f"(largest Newmark error {r['err_max']:.1e} b0)"
                )
                rec.add(
                    f"fresh-start diagram's work, {model} model, simulate_batch vs DOP853 {label}", "x", [x["batch"]]
                )
    if args.work_precision:
        print("\n== work-precision: error (b0) / CPU time per run; smallest N and loosest rtol reaching an error bound")
        for model, w in work:
            print_work_precision(model, w, 20 if args.quick else 50)
    if args.json:
        rec.write(args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
