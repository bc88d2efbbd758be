"""Which integration scheme buys accuracy cheapest? (issue 24: the design study for a tolerance.)

For period-1 attractors on an omega grid (both models), from a common state on the attractor
(Newmark, 512 steps per period, 300 periods from MODEL.md A10) each scheme integrates ``--periods``
mesh periods; the error is the largest |state - reference| over those Poincare points and the 10
states (b0 units), the reference being ``gear_env.sim.reference`` (DOP853, rtol 1e-11, contact changes
located by events). Cost: Newmark step solves per mesh period, counting the extra solves of a
located contact change (the root search) as steps. Schemes:

* ``fixed N``: today's kernel (contact changes inside steps);
* ``located N``: contact changes located and the step split there (``tangent_map`` mode 2);
* ``richardson N``: per mesh period, (4 P_2N(x) - P_N(x)) / 3 of the located map (4th order on
  each smooth piece, since no contact change lies inside a step);
* ``richardson-unlocated N``: the same of the unlocated map.

    python benchmarks/scheme_study.py --omega-step 0.02        # the full grid (~10-20 min: the reference)
    python benchmarks/scheme_study.py --omega-step 0.1 --periods 5
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gear_env import GearParams, GearSimulator
from gear_env.analysis import tangent as TG
from gear_env.sim import kernels as K
from gear_env.sim.params import model_code
from gear_env.sim.reference import reference_poincare

C = K.readonly(np.ascontiguousarray(GearParams().consts))


def one_period(x, omega, model, n, mode):
    y = np.array(x, float)
    jac = np.zeros((10, 10))
    pc = np.zeros((1, 10))
    info = np.zeros(TG.N_INFO)
    if TG.tangent_map(y, omega, 1, n, C, model_code(model), 12, 1e-10, jac, pc, info, mode) != K.OK:
        raise RuntimeError("kernel failure")
    # extra solves of the located steps: the root search (~8 parts) and the two parts, and the
    # central difference of the tangent (4 parts; only the map is counted here, so not those)
    return y, n + 10 * info[TG.INFO_LOCATED]


def run_scheme(x0, omega, model, periods, scheme, n):
    x = np.array(x0, float)
    out = np.empty((periods, 10))
    cost = 0.0
    for p in range(periods):
        if scheme == "fixed":
            x, c = one_period(x, omega, model, n, 0)
        elif scheme == "located":
            x, c = one_period(x, omega, model, n, 2)
        else:
            mode = 2 if scheme == "richardson" else 0
            x1, c1 = one_period(x, omega, model, n, mode)
            x2, c2 = one_period(x, omega, model, 2 * n, mode)
            x, c = (4.0 * x2 - x1) / 3.0, c1 + c2
        cost += c
        out[p] = x
    return out, cost / periods


SCHEMES = (
    [("fixed", n) for n in (48, 64, 96, 128, 192)]
    + [("located", n) for n in (48, 64, 96, 128, 192)]
    + [("richardson", n) for n in (12, 16, 24, 32, 48)]
    + [("richardson-unlocated", n) for n in (16, 32)]
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--omega-min", type=float, default=0.3)
    ap.add_argument("--omega-max", type=float, default=3.0)
    ap.add_argument("--omega-step", type=float, default=0.02)
    ap.add_argument("--periods", type=int, default=10)
    ap.add_argument("--models", nargs="+", default=["constant", "dynamic"])
    args = ap.parse_args(argv)
    omegas = np.round(np.arange(args.omega_min, args.omega_max + 1e-9, args.omega_step), 6)
    errs: dict = {s: [] for s in SCHEMES}
    costs: dict = {s: [] for s in SCHEMES}
    n_orbits = 0
    t0 = time.perf_counter()
    for model in args.models:
        for w in omegas:
            sim = GearSimulator(GearParams(), model, 512, float(w))
            sim.advance(300)
            x0 = sim.state
            ref = reference_poincare(float(w), model, None, 0, args.periods, initial_state=x0)
            if np.max(np.abs(ref.states[-1] - ref.states[-2])) > 1e-5 * (1 + np.max(np.abs(ref.states[-1]))):
                continue  # not a period-1 orbit (within 1e-5): left out
            n_orbits += 1
            for s in SCHEMES:
                pc, cost = run_scheme(x0, float(w), model, args.periods, *s)
                errs[s].append(float(np.max(np.abs(pc - ref.states))))
                costs[s].append(cost)
    print(
        f"{n_orbits} period-1 orbits ({', '.join(args.models)}; omega {args.omega_min}-{args.omega_max} step "
        f"{args.omega_step}), {args.periods} Poincare points each; {time.perf_counter() - t0:.0f} s"
    )
    print("scheme                  N  | steps/period (mean) | median error | p95 error | max error")
    for s in SCHEMES:
        e = np.array(errs[s])
        print(
            f"{s[0]:22s} {s[1]:4d} | {np.mean(costs[s]):19.1f} | {np.median(e):12.2e} | "
            f"{np.percentile(e, 95):9.2e} | {np.max(e):.2e}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
