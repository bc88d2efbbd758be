"""Contact changes located inside the Newmark step (``tangent.tangent_map(..., corrected=2)``): the
sawtooth of the Floquet multipliers, the multipliers at grazing orbits against the event-located
reference (``gear_env.sim.reference``), and the convergence order on impacting motion.

    python benchmarks/located_crossings.py                  # all three parts (~2-4 min)
    python benchmarks/located_crossings.py --part sawtooth  # or: grazing, order

Modes of the period map's Jacobian: 0 = exact Jacobian of the unlocated discrete map (the contact
change stays inside the step), 1 = the crossing-corrected tangent (continuation's multipliers so
far), 2 = contact changes located and the step split there (the map and its exact Jacobian).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gear_env import GearParams, GearSimulator, default_steps_per_period
from gear_env.analysis import tangent as TG
from gear_env.sim import kernels as K
from gear_env.sim.params import model_code
from gear_env.sim.reference import reference_poincare

MODES = {0: "exact, unlocated", 1: "crossing-corrected", 2: "located (exact)"}


def period_map(x, omega, model, mode, n, periods=1, params=None):
    """(P^periods(x), Jacobian, Poincare states, info) of the Newmark map in the given mode."""
    c = K.readonly(np.ascontiguousarray((params or GearParams()).consts))
    y = np.array(x, float)
    jac = np.zeros((10, 10))
    pc = np.zeros((periods, 10))
    info = np.zeros(TG.N_INFO)
    st = TG.tangent_map(y, omega, periods, n, c, model_code(model), 12, 1e-10, jac, pc, info, mode)
    if st != K.OK:
        raise RuntimeError(f"kernel status {st} at omega={omega}")
    return y, jac, pc, info


def fixed_point(x, omega, model, mode, n, tol=1e-12):
    """Newton on P(x) - x with the mode's Jacobian; returns (x, Jacobian, iterations)."""
    for it in range(40):
        y, jac, _, _ = period_map(x, omega, model, mode, n)
        r = y - x
        if np.max(np.abs(r)) < tol * (1 + np.max(np.abs(x))):
            return x, jac, it
        x = x - np.linalg.solve(jac - np.eye(10), r)
    raise RuntimeError(f"no fixed point at omega={omega} (mode {mode})")


def sawtooth(model: str, lo=1.62, hi=1.66, n_omega=81, n=192) -> None:
    sim = GearSimulator(GearParams(), model, n, lo)
    sim.advance(500)
    ws = np.linspace(lo, hi, n_omega)
    print(f"\n{model}: |mu|max along the period-1 branch, omega {lo}-{hi} ({n_omega} points), N = {n}")
    print("mode                  | sawtooth max|mu_i - (mu_i-1 + mu_i+1)/2| | Newton iterations (last) | time")
    for mode in (0, 1, 2):
        x = sim.state
        mus = []
        t0 = time.perf_counter()
        it = 0
        for w in ws:
            x, jac, it = fixed_point(x, w, model, mode, n)
            mus.append(np.max(np.abs(np.linalg.eigvals(jac))))
        mu = np.array(mus)
        saw = float(np.max(np.abs(mu[1:-1] - 0.5 * (mu[:-2] + mu[2:]))))
        print(
            f"{mode} {MODES[mode]:19s} | {saw:.2e}                                 | {it:2d}"
            f"                       | {time.perf_counter() - t0:.2f} s"
        )


def reference_monodromy(x, omega, model, fd=1e-6, newton=3):
    """Fixed point and multipliers of the event-located reference map (DOP853, rtol 1e-11):
    Newton with a central-difference Jacobian."""

    def P(z):
        return reference_poincare(omega, model, None, 0, 1, initial_state=z, rtol=1e-11, atol=1e-12).states[-1]

    for _ in range(newton):
        jac = np.zeros((10, 10))
        for j in range(10):
            e = np.zeros(10)
            e[j] = fd * (1 + abs(x[j]))
            jac[:, j] = (P(x + e) - P(x - e)) / (2 * e[j])
        r = P(x) - x
        x = x - np.linalg.solve(jac - np.eye(10), r)
        if np.max(np.abs(r)) < 1e-9:
            break
    return x, jac, float(np.max(np.abs(r)))


def grazing(cases=(("constant", 0.25), ("dynamic", 0.20))) -> None:
    print("\nFloquet multipliers at grazing orbits: Newmark modes vs the event-located reference")
    for model, w in cases:
        sim = GearSimulator(GearParams(), model, None, w)
        sim.advance(600)
        nd = default_steps_per_period(w)
        t0 = time.perf_counter()
        xr, jr, res = reference_monodromy(sim.state, w, model)
        mur = np.linalg.eigvals(jr)
        mur = mur[np.argsort(-np.abs(mur))]
        print(
            f"{model} omega={w}: reference |mu|max {abs(mur[0]):.5f} (mu1 {complex(mur[0]):.4f}, residual {res:.1e}, "
            f"{time.perf_counter() - t0:.0f} s)"
        )
        for n in (nd, 2 * nd, 4 * nd):
            cells = []
            for mode in (0, 1, 2):
                x, jac, _ = fixed_point(xr.copy(), w, model, mode, n)
                mu = np.linalg.eigvals(jac)
                mu = mu[np.argsort(-np.abs(mu))]
                cells.append(f"mode {mode}: {abs(mu[0]):.5f} (err {abs(mu[0]) - abs(mur[0]):+.4f})")
            print(f"  N={n:4d}  " + "  ".join(cells))


def order(model: str, omega: float, ns=(32, 64, 128, 256), periods=10) -> None:
    sim = GearSimulator(GearParams(), model, 512, omega)
    sim.advance(300)
    x0 = sim.state
    ref = reference_poincare(omega, model, None, 0, periods, initial_state=x0)
    print(
        f"\n{model} omega={omega}: max Poincare error over {periods} periods vs the reference "
        f"({ref.events} contact changes)"
    )
    for mode in (0, 2):
        errs = []
        for n in ns:
            _, _, pc, info = period_map(x0, omega, model, mode, n, periods)
            errs.append(float(np.max(np.abs(pc - ref.states))))
        slope = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
        cells = "  ".join(f"N={n}: {e:.2e}" for n, e in zip(ns, errs))
        ratios = "  ".join(f"{errs[i] / errs[i + 1]:.2f}" for i in range(len(ns) - 1))
        print(f"  mode {mode} {MODES[mode]:17s} {cells} | order {slope:.2f} | ratios per doubling {ratios}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["all", "sawtooth", "grazing", "order"], default="all")
    args = ap.parse_args(argv)
    if args.part in ("all", "sawtooth"):
        for m in ("constant", "dynamic"):
            sawtooth(m)
    if args.part in ("all", "order"):
        for m, w in (("constant", 1.5), ("dynamic", 1.5), ("constant", 0.45), ("dynamic", 2.0)):
            order(m, w)
    if args.part in ("all", "grazing"):
        grazing()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
