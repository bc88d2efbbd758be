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
N_CONSTS = 21

MODELS = ("constant", "dynamic")


def model_code(model: str) -> int:
    """Return the kernel code of a backlash model name (0 = constant, 1 = dynamic)."""
    if not isinstance(model, str) or model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    return MODELS.index(model)


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
}
TEETH_RANGE = (5, 1000)


def _range_text(lo: float, hi: float, lo_in: bool, hi_in: bool) -> str:
    return f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


def _check_range(name: str, value: float) -> None:
    lo, hi, lo_in, hi_in = BOUNDS[name]
    ok = math.isfinite(value) and (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)
    if not ok:
        raise ValueError(f"GearParams.{name} must be in {_range_text(lo, hi, lo_in, hi_in)}, got {value!r}")


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
    _consts: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name.startswith("_"):
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
                flo, fhi, lo_in, hi_in = BOUNDS[f.name]
                raise ValueError(
                    f"GearParams.{f.name} must be a real number in {_range_text(flo, fhi, lo_in, hi_in)}, got {v!r}"
                )
            object.__setattr__(self, f.name, float(v))
            _check_range(f.name, float(v))
        consts = self._build_consts()
        if not np.all(np.isfinite(consts)):
            raise ValueError(f"GearParams give non-finite dimensionless constants: {self!r}")
        object.__setattr__(self, "_consts", consts)

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
            "E1": c[C_E1],
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
        """Plain dict of the SI inputs (JSON-serialisable)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if not f.name.startswith("_")}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GearParams:
        """Build from a dict; unknown keys raise ``ValueError`` listing the valid ones."""
        valid = [f.name for f in fields(cls) if not f.name.startswith("_")]
        unknown = sorted(set(data) - set(valid))
        if unknown:
            raise ValueError(f"unknown GearParams field(s) {unknown}; valid fields: {valid}")
        return cls(**data)


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
