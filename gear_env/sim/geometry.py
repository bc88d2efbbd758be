"""Spur gear geometry and the time-varying mesh stiffness computed from the teeth.

The layer below :mod:`gear_env.sim.params`: NumPy only, no kernel. A :class:`SpurGear` is a standard
involute spur gear (rack-generated, full-fillet transition) on a solid body with a bore; a
:class:`SpurPair` is two of them at the standard centre distance. From the geometry:

* radii, contact ratio, masses and polar inertias of the gear bodies (hollow cylinders of the
  pitch diameter, as ROSS does);
* the single-tooth stiffness along the path of contact by the potential-energy method: bending,
  shear and axial compression of the tooth (integrated over the fillet transition curve and the
  involute), the fillet-foundation (gear body) term of Sainsot, Velex and Duverger (2004) and the
  Hertzian contact stiffness (Yang and Lin's constant pi E b / (4 (1 - nu^2)));
* the mesh stiffness over one mesh period, one or two tooth pairs in contact (phase 0 = start of
  contact of a tooth pair, so the double-contact zone comes first);
* ISO 6336-1 (method B) single-pair stiffness c' and mesh stiffness c_gamma_alpha beside it;
* an optional root crack on one tooth of the pinion or the gear (:class:`ToothCrack`).

The tooth model, its integration limits and the kinematics along the path of contact follow ROSS
(petrobras/ross, ``ross/multi_rotor/gear_element.py`` ``GearElementTVMS`` and ``mesh.py``
``Mesh``), the independent code this module is validated against (docs/VALIDATION.md): the
contact point moves linearly in the pressure angle of the driving tooth from its form-circle
angle (``start_angle``) to its tip angle over ``contact_ratio`` mesh periods, and the driven
tooth's pressure angle moves back from its tip angle at the gear ratio. ROSS integrates each
compliance with adaptive quadrature point by point (~8 s for 1000 phases); here every integral
is a fixed Gauss-Legendre rule evaluated for all phases at once (a few milliseconds).

Everything is SI: lengths [m], moduli [Pa], density [kg/m^3], stiffness [N/m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Gauss-Legendre nodes per integral (the integrands are smooth; 48 nodes agree with SciPy's
# adaptive quad to ~1e-12 relative on the ROSS pair, tests/test_geometry.py)
N_GAUSS = 48
_GL_T, _GL_W = np.polynomial.legendre.leggauss(N_GAUSS)

# Sainsot et al. (2004) fillet-foundation coefficients: A/theta_f^2 + B h^2 + C h/theta_f +
# D/theta_f + E h + F for L, M, P, Q, and the ranges over which they were fitted
_SAINSOT = (
    (-5.574e-5, -1.9986e-3, -2.3015e-4, 4.7702e-3, 0.0271, 6.8045),
    (60.111e-5, 28.100e-3, -83.431e-4, -9.9256e-3, 0.1624, 0.9086),
    (-50.952e-5, 185.50e-3, 0.0538e-4, 53.300e-3, 0.2895, 0.9236),
    (-6.2042e-5, 9.0889e-3, -4.0964e-4, 7.8297e-3, -0.1472, 0.6904),
)
_SAINSOT_RANGE = ((6.82, 6.94), (1.08, 3.29), (2.56, 13.47), (0.141, 0.62))

# ISO 6336-1:2006/2019 method B, theoretical single stiffness q' [mm um / N] coefficients C1..C9
_ISO_C = (0.04723, 0.15551, 0.25791, -0.00635, -0.11654, -0.00193, -0.24188, 0.00529, 0.00182)
_ISO_E_STEEL = 206e9  # [Pa] the Young's modulus of ISO 6336's steel reference

_BOUNDS: dict[str, tuple[float, float]] = {
    "module": (1e-4, 0.1),
    "face_width": (1e-4, 2.0),
    "pressure_angle_deg": (10.0, 35.0),
    "youngs_modulus": (1e9, 1e12),
    "poisson": (0.0, 0.5),
    "density": (100.0, 30000.0),
    "addendum_coeff": (0.5, 1.5),
    "tip_clearance_coeff": (0.05, 0.6),
}
TEETH_RANGE = (12, 1000)  # below 12 teeth a standard rack undercuts the involute (not modelled)


def involute(angle: Any) -> Any:
    """inv(alpha) = tan(alpha) - alpha [rad], element-wise."""
    return np.tan(angle) - angle


def _real(owner: str, name: str, value: Any) -> float:
    lo, hi = _BOUNDS[name]
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{owner}.{name} must be a real number in [{lo:g}, {hi:g}], got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{owner}.{name} must be in [{lo:g}, {hi:g}], got {value!r}")
    return v


def _teeth(owner: str, name: str, value: Any) -> int:
    lo, hi = TEETH_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{owner}.{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


@dataclass(frozen=True)
class ToothCrack:
    """A straight root crack on one tooth (tooth 0, the pair that enters contact at phase 0).

    The crack starts on the loaded (tension) side where the involute meets the fillet, and runs
    into the tooth at ``angle_deg`` above the normal to the tooth centre
    line, to ``depth``. Sections of the tooth below the crack tip lose the material beyond the
    tip: area and second moment become those of the section from the far flank to the crack
    tip (Tian 2004; Chen and Shao 2011 case 1; crack parameters as in Ma et al. 2014). The
    fillet-foundation term is kept healthy. Limits: the crack tip stays on the loaded side of
    the centre line (``depth cos(angle) <`` the tooth's half-thickness there, checked by the pair).

    Attributes:
        depth: crack length q [m], > 0.
        angle_deg: crack angle nu [deg] in [0, 75].
        on: ``"pinion"`` or ``"gear"``: which gear's tooth 0 is cracked.
    """

    depth: float
    angle_deg: float = 45.0
    on: str = "pinion"

    def __post_init__(self) -> None:
        if isinstance(self.depth, bool) or not isinstance(self.depth, (int, float, np.integer, np.floating)):
            raise ValueError(f"ToothCrack.depth must be a real number in (0, 0.05] m, got {self.depth!r}")
        if not (math.isfinite(float(self.depth)) and 0.0 < float(self.depth) <= 0.05):
            raise ValueError(f"ToothCrack.depth must be in (0, 0.05] m, got {self.depth!r}")
        a = self.angle_deg
        if isinstance(a, bool) or not isinstance(a, (int, float, np.integer, np.floating)) or not 0.0 <= a <= 75.0:
            raise ValueError(f"ToothCrack.angle_deg must be in [0, 75], got {a!r}")
        if self.on not in ("pinion", "gear"):
            raise ValueError(f"ToothCrack.on must be 'pinion' or 'gear', got {self.on!r}")
        object.__setattr__(self, "depth", float(self.depth))
        object.__setattr__(self, "angle_deg", float(a))


@dataclass(frozen=True)
class SpurGear:
    """One standard involute spur gear on a solid body with a central bore (SI units).

    Attributes:
        module: module m [m], in [1e-4, 0.1].
        teeth: number of teeth z, integer in [12, 1000].
        face_width: face width b [m], in [1e-4, 2].
        bore: bore diameter [m], in (0, root diameter).
        pressure_angle_deg: pressure angle alpha [deg], in [10, 35].
        youngs_modulus: E [Pa]; poisson: nu [-]; density: rho [kg/m^3].
        addendum_coeff: addendum h_a* (addendum = h_a* m), in [0.5, 1.5].
        tip_clearance_coeff: tip clearance c* (dedendum = (h_a* + c*) m), in [0.05, 0.6].
    """

    module: float
    teeth: int
    face_width: float
    bore: float
    pressure_angle_deg: float = 20.0
    youngs_modulus: float = 206e9
    poisson: float = 0.3
    density: float = 7810.0
    addendum_coeff: float = 1.0
    tip_clearance_coeff: float = 0.25
    _g: dict[str, float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        o = "SpurGear"
        for name in _BOUNDS:
            object.__setattr__(self, name, _real(o, name, getattr(self, name)))
        object.__setattr__(self, "teeth", _teeth(o, "teeth", self.teeth))
        g = _tooth_geometry(self.module, self.teeth, math.radians(self.pressure_angle_deg),
                            self.addendum_coeff, self.tip_clearance_coeff)  # fmt: skip
        b = self.bore
        if isinstance(b, bool) or not isinstance(b, (int, float, np.integer, np.floating)):
            raise ValueError(f"{o}.bore must be a real number in (0, {2 * g['root']:.6g}) m, got {b!r}")
        if not (math.isfinite(float(b)) and 0.0 < float(b) < 2.0 * g["root"]):
            raise ValueError(f"{o}.bore must be in (0, {2 * g['root']:.6g}) m (the root diameter), got {b!r}")
        object.__setattr__(self, "bore", float(b))
        if g["start_angle"] >= g["tip_angle"] or g["a1"] <= 0.0:
            raise ValueError(f"{o}: addendum_coeff and tip_clearance_coeff give no involute flank")
        object.__setattr__(self, "_g", g)

    # ------------------------------------------------------------------ radii and angles
    @property
    def alpha(self) -> float:
        """Pressure angle [rad]."""
        return math.radians(self.pressure_angle_deg)

    @property
    def pitch_radius(self) -> float:
        """Reference (pitch) radius m z / 2 [m]."""
        return self._g["pitch"]

    @property
    def base_radius(self) -> float:
        """Base radius r_p cos(alpha) [m]."""
        return self._g["base"]

    @property
    def tip_radius(self) -> float:
        """Tip (addendum) radius r_p + h_a* m [m]."""
        return self._g["tip"]

    @property
    def root_radius(self) -> float:
        """Root radius r_p - (h_a* + c*) m [m]."""
        return self._g["root"]

    @property
    def form_radius(self) -> float:
        """Radius where the rack-generated involute starts (the fillet above it) [m]."""
        return self._g["form"]

    @property
    def tip_angle(self) -> float:
        """Pressure angle of the involute at the tip circle [rad]."""
        return self._g["tip_angle"]

    @property
    def start_angle(self) -> float:
        """Pressure angle of the involute at the form circle [rad] (ROSS's ``start_point``)."""
        return self._g["start_angle"]

    # ------------------------------------------------------------------ body
    @property
    def mass(self) -> float:
        """Mass of the body, a hollow cylinder of the pitch diameter and the bore [kg]."""
        d = 2.0 * self.pitch_radius
        return self.density * math.pi * self.face_width * (d * d - self.bore**2) / 4.0

    @property
    def polar_inertia(self) -> float:
        """Polar moment of inertia m (d^2 + d_bore^2) / 8 of the body [kg m^2]."""
        d = 2.0 * self.pitch_radius
        return self.mass * (d * d + self.bore**2) / 8.0

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) [Pa]."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson))

    # ------------------------------------------------------------------ tooth compliance
    def _curves(self, tau: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, ...]:
        g = self._g
        rb, tb = g["base"], g["theta_b"]
        xi = rb * ((tau + tb) * np.cos(tau) - np.sin(tau))
        yi = rb * ((tau + tb) * np.sin(tau) + np.cos(tau))
        a1, b1, rp, rr = g["a1"], g["b1"], g["pitch"], g["rho"]
        tg = np.tan(gamma)
        ph = (a1 / tg + b1) / rp
        lever = a1 / np.sin(gamma) + rr
        xt = rp * np.sin(ph) - lever * np.cos(gamma - ph)
        yt = rp * np.cos(ph) - lever * np.sin(gamma - ph)
        dyt = (
            a1 * np.sin(ph) * (1.0 + tg**2) / tg**2
            + a1 * np.cos(gamma) / np.sin(gamma) ** 2 * np.sin(gamma - ph)
            - lever * np.cos(gamma - ph) * (1.0 + a1 * (1.0 + tg**2) / (rp * tg**2))
        )
        dyi = rb * (tau + tb) * np.cos(tau)
        return xi, yi, dyi, xt, yt, dyt

    def tooth_compliance(self, contact_angle: Any, crack: ToothCrack | None = None) -> dict[str, np.ndarray]:
        """Compliances [m/N] of one tooth loaded at the involute point of pressure angle
        ``contact_angle`` [rad] (array): ``bending``, ``shear``, ``axial``, ``foundation``.

        Potential-energy method (Ma et al. 2014's formulation, ROSS's integration limits): each
        of bending, shear and axial compression is an integral over the tooth height, from the
        root along the fillet transition curve and then along the involute up to the load point;
        the foundation term is Sainsot et al. (2004). The load acts along the line of action at
        the angle beta = alpha + inv(alpha) - theta_b to the tooth's normal section. ``crack``
        (optional) weakens the sections below its tip (:class:`ToothCrack`).
        """
        g = self._g
        E, G, w = self.youngs_modulus, self.shear_modulus, self.face_width
        alpha = np.asarray(contact_angle, dtype=float)
        beta = alpha + involute(alpha) - g["theta_b"]
        cb, sb = np.cos(beta), np.sin(beta)
        tau_c = g["tau_c"]
        # involute: nodes between tau_c and beta for every phase (..., N_GAUSS)
        half = 0.5 * (beta - tau_c)[..., None]
        tau = tau_c + half * (_GL_T + 1.0)
        gam = (math.pi / 2 + g["alpha"]) / 2 + (g["alpha"] - math.pi / 2) / 2 * _GL_T  # fillet, pi/2 -> alpha
        xi, yi, dyi, xt, yt, dyt = self._curves(tau, gam)
        wi = _GL_W * half * dyi  # dy of each involute node
        wt = _GL_W * ((g["alpha"] - math.pi / 2) / 2) * dyt
        xo = g["base"] * ((beta + g["theta_b"]) * cb - sb)
        yo = g["base"] * ((beta + g["theta_b"]) * sb + cb)
        # section widths (full thickness 2x, or far flank to crack tip)
        ti, tt = 2.0 * xi, 2.0 * xt
        if crack is not None:
            hq, ytip = self._crack_tip(crack)
            ti = np.where(yi <= ytip, np.minimum(ti, xi + hq), ti)
            tt = np.where(yt <= ytip, np.minimum(tt, xt + hq), tt)
        area_i, area_t = ti * w, tt * w
        inert_i, inert_t = ti**3 * w / 12.0, tt**3 * w / 12.0
        cb_, sb_, xo_, yo_ = cb[..., None], sb[..., None], xo[..., None], yo[..., None]
        bend = ((cb_ * (yo_ - yi) - xo_ * sb_) ** 2 / (E * inert_i) * wi).sum(-1) + (
            (cb_ * (yo_ - yt) - xo_ * sb_) ** 2 / (E * inert_t) * wt
        ).sum(-1)
        shear = 1.2 * cb**2 / G * ((wi / area_i).sum(-1) + (wt / area_t).sum(-1))
        axial = sb**2 / E * ((wi / area_i).sum(-1) + (wt / area_t).sum(-1))
        h = g["root"] / (0.5 * self.bore)
        L, M, P, Q = (_sainsot(c, g["theta_f"], h) for c in _SAINSOT)
        sf = 2.0 * g["root"] * g["theta_f"]
        u = yo - g["root"]
        found = cb**2 / (E * w) * (L * (u / sf) ** 2 + M * u / sf + P * (1.0 + Q * np.tan(beta) ** 2))
        return {"bending": bend, "shear": shear, "axial": axial, "foundation": found}

    def foundation_coefficients_in_range(self) -> bool:
        """Whether Sainsot's L, M, P, Q lie inside the ranges they were fitted on (else the
        foundation term is an extrapolation; ROSS warns in the same case)."""
        h = self.root_radius / (0.5 * self.bore)
        vals = [_sainsot(c, self._g["theta_f"], h) for c in _SAINSOT]
        return all(lo <= v <= hi for v, (lo, hi) in zip(vals, _SAINSOT_RANGE))

    def tooth_stiffness(self, contact_angle: Any, crack: ToothCrack | None = None) -> np.ndarray:
        """Single-tooth stiffness [N/m] (bending, shear, axial, foundation in series; no Hertz)
        at the involute pressure angle ``contact_angle`` [rad] (array)."""
        c = self.tooth_compliance(contact_angle, crack)
        return 1.0 / (c["bending"] + c["shear"] + c["axial"] + c["foundation"])

    def _crack_tip(self, crack: ToothCrack) -> tuple[float, float]:
        """(h_q, y_tip): the crack tip's distance from the centre line towards the loaded flank
        and its height [m] in the tooth frame. The crack starts where the involute meets the
        fillet (the form circle; Chen and Shao start it where the involute meets the base circle)."""
        g = self._g
        tc, tb, rb = g["tau_c"], g["theta_b"], g["base"]
        xc = rb * ((tc + tb) * math.cos(tc) - math.sin(tc))
        yc = rb * ((tc + tb) * math.sin(tc) + math.cos(tc))
        nu = math.radians(crack.angle_deg)
        return xc - crack.depth * math.cos(nu), yc + crack.depth * math.sin(nu)

    def root_half_thickness(self) -> float:
        """Half thickness of the tooth where the involute starts [m] (the crack's limit)."""
        g = self._g
        tc, tb, rb = g["tau_c"], g["theta_b"], g["base"]
        return rb * ((tc + tb) * math.cos(tc) - math.sin(tc))


def _sainsot(c: tuple[float, ...], theta_f: float, h: float) -> float:
    A, B, C, D, E, F = c
    return A / theta_f**2 + B * h * h + C * h / theta_f + D / theta_f + E * h + F


def _tooth_geometry(m: float, z: int, a: float, ha: float, cc: float) -> dict[str, float]:
    """Radii, angles and fillet constants of a rack-generated standard tooth (ROSS's
    ``GearElementTVMS`` construction: full-radius rack tip, radius c* m / (1 - sin alpha))."""
    rp = m * z / 2.0
    rb = rp * math.cos(a)
    am, cm = ha * m, cc * m
    ra = rp + am
    rc = math.sqrt((rb * math.tan(a) - am / math.sin(a)) ** 2 + rb * rb)
    rf = rp - (am + cm)
    rho = cm / (1.0 - math.sin(a))
    rho_ = rho / m
    theta_f = (math.pi / 2 + 2 * math.tan(a) * (ha - rho_) + 2 * rho_ / math.cos(a)) / z
    theta_b = math.pi / (2 * z) + float(involute(a))
    start = math.acos(min(1.0, rb / rc))
    g = {
        "alpha": a,
        "pitch": rp,
        "base": rb,
        "tip": ra,
        "form": rc,
        "root": rf,
        "rho": rho,
        "theta_f": theta_f,
        "theta_b": theta_b,
        "a1": (am + cm) - rho,
        "b1": math.pi * m / 4 + am * math.tan(a) + rho * math.cos(a),
        "tip_angle": math.acos(rb / ra),
        "start_angle": start,
    }
    g["tau_c"] = start + float(involute(start)) - theta_b
    return g


@dataclass(frozen=True)
class SpurPair:
    """A pair of standard spur gears at the standard centre distance (SI units throughout).

    ``SpurPair(module=, teeth=(z1, z2), face_width=, bore=(d1, d2), pressure_angle_deg=,
    youngs_modulus=, poisson=, addendum_coeff=1.0, tip_clearance_coeff=0.25)``; gear 1 (the
    pinion) drives. Both gears share the module, face width, pressure angle and material.

    Attributes:
        module: module [m], in [1e-4, 0.1].
        teeth: (z1, z2), integers in [12, 1000].
        face_width: face width [m], in [1e-4, 2].
        bore: bore diameters (d1, d2) [m], each in (0, its root diameter).
        pressure_angle_deg: pressure angle [deg], in [10, 35].
        youngs_modulus: E [Pa], in [1e9, 1e12]; poisson: nu [-], in [0, 0.5].
        density: rho [kg/m^3] (masses and inertias only).
        addendum_coeff, tip_clearance_coeff: h_a* and c* of the basic rack.
        crack: an optional :class:`ToothCrack` on tooth 0 of the pinion or the gear.
        kinematics: how the contact point moves along the flanks (:meth:`contact_angles`):
            ``"ross"`` (default; ROSS's convention, what docs/VALIDATION.md pins) or
            ``"line_of_action"`` (the exact path of contact of rigid involutes).
    """

    module: float
    teeth: tuple[int, int]
    face_width: float
    bore: tuple[float, float]
    pressure_angle_deg: float = 20.0
    youngs_modulus: float = 206e9
    poisson: float = 0.3
    density: float = 7810.0
    addendum_coeff: float = 1.0
    tip_clearance_coeff: float = 0.25
    crack: ToothCrack | None = None
    kinematics: str = "ross"
    pinion: SpurGear = field(init=False, repr=False, compare=False)
    gear: SpurGear = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, v in (("teeth", self.teeth), ("bore", self.bore)):
            if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != 2:
                raise ValueError(f"SpurPair.{name} must be a pair (pinion, gear), got {v!r}")
        object.__setattr__(self, "teeth", (_teeth("SpurPair", "teeth[0]", self.teeth[0]),
                                           _teeth("SpurPair", "teeth[1]", self.teeth[1])))  # fmt: skip
        common = {
            k: getattr(self, k)
            for k in (
                "module",
                "face_width",
                "pressure_angle_deg",
                "youngs_modulus",
                "poisson",
                "density",
                "addendum_coeff",
                "tip_clearance_coeff",
            )  # fmt: skip
        }
        gears = []
        for i, who in enumerate(("pinion", "gear")):
            try:
                gears.append(SpurGear(teeth=self.teeth[i], bore=self.bore[i], **common))
            except ValueError as e:
                raise ValueError(str(e).replace("SpurGear.bore", f"SpurPair.bore[{i}] ({who})").replace(
                    "SpurGear.", "SpurPair.")) from None  # fmt: skip
        for k in common:
            object.__setattr__(self, k, getattr(gears[0], k))
        object.__setattr__(self, "bore", (gears[0].bore, gears[1].bore))
        object.__setattr__(self, "pinion", gears[0])
        object.__setattr__(self, "gear", gears[1])
        if self.crack is not None:
            if not isinstance(self.crack, ToothCrack):
                raise ValueError(f"SpurPair.crack must be a ToothCrack or None, got {self.crack!r}")
            g = gears[0] if self.crack.on == "pinion" else gears[1]
            lim = g.root_half_thickness()
            if self.crack.depth * math.cos(math.radians(self.crack.angle_deg)) >= lim:
                raise ValueError(
                    f"SpurPair.crack: depth cos(angle) must stay below the {self.crack.on}'s root half-thickness "
                    f"{lim:.4g} m, got {self.crack.depth * math.cos(math.radians(self.crack.angle_deg)):.4g} m"
                )
        if self.kinematics not in ("ross", "line_of_action"):
            raise ValueError(f"SpurPair.kinematics must be 'ross' or 'line_of_action', got {self.kinematics!r}")
        if not 1.0 < self.contact_ratio < 2.0:
            raise ValueError(
                f"SpurPair: contact ratio {self.contact_ratio:.4f} outside (1, 2): the one/two-pair mesh model "
                "does not apply (change teeth, addendum_coeff or pressure_angle_deg)"
            )

    # ------------------------------------------------------------------ pair geometry
    @property
    def centre_distance(self) -> float:
        """Standard centre distance m (z1 + z2) / 2 [m]."""
        return self.module * (self.teeth[0] + self.teeth[1]) / 2.0

    @property
    def base_pitch(self) -> float:
        """Base pitch pi m cos(alpha) [m]."""
        return math.pi * self.module * math.cos(math.radians(self.pressure_angle_deg))

    @property
    def contact_length(self) -> float:
        """Length of the path of contact [m]."""
        p, g = self.pinion, self.gear
        return (
            math.sqrt(p.tip_radius**2 - p.base_radius**2)
            + math.sqrt(g.tip_radius**2 - g.base_radius**2)
            - self.centre_distance * math.sin(math.radians(self.pressure_angle_deg))
        )

    @property
    def contact_ratio(self) -> float:
        """Transverse contact ratio epsilon_alpha [-]: path of contact / base pitch."""
        return self.contact_length / self.base_pitch

    @property
    def hertzian_stiffness(self) -> float:
        """Hertzian contact stiffness pi E b / (4 (1 - nu^2)) [N/m] (constant along the path)."""
        return math.pi * self.youngs_modulus * self.face_width / (4.0 * (1.0 - self.poisson**2))

    # ------------------------------------------------------------------ mesh stiffness
    def contact_angles(self, u: Any) -> tuple[np.ndarray, np.ndarray]:
        """Pressure angles [rad] of the contact point on the pinion and on the gear tooth of a pair
        ``u`` mesh periods after it entered contact (0 <= u <= contact_ratio), by ``kinematics``:
        ``"ross"`` linear in the pinion's pressure angle from its form circle to its tip (ROSS's
        convention), ``"line_of_action"`` the contact point moving along the line of action by one
        base pitch per mesh period from where the gear's tip circle cuts it to the pinion's tip."""
        p, g = self.pinion, self.gear
        u = np.asarray(u, dtype=float)
        if self.kinematics == "ross":
            d_alpha = (p.tip_angle - p.start_angle) / self.contact_ratio * u
            return p.start_angle + d_alpha, g.tip_angle - self.teeth[0] / self.teeth[1] * d_alpha
        path = self.centre_distance * math.sin(math.radians(self.pressure_angle_deg))  # T1 T2
        s = path - math.sqrt(g.tip_radius**2 - g.base_radius**2) + self.base_pitch * u  # from T1
        return np.arctan(s / p.base_radius), np.arctan((path - s) / g.base_radius)

    def _pair_stiffness(self, u: np.ndarray, cracked: np.ndarray) -> np.ndarray:
        """Stiffness of one tooth pair [N/m] ``u`` mesh periods after it entered contact."""
        p, g = self.pinion, self.gear
        a1, a2 = self.contact_angles(u)
        cp = p.tooth_compliance(a1)
        cg = g.tooth_compliance(a2)
        inv = np.asarray(1.0 / self.hertzian_stiffness + sum(cp.values()) + sum(cg.values()), dtype=float)
        if self.crack is not None and np.any(cracked):
            # ``cracked``: this pair's tooth of the cracked gear is tooth 0 (mesh_stiffness)
            who, ang = (p, a1) if self.crack.on == "pinion" else (g, a2)
            cc = who.tooth_compliance(ang[cracked], self.crack)
            hc = who.tooth_compliance(ang[cracked])
            inv[cracked] += sum(cc.values()) - sum(hc.values())
        return 1.0 / inv

    def mesh_stiffness(self, phase: Any) -> np.ndarray:
        """Mesh stiffness [N/m] at ``phase`` [mesh periods] (scalar or array, vectorised).

        Phase 0 is the start of contact of a tooth pair: for phase mod 1 below
        ``contact_ratio - 1`` two pairs are in contact (this one and the one that entered a mesh
        period earlier), above it one. Healthy teeth: periodic with period 1. With a
        :class:`ToothCrack` on tooth 0 the stiffness has period z (the cracked gear's teeth):
        tooth j enters at phase j.
        """
        ph = np.asarray(phase, dtype=float)
        if not np.all(np.isfinite(ph)):
            raise ValueError("SpurPair.mesh_stiffness: phase must be finite")
        cr = self.contact_ratio
        j = np.floor(ph)
        frac = ph - j
        two = frac <= cr - 1.0
        zc = self.teeth[0] if self.crack is None or self.crack.on == "pinion" else self.teeth[1]
        first_cracked = np.mod(j, zc) == 0
        second_cracked = np.mod(j - 1.0, zc) == 0
        flat = frac.ravel()
        k = self._pair_stiffness(flat, first_cracked.ravel())
        k2 = self._pair_stiffness(flat + 1.0, second_cracked.ravel())
        k = k + np.where(two.ravel(), k2, 0.0)
        return k.reshape(ph.shape)

    def _period_rule(self, n: int = 96) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Legendre phases and weights over one mesh period, split at the jumps."""
        c = self.contact_ratio - 1.0
        t, w = np.polynomial.legendre.leggauss(n)
        x = np.concatenate([c / 2 * (t + 1), c + (1 - c) / 2 * (t + 1)])
        return x, np.concatenate([w * c / 2, w * (1 - c) / 2])

    @property
    def mean_mesh_stiffness(self) -> float:
        """Mean of the healthy mesh stiffness over one mesh period [N/m]."""
        x, w = self._period_rule()
        return float(np.dot(w, self.mesh_stiffness(x)))

    def stiffness_harmonics(self, n_harmonics: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Fourier series of the healthy mesh stiffness in the mesh phase phi = 2 pi phase:
        k(phi) = k_m0 (1 + sum_n kappa_n cos(n phi + phi_n)), n = 1..n_harmonics.

        Returns (k_m0 [N/m], kappa_n [-], phi_n [rad]) with the coefficients computed by
        Gauss-Legendre quadrature on the two smooth pieces of the period (exact to ~1e-12).
        """
        if (
            isinstance(n_harmonics, bool)
            or not isinstance(n_harmonics, (int, np.integer))
            or not 1 <= n_harmonics <= 64
        ):
            raise ValueError(f"n_harmonics must be an integer in [1, 64], got {n_harmonics!r}")
        x, w = self._period_rule(max(96, 8 * int(n_harmonics)))
        k = self.mesh_stiffness(x)
        k0 = float(np.dot(w, k))
        n = np.arange(1, int(n_harmonics) + 1)[:, None]
        a = 2.0 * (np.cos(2 * np.pi * n * x) * k * w).sum(-1)
        b = 2.0 * (np.sin(2 * np.pi * n * x) * k * w).sum(-1)
        return k0, np.hypot(a, b) / k0, np.arctan2(-b, a)

    # ------------------------------------------------------------------ ISO 6336-1
    def iso_single_pair_stiffness(self) -> float:
        """ISO 6336-1 method B single-pair tooth stiffness c' times the face width [N/m].

        c' = c'_th C_M C_R C_B (E / 206 GPa), c'_th = 1/q' with q' from C1..C9 (no profile shift),
        C_M = 0.8, C_R = 1 (solid blanks), C_B = [1 + 0.5 (1.2 - h_fP/m)] [1 - 0.02 (20 - alpha)].
        """
        z1, z2 = self.teeth
        C = _ISO_C
        q = C[0] + C[1] / z1 + C[2] / z2  # [mm um / N]
        hfp = self.addendum_coeff + self.tip_clearance_coeff
        cb = (1.0 + 0.5 * (1.2 - hfp)) * (1.0 - 0.02 * (20.0 - self.pressure_angle_deg))
        c_prime = (1.0 / q) * 0.8 * 1.0 * cb * self.youngs_modulus / _ISO_E_STEEL  # [N / (mm um)]
        return c_prime * 1e9 * self.face_width  # N/(mm um) = 1e9 N/m^2

    def iso_mesh_stiffness(self) -> float:
        """ISO 6336-1 mesh stiffness c_gamma_alpha = c' (0.75 epsilon_alpha + 0.25) times the face
        width [N/m] (the standard's estimate of the mean mesh stiffness of a spur pair)."""
        return self.iso_single_pair_stiffness() * (0.75 * self.contact_ratio + 0.25)

    def summary(self) -> dict[str, float]:
        """Key derived quantities (SI) in a flat dict, for reports."""
        return {
            "contact_ratio": self.contact_ratio,
            "centre_distance": self.centre_distance,
            "hertzian_stiffness": self.hertzian_stiffness,
            "mean_mesh_stiffness": self.mean_mesh_stiffness,
            "iso_c_prime_b": self.iso_single_pair_stiffness(),
            "iso_c_gamma_alpha_b": self.iso_mesh_stiffness(),
            "mass_pinion": self.pinion.mass,
            "mass_gear": self.gear.mass,
            "inertia_pinion": self.pinion.polar_inertia,
            "inertia_gear": self.gear.polar_inertia,
        }
