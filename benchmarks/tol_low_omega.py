"""Error-controlled integration (``GearSimulator(..., tol=...)``) at low omega, next to the period doublings:
the largest error over 40 Poincare points against ``gear_env.sim.reference`` (DOP853, rtol 1e-11, events),
from a state on the attractor (Newmark 512 steps x 300 periods from A10), beside the simulator's automatic
fixed step count (192 at omega >= 0.27, more below) and, with ``--fox-goodwin N ...``, fixed Fox-Goodwin steps
(N, or the stability floor where it is higher).

    python benchmarks/tol_low_omega.py                         # omega 0.3, 0.35, 0.45, 0.6; ~2 min
    python benchmarks/tol_low_omega.py --omegas 0.3 0.4 --tols 3e-3 3e-4 --periods 20
    python benchmarks/tol_low_omega.py --omegas 0.12 0.15 0.2 0.25 0.3 --tols --fox-goodwin 88 --periods 10
    python benchmarks/tol_low_omega.py --omegas 0.2 0.22 0.25 --tols --fox-goodwin-vc 64 --fox-goodwin-vc-located 64
    python benchmarks/tol_low_omega.py --omegas 0.2 0.22 0.24 --tols --fox-goodwin-vc-corrected 64 --periods 20

Prints, per model and omega, the error of each mode and the step count (for tol: the coarse N it ended with).
"""

from __future__ import annotations

import argparse

import numpy as np

from gear_env import GearParams, GearSimulator
from gear_env.sim.linear import min_steps_per_period
from gear_env.sim.params import FOX_GOODWIN_BETA
from gear_env.sim.reference import reference_poincare
from gear_env.sim.simulator import default_steps_per_period


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--omegas", type=float, nargs="+", default=[0.3, 0.35, 0.45, 0.6], help="omegas of the orbits")
    ap.add_argument("--tols", type=float, nargs="*", default=[3e-3, 1e-3, 3e-4], help="tol modes (none: no tol)")
    ap.add_argument("--fox-goodwin", type=int, nargs="*", default=[], metavar="N",
                    help="also N Fox-Goodwin steps per period (beta 1/12; the stability floor if higher)")  # fmt: skip
    ap.add_argument("--fox-goodwin-vc", type=int, nargs="*", default=[], metavar="N",
                    help="also N steps of Fox-Goodwin with the velocity correction (the floor if higher)")  # fmt: skip
    ap.add_argument("--fox-goodwin-vc-located", type=int, nargs="*", default=[], metavar="N",
                    help="also N steps of Fox-Goodwin with the velocity correction, contact changes located (the "
                    "environments' locate_contacts; the floor if higher)")  # fmt: skip
    ap.add_argument("--fox-goodwin-vc-corrected", type=int, nargs="*", default=[], metavar="N",
                    help="also N steps of Fox-Goodwin with the velocity correction, kinks corrected (the "
                    "environments' correct_kinks; the floor if higher)")  # fmt: skip
    ap.add_argument("--periods", type=int, default=40, help="Poincare points compared (40)")
    args = ap.parse_args(argv)
    from contact_steps import located

    fg = GearParams(newmark_beta=FOX_GOODWIN_BETA)
    vc = fg.replace(velocity_correction=True)
    print(f"largest error over {args.periods} Poincare points (b0), and the step count N of each mode")
    print(
        "model     omega | automatic fixed  | "
        + " | ".join(
            [f"tol {t:g}".ljust(16) for t in args.tols]
            + [f"fox-goodwin {n}".ljust(16) for n in args.fox_goodwin]
            + [f"fox-goodwin-vc {n}".ljust(16) for n in args.fox_goodwin_vc]
            + [f"vc {n} located".ljust(16) for n in args.fox_goodwin_vc_located]
            + [f"vc {n} corrected".ljust(16) for n in args.fox_goodwin_vc_corrected]
        )
    )
    for model in ("constant", "dynamic"):
        for w in args.omegas:
            sim = GearSimulator(GearParams(), model, 512, w)
            sim.advance(300)
            x0 = sim.state
            ref = reference_poincare(w, model, None, 0, args.periods, initial_state=x0).states
            cells = []
            modes = [(GearParams(), default_steps_per_period(w), None)] + [(GearParams(), None, t) for t in args.tols]
            modes += [(fg, max(n, min_steps_per_period(fg, w)), None) for n in args.fox_goodwin]
            modes += [(vc, max(n, min_steps_per_period(vc, w)), None) for n in args.fox_goodwin_vc]
            for par, nsp, tol in modes:
                s = GearSimulator(par, model, nsp, w, x0, tol=tol)
                iv = s.advance(args.periods)
                err = float(np.max(np.abs(iv.poincare[:, :10] - ref[: args.periods])))
                n_shown = s.steps_per_period // 2 if tol is not None else s.steps_per_period
                cells.append(f"{err:8.1e} (N {n_shown:3d})")
            for n, corrected in [(n, False) for n in args.fox_goodwin_vc_located] + [
                (n, True) for n in args.fox_goodwin_vc_corrected
            ]:
                nsp = max(n, min_steps_per_period(vc, w))
                err = located(vc, model, w, x0, ref[: args.periods], nsp, args.periods, corrected)[0]  # contact_steps
                cells.append(f"{err:8.1e} (N {nsp:3d})")
            print(f"{model:8s} {w:6.2f} | " + " | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
