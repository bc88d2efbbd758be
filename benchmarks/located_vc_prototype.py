"""Prototype (pure Python, not the kernels): Fox-Goodwin with the velocity correction, with its contact changes
located inside the step, with and without re-biasing Newmark's velocity where the step size changes. The experiment
behind the next step of issue 24 (docs/SIMULATOR.md, "Fox-Goodwin with the velocity correction").

    python benchmarks/located_vc_prototype.py                 # the 197 Table 1 orbits, 64 steps, ~3 min on 2 cores
    python benchmarks/located_vc_prototype.py --steps 64 96 --omegas 0.3 1.46 1.49

Why re-bias: under beta 1/12 Newmark's velocity is v + h^2/12 da/dt (the bias that makes Fox-Goodwin's positions
fourth order), so a step of another size (a part of a step split at a contact change) needs v + h'^2/12 da/dt.
The kernels' located steps (``drivers.located_step_t``) keep the bias of the full step; this prototype sets it for
each part: v_true = v - h_prev^2/12 a'(t-), then v = v_true + h_next^2/12 a'(t+), a' from differences of the
accelerations (before the crossing: the last step's; after it: the remainder's, the remainder then corrected).

Each step is an implicit Newmark step on ``gear_env.sim.reference.rhs`` (scipy ``fsolve``), the damping forces
at v_f = v_{n+1} - (h/12)(a_{n+1} - a_n) (the corrected scheme); a contact change is located by ``brentq`` on the
gap at the end of the part held on the old branch. Errors: the largest difference of 10 Poincare points from the
event-located reference, from a state on each period-1 orbit (``contact_steps.orbits``), both models.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

MODES = ("unlocated", "located", "located, re-biased")


def _newmark(q, v, a, s, h, w, model, kc, region):
    """One Fox-Goodwin step of size h (natural time) from (q, v, a) at time s; forces at the corrected velocity."""
    from scipy.optimize import fsolve

    from gear_env.sim.reference import rhs

    qp = q + h * v + h * h * (5.0 / 12.0) * a

    def parts(a1):
        return qp + h * h / 12.0 * a1, v + 0.5 * h * (a + a1), v + h * ((7.0 / 12.0) * a + (5.0 / 12.0) * a1)

    def res(a1):
        q1, _v1, vf = parts(a1)
        return a1 - rhs(s + h, np.r_[q1, vf, w * (s + h)], w, kc, model, region)[5:10]

    a1 = fsolve(res, a, xtol=1e-13)
    q1, v1, vf = parts(a1)
    return q1, v1, a1, vf


def _region(q, vf, s, w, model, kc):
    from gear_env.sim.reference import contact_region, mesh_quantities

    d, _dd, bd, _psi = mesh_quantities(np.r_[q, vf, w * s], w, kc, model)
    return contact_region(d, bd), d, bd


def run(x0, w: float, model: str, n: int, mode: str, kc, periods: int = 10) -> tuple[np.ndarray, float]:
    """Poincare points (periods, 10: q and the corrected velocity) and contact changes located per period."""
    from scipy.optimize import brentq

    from gear_env.sim.reference import rhs

    h = 2.0 * np.pi / (n * w)
    q, v, s = x0[:5].copy(), x0[5:].copy(), 0.0
    a = rhs(0.0, np.r_[x0, 0.0], w, kc, model)[5:10]
    a_old = None
    r0 = _region(q, v, 0.0, w, model, kc)[0]
    rebias = mode == MODES[2]
    out, splits = [], 0
    for j in range(periods * n):
        s_end = (j + 1) * h
        q1, v1, a1, vf = _newmark(q, v, a, s, h, w, model, kc, None)
        r1 = _region(q1, vf, s_end, w, model, kc)[0]
        if mode != MODES[0] and r1 != r0:
            side = 1 if 1 in (r0, r1) else -1
            ad0 = (a - a_old) / h if (rebias and a_old is not None) else np.zeros(5)
            vt = v - h * h / 12.0 * ad0  # Newmark's velocity without its bias

            def part(th, q=q, a=a, s=s, vt=vt, ad0=ad0, r0=r0):
                return _newmark(q, vt + (th * h) ** 2 / 12.0 * ad0, a, s, th * h, w, model, kc, r0)

            def gap(th, s=s, side=side):
                qq, _vv, _aa, vvf = part(th)
                _r, d, bd = _region(qq, vvf, s + th * h, w, model, kc)
                return d - side * bd

            if gap(1e-9) * gap(1.0) < 0.0:
                th = brentq(gap, 1e-9, 1.0, xtol=1e-13)
                splits += 1
                h1, h2 = th * h, (1.0 - th) * h
                qk, vk, ak, _vkf = part(th)
                if rebias:
                    adm = (ak - a) / h1  # a' before the crossing; first guess after it
                    q1, v1, a1, vf = _newmark(qk, vk + (h2 * h2 - h1 * h1) / 12.0 * adm, ak, s + h1, h2, w, model, kc,
                                              None)  # fmt: skip
                    adp = (a1 - ak) / h2
                    db = h2 * h2 / 12.0 * (adp - adm)  # the remainder's bias, corrected after the fact
                    q1, v1, vf = q1 + h2 * db, v1 + db, vf + db
                    v1 = v1 + (h * h - h2 * h2) / 12.0 * adp  # the next full step's bias
                else:
                    q1, v1, a1, vf = _newmark(qk, vk, ak, s + h1, h2, w, model, kc, None)
                r1 = _region(q1, vf, s_end, w, model, kc)[0]
        a_old = a
        q, v, a, s, r0 = q1, v1, a1, s_end, r1
        if (j + 1) % n == 0:
            out.append(np.r_[q, vf])
    return np.array(out), splits / periods


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, nargs="+", default=[64], help="steps per mesh period (default 64)")
    ap.add_argument("--omegas", type=float, nargs="*", default=None,
                    help="omegas (default: the Table 1 set, 0.30 + 0.01 k up to 3.0, its period-1 orbits)")  # fmt: skip
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    from contact_steps import orbits

    from gear_env import GearParams
    from gear_env.sim.reference import RefConsts

    base = GearParams()
    kc = RefConsts.from_params(base.replace(newmark_beta=1.0 / 12.0))
    om = np.round(np.arange(0.30, 3.0 + 1e-9, 0.01), 6) if args.omegas is None else np.asarray(args.omegas)
    cases = orbits(base, om)
    print(f"{len(cases)} period-1 orbits; error = max over 10 Poincare points [b0]")
    for n in args.steps:
        err = {m: [] for m in MODES}
        spl = []
        for model, w, x0, ref in cases:
            for m in MODES:
                o, sp = run(np.asarray(x0, float), w, model, n, m, kc)
                err[m].append(float(np.max(np.abs(o - ref))))
            spl.append(sp)
            if args.omegas is not None:
                print(f"  {model:8s} {w:.3f}: " + "  ".join(f"{m} {err[m][-1]:.1e}" for m in MODES))
        for m in MODES:
            e = np.array(err[m])
            p95, top, above = np.percentile(e, 95), e.max(), int((e > 1e-3).sum())
            print(f"N {n:3d} {m:20s}: p95 {p95:.1e}  max {top:.1e}  above 1e-3: {above}")
        print(f"N {n:3d} contact changes per mesh period: mean {np.mean(spl):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
