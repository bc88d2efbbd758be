"""numba kernel of the two-trajectory (Benettin) Lyapunov record: both copies and the per-period
renormalisation in one compiled call.

Kept in a module of its own so that the Python API (:mod:`gear_env.analysis.lyapunov`) holds no
compiled code. The on-disk cache is keyed on a hash of this file and of the kernels package
(:mod:`gear_env._numba_cache`), so a change of the Newmark kernels never meets a stale copy.
"""

from __future__ import annotations

import math

import numpy as np

from ..sim import kernels as K


@K.kernel
def lyapunov_pair(x, omega, periods, n_steps, c, dynamic, d0, u, skip, pc, st_all, max_iter, tol):
    """Advance the reference state ``x`` (10, updated in place) and a copy at distance ``d0`` along
    the unit vector ``u`` by ``periods`` mesh periods at constant ``omega``, renormalising the copy
    to ``d0`` along the current separation after every period.

    Each period of each copy is one :func:`gear_env.sim.kernels.integrate_stats_tab` call from phase 0
    (consistent start acceleration), as a per-period ``integrate_stats`` call would do, with the
    excitation table computed once. Writes the reference's Poincare sample and interval
    statistics of period p into ``pc[p]`` (N_PC) and ``st_all[p]`` (N_STATS). Periods before
    ``skip`` only align the separation.

    Returns (status, failed period, sum of log(d/d0) over periods >= skip, natural time of those
    periods, natural time of all periods). On return ``u`` holds the unit separation direction at the
    end (after the last renormalisation), so that a caller can continue the copy in a next record.
    """
    n = K.NSTATE
    xc = np.empty(n)
    for i in range(n):
        xc[i] = x[i] + d0 * u[i]
    a0 = np.zeros(K.NDOF)
    a1 = np.zeros(K.NDOF)
    pc1 = np.empty((1, K.N_PC))
    st1 = np.empty(K.N_STATS)
    sum_log = 0.0
    t_count = 0.0
    t_all = 0.0
    # runtime-typed 1 and True: literal arguments would make numba compile a second, literal-
    # specialised copy of integrate_stats (~25 s of first-call compile) instead of reusing the
    # one GearSimulator already compiled (tests/test_compile_signatures.py)
    one = K.runtime_int(1)
    reset = K.runtime_true()
    for p in range(periods):
        s0, _, el = K.integrate_stats(
            x, a0, 0.0, omega, omega, one, n_steps, c, dynamic, pc[p : p + 1], st_all[p], max_iter, tol, reset
        )
        s1, _, _ = K.integrate_stats(
            xc, a1, 0.0, omega, omega, one, n_steps, c, dynamic, pc1, st1, max_iter, tol, reset
        )
        if s0 != K.OK:
            return s0, p, sum_log, t_count, t_all
        if s1 != K.OK:
            return s1, p, sum_log, t_count, t_all
        t_all += el
        dd = 0.0
        for i in range(n):
            dv = xc[i] - x[i]
            dd += dv * dv
        d = math.sqrt(dd)
        if p >= skip:
            sum_log += math.log(max(d, 1e-300) / d0)
            t_count += el
        if d > 0.0 and math.isfinite(d):
            f = d0 / d
            for i in range(n):
                xc[i] = x[i] + f * (xc[i] - x[i])
        else:  # separation lost below round-off: restart along the start direction u
            for i in range(n):
                xc[i] = x[i] + d0 * u[i]
    for i in range(n):
        u[i] = (xc[i] - x[i]) / d0
    return K.OK, periods, sum_log, t_count, t_all
