"""Convergence study of the Newmark simulator against the independent solve_ivp reference.

For each meshing frequency omega and backlash model: a state on the attractor is obtained first
(Newmark, 512 steps per period, 300 mesh periods from MODEL.md A10); from that common state both
the Newmark simulator (N steps per mesh period) and ``gear_env.sim.reference`` (DOP853, rtol 1e-11,
contact changes located by events) integrate ``--periods`` mesh periods. The error is the maximum
over those Poincare points of |state_newmark - state_reference| over all 10 states (b0 units;
velocities per unit natural time), and separately of Delta. The observed order is the least-squares slope of log(error)
vs log(N) over N = 32..256.

    python benchmarks/convergence_study.py            # full table (~1 min)
    python benchmarks/convergence_study.py --omegas 1.2 2.8 --periods 5
    python benchmarks/convergence_study.py --fixed-point --omegas 0.8 1.5 2.8
    python benchmarks/convergence_study.py --ns 64 96 128 192 --omegas 0.85 0.88 1.04 1.2
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gear_env import GearParams, GearSimulator, default_steps_per_period
from gear_env.sim.kernels import PC_DELTA
from gear_env.sim.reference import reference_poincare

NS = (16, 32, 64, 128, 160, 192, 256, 512)
DEFAULT_OMEGAS = (0.1, 0.2, 0.25, 0.35, 0.45, 0.8, 1.2, 1.5, 2.0, 2.8, 3.0)


def study(
    omega: float, model: str, periods: int, params: GearParams, ns: tuple[int, ...] = NS
) -> tuple[dict[int, float], dict[int, float], dict]:
    """Errors per N in ``ns`` (all 10 states; Delta) and information about the reference run."""
    sim = GearSimulator(params, model, 512, omega)
    sim.advance(300)
    start = sim.state
    t0 = time.perf_counter()
    ref = reference_poincare(omega, model, params, transient=0, periods=periods, initial_state=start)
    t_ref = time.perf_counter() - t0
    err, err_d = {}, {}
    sep = 0.0
    for n in ns:
        st = GearSimulator(params, model, n, omega, start).advance(periods)
        err[n] = float(np.max(np.abs(st.poincare[:, :10] - ref.states)))
        err_d[n] = float(np.max(np.abs(st.poincare[:, PC_DELTA] - ref.delta)))
    sep = GearSimulator(params, model, 512, omega, start).advance(periods).separation_fraction
    nd = default_steps_per_period(omega)
    st = GearSimulator(params, model, None, omega, start).advance(periods)
    err["default"] = float(np.max(np.abs(st.poincare[:, :10] - ref.states)))
    err_d["default"] = float(np.max(np.abs(st.poincare[:, PC_DELTA] - ref.delta)))
    return err, err_d, {"events": ref.events, "t_ref": t_ref, "sep": sep, "n_default": nd}


def fixed_point(omega: float, model: str, params: GearParams) -> None:
    """Print the error of the Newmark attractor's Poincare point vs the reference's (period-1 regimes)."""
    sim = GearSimulator(params, model, 512, omega)
    sim.advance(1000)
    start = sim.state
    ref = reference_poincare(omega, model, params, transient=0, periods=30, initial_state=start)
    per = float(np.max(np.abs(ref.states[-1] - ref.states[-2])))
    cells = []
    for n in (128, 160, 192, 256, None):
        st = GearSimulator(params, model, n, omega, start).advance(300)
        e = float(np.max(np.abs(st.poincare[-1, :10] - ref.states[-1])))
        ed = abs(float(st.poincare[-1, PC_DELTA]) - float(ref.delta[-1]))
        label = f"N={n}" if n is not None else f"default N={default_steps_per_period(omega)}"
        cells.append(f"{label}: states {e:.2e} Delta {ed:.2e}")
    print(f"{omega:<5.2f}  {model:<8s} reference periodicity {per:.1e} | " + " | ".join(cells))


def order(err: dict[int, float], ns: tuple[int, ...] = NS, lo: int = 32, hi: int = 256) -> float:
    """Least-squares slope -d log(err)/d log(N) over the N of ``ns`` in [lo, hi] (NaN if < 2)."""
    ns = np.array([n for n in ns if lo <= n <= hi])
    if len(ns) < 2:
        return float("nan")
    e = np.array([err[n] for n in ns])
    return float(-np.polyfit(np.log(ns), np.log(e), 1)[0])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--omegas", type=float, nargs="+", default=list(DEFAULT_OMEGAS))
    ap.add_argument("--models", nargs="+", default=["constant", "dynamic"])
    ap.add_argument("--periods", type=int, default=10, help="mesh periods compared (default 10)")
    ap.add_argument("--fixed-point", action="store_true", help="compare the period-1 attractors instead")
    ap.add_argument("--ns", type=int, nargs="+", default=list(NS), help="step counts compared (default %(default)s)")
    args = ap.parse_args(argv)
    ns = tuple(sorted(set(args.ns)))
    p = GearParams()
    if args.fixed_point:
        print("Poincare point of the attractor after 300 periods (Newmark) vs the reference's, from a common start")
        for w in args.omegas:
            for m in args.models:
                fixed_point(w, m, p)
        return 0
    rows = []
    for w in args.omegas:
        for m in args.models:
            rows.append((w, m, *study(w, m, args.periods, p, ns)))
    for title, k in (("all 10 states", 2), ("Delta (dynamic transmission error)", 3)):
        head = "omega  model     sep  events | " + " ".join(f"N={n:<7d}" for n in ns) + "| order(32-256) | default N"
        print(f"\nmax |Newmark - solve_ivp| over {args.periods} Poincare points: {title} [b0]")
        print(head)
        print("-" * len(head))
        worst = {n: 0.0 for n in ns}
        worst_default = 0.0
        for row in rows:
            w, m, err, info = row[0], row[1], row[k], row[4]
            for n in ns:
                worst[n] = max(worst[n], err[n])
            worst_default = max(worst_default, err["default"])
            cells = " ".join(f"{err[n]:.2e}  " for n in ns)
            print(
                f"{w:<5.2f}  {m:<8s} {info['sep']:.2f} {info['events']:6d} | {cells}| {order(err, ns):5.2f}         "
                f"| {err['default']:.2e} ({info['n_default']})"
            )
        print("-" * len(head))
        print(
            "worst                        "
            + " ".join(f"{worst[n]:.2e}  " for n in ns)
            + f"| {order(worst, ns):5.2f}         | {worst_default:.2e}"
        )
        ok = [n for n in ns if worst[n] < 1e-3]
        print(f"smallest fixed N with worst-case error < 1e-3: {ok[0] if ok else 'none'}")
        print(f"default_steps_per_period(omega): worst-case error {worst_default:.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
