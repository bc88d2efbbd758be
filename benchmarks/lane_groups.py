"""What a vector-env step costs when its rows are split into batches of different step counts (as
``steps_per_period="auto"`` split them before the lanes took a count per row): one SIMD-lane call for 16 rows against
the same rows in smaller calls; then rows of two counts (``--mixed``, default 48 and 64) in one call, each lane at its
own count (what the vector env does now), against the same rows in one call per count and against one count for all.

    python benchmarks/lane_groups.py [--steps 80] [--repeats 20] [--mixed 48 64]

Times ``GearSpeedCore._integrate_fixed`` (the environments' batch integration; SIMD lanes from 2 rows, the scalar
batch kernel for 1) on 16 GearSpeedDemand sub-environments at Fox-Goodwin's beta, 48 mesh periods, omega 1.0-1.5,
each split run from the same states; prints the milliseconds per call pattern and the ratio to one call.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

SPLITS = ([16], [8, 8], [5, 5, 6], [2, 14], [1, 15], [4, 4, 4, 4])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=80, help="steps per mesh period of every call (default 80)")
    ap.add_argument("--repeats", type=int, default=20, help="calls timed per pattern (default 20)")
    ap.add_argument("--mixed", type=int, nargs=2, default=(48, 64), metavar=("LOW", "HIGH"),
                    help="the two counts of the mixed calls (default 48 64)")  # fmt: skip
    args = ap.parse_args(argv)
    from gear_env.envs.env_config import task_config
    from gear_env.envs.vector_env import GearSpeedVectorEnv

    n = 16
    env = GearSpeedVectorEnv(n, task_config("GearSpeedDemand-v1", {"steps_per_period": args.steps}))
    env.reset(seed=list(range(n)))
    core = env._core
    rows = np.arange(n)
    w = np.linspace(1.0, 1.5, n)
    X0, A0 = core.X.copy(), core.A.copy()

    def run(sizes: list[int]) -> None:
        core.X[:], core.A[:] = X0, A0
        i = 0
        for s in sizes:
            sel = rows[i : i + s]
            core._integrate_fixed(sel, w[sel], w[sel], 48, args.steps)
            i += s

    ms = {}
    for sizes in SPLITS:
        run(sizes)  # compile, warm
        t0 = time.perf_counter()
        for _ in range(args.repeats):
            run(sizes)
        ms[str(sizes)] = (time.perf_counter() - t0) / args.repeats * 1e3
    base = ms[str(SPLITS[0])]
    print(f"16 rows, {args.steps} steps per mesh period, 48 periods ({args.repeats} calls each):")
    for k, v in ms.items():
        print(f"  batches {k:16s} {v:6.2f} ms  ({v / base:.2f}x one batch)")

    lo, hi = args.mixed

    def run_counts(counts: np.ndarray, one_call: bool) -> None:
        core.X[:], core.A[:] = X0, A0
        if one_call:
            core._integrate_fixed(rows, w, w, 48, counts)
            return
        for c in np.unique(counts):
            sel = rows[counts == c]
            core._integrate_fixed(sel, w[sel], w[sel], 48, int(c))

    cases = {}
    for n_hi in (0, 1, 4, 8, 16):
        counts = np.full(n, lo, np.int64)
        counts[n - n_hi :] = hi
        cases[f"{n - n_hi} x {lo} + {n_hi} x {hi}"] = counts
    ms2: dict[str, tuple[float, float]] = {}
    for name, counts in cases.items():
        t = []
        for one in (True, False):
            run_counts(counts, one)  # compile, warm
            t0 = time.perf_counter()
            for _ in range(args.repeats):
                run_counts(counts, one)
            t.append((time.perf_counter() - t0) / args.repeats * 1e3)
        ms2[name] = (t[0], t[1])
    base = ms2[f"0 x {lo} + {n} x {hi}"][0]
    print(
        f"\n16 rows at {lo} or {hi} steps per mesh period, 48 periods: one call (a count per lane) | a call per count;"
    )
    print(f"x: against one call of all 16 at {hi}")
    for name, (one, split) in ms2.items():
        print(f"  {name:16s} {one:6.2f} ms ({one / base:.2f}x) | {split:6.2f} ms ({split / base:.2f}x)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
