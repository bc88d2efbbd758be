"""Error-controlled integration (``GearSimulator(..., tol=...)``) against fixed steps: accuracy on
the period-1 orbits and mesh periods per second, as ratios taken in one interleaved run.

Accuracy: for period-1 attractors on an omega grid (both models; from a common state on the
attractor, Newmark 512 steps x 300 periods from A10; orbits whose reference Poincare points repeat
within 1e-5 (1 + max|x|)), the largest error over 10 Poincare points and the 10 states against
``gear_env.sim.reference`` (DOP853, rtol 1e-11, events). Speed: ``advance(periods)`` from the same
states, fixed 192 steps and each tol alternately, ``--repeats`` rounds; the ratio is the
summed time of fixed 192 over the summed time of the tol mode (> 1: tol mode faster).

    python benchmarks/bench_tolerance.py                      # omega step 0.02 (~5 min)
    python benchmarks/bench_tolerance.py --omega-step 0.1 --tols 1e-3 3e-4
    python benchmarks/bench_tolerance.py --tols 3e-3 --strict-newton   # A/B of the Newton rule of the runs
    python benchmarks/bench_tolerance.py --tols 3e-3 --fox-goodwin 64 96 --fixed 64 96   # the schemes side by side

``--fox-goodwin N ...`` adds fixed-step modes with Fox-Goodwin's Newmark beta 1/12
(``GearParams(newmark_beta=1/12)``), ``--fox-goodwin-vc N ...`` the same with the velocity correction
(``velocity_correction=True``, scheme ``"fox-goodwin-vc"``), ``--fixed N ...`` fixed-step modes of the paper's
beta 1/4 at other step counts,
``--beta BETA:N ...`` fixed-step modes of any beta in [1/12, 1/4]. ``--omega-step 0.01`` doubles the orbits: the
grid of the default step plus the omegas halfway between (a set nobody chose a step count on).

``--strict-newton`` adds every tol mode a second time with the Newton iteration of the fixed-step drivers
(``kernels.TOL_DQ_SCALE = 0``: a dynamic-model update is final only below ``DQ_LINEAR`` = 1e-4 b0), so the
gain of the coarse runs' rule (``kernels.tol_dq_linear``) is measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import time
from fractions import Fraction

import numpy as np

import gear_env.sim.kernels as K
from gear_env import GearParams, GearSimulator
from gear_env.sim.params import FOX_GOODWIN_BETA
from gear_env.sim.reference import reference_poincare
from gear_env.sim.simulator import check_stable_steps, check_steps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--omega-step", type=float, default=0.02,
                    help="step of the omega grid 0.3-3.0 (0.02: 100 period-1 orbits in all; 0.01: 197)")  # fmt: skip
    ap.add_argument("--tols", type=float, nargs="*", default=[2e-3, 1e-3, 5e-4, 2e-4, 1e-4],
                    help="tol modes (b0 per mesh period; none: only fixed-step modes)")  # fmt: skip
    ap.add_argument("--periods", type=int, default=50, help="mesh periods per timed advance (50)")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved timing rounds (3)")
    ap.add_argument(
        "--speed-only",
        action="store_true",
        help="no accuracy part: time the modes on period-1 attractors at omega 0.7, 1.0, 1.3, 1.5, 2.6, 2.9",
    )
    ap.add_argument("--strict-newton", action="store_true",
                    help="also run every tol mode with the fixed-step drivers' Newton rule (A/B)")  # fmt: skip
    ap.add_argument("--fox-goodwin", type=int, nargs="*", default=[], metavar="N",
                    help="also time fixed N steps per period with Newmark beta 1/12 (Fox-Goodwin)")  # fmt: skip
    ap.add_argument("--fox-goodwin-vc", type=int, nargs="*", default=[], metavar="N",
                    help="also time fixed N steps per period with Fox-Goodwin and the velocity correction")  # fmt: skip
    ap.add_argument("--fixed", type=int, nargs="*", default=[], metavar="N",
                    help="also time fixed N steps per period with the paper's beta 1/4")  # fmt: skip
    ap.add_argument("--beta", nargs="*", default=[], metavar="BETA:N",
                    help="also time fixed N steps per period with Newmark beta BETA (1/12-1/4): 0.1:88")  # fmt: skip
    args = ap.parse_args(argv)
    dq_default = float(K.TOL_DQ_SCALE)
    paper, fg = GearParams(), GearParams(newmark_beta=FOX_GOODWIN_BETA)
    # (name, tol, steps per period, parameters)
    modes = [("fixed 192", None, 192, paper)] + [(f"tol {t:g}", t, None, paper) for t in args.tols]
    if args.strict_newton:
        modes += [(f"tol {t:g} strict", t, None, paper) for t in args.tols]
    modes += [(f"fixed {n}", None, n, paper) for n in args.fixed]
    modes += [(f"fox-goodwin {n}", None, n, fg) for n in args.fox_goodwin]
    fgvc = fg.replace(velocity_correction=True)
    modes += [(f"fox-goodwin-vc {n}", None, n, fgvc) for n in args.fox_goodwin_vc]
    for spec in args.beta:
        b, _, n = spec.partition(":")
        try:
            par_b, n_b = GearParams(newmark_beta=float(Fraction(b))), int(n)  # GearParams snaps a rounded 1/12
        except (ValueError, ZeroDivisionError) as exc:
            ap.error(
                f"--beta {spec!r}: need BETA:N, BETA in [1/12, 1/4] (a number or a fraction) and N an integer ({exc})"
            )
        modes.append((f"beta {par_b.newmark_beta:.4g} {n_b}", None, n_b, par_b))
    w_low = 0.7 if args.speed_only else 0.3
    for name, _tol, nsp, par in modes:  # refused before the references are computed
        if nsp is None:
            continue
        try:
            check_steps(nsp)
            check_stable_steps(par, nsp, w_low)
        except ValueError as exc:
            ap.error(f"{name}: {exc}")

    omegas = np.round(np.arange(0.3, 3.0 + 1e-9, args.omega_step), 6)
    if args.speed_only:
        omegas = np.array([0.7, 1.0, 1.3, 1.5, 2.6, 2.9])
    cases = []
    for model in ("constant", "dynamic"):
        for w in omegas:
            sim = GearSimulator(GearParams(), model, 512, float(w))
            sim.advance(300)
            x0 = sim.state
            if args.speed_only:
                cases.append((model, float(w), x0, None))
                continue
            ref = reference_poincare(float(w), model, None, 0, 10, initial_state=x0)
            if np.max(np.abs(ref.states[-1] - ref.states[-2])) <= 1e-5 * (1 + np.max(np.abs(ref.states[-1]))):
                cases.append((model, float(w), x0, ref.states))

    def newton_rule(name: str) -> None:
        K.TOL_DQ_SCALE = 0.0 if name.endswith("strict") else dq_default  # read by integration.integrate

    errs: dict[str, list[float]] = {m[0]: [] for m in modes}
    steps: dict[str, list[float]] = {m[0]: [] for m in modes}
    for model, w, x0, ref in [] if args.speed_only else cases:
        for name, tol, nsp, par in modes:
            newton_rule(name)
            sim = GearSimulator(par, model, nsp, w, x0, tol=tol)
            iv = sim.advance(10)
            errs[name].append(float(np.max(np.abs(iv.poincare[:, :10] - ref))))
            steps[name].append(float(iv.stats[19]) / 10 * (1.5 if tol is not None else 1.0))
    if not args.speed_only:
        print(
            f"{len(cases)} period-1 orbits in all (omega 0.3-3.0 step {args.omega_step}, both models), "
            "10 Poincare points"
        )
        print("mode        | median error | p95 error | max error | orbits > 1e-3 (their omegas) | Newmark steps per "
              "period (mean)")  # fmt: skip
    ws = np.array([w for _m, w, _x, _r in cases])
    for name, *_ in [] if args.speed_only else modes:
        e = np.array(errs[name])
        over = ws[e > 1e-3]
        where = f" ({over.min():.2f}-{over.max():.2f})" if len(over) else ""
        print(f"{name:16s} | {np.median(e):12.2e} | {np.percentile(e, 95):9.2e} | {np.max(e):9.2e} | "
              f"{len(over):4d}{where:12s} | {np.mean(steps[name]):.0f}")  # fmt: skip
    # speed, interleaved: the same states, all modes in turn, several rounds
    timed = cases if args.speed_only else cases[:: max(1, len(cases) // 12)]
    total = dict.fromkeys([m[0] for m in modes], 0.0)
    by_model = {(mo, m[0]): 0.0 for mo in ("constant", "dynamic") for m in modes}
    for _name, tol, nsp, par in modes:  # compile and warm up
        GearSimulator(par, "dynamic", nsp, 1.0, tol=tol).advance(2)
    for _ in range(args.repeats):
        for model, w, x0, _ref in timed:
            for name, tol, nsp, par in modes:
                newton_rule(name)
                sim = GearSimulator(par, model, nsp, w, x0, tol=tol)
                t0 = time.perf_counter()
                sim.advance(args.periods)
                dt = time.perf_counter() - t0
                total[name] += dt
                by_model[model, name] += dt
    newton_rule("")
    base = total["fixed 192"]
    n_per = len(timed) * args.repeats * args.periods
    print(f"\nspeed over {len(timed)} orbits x {args.repeats} rounds x {args.periods} periods, interleaved "
          f"(load average {os.getloadavg()[0]:.1f}):")  # fmt: skip
    for name, *_ in modes:
        print(f"{name:16s} | {n_per / total[name]:9.0f} mesh periods/s | ratio vs fixed 192: {base / total[name]:.2f}"
              + "".join(f" | {mo} {by_model[mo, 'fixed 192'] / by_model[mo, name]:.2f}"
                        for mo in ("constant", "dynamic") if by_model[mo, name] > 0))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
