"""Independent reference integrator of MODEL.md sec. 3b (pure Python/NumPy + SciPy ``solve_ivp``).

Written from MODEL.md only (it shares no code with :mod:`gear_env.sim.kernels`): the dimensionless
constants are derived again from the SI fields of :class:`~gear_env.sim.params.GearParams`, the
right-hand side is the first-order system of the 10 states plus the mesh phase, in natural time
s = omega_n t, and the initial state (A10) is computed again here.

Contact changes are handled exactly: inside one contact region (drive side, apart, back side)
the right-hand side is smooth, so the integration runs region by region; events on
``Delta - B_d`` and ``Delta + B_d`` locate each region change to the solver's root tolerance and
the integration is restarted there with the new region. This keeps the high order of DOP853/Radau
across impacts. The module is slow (a Python right-hand side); it is used by the tests, the
convergence study and the benchmark, never by the simulator itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .params import GearParams

_MODELS = ("constant", "dynamic")


@dataclass(frozen=True)
class RefConsts:
    """Dimensionless constants of MODEL.md sec. 3 (b0 units, natural time)."""

    eps_p: float
    eps_g: float
    sig_p: float
    sig_g: float
    xi_p: float
    xi_g: float
    xi_m: float
    kappa: float
    phi_k: float
    E1: float
    phi_e: float
    F_s: float
    A0: float
    R: float
    B_c: float
    alpha0: float
    g_p: float
    g_g: float
    # the excitation as Fourier series in the mesh phase: ((kappa_n, phi_kn), ...) and
    # ((E_n, phi_en), ...) [b0]; one term each for the paper's single cosines
    stiffness: tuple[tuple[float, float], ...] = ()
    te: tuple[tuple[float, float], ...] = ()
    # the dynamic backlash law: "paper" (eq. 8) or "involute" (Yi et al. 2019, GearParams.backlash_law)
    law: str = "paper"
    # a fluctuating torque: the U row's load F_s + sum_j A_j sin(nu_j phi + ph_j), ((A_p, nu_p, ph_p), (A_g, ...))
    torque: tuple[tuple[float, float, float], ...] = ()
    # the dynamic model's mesh force along the gradient of Delta - region B_d (GearParams.mesh_force_direction)
    gradient: bool = False

    @classmethod
    def from_params(cls, p: GearParams) -> RefConsts:
        """Derive the constants from the SI inputs (MODEL.md A1-A5, sec. 3).

        The tooth-friction extension is not part of eq. (10): ``params.friction`` must be 0.
        """
        if getattr(p, "friction", 0.0) != 0.0:
            raise ValueError(f"the reference implements eq. (10) only: friction must be 0, got {p.friction!r}")
        a0 = math.radians(p.pressure_angle_deg)
        rbp = p.module * p.z_p * math.cos(a0) / 2.0
        rbg = p.module * p.z_g * math.cos(a0) / 2.0
        me = p.J_p * p.J_g / (p.J_p * rbg**2 + p.J_g * rbp**2)
        b0 = p.b_c if p.b0 is None else p.b0
        eps_p, eps_g = p.m_p / me, p.m_g / me
        lam_p, lam_g = p.k_p / p.k_m0, p.k_g / p.k_m0
        fs = me * (rbp * p.T_p / p.J_p + rbg * p.T_g / p.J_g) / (p.k_m0 * b0)
        return cls(
            eps_p=eps_p,
            eps_g=eps_g,
            sig_p=math.sqrt(lam_p / eps_p),
            sig_g=math.sqrt(lam_g / eps_g),
            xi_p=p.xi_p,
            xi_g=p.xi_g,
            xi_m=p.xi_m,
            kappa=p.kappa,
            phi_k=p.phi_k,
            E1=p.e_m1 / b0,
            phi_e=p.phi_e,
            F_s=fs,
            A0=p.module * (p.z_p + p.z_g) / 2.0 / b0,
            R=(rbp + rbg) / b0,
            B_c=p.b_c / b0,
            alpha0=a0,
            g_p=p.m_p * p.gravity / (p.k_m0 * b0),
            g_g=p.m_g * p.gravity / (p.k_m0 * b0),
            stiffness=tuple(p.stiffness_harmonics) or ((p.kappa, p.phi_k),),
            te=tuple((a / b0, ph) for a, ph in p.te_harmonics) or ((p.e_m1 / b0, p.phi_e),),
            law=p.backlash_law,
            gradient=p.mesh_force_direction == "gradient",
            # T_j(t) = T_j + T_j1 sin(order theta_j + phi_Tj), theta_j = phi / z_j: its share of the U row's load
            torque=(
                (me * rbp * p.T_p1 / (p.J_p * p.k_m0 * b0), p.torque_order / p.z_p, p.phi_Tp),
                (me * rbg * p.T_g1 / (p.J_g * p.k_m0 * b0), p.torque_order / p.z_g, p.phi_Tg),
            ),
        )


def load(phi: float, k: RefConsts) -> float:
    """The U row's load at mesh phase phi (from t = 0): F_s plus the torque fluctuation's share."""
    return k.F_s + sum(a * math.sin(nu * phi + ph) for a, nu, ph in k.torque)


def stiffness_factor(phi: float, k: RefConsts) -> float:
    """k_m / k_m0 = 1 + sum_n kappa_n cos(n phi + phi_kn) at mesh phase phi."""
    return 1.0 + sum(a * math.cos(n * phi + ph) for n, (a, ph) in enumerate(k.stiffness, start=1))


def transmission_error(phi: float, k: RefConsts) -> tuple[float, float]:
    """(e, de/dphi) [b0] of the static transmission error at mesh phase phi."""
    e = sum(a * math.cos(n * phi + ph) for n, (a, ph) in enumerate(k.te, start=1))
    de = -sum(n * a * math.sin(n * phi + ph) for n, (a, ph) in enumerate(k.te, start=1))
    return e, de


def mesh_geometry(q: np.ndarray, k: RefConsts, model: str) -> tuple[float, float]:
    """(psi [rad], B_d [b0]) at positions q = (X_p, Y_p, X_g, Y_g, ...) (eqs. 5-8, A8/A9)."""
    if model == "constant":
        return k.alpha0, k.B_c
    d1 = k.A0 - q[0] + q[2]
    d2 = q[1] - q[3]
    ad = math.hypot(d1, d2)
    alpha_d = math.acos(k.R / ad)
    psi = alpha_d + math.asin((q[3] - q[1]) / ad)
    if k.law == "involute":  # Yi et al. (2019): B_c + R (inv alpha_d - inv alpha0), inv a = tan a - a
        return psi, k.B_c + k.R * ((math.tan(alpha_d) - alpha_d) - (math.tan(k.alpha0) - k.alpha0))
    return psi, k.B_c + (ad - k.A0) * math.tan(alpha_d)


def _psi_dot(q: np.ndarray, v: np.ndarray, k: RefConsts) -> float:
    """d psi / ds of the dynamic model (chain rule through A_d and the arcsin term)."""
    d1 = k.A0 - q[0] + q[2]
    d2 = q[1] - q[3]
    d1d = -v[0] + v[2]
    d2d = v[1] - v[3]
    ad = math.hypot(d1, d2)
    add = (d1 * d1d + d2 * d2d) / ad
    alpha_dot = k.R * add / (ad * math.sqrt(ad * ad - k.R * k.R))
    z = -d2 / ad
    zd = -(d2d * ad - d2 * add) / (ad * ad)
    return alpha_dot + zd / math.sqrt(1.0 - z * z)


def mesh_quantities(y: np.ndarray, omega: float, k: RefConsts, model: str) -> tuple[float, float, float, float]:
    """(Delta, Delta', B_d, psi) for a state y = (10 states, phase) at meshing frequency omega."""
    q, v, phi = y[0:5], y[5:10], y[10]
    psi, bd = mesh_geometry(q, k, model)
    s, c = math.sin(psi), math.cos(psi)
    dx, dy = q[0] - q[2], q[1] - q[3]
    e, de = transmission_error(phi, k)
    delta = dx * s - dy * c + q[4] - e
    ddelta = (v[0] - v[2]) * s - (v[1] - v[3]) * c + v[4] - omega * de
    if model == "dynamic":
        ddelta += _psi_dot(q, v, k) * (dx * c + dy * s)
    return delta, ddelta, bd, psi


def force_gradient(q: np.ndarray, phi: float, k: RefConsts, model: str, region: int) -> np.ndarray:
    """d(Delta - region B_d)/dq (5 entries) by central differences of :func:`mesh_geometry` and Delta: the
    direction of the mesh force with ``GearParams.mesh_force_direction = "gradient"`` (ROSS's force)."""

    def gap(qq: np.ndarray) -> float:
        psi, bd = mesh_geometry(qq, k, model)
        e = transmission_error(phi, k)[0]
        return (qq[0] - qq[2]) * math.sin(psi) - (qq[1] - qq[3]) * math.cos(psi) + qq[4] - e - region * bd

    h = 1e-3  # b0: B_d and psi come from A0 ~ 1e3-1e4 b0, so a smaller step loses digits to round-off
    out = np.empty(5)
    for i in range(5):
        d = np.zeros(5)
        d[i] = h
        out[i] = (gap(q + d) - gap(q - d)) / (2.0 * h)
    return out


def _direction(q: np.ndarray, phi: float, psi: float, k: RefConsts, model: str, region: int) -> np.ndarray:
    """The generalised force of a unit mesh force on (X_p, Y_p, X_g, Y_g), with the sign of dDelta/dq: eq. (10)'s
    line of action (psi frozen), or the gradient of Delta - region B_d (:func:`force_gradient`)."""
    if k.gradient and model == "dynamic":
        return force_gradient(q, phi, k, model, region)[:4]
    s, c = math.sin(psi), math.cos(psi)
    return np.array([s, -c, -s, c])


def contact_region(delta: float, bd: float) -> int:
    """+1 drive-side contact (Delta >= B_d), 0 apart, -1 back-side contact (Delta <= -B_d)."""
    if delta >= bd:
        return 1
    if delta <= -bd:
        return -1
    return 0


def rhs(s: float, y: np.ndarray, omega: float, k: RefConsts, model: str, region: int | None = None) -> np.ndarray:
    """Right-hand side dy/ds of MODEL.md sec. 3b (natural time, constant omega).

    ``region`` forces the backlash branch (used between events); None picks it from Delta.
    """
    delta, ddelta, bd, psi = mesh_quantities(y, omega, k, model)
    reg = contact_region(delta, bd) if region is None else region
    f = delta - bd if reg > 0 else (delta + bd if reg < 0 else 0.0)
    F = 2.0 * k.xi_m * ddelta + stiffness_factor(y[10], k) * f
    g = _direction(y[0:5], y[10], psi, k, model, reg)
    out = np.empty(11)
    out[0:5] = y[5:10]
    out[5] = -(2.0 * k.xi_p * k.sig_p * y[5] + k.sig_p**2 * y[0] + F * g[0] / k.eps_p)
    out[6] = -(2.0 * k.xi_p * k.sig_p * y[6] + k.sig_p**2 * y[1] + F * g[1] / k.eps_p) - k.g_p / k.eps_p
    out[7] = -(2.0 * k.xi_g * k.sig_g * y[7] + k.sig_g**2 * y[2] + F * g[2] / k.eps_g)
    out[8] = -(2.0 * k.xi_g * k.sig_g * y[8] + k.sig_g**2 * y[3] + F * g[3] / k.eps_g) - k.g_g / k.eps_g
    out[9] = load(y[10], k) - F
    out[10] = omega
    return out


def reference_initial_state(params: GearParams | None = None, model: str = "dynamic") -> np.ndarray:
    """MODEL.md A10: drive-side static equilibrium with kappa = 0 and the TE frozen at phase 0.

    Returns the 10 states [X_p, Y_p, X_g, Y_g, U, velocities = 0] in b0 units.
    """
    _check_model(model)
    k = RefConsts.from_params(params or GearParams())
    lam_p, lam_g = k.eps_p * k.sig_p**2, k.eps_g * k.sig_g**2
    psi, bd = k.alpha0, k.B_c
    fs = load(0.0, k)  # a fluctuating torque frozen at phase 0, like the TE
    q = np.zeros(5)
    for _ in range(200):
        s, c = math.sin(psi), math.cos(psi)
        g = _direction(q, 0.0, psi, k, model, 1)  # drive-side contact
        q[0] = -fs * g[0] / lam_p
        q[1] = -(fs * g[1] + k.g_p) / lam_p
        q[2] = -fs * g[2] / lam_g
        q[3] = -(fs * g[3] + k.g_g) / lam_g
        q[4] = bd + fs + transmission_error(0.0, k)[0] - ((q[0] - q[2]) * s - (q[1] - q[3]) * c)
        psi_new, bd_new = mesh_geometry(q, k, model)
        if abs(psi_new - psi) < 1e-16 and abs(bd_new - bd) < 1e-15:
            break
        psi, bd = psi_new, bd_new
    return np.concatenate([q, np.zeros(5)])


@dataclass
class ReferenceResult:
    """Poincare samples of :func:`reference_poincare` (one row per recorded mesh period)."""

    states: np.ndarray  # (periods, 10), b0 units
    delta: np.ndarray  # (periods,)
    bd: np.ndarray  # (periods,)
    psi: np.ndarray  # (periods,) rad
    final: np.ndarray  # (11,) state and phase at the end
    events: int  # contact changes located
    nfev: int  # right-hand-side evaluations


def _check_model(model: str) -> None:
    if model not in _MODELS:
        raise ValueError(f"model must be one of {_MODELS}, got {model!r}")


def integrate_events(
    y0: np.ndarray,
    s0: float,
    s1: float,
    omega: float,
    k: RefConsts,
    model: str,
    rtol: float,
    atol: float,
    method: str = "DOP853",
    max_step: float = math.inf,
) -> tuple[np.ndarray, int, int]:
    """Integrate from s0 to s1 region by region, restarting at every located contact change.

    Returns (y(s1), number of events, number of RHS evaluations).
    """
    y = np.asarray(y0, dtype=float).copy()
    s = s0
    d, _, bd, _ = mesh_quantities(y, omega, k, model)
    region = contact_region(d, bd)
    n_ev = 0
    nfev = 0

    def g_drive(_s, yy):
        dd, _, bb, _ = mesh_quantities(yy, omega, k, model)
        return dd - bb

    def g_back(_s, yy):
        dd, _, bb, _ = mesh_quantities(yy, omega, k, model)
        return dd + bb

    g_drive.terminal = True
    g_back.terminal = True
    while s < s1:
        if region > 0:
            g_drive.direction = -1.0
            events = [g_drive]
            nxt = [0]
        elif region < 0:
            g_back.direction = 1.0
            events = [g_back]
            nxt = [0]
        else:
            g_drive.direction = 1.0
            g_back.direction = -1.0
            events = [g_drive, g_back]
            nxt = [1, -1]
        reg = region
        sol = solve_ivp(
            lambda t, yy, reg=reg: rhs(t, yy, omega, k, model, reg),
            (s, s1),
            y,
            method=method,
            rtol=rtol,
            atol=atol,
            events=events,
            max_step=max_step,
        )
        nfev += sol.nfev
        if sol.status == -1:
            raise RuntimeError(f"solve_ivp failed at s={s}: {sol.message}")
        if sol.status == 1:
            hit = [i for i, te in enumerate(sol.t_events) if len(te)]
            i = hit[0]
            s_ev = float(sol.t_events[i][0])
            if s_ev <= s:  # spurious zero at the restart point: nudge by the solver's last step
                s_ev = s
            y = sol.y_events[i][0].copy()
            s = s_ev
            region = nxt[i]
            n_ev += 1
            if n_ev > 10_000_000:
                raise RuntimeError("too many contact events")
        else:
            y = sol.y[:, -1].copy()
            s = s1
    return y, n_ev, nfev


def reference_poincare(
    omega: float,
    model: str = "dynamic",
    params: GearParams | None = None,
    transient: int = 0,
    periods: int = 10,
    initial_state: np.ndarray | None = None,
    rtol: float = 1e-11,
    atol: float = 1e-12,
    method: str = "DOP853",
    max_step: float = math.inf,
    events: bool = True,
) -> ReferenceResult:
    """Poincare samples (mesh phase 2 pi k) of MODEL.md sec. 3b at constant omega, by ``solve_ivp``.

    Args:
        omega: meshing frequency Omega/omega_n (> 0).
        model: ``"constant"`` or ``"dynamic"``.
        params: physical parameters (default Table 1).
        transient: mesh periods integrated first and discarded.
        periods: mesh periods recorded (one sample at the end of each).
        initial_state: 10 states in b0 units at phase 0 (default A10, computed here).
        rtol, atol: ``solve_ivp`` tolerances.
        method: ``solve_ivp`` method (DOP853, Radau, ...).
        max_step: maximum step in natural time.
        events: locate contact changes and restart there (True), or integrate straight through
            the kinks of the piecewise-linear force (False; what a naive user would do).

    Returns:
        :class:`ReferenceResult`.
    """
    _check_model(model)
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"omega must be finite and > 0, got {omega!r}")
    p = params or GearParams()
    k = RefConsts.from_params(p)
    x0 = reference_initial_state(p, model) if initial_state is None else np.asarray(initial_state, float)
    if x0.shape != (10,):
        raise ValueError(f"initial_state must have shape (10,), got {x0.shape}")
    y = np.concatenate([x0, [0.0]])
    T = 2.0 * math.pi / omega
    n_ev = nfev = 0
    rows = np.empty((periods, 10))
    dl, bdl, psil = np.empty(periods), np.empty(periods), np.empty(periods)
    if not events:
        # one call, dense output sampled at the section
        t_eval = T * np.arange(transient + 1, transient + periods + 1)
        sol = solve_ivp(
            lambda t, yy: rhs(t, yy, omega, k, model),
            (0.0, t_eval[-1]),
            y,
            method=method,
            rtol=rtol,
            atol=atol,
            t_eval=t_eval,
            max_step=max_step,
        )
        if sol.status != 0:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        for j in range(periods):
            yy = sol.y[:, j]
            rows[j] = yy[:10]
            dl[j], _, bdl[j], psil[j] = mesh_quantities(yy, omega, k, model)
        return ReferenceResult(rows, dl, bdl, psil, sol.y[:, -1].copy(), 0, sol.nfev)
    if transient > 0:
        y, ne, nf = integrate_events(y, 0.0, T * transient, omega, k, model, rtol, atol, method, max_step)
        n_ev += ne
        nfev += nf
    for j in range(periods):
        s0 = T * (transient + j)
        y, ne, nf = integrate_events(y, s0, s0 + T, omega, k, model, rtol, atol, method, max_step)
        n_ev += ne
        nfev += nf
        rows[j] = y[:10]
        dl[j], _, bdl[j], psil[j] = mesh_quantities(y, omega, k, model)
    return ReferenceResult(rows, dl, bdl, psil, y, n_ev, nfev)


__all__ = [
    "RefConsts",
    "ReferenceResult",
    "contact_region",
    "integrate_events",
    "mesh_geometry",
    "mesh_quantities",
    "reference_initial_state",
    "reference_poincare",
    "rhs",
]
