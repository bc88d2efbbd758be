"""How much of solve_ivp's time is our Python right-hand side? The same DOP853 run with the RHS of
``gear_env.sim.reference`` (pure Python) and with a numba-compiled copy of it, straight through the
contact kinks (no events), on the work of ``bench_simulator.py`` (50 mesh periods from a state on
the attractor), and the paired ratio of each to Newmark at the default step count.

A fast RHS is what a careful solve_ivp user would write; it makes the baseline faster and every
speed-up of Newmark over solve_ivp smaller. In one run on one core:

    python benchmarks/solve_ivp_numba_rhs.py
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))
from bench_simulator import _timeit, paired_ratio  # noqa: E402


@njit(cache=False)
def rhs_numba(s, y, omega, kc, dynamic):
    """MODEL.md sec. 3b, as gear_env.sim.reference.rhs (region from Delta), constants in ``kc``:
    (eps_p, eps_g, sig_p, sig_g, xi_p, xi_g, xi_m, kappa, phi_k, E1, phi_e, F_s, A0, R, B_c,
    alpha0, g_p, g_g)."""
    eps_p, eps_g, sig_p, sig_g, xi_p, xi_g, xi_m = kc[0], kc[1], kc[2], kc[3], kc[4], kc[5], kc[6]
    kappa, phi_k, E1, phi_e, F_s, A0, R, B_c, alpha0 = (
        kc[7],
        kc[8],
        kc[9],
        kc[10],
        kc[11],
        kc[12],
        kc[13],
        kc[14],
        kc[15],
    )
    psi = alpha0
    bd = B_c
    psid = 0.0
    if dynamic:
        d1 = A0 - y[0] + y[2]
        d2 = y[1] - y[3]
        ad = math.hypot(d1, d2)
        alpha_d = math.acos(R / ad)
        psi = alpha_d + math.asin((y[3] - y[1]) / ad)
        bd = B_c + (ad - A0) * math.tan(alpha_d)
        d1d = -y[5] + y[7]
        d2d = y[6] - y[8]
        add = (d1 * d1d + d2 * d2d) / ad
        z = -d2 / ad
        zd = -(d2d * ad - d2 * add) / (ad * ad)
        psid = R * add / (ad * math.sqrt(ad * ad - R * R)) + zd / math.sqrt(1.0 - z * z)
    sn, cs = math.sin(psi), math.cos(psi)
    dx, dy = y[0] - y[2], y[1] - y[3]
    delta = dx * sn - dy * cs + y[4] - E1 * math.cos(y[10] + phi_e)
    ddelta = (y[5] - y[7]) * sn - (y[6] - y[8]) * cs + y[9] + E1 * omega * math.sin(y[10] + phi_e)
    ddelta += psid * (dx * cs + dy * sn)
    f = delta - bd if delta >= bd else (delta + bd if delta <= -bd else 0.0)
    F = 2.0 * xi_m * ddelta + (1.0 + kappa * math.cos(y[10] + phi_k)) * f
    out = np.empty(11)
    out[0:5] = y[5:10]
    out[5] = -(2.0 * xi_p * sig_p * y[5] + sig_p**2 * y[0] + F * sn / eps_p)
    out[6] = -(2.0 * xi_p * sig_p * y[6] + sig_p**2 * y[1] - F * cs / eps_p) - kc[16] / eps_p
    out[7] = -(2.0 * xi_g * sig_g * y[7] + sig_g**2 * y[2] - F * sn / eps_g)
    out[8] = -(2.0 * xi_g * sig_g * y[8] + sig_g**2 * y[3] + F * cs / eps_g) - kc[17] / eps_g
    out[9] = F_s - F
    out[10] = omega
    return out


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    from gear_env import GearParams, GearSimulator, default_steps_per_period
    from gear_env.sim.reference import RefConsts, reference_poincare, rhs

    p = GearParams()
    k = RefConsts.from_params(p)
    names = ("eps_p", "eps_g", "sig_p", "sig_g", "xi_p", "xi_g", "xi_m", "kappa", "phi_k", "E1", "phi_e", "F_s",
             "A0", "R", "B_c", "alpha0", "g_p", "g_g")  # fmt: skip
    kc = np.array([getattr(k, f) for f in names])
    periods = 50
    for model in ("dynamic", "constant"):
        for w in (1.2, 2.8):
            sim = GearSimulator(p, model, 512, w)
            sim.advance(300)
            start = sim.state
            n = default_steps_per_period(w)
            fine = reference_poincare(w, model, p, 0, periods, start, rtol=1e-12, atol=1e-13).states
            nm = GearSimulator(p, model, n, w, start)
            err_nm = float(np.max(np.abs(nm.advance(periods).poincare[:, :10] - fine)))
            T = 2 * math.pi / w
            t_eval = T * np.arange(1, periods + 1)
            y0 = np.r_[start, 0.0]
            dyn = model == "dynamic"

            def newmark(start=start, n=n, w=w, model=model):
                return GearSimulator(p, model, n, w, start).advance(periods)

            rhs_numba(0.0, y0, w, kc, dyn)
            for rtol in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):

                def py(rtol=rtol, w=w, y0=y0, t_eval=t_eval, model=model):
                    return solve_ivp(rhs, (0, t_eval[-1]), y0, "DOP853", t_eval=t_eval, rtol=rtol,
                                     atol=rtol * 1e-2, args=(w, k, model))  # fmt: skip

                def nb(rtol=rtol, w=w, y0=y0, t_eval=t_eval, dyn=dyn):
                    return solve_ivp(rhs_numba, (0, t_eval[-1]), y0, "DOP853", t_eval=t_eval, rtol=rtol,
                                     atol=rtol * 1e-2, args=(w, kc, dyn))  # fmt: skip

                sol = nb()
                err = float(np.max(np.abs(sol.y[:10].T - fine)))
                if err <= err_nm:
                    break
            reached = "" if err <= err_nm else " (NOT reaching the Newmark error)"
            t_py = _timeit(py, 0.3)
            t_nb = _timeit(nb, 0.3)
            r_py, _, _ = paired_ratio(newmark, py)
            r_nb, _, _ = paired_ratio(newmark, nb)
            print(
                f"{model:8s} omega={w}: Newmark N={n} error {err_nm:.1e}; "
                f"DOP853 rtol {rtol:.0e} error {err:.1e}{reached}, "
                f"{sol.nfev} RHS evals: Python RHS {t_py * 1e3:.0f} ms, numba RHS {t_nb * 1e3:.0f} ms "
                f"(RHS = {100 * (1 - t_nb / t_py):.0f} % of the Python run); "
                f"Newmark faster by {r_py:,.0f}x / {r_nb:,.0f}x"
            )


if __name__ == "__main__":
    main()
