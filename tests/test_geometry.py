"""Spur geometry and the mesh stiffness from the teeth (gear_env/sim/geometry.py), pinned to ROSS.

ROSS values: ROSS's own tests/test_gear_element.py (the 62/62 pair), and for the other pairs
the output of ``python benchmarks/geometry_vs_ross.py --ross-python <python with ross> --json``
run once against petrobras/ross at commit 631a249a (ROSS ``Mesh`` of two
``GearElementTVMS``; ``stiffness_range`` = 1000 points ``linspace(0, one mesh period, 1000)``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from gear_env.sim.geometry import SpurGear, SpurPair, ToothCrack

ROSS_PAIR = dict(
    module=2e-3,
    teeth=(62, 62),
    face_width=0.02,
    bore=(0.035, 0.035),
    pressure_angle_deg=20.0,
    youngs_modulus=206e9,
    poisson=0.3,
    addendum_coeff=1.0,
    tip_clearance_coeff=0.25,
)

# (SpurPair keywords, ROSS: contact ratio, max, min, mean of the 1000-point waveform [N/m])
ROSS_REFERENCE = [
    (dict(module=2e-3, teeth=(55, 75), face_width=0.0387, bore=(0.04, 0.05)),
     1.7939883590132288, 886563610.3350345, 488006619.07114655, 791347304.0805657),
    (dict(module=3e-3, teeth=(20, 40), face_width=0.025, bore=(0.02, 0.04)),
     1.6351859635714614, 564445694.4634221, 314239923.63292164, 469071588.6597274),
    (dict(module=4e-3, teeth=(31, 47), face_width=0.04, bore=(0.05, 0.08), pressure_angle_deg=25.0),
     1.5039976948757665, 1059044180.9121268, 592820871.9653096, 828303566.5898292),
    (dict(module=1.5e-3, teeth=(25, 93), face_width=0.012, bore=(0.012, 0.05), youngs_modulus=70e9, poisson=0.33,
          density=2700.0),
     1.727959352645959, 90817600.58296451, 49876838.67771769, 78638012.49521632),
    (dict(module=5e-3, teeth=(40, 40), face_width=0.05, bore=(0.06, 0.06), tip_clearance_coeff=0.3),
     1.7135336237677612, 1087961453.5890226, 601176201.1313995, 935323038.937726),
]  # fmt: skip


def test_ross_test_pair_values():
    """ROSS's tests/test_gear_element.py::test_mesh_params and test_gear_tvms_params."""
    p = SpurPair(**ROSS_PAIR)
    assert p.contact_ratio == pytest.approx(1.7897798668330458, abs=1e-10)
    assert p.hertzian_stiffness == pytest.approx(3555868607.9093266, rel=1e-12)
    k = p.mesh_stiffness(np.linspace(0.0, 1.0, 1000))
    ross5 = [396622921.3581085, 396738680.0375346, 396854147.2919756, 396969323.136738, 397084207.5865779]
    np.testing.assert_allclose(k[:5], ross5, rtol=1e-9)
    g = p.pinion
    assert g.base_radius == pytest.approx(0.05826094248872632, rel=1e-14)
    assert g.mass == pytest.approx(1.7360332618790646, rel=1e-12)
    assert g.polar_inertia == pytest.approx(0.0036024860225567935, rel=1e-12)
    assert g.tip_radius == pytest.approx(0.064) and g.root_radius == pytest.approx(0.0595)
    assert g.start_angle == pytest.approx(0.2577380345253824, rel=1e-12)
    assert g.tip_angle == pytest.approx(0.42672233774374957, rel=1e-12)


@pytest.mark.parametrize("case", ROSS_REFERENCE, ids=lambda c: f"{c[0]['teeth']}")
def test_pairs_agree_with_ross(case):
    """Contact ratio to 1e-10 and the waveform's max, min and mean to 1e-6 (the issue asks
    1e-4 and 3 %). ROSS's last sample, phase 1, is the end of the single-contact zone (its
    ``mod`` maps a whole period to the period, not to 0); here phase 1 = phase 0 is the start
    of double contact, so the last sample is taken just below 1, as ROSS does."""
    kw, cr, kmax, kmin, kmean = case
    p = SpurPair(**kw)
    assert abs(p.contact_ratio - cr) < 1e-10
    x = np.linspace(0.0, 1.0, 1000)
    x[-1] = np.nextafter(1.0, 0.0)
    k = p.mesh_stiffness(x)
    assert k.max() == pytest.approx(kmax, rel=1e-6)
    assert k.min() == pytest.approx(kmin, rel=1e-6)
    assert k.mean() == pytest.approx(kmean, rel=1e-6)


def test_gauss_rule_matches_adaptive_quadrature():
    """The fixed 48-node rule against SciPy's adaptive quad on the bending integral (involute
    part) at a mid-flank contact: the same integrand, integrated independently."""
    g = SpurGear(module=2e-3, teeth=30, face_width=0.02, bore=0.02)
    alpha = 0.5 * (g.start_angle + g.tip_angle)
    gg = g._g
    beta = alpha + math.tan(alpha) - alpha - gg["theta_b"]
    rb, tb = gg["base"], gg["theta_b"]
    xo = rb * ((beta + tb) * math.cos(beta) - math.sin(beta))
    yo = rb * ((beta + tb) * math.sin(beta) + math.cos(beta))

    def f(tau):
        x = rb * ((tau + tb) * math.cos(tau) - math.sin(tau))
        y = rb * ((tau + tb) * math.sin(tau) + math.cos(tau))
        inert = 2.0 / 3.0 * x**3 * g.face_width
        return (
            (math.cos(beta) * (yo - y) - xo * math.sin(beta)) ** 2
            / (g.youngs_modulus * inert)
            * (rb * (tau + tb) * math.cos(tau))
        )

    ref_inv, _ = integrate.quad(f, gg["tau_c"], beta, epsabs=0, epsrel=1e-13)

    def ft(gam):
        a1, b1, rp, rr = gg["a1"], gg["b1"], gg["pitch"], gg["rho"]
        ph = (a1 / math.tan(gam) + b1) / rp
        x = rp * math.sin(ph) - (a1 / math.sin(gam) + rr) * math.cos(gam - ph)
        y = rp * math.cos(ph) - (a1 / math.sin(gam) + rr) * math.sin(gam - ph)
        h = 1e-7
        ph2 = (a1 / math.tan(gam + h) + b1) / rp
        y2 = rp * math.cos(ph2) - (a1 / math.sin(gam + h) + rr) * math.sin(gam + h - ph2)
        ph1 = (a1 / math.tan(gam - h) + b1) / rp
        y1 = rp * math.cos(ph1) - (a1 / math.sin(gam - h) + rr) * math.sin(gam - h - ph1)
        dy = (y2 - y1) / (2 * h)  # the curve's dy/dgamma by central differences, not ROSS's closed form
        inert = 2.0 / 3.0 * x**3 * g.face_width
        return (math.cos(beta) * (yo - y) - xo * math.sin(beta)) ** 2 / (g.youngs_modulus * inert) * dy

    ref_tr, _ = integrate.quad(ft, math.pi / 2, g.alpha, epsabs=0, epsrel=1e-8)
    ours = g.tooth_compliance(np.array([alpha]))["bending"][0]
    assert ours == pytest.approx(ref_inv + ref_tr, rel=1e-7)


def test_waveform_structure_and_scaling():
    """Double contact first (phase < CR - 1), one jump up at phase 0 and one down at CR - 1;
    every compliance scales as 1/b, so the stiffness is proportional to the face width."""
    p = SpurPair(**ROSS_PAIR)
    cr = p.contact_ratio
    k = p.mesh_stiffness(np.array([0.0, cr - 1 - 1e-9, cr - 1 + 1e-9, 0.999999, 1.0, 2.3]))
    assert k[0] > 1.5 * k[3] and k[1] > 1.5 * k[2]
    assert k[4] == k[0]  # periodic
    assert k[5] == pytest.approx(p.mesh_stiffness(0.3), rel=1e-14)
    wide = SpurPair(**{**ROSS_PAIR, "face_width": 0.05})
    x = np.linspace(0, 1, 37)
    np.testing.assert_allclose(wide.mesh_stiffness(x), 2.5 * p.mesh_stiffness(x), rtol=1e-12)
    assert np.shape(p.mesh_stiffness(0.25)) == ()
    assert p.mesh_stiffness(np.zeros((2, 3))).shape == (2, 3)


def test_harmonics_reconstruct_waveform():
    """k_m0 is the period mean, and the 64-harmonic series reproduces the waveform away from its
    two jumps; kappa_1 is the amplitude of the first Fourier coefficient (checked by FFT)."""
    p = SpurPair(**ROSS_PAIR)
    k0, kap, ph = p.stiffness_harmonics(64)
    x = np.linspace(0, 1, 4096, endpoint=False)
    k = p.mesh_stiffness(x)
    assert k0 == pytest.approx(k.mean(), rel=1e-3)
    n = np.arange(1, 65)[:, None]
    series = k0 * (1 + (kap[:, None] * np.cos(2 * np.pi * n * x + ph[:, None])).sum(0))
    cr = p.contact_ratio
    away = (np.abs(x - (cr - 1)) > 0.05) & (x > 0.05) & (x < 0.95)
    assert np.max(np.abs(series[away] / k[away] - 1)) < 0.01
    fft = np.fft.rfft(k) / len(k)
    assert kap[0] == pytest.approx(2 * abs(fft[1]) / k0, rel=1e-3)


def test_iso_6336_values():
    """c' and c_gamma_alpha by hand for the ROSS pair: q' = C1 + C2/62 + C3/62, C_M 0.8,
    C_B = 1 + 0.5 (1.2 - 1.25) = 0.975, so c' = 0.78/q' N/(mm um)."""
    p = SpurPair(**ROSS_PAIR)
    q = 0.04723 + 0.15551 / 62 + 0.25791 / 62
    c1 = 0.8 * 0.975 / q
    assert p.iso_single_pair_stiffness() == pytest.approx(c1 * 20 * 1e6, rel=1e-12)
    assert p.iso_mesh_stiffness() == pytest.approx(c1 * (0.75 * p.contact_ratio + 0.25) * 20e6, rel=1e-12)


def test_crack_weakens_only_the_cracked_tooth():
    """A pinion root crack lowers the stiffness while tooth 0 is in contact (phases [0, CR)),
    more for a deeper crack, and leaves the other z - 1 mesh periods healthy."""
    healthy = SpurPair(**ROSS_PAIR)
    x = np.linspace(0, 62, 62 * 50, endpoint=False)
    kh = healthy.mesh_stiffness(x)
    drops = []
    for depth in (0.5e-3, 1.0e-3):
        cracked = SpurPair(**ROSS_PAIR, crack=ToothCrack(depth=depth, angle_deg=45.0, on="pinion"))
        kc = cracked.mesh_stiffness(x)
        inside = x < healthy.contact_ratio
        assert np.all(kc[inside] < kh[inside])
        np.testing.assert_array_equal(kc[x >= 2.0], kh[x >= 2.0])
        drops.append(np.max(1 - kc / kh))
    assert 0 < drops[0] < drops[1] < 0.5
    gear_crack = SpurPair(**ROSS_PAIR, crack=ToothCrack(depth=1e-3, on="gear"))
    assert np.all(gear_crack.mesh_stiffness(x[x < 1.0]) < kh[x < 1.0])


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(module=-1.0), "SpurPair.module must be in"),
        (dict(teeth=(8, 40)), r"SpurPair.teeth\[0\] must be an integer in \[12, 1000\]"),
        (dict(teeth=(30,)), "SpurPair.teeth must be a pair"),
        (dict(bore=(0.035, 0.2)), r"SpurPair.bore\[1\] \(gear\) must be in \(0, 0.119\)"),
        (dict(poisson=0.7), r"SpurPair.poisson must be in \[0, 0.5\]"),
        (dict(pressure_angle_deg=float("nan")), "SpurPair.pressure_angle_deg must be in"),
        (dict(face_width="20 mm"), "SpurPair.face_width must be a real number"),
        (dict(crack=ToothCrack(depth=0.01, angle_deg=0.0)), "half-thickness"),
    ],
)
def test_bad_inputs_name_field_and_range(change, match):
    with pytest.raises(ValueError, match=match):
        SpurPair(**{**ROSS_PAIR, **change})


def test_bad_crack_and_phase():
    with pytest.raises(ValueError, match=r"ToothCrack.angle_deg must be in \[0, 75\]"):
        ToothCrack(depth=1e-3, angle_deg=80.0)
    with pytest.raises(ValueError, match="ToothCrack.on must be"):
        ToothCrack(depth=1e-3, on="wheel")
    with pytest.raises(ValueError, match="phase must be finite"):
        SpurPair(**ROSS_PAIR).mesh_stiffness([0.1, float("inf")])
    with pytest.raises(ValueError, match=r"n_harmonics must be an integer in \[1, 64\]"):
        SpurPair(**ROSS_PAIR).stiffness_harmonics(0)


def test_line_of_action_kinematics():
    """The exact path of contact: a pair enters where the gear's tip circle cuts the line of action
    (the gear tooth at its tip angle) and leaves at the pinion's tip, one base pitch per mesh
    period; against ROSS's convention (linear in pressure angle from the form circle) the
    stiffness is a few per cent lower (contact higher on the pinion flank): 3.2 % on the mean
    of the ROSS pair, 5.7 % on the 20/40 pair."""
    exact = SpurPair(**ROSS_PAIR, kinematics="line_of_action")
    a1, a2 = exact.contact_angles(np.array([0.0, exact.contact_ratio]))
    assert a2[0] == pytest.approx(exact.gear.tip_angle, abs=1e-12)
    assert a1[1] == pytest.approx(exact.pinion.tip_angle, abs=1e-12)
    rb, path = exact.pinion.base_radius, exact.centre_distance * math.sin(math.radians(20.0))
    assert math.tan(a1[1]) * rb - math.tan(a1[0]) * rb == pytest.approx(exact.contact_ratio * exact.base_pitch)
    assert math.tan(a1[0]) * rb + math.tan(a2[0]) * exact.gear.base_radius == pytest.approx(path)
    ross = SpurPair(**ROSS_PAIR)
    assert exact.mean_mesh_stiffness / ross.mean_mesh_stiffness - 1 == pytest.approx(-0.0321, abs=5e-4)
    kw = dict(module=3e-3, teeth=(20, 40), face_width=0.025, bore=(0.02, 0.04))
    ratio = SpurPair(**kw, kinematics="line_of_action").mean_mesh_stiffness / SpurPair(**kw).mean_mesh_stiffness
    assert ratio - 1 == pytest.approx(-0.0574, abs=5e-4)
    with pytest.raises(ValueError, match="SpurPair.kinematics must be 'ross' or 'line_of_action'"):
        SpurPair(**ROSS_PAIR, kinematics="exact")
