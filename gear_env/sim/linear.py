"""Linearised gear-bearing model (MODEL.md sec. 5): contact kept, k_m = k_m0, psi = alpha0.

Matrices in the units of MODEL.md sec. 5 (b0 units, natural time s = omega_n t, frequencies in
units of omega_n)::

    M = diag(eps_p, eps_p, eps_g, eps_g, 1)
    K = diag(lam_p, lam_p, lam_g, lam_g, 0) + g g^T           (constant backlash)
    K = diag(lam_p, lam_p, lam_g, lam_g, 0) + g (g - b)^T     (dynamic backlash, non-symmetric)
    C = diag(2 xi_p sig_p eps_p (x2), 2 xi_g sig_g eps_g (x2), 0) + 2 xi_m g g^T
    g = (sin a0, -cos a0, -sin a0, cos a0, 1)

with b = dB_d/dq = tan(a0) dA_d/dq = tan(a0) (-1, 0, 1, 0, 0) at the nominal centre distance
(so that dB_d/dk = sin(a0) tan(a0) for a relative centre separation k along the line of action).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .params import GearParams


def _check_model(model: str) -> None:
    if model not in ("constant", "dynamic"):
        raise ValueError(f"model must be 'constant' or 'dynamic', got {model!r}")


def mesh_vector(params: GearParams) -> np.ndarray:
    """g = dDelta/dq at psi = alpha0: (sin a0, -cos a0, -sin a0, cos a0, 1)."""
    a = math.radians(params.pressure_angle_deg)
    return np.array([math.sin(a), -math.cos(a), -math.sin(a), math.cos(a), 1.0])


def backlash_gradient(params: GearParams) -> np.ndarray:
    """b = dB_d/dq of the dynamic model at the nominal centre distance (b0 units per b0): tan(alpha0) along
    the centre line under the paper's law, sin(alpha0) under the involute law (``GearParams.backlash_law``)."""
    a = math.radians(params.pressure_angle_deg)
    slope = math.sin(a) if params.backlash_law == "involute" else math.tan(a)
    return slope * np.array([-1.0, 0.0, 1.0, 0.0, 0.0])


def matrices(params: GearParams | None = None, model: str = "constant") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, C, K) of the linearised system, dimensionless (MODEL.md sec. 5 units).

    ``model="dynamic"`` adds the dependence of B_d on the centre positions (non-symmetric K); with
    ``params.mesh_force_direction == "gradient"`` the mesh force acts along w = g - b (g = dDelta/dq, b =
    dB_d/dq), so K = diag + w w^T and C = diag + 2 xi_m w g^T (the force's curvature term, F_s times the
    second derivatives of Delta - B_d, is left out, as psi's is for the line of action).
    """
    _check_model(model)
    p = params or GearParams()
    d = p.dimensionless()
    g = mesh_vector(p)
    M = np.diag([d["eps_p"], d["eps_p"], d["eps_g"], d["eps_g"], 1.0])
    K = np.diag([d["lam_p"], d["lam_p"], d["lam_g"], d["lam_g"], 0.0]) + np.outer(g, g)
    cp = 2.0 * p.xi_p * d["sigma_p"] * d["eps_p"]
    cg = 2.0 * p.xi_g * d["sigma_g"] * d["eps_g"]
    if model == "dynamic" and p.mesh_force_direction == "gradient":
        w = g - backlash_gradient(p)
        K = np.diag([d["lam_p"], d["lam_p"], d["lam_g"], d["lam_g"], 0.0]) + np.outer(w, w)
        return M, np.diag([cp, cp, cg, cg, 0.0]) + 2.0 * p.xi_m * np.outer(w, g), K
    if model == "dynamic":
        K = K - np.outer(g, backlash_gradient(p))
    C = np.diag([cp, cp, cg, cg, 0.0]) + 2.0 * p.xi_m * np.outer(g, g)
    return M, C, K


def natural_frequencies(params: GearParams | None = None, model: str = "constant") -> np.ndarray:
    """Undamped natural frequencies w/omega_n (ascending, 5 values) of the linearised system.

    Solves (K - w^2 M) phi = 0. For ``model="dynamic"`` K is non-symmetric (dB_d/dq); its
    eigenvalues are real for the default parameters (a complex pair raises ``ValueError``).
    """
    M, _, K = matrices(params, model)
    lam = np.linalg.eigvals(np.linalg.solve(M, K))
    if np.max(np.abs(lam.imag)) > 1e-9 * np.max(np.abs(lam)) or np.min(lam.real) <= 0:
        raise ValueError(f"linearised system has non-real or non-positive eigenvalues: {lam}")
    return np.sqrt(np.sort(lam.real))


STABILITY_MARGIN = 0.9
"""Share of the Newmark stability limit that :func:`newmark_step_limit` allows (the nonlinear terms, the
dynamic model's geometry and the friction extension move the frequencies a little)."""


def newmark_step_limit(params: GearParams | None = None, plain: bool = False) -> float:
    """Largest stable Newmark step in natural time (s = omega_n t) for ``params.newmark_beta``.

    beta = 1/4 (the paper's average acceleration) is unconditionally stable: ``math.inf``. For beta < 1/4
    (gamma = 1/2) the scheme is stable for Omega_max h < 1 / sqrt(1/4 - beta) (sqrt(6) for Fox-Goodwin,
    beta = 1/12), Omega_max the highest natural frequency (units of omega_n) of the linearised system in
    contact with the mesh stiffness at its peak over the mesh cycle, taken over both backlash models. With
    ``params.velocity_correction`` the limit is the largest step up to which the damped linearised system's step
    (:func:`vc_amplification`) stays stable, a little below Fox-Goodwin's at this model's damping. The limit
    returned is :data:`STABILITY_MARGIN` times that. ``plain``: the limit of the plain Newmark step of
    ``params.newmark_beta`` (the correction ignored; what a step that the environments move off beta 1/12 takes).
    """
    p = params or GearParams()
    if p.newmark_beta >= 0.25:
        return math.inf
    vc = bool(p.velocity_correction and not plain)
    key = tuple(getattr(p, f.name) for f in fields(p) if f.init and f.name not in _LOAD_FIELDS) + (vc,)
    if key not in _STEP_LIMITS:
        if len(_STEP_LIMITS) >= 1024:
            _STEP_LIMITS.clear()
        _STEP_LIMITS[key] = _step_limit(p, vc)
    return _STEP_LIMITS[key]


_LOAD_FIELDS = frozenset({"T_p", "T_g", "e_m1", "phi_e", "te_harmonics", "T_p1", "T_g1", "phi_Tp", "phi_Tg"})
"""Fields that move only the forcing (torques, transmission error), not the linearised system's M, C, K: a plant
family's load duty cycle and wear change them every few steps, and the step limit is kept across them."""


_STEP_LIMITS: dict[tuple, float] = {}


def _step_limit(p: GearParams, vc: bool | None = None) -> float:
    """:func:`newmark_step_limit` of ``p`` (beta < 1/4; with the velocity correction if ``vc``, default
    ``p.velocity_correction``), computed; the caller keeps it per linearised system."""
    vc = p.velocity_correction if vc is None else vc
    phi = np.linspace(0.0, 2.0 * math.pi, 1024, endpoint=False)
    peak = float(np.max(p.stiffness_factor(phi)))
    w2 = 0.0
    systems = []
    for model in ("constant", "dynamic"):
        M, C, K = matrices(p, model)
        g = mesh_vector(p)
        K = K + (peak - 1.0) * np.outer(g, g if model == "constant" else g - backlash_gradient(p))
        w2 = max(w2, float(np.max(np.abs(np.linalg.eigvals(np.linalg.solve(M, K))))))
        systems.append((M, C, K))
    h = 1.0 / (math.sqrt(0.25 - p.newmark_beta) * math.sqrt(w2))
    if vc:
        h = min(_vc_limit(M, C, K, h) for M, C, K in systems)
    return STABILITY_MARGIN * h


def vc_amplification(M: np.ndarray, C: np.ndarray, K: np.ndarray, h: float) -> np.ndarray:
    """The 15 x 15 matrix that maps (q, v, a) over one step h of Fox-Goodwin with the velocity correction
    (``GearParams.velocity_correction``) for the linear system M a + C v_f + K q = 0, where the damping feels
    v_f = v + h (7/12 a + 5/12 a_new) and the state keeps Newmark's v_new = v + h/2 (a + a_new).

    M, C, K: dimensionless (5, 5) matrices as :func:`matrices` returns them; h: the step in natural time
    (s = omega_n t). States in b0 units, velocities and accelerations per natural time unit."""
    n = M.shape[0]
    beta, gf = 1.0 / 12.0, 0.5 - 1.0 / 12.0
    S = M + gf * h * C + beta * h * h * K
    # a_new = A_q q + A_v v + A_a a
    A = -np.linalg.solve(S, np.hstack([K, C + h * K, (1.0 - gf) * h * C + (0.5 - beta) * h * h * K]))
    eye = np.eye(n)
    zero = np.zeros((n, n))
    base = np.block([[eye, h * eye, (0.5 - beta) * h * h * eye], [zero, eye, 0.5 * h * eye], [zero, zero, zero]])
    return base + np.vstack([beta * h * h * A, 0.5 * h * A, A])


def _vc_limit(M: np.ndarray, C: np.ndarray, K: np.ndarray, h_fg: float) -> float:
    """Largest step below Fox-Goodwin's limit ``h_fg`` up to which :func:`vc_amplification` has no eigenvalue
    above 1 in modulus (damping lowers it: Omega h < 2.35 at a damping ratio of 0.1, 1.65 at 1, against
    sqrt(6) = 2.449 without the correction)."""

    def stable(h: float) -> bool:
        return float(np.max(np.abs(np.linalg.eigvals(vc_amplification(M, C, K, h))))) <= 1.0 + 1e-9

    grid = np.linspace(h_fg / 60.0, h_fg, 60)
    lo = 0.0
    for h in grid:
        if not stable(float(h)):
            break
        lo = float(h)
    else:
        return h_fg
    hi = float(h)
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def stable_beta(params: GearParams | None, omega: float, steps_per_period: int) -> float:
    """The Newmark beta closest to ``params.newmark_beta`` that is stable with ``steps_per_period`` steps per
    mesh period at meshing frequency ``omega`` (units of omega_n): ``params.newmark_beta`` itself wherever
    that is stable (:func:`newmark_step_limit`), else the smallest larger beta (up to 1/4) whose limit,
    with the same :data:`STABILITY_MARGIN`, admits the step h = 2 pi / (omega N):
    beta = 1/4 - (STABILITY_MARGIN / (Omega_max h))^2. The environments use it to keep their step count
    (and cost) where a conditionally stable beta would need more steps at low omega; the scheme then moves
    from Fox-Goodwin towards the paper's average acceleration (error between the two; docs/SIMULATOR.md).
    The beta of the plain Newmark step: with ``params.velocity_correction`` the environments leave the corrected
    step where its own (lower) limit is exceeded and take this beta, 1/12 itself where plain Fox-Goodwin is stable.
    """
    p = params or GearParams()
    w = stability_frequency(p, plain=True)
    return float(stable_betas(p.newmark_beta, w, np.array([omega], float), steps_per_period)[0])


def stability_frequency(params: GearParams | None = None, plain: bool = False) -> float:
    """Omega_max / :data:`STABILITY_MARGIN` (units of omega_n) for the stability limit of a Newmark beta < 1/4:
    the step h is stable with margin for beta >= 1/4 - 1 / (this h)^2. 0.0 for the paper's beta (no limit). With
    ``params.velocity_correction`` (and not ``plain``) the frequency that gives the corrected step's limit
    (:func:`newmark_step_limit`) the same way at beta 1/12: where to leave the corrected scheme."""
    p = params or GearParams()
    h = newmark_step_limit(p, plain)
    if not math.isfinite(h):
        return 0.0
    return 1.0 / (math.sqrt(0.25 - p.newmark_beta) * h)


def stable_betas(
    beta: np.ndarray | float, w_stab: np.ndarray | float, omega: np.ndarray, steps_per_period: int | np.ndarray
) -> np.ndarray:
    """Vectorised :func:`stable_beta` for rows of (beta, :func:`stability_frequency`, omega; ``steps_per_period``
    one count or one per row); the same
    floating-point operations per row whatever the number of rows (so one row's result does not depend on
    the others)."""
    h = (2.0 * math.pi / steps_per_period) / np.asarray(omega, float)
    wh = np.asarray(w_stab, float) * h
    with np.errstate(divide="ignore"):
        floor = 0.25 - (1.0 - 1e-9) / (wh * wh)  # 1e-9: the step then lies inside the limit after rounding
    return np.minimum(np.maximum(np.asarray(beta, float), floor), 0.25)


def min_steps_per_period(params: GearParams | None, omega: float) -> int:
    """Fewest Newmark steps per mesh period that are stable at meshing frequency ``omega`` (units of
    omega_n) for ``params.newmark_beta`` (:func:`newmark_step_limit`): 1 for the paper's beta = 1/4."""
    h = newmark_step_limit(params)
    if not math.isfinite(h):
        return 1
    return max(1, math.ceil(2.0 * math.pi / (omega * h)))


def modes(params: GearParams | None = None, model: str = "constant") -> tuple[np.ndarray, np.ndarray]:
    """(frequencies w/omega_n ascending, mode shapes as columns) of the undamped linear system."""
    M, _, K = matrices(params, model)
    lam, vec = np.linalg.eig(np.linalg.solve(M, K))
    order = np.argsort(lam.real)
    return np.sqrt(lam.real[order]), vec.real[:, order]


@dataclass(frozen=True)
class LinearResponse:
    """Steady response of the linearised system in full drive-side contact (kappa = 0).

    q(phi) = q_static + Re(Q exp(i phi)) for the positions (b0 units) at mesh phase phi;
    velocities (per unit natural time) are Re(i omega Q exp(i phi)).
    """

    omega: float
    q_static: np.ndarray  # (5,)
    Q: np.ndarray  # (5,) complex amplitudes
    delta_static: float  # Delta of the static part (= B_c + F_s)
    delta_amp: complex  # complex amplitude of Delta(phi)

    def state(self, phi: float = 0.0) -> np.ndarray:
        """The 10 states at mesh phase phi (b0 units, natural time)."""
        e = np.exp(1j * phi)
        return np.concatenate([self.q_static + (self.Q * e).real, (1j * self.omega * self.Q * e).real])

    def amplitude(self, name: str = "U") -> float:
        """Half peak-to-peak of 'U' or 'delta' (b0 units)."""
        if name == "U":
            return float(abs(self.Q[4]))
        if name == "delta":
            return float(abs(self.delta_amp))
        raise ValueError(f"name must be 'U' or 'delta', got {name!r}")


def linear_frequency_response(params: GearParams | None, omega: float, model: str = "constant") -> LinearResponse:
    """Steady response to the transmission-error harmonic in full drive-side contact, kappa = 0.

    Solves M q'' + C q' + K q = e_U F_s + g B_c + Re[g E1 (1 + 2 i xi_m omega) e^{i(phi + phi_e)}]
    (natural time, phi = omega s) with the matrices of :func:`matrices`. Valid as long as
    Delta(phi) stays >= B_d (no contact loss); the stiffness harmonic kappa is ignored.

    Args:
        params: physical parameters (SI), default Table 1.
        omega: meshing frequency Omega/omega_n (> 0).
        model: ``"constant"`` or ``"dynamic"`` (K with dB_d/dq).
    """
    if not (isinstance(omega, (int, float)) and math.isfinite(omega) and omega > 0):
        raise ValueError(f"omega must be a finite number > 0, got {omega!r}")
    p = params or GearParams()
    d = p.dimensionless()
    M, C, K = matrices(p, model)
    g = mesh_vector(p)
    e_u = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    # force k (g.q - B_c - b.q) (b = 0 for the constant model; b.q is inside K)
    rhs0 = e_u * d["F_s"] + g * d["B_c"]
    q_s = np.linalg.solve(K, rhs0)
    f = g * d["E1"] * (1.0 + 2j * p.xi_m * omega) * np.exp(1j * p.phi_e)
    Z = K - omega**2 * M + 1j * omega * C
    Q = np.linalg.solve(Z, f)
    d_static = float(g @ q_s)
    d_amp = complex(g @ Q - d["E1"] * np.exp(1j * p.phi_e))
    return LinearResponse(float(omega), q_s, Q, d_static, d_amp)


__all__ = [
    "LinearResponse",
    "backlash_gradient",
    "linear_frequency_response",
    "matrices",
    "mesh_vector",
    "min_steps_per_period",
    "modes",
    "natural_frequencies",
    "newmark_step_limit",
]
