"""Property-based tests of the core surface: GearParams and simulate either work or raise the
documented error naming the culprit; no NaN ever comes out."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gear_env import GearParams, GearSimulator, SimulationDivergedError, simulate

FLOAT_FIELDS = [
    "pressure_angle_deg",
    "J_p",
    "J_g",
    "m_p",
    "m_g",
    "k_p",
    "k_g",
    "k_m0",
    "module",
    "e_m1",
    "kappa",
    "b_c",
    "T_p",
    "T_g",
    "xi_m",
    "xi_p",
    "xi_g",
]

weird_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 1e300, float("nan"), float("inf"), -float("inf")]),
)


@settings(max_examples=300, deadline=None)
@given(field=st.sampled_from(FLOAT_FIELDS), value=weird_floats)
def test_params_accept_or_name_the_field(field, value):
    try:
        p = GearParams(**{field: value})
    except ValueError as exc:
        assert field in str(exc)
        return
    assert np.all(np.isfinite(p.consts)), (field, value, p.consts)


@settings(max_examples=50, deadline=None)
@given(value=st.one_of(st.text(max_size=3), st.none(), st.lists(st.floats(), max_size=2), st.booleans()))
def test_params_reject_non_numbers(value):
    with pytest.raises(ValueError, match="k_p"):
        GearParams(k_p=value)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    omega=st.one_of(weird_floats, st.integers(-5, 5), st.text(max_size=2), st.none()),
)
def test_simulate_omega_validated(omega):
    try:
        tr = simulate(omega, periods=2, transient=0, steps_per_period=16)
    except ValueError as exc:
        assert "omega" in str(exc)
        return
    assert np.all(np.isfinite(tr.data))


@pytest.mark.parametrize(
    "kwargs,word",
    [
        ({"periods": 0}, "periods"),
        ({"periods": 2.5}, "periods"),
        ({"transient": -1}, "transient"),
        ({"model": "elastic"}, "model"),
        ({"steps_per_period": 4}, "steps_per_period"),
        ({"initial_state": np.zeros(9)}, "initial_state"),
        ({"initial_state": np.full(10, np.nan)}, "initial_state"),
    ],
)
def test_simulate_bad_arguments(kwargs, word):
    args = {"omega": 1.0, "periods": 2, "transient": 0, **kwargs}
    with pytest.raises(ValueError, match=word):
        simulate(**args)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    xi=st.sampled_from([0.0, 1e-4, 0.07, 2.0]),
    k_scale=st.sampled_from([1e-3, 1.0, 1e3]),
    e_scale=st.sampled_from([0.0, 1.0, 50.0]),
    omega=st.sampled_from([0.05, 1.0, 3.0, 8.0]),
    steps=st.sampled_from([8, 16, 128]),
    model=st.sampled_from(["constant", "dynamic"]),
)
def test_extremes_stay_finite_or_raise(xi, k_scale, e_scale, omega, steps, model):
    """Extreme but valid parameters: finite output or SimulationDivergedError, never NaN."""
    p = GearParams(xi_m=xi, xi_p=xi, xi_g=xi, k_p=2e8 * k_scale, k_g=2e8 * k_scale, e_m1=1e-5 * e_scale)
    try:
        tr = simulate(omega, model=model, periods=3, transient=5, steps_per_period=steps, params=p)
    except SimulationDivergedError as exc:
        assert exc.period >= 0 and exc.reason
        return
    assert np.all(np.isfinite(tr.data))
    d = tr.to_dict()
    for key in ("amplitude_u", "amplitude_delta", "contact_loss_fraction"):
        assert math.isfinite(d[key])


def test_divergence_is_reported_not_nan():
    sim = GearSimulator(steps_per_period=16)
    sim.reset(initial_state=np.r_[np.zeros(4), 5e5, np.zeros(4), 1e6])
    before = sim.state
    with pytest.raises(SimulationDivergedError) as exc:
        sim.advance(5)
    assert "mesh period" in str(exc.value)
    # the failed interval is discarded: the state is unchanged
    assert np.array_equal(sim.state, before)
