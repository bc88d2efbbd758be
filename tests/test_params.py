"""GearParams: MODEL.md sec. 4 values to 6 significant digits, validation messages."""

import dataclasses
import math

import numpy as np
import pytest

from gear_env import GearParams


def rel(a, b):
    return abs(a - b) / abs(b)


def test_derived_values_match_model_md():
    p = GearParams()
    d = p.dimensionless()
    expected = {
        "eps_p": 0.1958755,
        "eps_g": 0.3853499,
        "lam_p": 0.2583979,
        "sigma_p": 1.1485619,
        "sigma_g": 0.8188736,
        "F_s": 0.02749813,
        "R": 6108.0020,
        "A0": 6500.0,
        "E1": 0.5,
        "B_c": 1.0,
    }
    for k, v in expected.items():
        assert rel(d[k], v) < 5e-7, (k, d[k], v)
    assert rel(p.r_bp * 1e3, 51.68309) < 5e-7
    assert rel(p.r_bg * 1e3, 70.47695) < 5e-7
    assert rel(p.a0, 0.130) < 1e-12
    assert rel(p.m_e, 7.811083) < 5e-7
    assert rel(p.omega_n, 9954.395) < 5e-7
    assert rel(p.omega_n / (2 * math.pi), 1584.291) < 5e-7
    assert rel(p.static_mesh_load, 425.671) < 5e-6
    assert rel(p.c_m, 10885.6) < 5e-6
    assert rel(p.c_p, 2449.0) < 5e-5
    assert rel(p.c_g, 3435.0) < 5e-5
    # omega = 1 is the pinion at 1728 rpm
    assert abs(p.pinion_rpm(1.0) - 1728.3) < 0.1
    # alpha_d(a0) = 20 deg exactly (A2)
    assert abs(math.degrees(math.acos((p.r_bp + p.r_bg) / p.a0)) - 20.0) < 1e-12


def test_consts_read_only():
    p = GearParams()
    with pytest.raises(ValueError):
        p.consts[0] = 1.0


@pytest.mark.parametrize(
    "field,value,words",
    [
        ("m_p", -1.0, "m_p"),
        ("b_c", 0.0, "b_c"),
        ("pressure_angle_deg", 45.0, "(0, 45)"),
        ("pressure_angle_deg", 0.0, "pressure_angle_deg"),
        ("k_m0", float("nan"), "k_m0"),
        ("kappa", 1.5, "kappa"),
        ("z_p", 3, "z_p"),
        ("xi_m", -0.1, "xi_m"),
        ("J_g", "heavy", "J_g"),
    ],
)
def test_invalid_values_name_the_field(field, value, words):
    with pytest.raises(ValueError, match=None) as exc:
        GearParams(**{field: value})
    assert field in str(exc.value)
    assert words in str(exc.value)


def test_from_dict_rejects_unknown_keys():
    with pytest.raises(ValueError, match="valid fields"):
        GearParams.from_dict({"mass": 1.0})
    p = GearParams.from_dict({"kappa": 0.1})
    assert p.kappa == 0.1
    assert GearParams.from_dict(p.to_dict()) == p


def test_frozen():
    p = GearParams()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.kappa = 0.3  # type: ignore[misc]
    assert np.isfinite(p.consts).all()


def test_pickle_keeps_the_constants_read_only():
    """A pickled GearParams (e.g. sent to a sweep worker) rebuilds its read-only constants: numba
    keys its compiled specialisations on the writeable flag, so writable constants in a worker
    would trigger a fresh compilation instead of a disk-cache load."""
    import pickle

    p = GearParams(kappa=0.15, b0=1.5e-5, gravity=9.81)
    q = pickle.loads(pickle.dumps(p))
    assert q == p and not q.consts.flags.writeable
    assert np.array_equal(q.consts, p.consts)
