"""SIMD lanes kernel against the scalar batch kernel: ns per system-step, both models, one core.

Run:  taskset -c 0 python benchmarks/bench_batch_kernels.py [--systems 8 64] [--repeats 7]

The work: the environment's control step (24 mesh periods x 64 Newmark steps) for n systems at
the environment's reset states, omega spread over 0.2-3.0 (a third held, the rest ramping by up
to +-0.1), from the same start for both kernels. Prints the best of ``--repeats`` timings of each
kernel (compile time excluded) and checks that both return the same numbers bit for bit.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _run(lanes: bool, core, w0: np.ndarray, w1: np.ndarray, P: int, N: int):
    """One control step of every system from the core's state; (seconds, outputs)."""
    from gear_env.sim import batch_kernels as BK
    from gear_env.sim import kernels as K

    n = core.X.shape[0]
    X, A = core.X.copy(), core.A.copy()
    pc = np.zeros((n, P, K.N_PC))
    st = np.zeros((n, K.N_STATS))
    status = np.zeros(n, np.int64)
    el = np.zeros(n)
    t = time.perf_counter()
    if lanes:
        BK.integrate_stats_lanes(X, A, w0, w1, P, N, core.C, core.code, pc, st, status, el, 12, 1e-10)
    else:
        K.integrate_stats_batch(X, A, w0, w1, P, N, core.C, core.codes, pc, st, status, el, 12, 1e-10)
    return time.perf_counter() - t, (X, A, pc, st, status, el)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", type=int, nargs="+", default=[8, 64], help="batch sizes (default 8 64)")
    ap.add_argument("--repeats", type=int, default=7, help="timings per kernel (best is printed)")
    args = ap.parse_args()

    from gear_env.envs.env_config import GearSpeedConfig
    from gear_env.envs.env_core import GearSpeedCore

    for n in args.systems:
        for model in ("dynamic", "constant"):
            cfg = GearSpeedConfig(model=model)
            core = GearSpeedCore(cfg, n)
            core.reset_rows(np.arange(n), [np.random.default_rng(i) for i in range(n)])
            rng = np.random.default_rng(0)
            w0 = rng.uniform(0.2, 3.0, n)
            w1 = np.clip(w0 + rng.uniform(-0.1, 0.1, n), 0.1, 3.5)
            w1[::3] = w0[::3]
            work = (core, w0, w1, cfg.periods_per_step, cfg.steps_per_period)
            _, ref = _run(False, *work)
            _, got = _run(True, *work)
            same = all(np.array_equal(a, b) for a, b in zip(ref, got))
            best = {lanes: min(_run(lanes, *work)[0] for _ in range(args.repeats)) for lanes in (False, True)}
            ns = {k: v / (n * cfg.periods_per_step * cfg.steps_per_period) * 1e9 for k, v in best.items()}
            print(
                f"{n:3d} systems, {model:8s}: scalar {ns[False]:6.1f} ns, SIMD lanes {ns[True]:6.1f} ns per "
                f"system-step ({best[False] / best[True]:.2f}x); bit-identical: {same}"
            )


if __name__ == "__main__":
    main()
