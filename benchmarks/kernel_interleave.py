"""Is one Newmark step latency-bound or throughput-bound? Interleave two independent trajectories.

A kernel whose step is a chain of dependent operations (latency-bound) leaves most of the core's
execution units idle; stepping two independent trajectories in the same loop body then costs
little more than one, and the time per step per trajectory drops towards half. A kernel limited by
the number of instructions (throughput-bound, e.g. by register spills) gains nothing. This script
compiles both loops from the simulator's own inline step (``kernels.newmark_try_t``, the
step of the kernels' hot loop, which calls no function) and prints
ns per step per trajectory and the gain, both models, in one run on one core:

    python benchmarks/kernel_interleave.py
"""

from __future__ import annotations

import os
import time

import numpy as np
from numba import njit

from gear_env import GearSimulator
from gear_env.sim import kernels as K


@njit(error_model="numpy", inline="always")
def _step(j, s, g, hc, w0, n_steps, tab, k, dynamic):
    """Step j of a trajectory at constant omega w0: (converged, new state tuple, mesh force)."""
    m = (j + 1) % n_steps
    ok, s1, F, _r, _d, _b, _sp, _cp = K.newmark_try_t(
        s, g, tab[m, 0], tab[m, 1], tab[m, 2], w0, hc, k, dynamic, 12, 1e-10
    )
    return ok, s1, F


@njit(error_model="numpy")
def one_lane(x, a, w0, n_periods, n_steps, c, dynamic):
    tab = K._excitation_table(0.0, n_steps, c)
    k = K.step_consts(c)
    dphi = K.TWO_PI / n_steps
    s = K.load_t(x, a)
    g = (a[0], a[1], a[2], a[3], a[4])
    hc = K.step_coeffs(dphi / w0, k)
    total = n_periods * n_steps
    acc = 0.0
    for j in range(total):
        ok, s1, F = _step(j, s, g, hc, w0, n_steps, tab, k, dynamic)
        if not ok:
            return np.nan  # a step that needs splitting: not part of this measurement
        g = K.guess_t(s, s1, dynamic == 0)
        s = s1
        acc += F
    K.store_t(s, x, a)
    return acc


@njit(error_model="numpy")
def two_lanes(x, a, x2, a2, w0, n_periods, n_steps, c, dynamic):
    tab = K._excitation_table(0.0, n_steps, c)
    k = K.step_consts(c)
    dphi = K.TWO_PI / n_steps
    s = K.load_t(x, a)
    g = (a[0], a[1], a[2], a[3], a[4])
    s2 = K.load_t(x2, a2)
    g2 = (a2[0], a2[1], a2[2], a2[3], a2[4])
    hc = K.step_coeffs(dphi / w0, k)
    hc2 = hc
    total = n_periods * n_steps
    acc = 0.0
    for j in range(total):
        ok, s1, F = _step(j, s, g, hc, w0, n_steps, tab, k, dynamic)
        ok2, s12, F2 = _step(j, s2, g2, hc2, w0, n_steps, tab, k, dynamic)
        if not (ok and ok2):
            return np.nan
        g = K.guess_t(s, s1, dynamic == 0)
        s = s1
        g2 = K.guess_t(s2, s12, dynamic == 0)
        s2 = s12
        acc += F + F2
    K.store_t(s, x, a)
    K.store_t(s2, x2, a2)
    return acc


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    n, periods = 192, 3000
    for model, code in (("constant", 0), ("dynamic", 1)):
        for w in (0.45, 1.2):
            sim = GearSimulator(model=model, omega=w, steps_per_period=n)
            sim.advance(100)
            x = sim.state.copy()
            x2 = x.copy()
            x2[4] += 0.01
            c = sim.params.consts
            if not (
                np.isfinite(one_lane(x.copy(), np.zeros(5), w, periods, n, c, code))
                and np.isfinite(two_lanes(x.copy(), np.zeros(5), x2.copy(), np.zeros(5), w, periods, n, c, code))
            ):
                print(f"{model:8s} omega={w}: a step needed splitting (not part of this measurement); skipped")
                continue
            t1 = t2 = np.inf
            for _ in range(5):
                t = time.process_time()
                one_lane(x.copy(), np.zeros(5), w, periods, n, c, code)
                t1 = min(t1, time.process_time() - t)
                t = time.process_time()
                two_lanes(x.copy(), np.zeros(5), x2.copy(), np.zeros(5), w, periods, n, c, code)
                t2 = min(t2, time.process_time() - t)
            per = periods * n
            print(
                f"{model:8s} omega={w}: one trajectory {t1 / per * 1e9:5.1f} ns/step, two interleaved "
                f"{t2 / (2 * per) * 1e9:5.1f} ns/step each -> gain {2 * t1 / t2:.2f}x"
            )


if __name__ == "__main__":
    main()
