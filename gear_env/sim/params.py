"""Physical parameters of the spur gear-bearing pair and their dimensionless form.

`GearParams` holds the inputs in SI units (Table 1 of the paper plus the decisions A1-A10 of
MODEL.md); `GearParams.dimensionless()` returns the constants the numba kernels use, packed in a
float64 array whose layout is fixed by the ``C_*`` indices below.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

# --------------------------------------------------------------------------------------------
# Layout of the float64 constants array passed to the kernels (dimensionless, natural time).
C_EPS_P = 0  # m_p / m_e
C_EPS_G = 1  # m_g / m_e
C_SIG_P = 2  # sqrt(k_p / (m_p omega_n^2))
C_SIG_G = 3  # sqrt(k_g / (m_g omega_n^2))
C_XI_BP = 4  # pinion bearing damping ratio
C_XI_BG = 5  # gear bearing damping ratio
C_XI_M = 6  # mesh damping ratio
C_KAPPA = 7  # relative amplitude of the mesh-stiffness harmonic
C_PHI_K = 8  # stiffness phase [rad]
C_E1 = 9  # TE amplitude / b0
C_PHI_E = 10  # TE phase [rad]
C_FS = 11  # static mesh load / (k_m0 b0)
C_A0 = 12  # nominal centre distance / b0
C_R = 13  # (r_bp + r_bg) / b0
C_BC = 14  # half backlash / b0
C_ALPHA0 = 15  # nominal pressure angle [rad]
C_GP = 16  # pinion weight along -y / (k_m0 b0) (0 unless gravity is switched on)
C_GG = 17  # gear weight along -y / (k_m0 b0)
C_SIN_A0 = 18  # sin(alpha0), precomputed
C_COS_A0 = 19  # cos(alpha0)
C_MU = 20  # tooth sliding-friction coefficient (0 = the paper's eq. 10; analysis extension)
C_NK = 21  # number N_k of stiffness harmonics in the tail (0: the single cosine kappa, phi_k above)
C_NE = 22  # number N_e of TE harmonics in the tail (0: the single cosine E1, phi_e above)
# torque fluctuation (GearParams.T_p1, T_g1; 0 = off, the paper's constant torques): the load of the U row is
# F_s + A_p sin(nu_p phi + ph_p) + A_g sin(nu_g phi + ph_g) at mesh phase phi (kernels.mesh.external_load_t)
C_NT = 23  # 1.0 if either torque fluctuates, else 0.0
C_TP1 = 24  # A_p = m_e r_bp T_p1 / (J_p k_m0 b0)
C_TG1 = 25  # A_g = m_e r_bg T_g1 / (J_g k_m0 b0)
C_NU_P = 26  # nu_p = torque_order / z_p: torque cycles per mesh period
C_NU_G = 27  # nu_g = torque_order / z_g
C_PH_TP = 28  # ph_p: phase [rad] at mesh phase 0 of the interval (GearSimulator advances it per interval)
C_PH_TG = 29  # ph_g
NEWMARK_BETA = 0.25
"""The paper's Newmark beta (average acceleration, gamma = 1/2): unconditionally stable, second order."""
FOX_GOODWIN_BETA = 1.0 / 12.0
"""Newmark beta of the Fox-Goodwin scheme (gamma = 1/2): second order with damping, with a far smaller error
constant on this model (docs/SIMULATOR.md, "Fox-Goodwin"), stable only for Omega_max h < sqrt(6)
(:func:`gear_env.sim.linear.newmark_step_limit`)."""
SCHEMES: dict[str, tuple[float, bool]] = {
    "paper": (NEWMARK_BETA, False),
    "fox-goodwin": (FOX_GOODWIN_BETA, False),
    "fox-goodwin-vc": (FOX_GOODWIN_BETA, True),
}
"""The Newmark schemes by name: (``GearParams.newmark_beta``, ``GearParams.velocity_correction``) (``gear-env ...
--scheme``, the environments' ``scheme`` setting). ``"fox-goodwin-vc"``: Fox-Goodwin with the velocity of the
damping forces corrected (:class:`GearParams`, ``velocity_correction``)."""


def scheme_name(newmark_beta: float, velocity_correction: bool) -> str | None:
    """The name in :data:`SCHEMES` of a (beta, velocity correction) pair, None for a beta between 1/12 and 1/4."""
    for name, pair in SCHEMES.items():
        if pair == (newmark_beta, bool(velocity_correction)):
            return name
    return None


C_BETA = 30  # Newmark beta of the integrator (numerics: GearParams.newmark_beta)
C_VC = 31  # 1.0 with GearParams.velocity_correction (Fox-Goodwin's velocity corrected in the forces), else 0.0
C_LOC = 32  # a contact change inside a fixed step: 0.0 stepped over (GearParams), else CONTACTS_LOCATED / _CORRECTED
CONTACTS_LOCATED = 1.0
"""``C_LOC``: the fixed-step drivers take a step whose contact region changes again, split at the crossing
(``kernels.located_fixed_step``; the environments' ``locate_contacts=True``)."""
CONTACTS_CORRECTED = 2.0
"""``C_LOC``: the fixed-step drivers correct such a step for the kink of the backlash force inside it, without a
solve (``kernels.kink_correct_t``; the environments' ``correct_kinks=True``)."""
N_CONSTS = 33  # length of the fixed part; the harmonic tail follows it
C_TAIL = N_CONSTS  # tail: kappa_n (cos, sin)(phi_kn), n = 1..N_k, then E_n / b0 (cos, sin)(phi_en), n = 1..N_e
MAX_HARMONICS = 64

MODELS = ("constant", "dynamic")
BACKLASH_LAWS = ("paper", "involute")
"""The dynamic backlash law (``GearParams.backlash_law``): ``"paper"`` eq. (8), b_d = b_c + (a_d - a0)
tan(alpha_d); ``"involute"`` Yi et al. (2019), as in ROSS: b_d = b_c + (r_bp + r_bg)(inv alpha_d - inv
alpha0), inv a = tan a - a (to first order sin alpha0 where eq. (8) has tan alpha0)."""
FORCE_DIRECTIONS = ("line_of_action", "gradient")
"""How the dynamic model's mesh force acts on the bearings (``GearParams.mesh_force_direction``):
``"line_of_action"`` eq. (10), along dDelta/dq with psi frozen; ``"gradient"`` as in ROSS, along
d(Delta - region B_d)/dq, the gradient of the mesh's potential (MODEL.md, extension)."""
LAW_INVOLUTE = 2
"""Bit of the kernels' model code (:func:`kernel_code`): the dynamic model under the involute backlash law."""
FORCE_GRADIENT = 4
"""Bit of the kernels' model code: the dynamic model's mesh force along the gradient of Delta - region B_d."""


def model_code(model: str) -> int:
    """Return the kernel code of a backlash model name (0 = constant, 1 = dynamic)."""
    if not isinstance(model, str) or model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    return MODELS.index(model)


def kernel_code(model: str, params: GearParams) -> int:
    """The kernels' model code of ``model`` under ``params``: :func:`model_code` (0 constant, 1 dynamic), and
    for the dynamic model the bits :data:`LAW_INVOLUTE` (``params.backlash_law == "involute"``) and
    :data:`FORCE_GRADIENT` (``params.mesh_force_direction == "gradient"``). The constant model has neither
    (B_d = B_c and psi = alpha0: no law, and the gradient is the line of action), so it stays 0."""
    code = model_code(model)
    if code == 1:
        if params.backlash_law == "involute":
            code |= LAW_INVOLUTE
        if params.mesh_force_direction == "gradient":
            code |= FORCE_GRADIENT
    return code


def refuse_extensions(params: GearParams, where: str) -> None:
    """Raise ``ValueError`` if ``params`` use an extension that only :func:`gear_env.simulate` and
    :class:`gear_env.GearSimulator` carry (a fluctuating torque, the involute backlash law, the gradient
    force direction).

    A torque fluctuating at shaft frequency repeats every z mesh periods, not every one, so the
    mesh-period maps (Floquet, continuation), the SIMD batch and the environments, whose
    intervals each start at mesh phase 0, cannot hold its phase."""
    if params.torque_fluctuates:
        raise ValueError(
            f"{where} does not take a torque fluctuation (GearParams.T_p1 = {params.T_p1:g}, T_g1 = {params.T_g1:g} "
            "N m); use gear_env.simulate or GearSimulator, or set T_p1 = T_g1 = 0"
        )
    if params.backlash_law != "paper":
        raise ValueError(
            f"{where} takes only the paper's backlash law (GearParams.backlash_law = 'paper'), got "
            f"{params.backlash_law!r}; use gear_env.simulate or GearSimulator for {params.backlash_law!r}"
        )
    if params.mesh_force_direction != "line_of_action":
        raise ValueError(
            f"{where} takes only the paper's mesh force direction (GearParams.mesh_force_direction = "
            f"'line_of_action'), got {params.mesh_force_direction!r}; use gear_env.simulate or GearSimulator"
        )


def refuse_velocity_correction(params: GearParams, where: str) -> None:
    """Raise ``ValueError`` if ``params.velocity_correction`` is set: the analyses built on the exact Jacobian of
    the plain Newmark step (Floquet multipliers, continuation) do not carry it."""
    if params.velocity_correction:
        raise ValueError(
            f"{where} takes the plain Newmark step (GearParams.velocity_correction = False): the corrected scheme "
            "carries Newmark's velocity but reports the corrected one, so its period map is not a map of its state "
            "and its Jacobian not the plain step's; use scheme 'fox-goodwin' (beta 1/12) or 'paper' for it"
        )


# allowed ranges of the SI inputs: (low, high, low inclusive?, high inclusive?)
BOUNDS: dict[str, tuple[float, float, bool, bool]] = {
    "pressure_angle_deg": (0.0, 45.0, False, False),
    "J_p": (1e-9, 1e6, True, True),
    "J_g": (1e-9, 1e6, True, True),
    "m_p": (1e-6, 1e6, True, True),
    "m_g": (1e-6, 1e6, True, True),
    "k_p": (1.0, 1e14, True, True),
    "k_g": (1.0, 1e14, True, True),
    "k_m0": (1.0, 1e14, True, True),
    "module": (1e-5, 1.0, True, True),
    "e_m1": (0.0, 1e-2, True, True),
    "phi_e": (-1e3, 1e3, True, True),
    "kappa": (0.0, 1.0, True, False),
    "phi_k": (-1e3, 1e3, True, True),
    "b_c": (1e-9, 1e-2, True, True),
    "T_p": (0.0, 1e7, True, True),
    "T_g": (0.0, 1e7, True, True),
    "xi_m": (0.0, 10.0, True, False),
    "xi_p": (0.0, 10.0, True, False),
    "xi_g": (0.0, 10.0, True, False),
    "b0": (1e-9, 1.0, True, True),
    "gravity": (0.0, 1000.0, True, True),
    "friction": (0.0, 1.0, True, True),
    "T_p1": (0.0, 1e7, True, True),
    "T_g1": (0.0, 1e7, True, True),
    "phi_Tp": (-1e3, 1e3, True, True),
    "phi_Tg": (-1e3, 1e3, True, True),
    "torque_order": (0.0, 1000.0, False, True),
    "newmark_beta": (FOX_GOODWIN_BETA, NEWMARK_BETA, True, True),
}
EXTENSION_DEFAULTS: dict[str, Any] = {
    "T_p1": 0.0,
    "T_g1": 0.0,
    "phi_Tp": 0.0,
    "phi_Tg": 0.0,
    "torque_order": 1.0,
    "backlash_law": "paper",
    "mesh_force_direction": "line_of_action",
    "newmark_beta": NEWMARK_BETA,
    "velocity_correction": False,
}
"""Fields that :meth:`GearParams.to_dict` leaves out at these values, so that the dict of the
paper's model is what it was before they existed."""
TEETH_RANGE = (5, 1000)


RANGE_TEXT = {"newmark_beta": f"[1/12, 1/4] (1/12 = {FOX_GOODWIN_BETA!r}: Fox-Goodwin; 1/4: the paper's scheme)"}
"""How a refusal writes the range of a field whose bounds ``%g`` would round (``BOUNDS`` gives the others)."""


def _range_text(name: str) -> str:
    if name in RANGE_TEXT:
        return RANGE_TEXT[name]
    lo, hi, lo_in, hi_in = BOUNDS[name]
    return f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


BETA_SNAP = 1e-6
"""A ``newmark_beta`` within this of 1/12 is taken as 1/12 (Fox-Goodwin), so that a rounded 0.083333 means it."""


def _check_range(name: str, value: float) -> None:
    lo, hi, lo_in, hi_in = BOUNDS[name]
    ok = math.isfinite(value) and (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)
    if not ok:
        raise ValueError(f"GearParams.{name} must be in {_range_text(name)}, got {value!r}")


@dataclass(frozen=True)
class GearParams:
    """Inputs of the 6-DOF spur gear-bearing model, SI units (MODEL.md sec. 1).

    Defaults are Table 1 of the paper with the decisions of MODEL.md (kappa = 0.2, base radii,
    b0 = half backlash, damping from ratios). All fields are validated on construction against
    the ranges in ``BOUNDS``; a bad value raises ``ValueError`` naming the field and its range.

    Attributes:
        pressure_angle_deg: nominal pressure angle alpha0 [deg], in (0, 45).
        J_p, J_g: polar moments of inertia of pinion and gear [kg m^2].
        m_p, m_g: masses [kg].
        k_p, k_g: bearing stiffnesses [N/m].
        k_m0: mean mesh stiffness [N/m].
        z_p, z_g: tooth numbers (integers >= 5).
        module: module [m].
        e_m1: first-harmonic static transmission error amplitude [m].
        phi_e: TE phase [rad].
        kappa: relative amplitude of the mesh-stiffness harmonic [-], in [0, 1).
        phi_k: stiffness phase [rad].
        b_c: half backlash [m].
        T_p, T_g: driving and load torques [N m].
        xi_m: mesh damping ratio [-].
        xi_p, xi_g: bearing damping ratios [-].
        b0: length scale of the dimensionless equations [m] (default: the half backlash).
        gravity: standard gravity along -y [m/s^2]; 0 (default) reproduces the paper's eq. (10).
        friction: tooth sliding-friction coefficient mu [-], in [0, 1]; 0 (default) reproduces eq. (10).
            Extension (docs/RESULTS.md): a friction force mu F_m s(phi) perpendicular to the line of
            action, s = tanh(10 sin phi) (a smoothed square wave: the sliding direction reverses at
            the pitch point and at the tooth-pair change), acting on the bearings; its moment on the
            gears is neglected. It is the simplest mechanism that moves the centres off the line of
            action and so makes the meshing angle psi fluctuate.
        stiffness_harmonics: any periodic mesh stiffness as a Fourier series in the mesh phase phi,
            k_m = k_m0 (1 + sum_n kappa_n cos(n phi + phi_kn)), given as ((kappa_1, phi_k1), ...,
            (kappa_N, phi_kN)) [-, rad], N <= 64; the series must stay positive. Empty (default): the
            single cosine ``kappa``, ``phi_k``. When given, ``kappa`` and ``phi_k`` are set to its
            first harmonic (so they always describe it); one harmonic is exactly the single cosine.
            :meth:`from_pair` fills it from a gear geometry, :func:`harmonics_from_samples` from a
            sampled waveform.
        te_harmonics: any periodic static transmission error e(phi) = sum_n e_n cos(n phi + phi_en),
            ((e_1, phi_e1), ..., (e_N, phi_eN)) [m, rad], N <= 64, e.g. a measured TE through
            :func:`harmonics_from_samples`. Empty (default): the single cosine ``e_m1``, ``phi_e``;
            when given, ``e_m1`` and ``phi_e`` are set to its first harmonic. More than one TE
            harmonic cannot be combined with ``friction`` (whose sliding direction is read from the
            first harmonic's phase).
        T_p1, T_g1: amplitudes of a torque fluctuation [N m], in [0, 1e7] (above T_p or T_g the torque
            reverses during part of the cycle, as in gear rattle): T_p(t) = T_p + T_p1 sin(n theta_p(t)
            + phi_Tp) with theta_p = phi / z_p the pinion's rotation since t = 0 (phi: mesh phase),
            likewise T_g(t) with theta_g = phi / z_g.
            0 (default): the paper's constant torques, bit for bit. Carried by :func:`gear_env.simulate`
            and :class:`gear_env.GearSimulator` (fixed steps); the other entry points refuse it
            (:func:`refuse_extensions`).
        phi_Tp, phi_Tg: phases of the torque fluctuations at t = 0 [rad].
        torque_order: n, torque cycles per shaft revolution (> 0, default 1: once per revolution,
            as in ROSS's ``test_mesh_with_backlash``), the same for both shafts.
        backlash_law: the dynamic model's backlash law, ``"paper"`` (default, eq. 8) or
            ``"involute"`` (Yi et al. 2019, ROSS's law; :data:`BACKLASH_LAWS`). Carried by
            :func:`gear_env.simulate` and :class:`gear_env.GearSimulator`; the other entry points
            refuse ``"involute"``.
        mesh_force_direction: how the dynamic model's mesh force acts on the bearings:
            ``"line_of_action"`` (default, eq. 10: F along dDelta/dq, psi frozen) or ``"gradient"``
            (ROSS: F along d(Delta - region B_d)/dq, the gradient of the mesh's potential, which adds the
            backlash's own dependence on the centre positions and psi's; :data:`FORCE_DIRECTIONS`). Carried
            by :func:`gear_env.simulate` and :class:`gear_env.GearSimulator`; the other entry points refuse
            ``"gradient"``.
        newmark_beta: the integrator's Newmark beta (numerics, not physics; gamma = 1/2), in [1/12, 1/4]
            (a value within 1e-6 of 1/12, such as 0.083333, is taken as 1/12).
            1/4 (default, :data:`NEWMARK_BETA`): the paper's average acceleration, unconditionally stable.
            1/12 (:data:`FOX_GOODWIN_BETA`, Fox-Goodwin): the same cost per step and 2-10x less error on
            period-1 orbits at omega 0.6-2 (docs/SIMULATOR.md, "Fox-Goodwin"), stable for steps below
            :func:`gear_env.sim.linear.newmark_step_limit`: ``GearSimulator`` refuses fewer steps than
            :func:`gear_env.sim.linear.min_steps_per_period` (omega); the environments keep their step count and
            take, per sub-environment and step where omega is that low, the nearest stable beta
            (:func:`gear_env.sim.linear.stable_beta`). Not with ``tol``. Left out of :meth:`to_dict` at 1/4.
        velocity_correction: Fox-Goodwin only (``newmark_beta`` 1/12; scheme ``"fox-goodwin-vc"``). Newmark's
            velocity carries a bias of h^2/12 da/dt under beta 1/12, which the damping forces (bearings, mesh) then
            feel; with this True they are evaluated with v - (h/12)(a_new - a_old) instead (the bias removed to
            O(h^3)), at the same cost per step. The Poincare samples and recorded trajectories hold that
            corrected velocity; the state carried from step to step (``GearSimulator.state``) keeps Newmark's
            velocity. Each call restarts the scheme from the state with the acceleration of that state, so a run
            continued from it differs from an uninterrupted one by ~1e-6 b0. Fixed steps only: ``tol``, the Floquet
            and continuation analyses and the stability map refuse it. Left out of :meth:`to_dict` at False.
    """

    pressure_angle_deg: float = 20.0
    J_p: float = 0.041
    J_g: float = 0.079
    m_p: float = 1.53
    m_g: float = 3.01
    k_p: float = 2e8
    k_g: float = 2e8
    k_m0: float = 7.74e8
    z_p: int = 55
    z_g: int = 75
    module: float = 2e-3
    e_m1: float = 1e-5
    phi_e: float = 0.0
    kappa: float = 0.2
    phi_k: float = 0.0
    b_c: float = 2e-5
    T_p: float = 22.0
    T_g: float = 30.0
    xi_m: float = 0.07
    xi_p: float = 0.07
    xi_g: float = 0.07
    b0: float | None = None
    gravity: float = 0.0
    friction: float = 0.0
    stiffness_harmonics: tuple[tuple[float, float], ...] = ()
    te_harmonics: tuple[tuple[float, float], ...] = ()
    T_p1: float = 0.0
    T_g1: float = 0.0
    phi_Tp: float = 0.0
    phi_Tg: float = 0.0
    torque_order: float = 1.0
    backlash_law: str = "paper"
    mesh_force_direction: str = "line_of_action"
    newmark_beta: float = NEWMARK_BETA
    velocity_correction: bool = False
    _consts: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._set_harmonics()
        for f in fields(self):
            if f.name.startswith("_") or f.name in (
                "stiffness_harmonics",
                "te_harmonics",
                "backlash_law",
                "mesh_force_direction",
                "velocity_correction",
            ):
                continue
            v = getattr(self, f.name)
            if f.name == "b0" and v is None:
                continue
            if f.name in ("z_p", "z_g"):
                lo, hi = TEETH_RANGE
                if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                    raise ValueError(f"GearParams.{f.name} must be an integer in [{lo}, {hi}], got {v!r}")
                object.__setattr__(self, f.name, int(v))
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"GearParams.{f.name} must be a real number in {_range_text(f.name)}, got {v!r}")
            if f.name == "newmark_beta" and abs(float(v) - FOX_GOODWIN_BETA) <= BETA_SNAP:
                v = FOX_GOODWIN_BETA  # a rounded 1/12 (0.0833333) means Fox-Goodwin
            object.__setattr__(self, f.name, float(v))
            _check_range(f.name, float(v))
        if not isinstance(self.backlash_law, str) or self.backlash_law not in BACKLASH_LAWS:
            raise ValueError(f"GearParams.backlash_law must be one of {BACKLASH_LAWS}, got {self.backlash_law!r}")
        if not isinstance(self.mesh_force_direction, str) or self.mesh_force_direction not in FORCE_DIRECTIONS:
            raise ValueError(
                f"GearParams.mesh_force_direction must be one of {FORCE_DIRECTIONS}, got {self.mesh_force_direction!r}"
            )
        if not isinstance(self.velocity_correction, (bool, np.bool_)):
            raise ValueError(f"GearParams.velocity_correction must be True or False, got {self.velocity_correction!r}")
        object.__setattr__(self, "velocity_correction", bool(self.velocity_correction))
        if self.velocity_correction and self.newmark_beta != FOX_GOODWIN_BETA:
            raise ValueError(
                "GearParams.velocity_correction takes Fox-Goodwin's beta: newmark_beta must be 1/12 "
                f"({FOX_GOODWIN_BETA!r}), got {self.newmark_beta!r}"
            )
        if len(self.te_harmonics) > 1 and self.friction > 0.0:
            raise ValueError(
                "GearParams.friction must be 0 when te_harmonics has more than one harmonic "
                f"(got friction={self.friction!r} and {len(self.te_harmonics)} TE harmonics)"
            )
        consts = self._build_consts()
        if not np.all(np.isfinite(consts)):
            raise ValueError(f"GearParams give non-finite dimensionless constants: {self!r}")
        object.__setattr__(self, "_consts", consts)

    def _set_harmonics(self) -> None:
        """Validate the harmonic fields, store them as tuples of float pairs and copy their first
        harmonic into kappa, phi_k / e_m1, phi_e."""
        for name, amp_max in (("stiffness_harmonics", 1.0), ("te_harmonics", 1e-2)):
            h = _harmonic_pairs(name, getattr(self, name), amp_max)
            object.__setattr__(self, name, h)
            if h:
                first = ("kappa", "phi_k") if name == "stiffness_harmonics" else ("e_m1", "phi_e")
                object.__setattr__(self, first[0], h[0][0])
                object.__setattr__(self, first[1], h[0][1])
        if len(self.stiffness_harmonics) > 1:
            phi = np.linspace(0.0, 2.0 * math.pi, 256 * len(self.stiffness_harmonics), endpoint=False)
            low = float(np.min(stiffness_factor(phi, self.stiffness_harmonics)))
            if not low > 0.0:
                raise ValueError(
                    f"GearParams.stiffness_harmonics must keep the stiffness positive: "
                    f"1 + sum kappa_n cos(n phi + phi_n) reaches {low:.4g}"
                )

    # ---------------------------------------------------------------- derived quantities (SI)
    @property
    def alpha0(self) -> float:
        """Nominal pressure angle [rad]."""
        return math.radians(self.pressure_angle_deg)

    @property
    def r_bp(self) -> float:
        """Pinion base radius [m] (A1)."""
        return self.module * self.z_p * math.cos(self.alpha0) / 2.0

    @property
    def r_bg(self) -> float:
        """Gear base radius [m] (A1)."""
        return self.module * self.z_g * math.cos(self.alpha0) / 2.0

    @property
    def a0(self) -> float:
        """Standard centre distance [m] (A2)."""
        return self.module * (self.z_p + self.z_g) / 2.0

    @property
    def length_scale(self) -> float:
        """b0 [m]: the length scale of the dimensionless coordinates."""
        return self.b_c if self.b0 is None else float(self.b0)

    @property
    def m_e(self) -> float:
        """Equivalent mass of the torsional mesh DOF [kg]."""
        return self.J_p * self.J_g / (self.J_p * self.r_bg**2 + self.J_g * self.r_bp**2)

    @property
    def omega_n(self) -> float:
        """Reference natural frequency sqrt(k_m0/m_e) [rad/s]."""
        return math.sqrt(self.k_m0 / self.m_e)

    @property
    def c_m(self) -> float:
        """Mesh damping coefficient [N s/m] (A5)."""
        return 2.0 * self.xi_m * math.sqrt(self.k_m0 * self.m_e)

    @property
    def c_p(self) -> float:
        """Pinion bearing damping coefficient [N s/m] (A5)."""
        return 2.0 * self.xi_p * math.sqrt(self.k_p * self.m_p)

    @property
    def c_g(self) -> float:
        """Gear bearing damping coefficient [N s/m] (A5)."""
        return 2.0 * self.xi_g * math.sqrt(self.k_g * self.m_g)

    @property
    def torque_fluctuates(self) -> bool:
        """True if either torque fluctuates (``T_p1`` or ``T_g1`` > 0)."""
        return self.T_p1 > 0.0 or self.T_g1 > 0.0

    def consts_at_period(self, periods: int) -> np.ndarray:
        """:attr:`consts` for an interval that starts ``periods`` mesh periods after t = 0: the
        torque fluctuation's phases advanced by 2 pi nu periods (the kernels count the mesh phase
        from 0 in every interval). The constants themselves if the torque does not fluctuate."""
        if not self.torque_fluctuates or periods == 0:
            return self._consts
        c = self._consts.copy()
        for nu, ph in ((C_NU_P, C_PH_TP), (C_NU_G, C_PH_TG)):
            c[ph] = math.fmod(c[ph] + 2.0 * math.pi * math.fmod(c[nu] * periods, 1.0), 2.0 * math.pi)
        c.setflags(write=False)
        return c

    @property
    def static_mesh_load(self) -> float:
        """Static mesh force m_e (r_bp T_p/J_p + r_bg T_g/J_g) [N]."""
        return self.m_e * (self.r_bp * self.T_p / self.J_p + self.r_bg * self.T_g / self.J_g)

    def mesh_frequency_hz(self, omega: float) -> float:
        """Mesh frequency [Hz] of the dimensionless meshing frequency ``omega``."""
        return omega * self.omega_n / (2.0 * math.pi)

    def pinion_rpm(self, omega: float) -> float:
        """Pinion speed [rev/min] at dimensionless meshing frequency ``omega``."""
        return 60.0 * self.mesh_frequency_hz(omega) / self.z_p

    # ---------------------------------------------------------------- dimensionless constants
    def _build_consts(self) -> np.ndarray:
        b0 = self.length_scale
        me = self.m_e
        c = np.zeros(N_CONSTS)
        c[C_EPS_P] = self.m_p / me
        c[C_EPS_G] = self.m_g / me
        c[C_SIG_P] = math.sqrt((self.k_p / self.k_m0) / c[C_EPS_P])
        c[C_SIG_G] = math.sqrt((self.k_g / self.k_m0) / c[C_EPS_G])
        c[C_XI_BP] = self.xi_p
        c[C_XI_BG] = self.xi_g
        c[C_XI_M] = self.xi_m
        c[C_KAPPA] = self.kappa
        c[C_PHI_K] = self.phi_k
        c[C_E1] = self.e_m1 / b0
        c[C_PHI_E] = self.phi_e
        c[C_FS] = self.static_mesh_load / (self.k_m0 * b0)
        c[C_A0] = self.a0 / b0
        c[C_R] = (self.r_bp + self.r_bg) / b0
        c[C_BC] = self.b_c / b0
        c[C_ALPHA0] = self.alpha0
        c[C_GP] = self.m_p * self.gravity / (self.k_m0 * b0)
        c[C_GG] = self.m_g * self.gravity / (self.k_m0 * b0)
        c[C_SIN_A0] = math.sin(self.alpha0)
        c[C_COS_A0] = math.cos(self.alpha0)
        c[C_MU] = self.friction
        c[C_BETA] = self.newmark_beta
        c[C_VC] = 1.0 if self.velocity_correction else 0.0
        nk = len(self.stiffness_harmonics) if len(self.stiffness_harmonics) > 1 else 0
        ne = len(self.te_harmonics) if len(self.te_harmonics) > 1 else 0
        c[C_NK] = nk
        c[C_NE] = ne
        if self.torque_fluctuates:
            c[C_NT] = 1.0
            c[C_TP1] = me * self.r_bp * self.T_p1 / (self.J_p * self.k_m0 * b0)
            c[C_TG1] = me * self.r_bg * self.T_g1 / (self.J_g * self.k_m0 * b0)
            c[C_NU_P] = self.torque_order / self.z_p
            c[C_NU_G] = self.torque_order / self.z_g
            c[C_PH_TP] = self.phi_Tp
            c[C_PH_TG] = self.phi_Tg
        # the tail holds (a cos(phase), a sin(phase)) per harmonic (kernels.mesh.excitation)
        tail = [v for a, ph in self.stiffness_harmonics[:nk] for v in (a * math.cos(ph), a * math.sin(ph))]
        tail += [v for a, ph in self.te_harmonics[:ne] for v in (a / b0 * math.cos(ph), a / b0 * math.sin(ph))]
        if ne:
            c[C_E1] = 1.0  # the series carries the amplitudes (kernels.mesh.excitation)
        c = np.concatenate([c, np.asarray(tail, dtype=float)])
        c.setflags(write=False)
        return c

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle by the SI fields and rebuild (and revalidate) on load, so that the constants
        come back read-only like the original's: numba compiles one specialisation per array
        flag, and a worker process that received writable constants would otherwise compile
        the kernels again instead of loading them from the disk cache."""
        return (self.__class__, tuple(getattr(self, f.name) for f in fields(self) if f.init))

    @property
    def consts(self) -> np.ndarray:
        """Read-only float64 array of dimensionless constants (layout: the ``C_*`` indices)."""
        return self._consts

    def dimensionless(self) -> dict[str, float]:
        """Named dimensionless constants (MODEL.md sec. 3-4), for reports and tests."""
        c = self._consts
        return {
            "eps_p": c[C_EPS_P],
            "eps_g": c[C_EPS_G],
            "lam_p": self.k_p / self.k_m0,
            "lam_g": self.k_g / self.k_m0,
            "sigma_p": c[C_SIG_P],
            "sigma_g": c[C_SIG_G],
            "E1": self.e_m1 / self.length_scale,  # first TE harmonic (c[C_E1] is 1 under a TE series)
            "F_s": c[C_FS],
            "A0": c[C_A0],
            "R": c[C_R],
            "B_c": c[C_BC],
            "xi_m": c[C_XI_M],
            "xi_p": c[C_XI_BP],
            "xi_g": c[C_XI_BG],
            "kappa": c[C_KAPPA],
        }

    def replace(self, **changes: Any) -> GearParams:
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the SI inputs (JSON-serialisable). The harmonic fields appear only when
        set, as lists of [amplitude, phase], and the torque fluctuation and backlash law only away
        from their defaults, so the dict of the paper's single-cosine parameters is unchanged."""
        out: dict[str, Any] = {}
        for f in fields(self):
            if f.name.startswith("_"):
                continue
            v = getattr(self, f.name)
            if f.name in ("stiffness_harmonics", "te_harmonics"):
                if not v:
                    continue
                v = [list(pair) for pair in v]
            if f.name in EXTENSION_DEFAULTS and v == EXTENSION_DEFAULTS[f.name]:
                continue
            out[f.name] = v
        return out

    @classmethod
    def from_pair(cls, pair: Any, n_harmonics: int = 16, **changes: Any) -> GearParams:
        """Parameters of a gear geometry (:class:`gear_env.sim.geometry.SpurPair`): module, tooth
        numbers, pressure angle, the mean mesh stiffness ``k_m0`` and ``n_harmonics`` harmonics
        of the mesh stiffness from the teeth, the masses and polar inertias of the gear bodies;
        every other field from the defaults or ``changes`` (which also override these)."""
        from .geometry import SpurPair

        if not isinstance(pair, SpurPair):
            raise ValueError(f"GearParams.from_pair takes a gear_env.sim.geometry.SpurPair, got {type(pair).__name__}")
        if pair.crack is not None:
            raise ValueError(
                "GearParams.from_pair: a cracked pair's stiffness repeats once per revolution, not per mesh "
                "period; the kernels' excitation is periodic in the mesh phase (use the healthy pair)"
            )
        k0, kap, ph = pair.stiffness_harmonics(n_harmonics)
        values: dict[str, Any] = {
            "pressure_angle_deg": pair.pressure_angle_deg,
            "module": pair.module,
            "z_p": pair.teeth[0],
            "z_g": pair.teeth[1],
            "k_m0": k0,
            "stiffness_harmonics": tuple(zip(kap.tolist(), ph.tolist())),
            "m_p": pair.pinion.mass,
            "m_g": pair.gear.mass,
            "J_p": pair.pinion.polar_inertia,
            "J_g": pair.gear.polar_inertia,
        }
        values.update(changes)
        return cls(**values)

    def with_te_scale(self, factor: float) -> GearParams:
        """A copy with the whole static transmission error (``e_m1`` or every ``te_harmonics``
        amplitude) multiplied by ``factor`` (>= 0)."""
        if not (math.isfinite(factor) and factor >= 0.0):
            raise ValueError(f"TE scale factor must be finite and >= 0, got {factor!r}")
        if self.te_harmonics:
            return self.replace(te_harmonics=tuple((a * factor, ph) for a, ph in self.te_harmonics))
        return self.replace(e_m1=self.e_m1 * factor)

    def with_stiffness_scale(self, factor: float) -> GearParams:
        """A copy with the mesh-stiffness variation (``kappa``, or every ``stiffness_harmonics``
        amplitude) multiplied by ``factor`` (>= 0), capped so that the stiffness stays positive:
        kappa at 0.99, a series where its minimum would fall below 1 % of k_m0."""
        if not (math.isfinite(factor) and factor >= 0.0):
            raise ValueError(f"stiffness scale factor must be finite and >= 0, got {factor!r}")
        if len(self.stiffness_harmonics) <= 1:
            return self.replace(kappa=min(self.kappa * factor, 0.99), stiffness_harmonics=())
        h = self.stiffness_harmonics
        phi = np.linspace(0.0, 2.0 * math.pi, 256 * len(h), endpoint=False)
        low = float(np.min(stiffness_factor(phi, h))) - 1.0  # the most negative variation
        if low < 0.0:
            factor = min(factor, 0.99 / -low)
        return self.replace(stiffness_harmonics=tuple((a * factor, ph) for a, ph in h))

    def stiffness_factor(self, phi: Any) -> np.ndarray:
        """k_m(phi) / k_m0 at mesh phase ``phi`` [rad] (array), the kernels' stiffness factor."""
        return stiffness_factor(np.asarray(phi, float), self.stiffness_harmonics or ((self.kappa, self.phi_k),))

    def transmission_error(self, phi: Any) -> tuple[np.ndarray, np.ndarray]:
        """(e(phi) [m], de/dphi [m/rad]) of the static transmission error at mesh phase ``phi`` [rad]."""
        h = self.te_harmonics or ((self.e_m1, self.phi_e),)
        phi = np.asarray(phi, float)
        e = np.zeros_like(phi)
        de = np.zeros_like(phi)
        for n, (a, ph) in enumerate(h, start=1):
            e += a * np.cos(n * phi + ph)
            de -= n * a * np.sin(n * phi + ph)
        return e, de

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GearParams:
        """Build from a dict; unknown keys raise ``ValueError`` listing the valid ones."""
        valid = [f.name for f in fields(cls) if not f.name.startswith("_")]
        unknown = sorted(set(data) - set(valid))
        if unknown:
            raise ValueError(f"unknown GearParams field(s) {unknown}; valid fields: {valid}")
        return cls(**data)


def stack_consts(rows: list[np.ndarray]) -> np.ndarray:
    """Constants of several systems as one (n, width) float64 array for the batch kernels: rows
    with shorter harmonic tails are padded with zeros (their ``C_NK``, ``C_NE`` say how much of the
    tail the kernels read), so single-cosine rows are unchanged."""
    width = max(len(r) for r in rows)
    out = np.zeros((len(rows), width))
    for i, r in enumerate(rows):
        out[i, : len(r)] = r
    return out


def stiffness_factor(phi: np.ndarray, harmonics: tuple[tuple[float, float], ...]) -> np.ndarray:
    """1 + sum_n kappa_n cos(n phi + phi_n) for ``harmonics`` = ((kappa_1, phi_1), ...), phi [rad]."""
    out = np.ones_like(np.asarray(phi, float))
    for n, (a, ph) in enumerate(harmonics, start=1):
        out = out + a * np.cos(n * phi + ph)
    return out


def harmonics_from_samples(samples: Any, n_harmonics: int, relative: bool = False) -> tuple[float, tuple]:
    """Fourier series of one period of a uniformly sampled periodic signal (a measured TE or
    stiffness): returns (mean, ((a_1, phi_1), ..., (a_N, phi_N))) with
    signal(phi) = mean + sum_n a_n cos(n phi + phi_n), phi = 2 pi j / len(samples) at sample j.

    ``relative=True`` divides the amplitudes by the mean (the form of ``stiffness_harmonics``:
    pass ``k_m0=mean``); otherwise they keep the samples' unit (``te_harmonics`` takes metres;
    a TE's mean is a constant offset the static equilibrium absorbs and is dropped).
    ``n_harmonics`` must be below half the number of samples.
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise ValueError("samples must be a 1-D array of finite values (one period, uniformly sampled)")
    if isinstance(n_harmonics, bool) or not isinstance(n_harmonics, (int, np.integer)):
        raise ValueError(f"n_harmonics must be an integer in [1, {MAX_HARMONICS}], got {n_harmonics!r}")
    if not 1 <= n_harmonics <= MAX_HARMONICS or 2 * n_harmonics >= len(x):
        raise ValueError(
            f"n_harmonics must be in [1, {MAX_HARMONICS}] and below half the {len(x)} samples, got {n_harmonics}"
        )
    X = np.fft.rfft(x) / len(x)
    mean = float(X[0].real)
    amp = 2.0 * np.abs(X[1 : n_harmonics + 1])
    if relative:
        if not mean > 0:
            raise ValueError(f"relative harmonics need a positive mean, got {mean:g}")
        amp = amp / mean
    ph = np.angle(X[1 : n_harmonics + 1])
    return mean, tuple((float(a), float(p)) for a, p in zip(amp, ph))


def _harmonic_pairs(name: str, value: Any, amp_max: float) -> tuple[tuple[float, float], ...]:
    """Validate a harmonic field: a sequence of at most MAX_HARMONICS (amplitude, phase) pairs."""
    try:
        rows = [tuple(r) for r in value]
    except TypeError:
        raise ValueError(f"GearParams.{name} must be a sequence of (amplitude, phase) pairs, got {value!r}") from None
    if len(rows) > MAX_HARMONICS:
        raise ValueError(f"GearParams.{name} takes at most {MAX_HARMONICS} harmonics, got {len(rows)}")
    out = []
    for i, r in enumerate(rows):
        ok = len(r) == 2 and all(
            not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)
            for v in r
        )
        if not ok or not 0.0 <= r[0] <= amp_max or abs(r[1]) > 1e3:
            raise ValueError(
                f"GearParams.{name}[{i}] must be (amplitude in [0, {amp_max:g}], phase in [-1e3, 1e3] rad), got {r!r}"
            )
        out.append((float(r[0]), float(r[1])))
    return tuple(out)


def _checked_init(init: Any) -> Any:
    """Wrap the dataclass ``__init__`` so that unknown or surplus arguments raise ``ValueError``
    (naming them and the valid fields) instead of Python's ``TypeError``, as every entry point does."""
    import functools

    @functools.wraps(init)
    def __init__(self: GearParams, *args: Any, **kwargs: Any) -> None:
        valid = [f.name for f in fields(GearParams) if f.init]
        unknown = sorted(set(kwargs) - set(valid))
        if unknown:
            raise ValueError(f"unknown GearParams field(s) {unknown}; valid fields: {valid}")
        if len(args) > len(valid):
            raise ValueError(f"GearParams takes at most {len(valid)} positional values, got {len(args)}")
        twice = sorted(set(valid[: len(args)]) & set(kwargs))
        if twice:
            raise ValueError(f"GearParams field(s) {twice} given both by position and by name")
        init(self, *args, **kwargs)

    return __init__


GearParams.__init__ = _checked_init(GearParams.__init__)  # type: ignore[method-assign]
