"""Error-controlled integration (``GearSimulator(..., tol=...)``) at low omega, next to the period doublings:
the largest error over 40 Poincare points against ``gear_env.sim.reference`` (DOP853, rtol 1e-11, events),
from a state on the attractor (Newmark 512 steps x 300 periods from A10), beside fixed 192 steps.

    python benchmarks/tol_low_omega.py                         # omega 0.3, 0.35, 0.45, 0.6; ~2 min
    python benchmarks/tol_low_omega.py --omegas 0.3 0.4 --tols 3e-3 3e-4 --periods 20

Prints, per model and omega, the error of each mode and the coarse step count N the controller ended with.
"""

from __future__ import annotations

import argparse

import numpy as np

from gear_env import GearParams, GearSimulator
from gear_env.sim.reference import reference_poincare


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--omegas", type=float, nargs="+", default=[0.3, 0.35, 0.45, 0.6])
    ap.add_argument("--tols", type=float, nargs="+", default=[3e-3, 1e-3, 3e-4])
    ap.add_argument("--periods", type=int, default=40)
    args = ap.parse_args(argv)
    print(f"largest error over {args.periods} Poincare points (b0), and the last coarse N of each tol run")
    print("model     omega | fixed 192 | " + " | ".join(f"tol {t:g}".ljust(16) for t in args.tols))
    for model in ("constant", "dynamic"):
        for w in args.omegas:
            sim = GearSimulator(GearParams(), model, 512, w)
            sim.advance(300)
            x0 = sim.state
            ref = reference_poincare(w, model, None, 0, args.periods, initial_state=x0).states
            cells = []
            for tol in [None, *args.tols]:
                s = GearSimulator(GearParams(), model, 192 if tol is None else None, w, x0, tol=tol)
                iv = s.advance(args.periods)
                err = float(np.max(np.abs(iv.poincare[:, :10] - ref[: args.periods])))
                cells.append(f"{err:9.1e}" if tol is None else f"{err:8.1e} (N {s.steps_per_period // 2:3d})")
            print(f"{model:8s} {w:6.2f} | " + " | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
