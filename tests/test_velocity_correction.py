"""Fox-Goodwin with the velocity correction (``GearParams.velocity_correction``, scheme ``"fox-goodwin-vc"``): the
damping forces feel v - (h/12)(a_new - a_old) instead of Newmark's v, whose bias under beta 1/12 is h^2/12 da/dt.
Checked against the event-located reference (less error than Fox-Goodwin at the same steps), against the linear
analysis of the scheme (the step limit and the kernel's own step map), for bit identity between the single and the
vector environment, and for clear refusals where the scheme is not carried."""

from __future__ import annotations

import numpy as np
import pytest
from env_runs import env_run

from gear_env import GearParams, GearSimulator, simulate
from gear_env.sim.linear import matrices, newmark_step_limit, vc_amplification
from gear_env.sim.params import C_BETA, FOX_GOODWIN_BETA
from gear_env.sim.reference import reference_poincare

FG = GearParams(newmark_beta=FOX_GOODWIN_BETA)
VC = FG.replace(velocity_correction=True)


def test_the_correction_needs_fox_goodwin_and_stays_out_of_the_dict_when_off():
    assert "velocity_correction" not in FG.to_dict()
    assert VC.to_dict()["velocity_correction"] is True
    assert GearParams.from_dict(VC.to_dict()) == VC
    with pytest.raises(ValueError, match=r"velocity_correction takes Fox-Goodwin's beta: newmark_beta must be 1/12"):
        GearParams(velocity_correction=True)
    with pytest.raises(ValueError, match=r"velocity_correction must be True or False, got 1"):
        GearParams(newmark_beta=FOX_GOODWIN_BETA, velocity_correction=1)


def _errors(model, omega, n_steps, periods=10):
    start = GearSimulator(GearParams(), model, 512, omega)
    start.advance(300)
    x0 = start.state
    ref = reference_poincare(omega, model, None, 0, periods, initial_state=x0, rtol=1e-12, atol=1e-13)
    out = {}
    for name, p in (("fg", FG), ("vc", VC)):
        iv = GearSimulator(p, model, n_steps, omega, x0).advance(periods)
        out[name] = float(np.max(np.abs(iv.poincare[:, :10] - ref.states)))
    return out


@pytest.mark.parametrize(
    "model, omega, gain",
    [("constant", 0.9, 3.0), ("dynamic", 1.2, 2.0), ("constant", 1.41, 5.0), ("constant", 1.42, 3.0),
     ("dynamic", 1.52, 1.8)],
)  # fmt: skip
def test_corrected_velocity_is_more_accurate_than_fox_goodwin_at_equal_steps(model, omega, gain):
    """Period-1 orbits in permanent contact (constant 0.9, dynamic 1.2) and impacting (the others, where plain
    Fox-Goodwin is at or above 1e-3 b0 at 64 steps): the corrected scheme's Poincare error against DOP853 with
    located contact changes is 2-15x smaller (``gain`` asserts less) and below 1e-3 b0 (docs/SIMULATOR.md)."""
    e = _errors(model, omega, 64)
    assert e["vc"] * gain <= e["fg"], e
    assert e["vc"] < 1e-3, e


def _linear_pair(**kw):
    """Constant model, no stiffness or TE fluctuation: in permanent contact the system is linear."""
    return GearParams(newmark_beta=FOX_GOODWIN_BETA, velocity_correction=True, kappa=0.0, e_m1=0.0, **kw)


def test_kernel_step_is_the_linear_analysis_step_map():
    """In permanent contact with constant stiffness the constant model is M a + C v + K q = F: one mesh period of
    the kernel from a perturbed equilibrium equals the N-th power of ``vc_amplification`` (the map the step limit
    is computed from) applied to the perturbation, to round-off."""
    p = _linear_pair()
    omega, n = 1.3, 64
    eq = GearSimulator(p, "constant", 64, omega)
    eq.advance(2000)  # settle to the equilibrium (static deflection under F_s)
    x_eq, a_eq = eq.state, eq.a.copy()
    assert np.max(np.abs(a_eq)) < 1e-9
    dx = np.array([1e-3, -2e-3, 5e-4, 1e-3, 2e-3, 1e-4, -2e-4, 3e-4, 1e-4, -1e-4])
    sim = GearSimulator(p, "constant", n, omega, x_eq + dx)
    sim.advance(1)
    M, C, K = matrices(p, "constant")
    a0 = -np.linalg.solve(M, C @ dx[5:] + K @ dx[:5])  # the interval starts with the state's own acceleration
    T = np.linalg.matrix_power(vc_amplification(M, C, K, 2.0 * np.pi / (n * omega)), n)
    want = T @ np.concatenate([dx, a0])
    got = np.concatenate([sim.state - x_eq, sim.a - a_eq])
    np.testing.assert_allclose(got, want, atol=1e-11 * np.max(np.abs(want)) + 1e-14)


def test_step_limit_is_where_the_linear_step_map_turns_unstable():
    """The limit of the corrected scheme, at this model's damping below Fox-Goodwin's, is where the spectral radius
    of the damped step map first exceeds 1 (times the margin); heavier damping lowers it further."""
    h_fg, h_vc = newmark_step_limit(FG), newmark_step_limit(VC)
    assert 0.85 * h_fg < h_vc < h_fg
    for model in ("constant", "dynamic"):
        M, C, K = matrices(VC, model)
        rho = max(np.abs(np.linalg.eigvals(vc_amplification(M, C, K, h_vc))))
        assert rho <= 1.0 + 1e-9
    damped = GearParams(newmark_beta=FOX_GOODWIN_BETA, velocity_correction=True, xi_m=1.0, xi_p=1.0, xi_g=1.0)
    assert newmark_step_limit(damped) < 0.5 * h_vc
    with pytest.raises(ValueError, match="steps_per_period"):
        GearSimulator(VC, "dynamic", 64, 0.16)  # Fox-Goodwin's 64 steps hold down to omega 0.158, these not


def test_automatic_step_count_follows_the_corrected_scheme_and_its_floor():
    from gear_env.sim.linear import min_steps_per_period
    from gear_env.sim.simulator import VC_STEPS_PER_PERIOD, auto_steps_rule, default_steps_per_period

    assert default_steps_per_period(1.2, VC) == VC_STEPS_PER_PERIOD == 68
    assert default_steps_per_period(0.12, VC) == min_steps_per_period(VC, 0.12) > 68  # the floor binds low down
    assert "fox-goodwin-vc" in auto_steps_rule(VC) and "fox-goodwin-vc" not in auto_steps_rule(FG)
    assert GearSimulator(VC, "dynamic", omega=1.2).steps_per_period == 68


def test_step_limit_is_kept_per_linear_system_and_follows_what_enters_it():
    """The limit is kept across the fields a plant family's duty cycle and wear change (torques, transmission error),
    which leave M, C and K alone, and recomputed for any field that enters them (here the damping and the stiffness
    variation): each kept value equals a fresh computation."""
    from gear_env.sim.linear import _step_limit

    for p in (VC.replace(T_p=0.4 * VC.T_p, T_g=0.4 * VC.T_g), VC.with_te_scale(2.0), FG.replace(T_g=2.0 * FG.T_g)):
        assert newmark_step_limit(p) == _step_limit(p)
    assert newmark_step_limit(VC.replace(T_p=0.4 * VC.T_p, T_g=0.4 * VC.T_g)) == newmark_step_limit(VC)
    for p in (VC.replace(xi_m=0.3), VC.replace(kappa=0.35), FG.replace(k_p=1e8)):
        assert newmark_step_limit(p) == _step_limit(p) != newmark_step_limit(VC if p.velocity_correction else FG)


def test_run_continued_from_the_state_and_samples_match_records():
    """The state carried between calls keeps Newmark's velocity; each call starts the scheme from it with the
    acceleration the equations give there, which under the correction (whose accelerations balance the corrected
    velocity) moves the run by ~1e-6 b0, far below the scheme's error. The Poincare samples hold the corrected
    velocity, as the recorded trajectory does at the same instants."""
    one = GearSimulator(VC, "dynamic", 64, 1.45)
    whole = one.advance(6)
    two = GearSimulator(VC, "dynamic", 64, 1.45)
    two.advance(3)
    rest = two.advance(3)
    np.testing.assert_allclose(whole.poincare[3:, :10], rest.poincare[:, :10], rtol=0, atol=1e-5)
    np.testing.assert_allclose(one.state, two.state, rtol=0, atol=1e-5)
    traj = simulate(1.45, model="dynamic", periods=3, transient=0, steps_per_period=64, params=VC)
    np.testing.assert_allclose(traj.states[64::64][:3, :10], whole.poincare[:3, :10], rtol=0, atol=1e-12)
    # and the corrected velocity is not Newmark's (the state's)
    assert not np.array_equal(whole.poincare[-1, 5:10], one.state[5:10])


def test_analyses_on_the_step_jacobian_refuse_it_naming_the_field(monkeypatch):
    from gear_env.analysis.continuation import OrbitMap
    from gear_env.analysis.floquet import PeriodMap, find_periodic_orbit

    with pytest.raises(ValueError, match="velocity_correction"):
        PeriodMap(1.2, "dynamic", params=VC)
    with pytest.raises(ValueError, match="velocity_correction"):
        find_periodic_orbit(1.2, "dynamic", params=VC)
    with pytest.raises(ValueError, match="velocity_correction"):
        OrbitMap("dynamic", VC, 1)
    from gear_env.analysis import stability as ST

    def no_work(*_a, **_k):
        raise AssertionError("the stability map started work before refusing")

    monkeypatch.setattr(ST, "compute_stability_map", no_work)
    with pytest.raises(ValueError, match="the stability map takes the plain Newmark step"):
        ST.stability_map("dynamic", params=VC, cache=False)
    with pytest.raises(ValueError, match="tol"):
        GearSimulator(VC, "dynamic", omega=1.2, tol=1e-3)


ENV_ACTIONS = np.linspace(-1.0, 1.0, 12)


@pytest.mark.parametrize("n", [3, 9])  # 9 rows: the SIMD lanes
def test_env_scheme_single_and_vector_agree_bit_for_bit_down_to_low_omega(n):
    """scheme="fox-goodwin-vc" on a Demand task, set-points down to the lowest speeds (where the rows take a
    larger, stable beta and so plain Newmark for that interval): every sub-environment's observations are the
    single env's bit for bit, and the plant keeps beta 1/12 and the correction."""
    kw = {"scheme": "fox-goodwin-vc", "omega_min": 0.05, "initial_omega": (0.06, 1.6)}
    obs, vec = env_run("GearSpeedDemand-v1", 60, ENV_ACTIONS, n, **kw)
    assert np.isfinite(obs).all()
    assert (vec._core.C[:, C_BETA] == FOX_GOODWIN_BETA).all()
    for i in (0, n - 1):
        so, env = env_run("GearSpeedDemand-v1", 60 + i, ENV_ACTIONS, None, **kw)
        np.testing.assert_array_equal(obs[i], so)
    assert env.config.params.velocity_correction and env.config.scheme == "fox-goodwin-vc"
    plain, _ = env_run("GearSpeedDemand-v1", 60, ENV_ACTIONS, None, **{**kw, "scheme": "fox-goodwin"})
    assert not np.array_equal(plain, env_run("GearSpeedDemand-v1", 60, ENV_ACTIONS, None, **kw)[0])


def test_env_rows_below_the_corrected_limit_take_the_plain_step_at_the_plain_beta(monkeypatch):
    """A row whose interval goes below the corrected scheme's stable omega at its step count leaves the correction
    for that interval: between the two limits (omega 0.158-0.171 at 64 steps) it keeps beta 1/12 with the plain
    step, lower down it takes the plain step's stable beta; the plant's constants come back after the call."""
    from gear_env.envs.env_core import GearSpeedCore as EnvCore
    from gear_env.sim.linear import min_steps_per_period
    from gear_env.sim.params import C_VC

    seen = []
    fixed = EnvCore._integrate_fixed

    def spy(self, rows, w0, w1, periods, nsp):
        w = float(np.min(np.minimum(w0, w1)))
        seen.append((w, float(self.C[rows[0], C_BETA]), float(self.C[rows[0], C_VC])))
        return fixed(self, rows, w0, w1, periods, nsp)

    monkeypatch.setattr(EnvCore, "_integrate_fixed", spy)
    for w in (0.165, 0.14, 0.5):
        start = {"omega_min": 0.1, "initial_omega": (w, w), "max_domega": 1e-3}
        env, _ = env_run("GearSpeedDemand-v1", 3, ENV_ACTIONS, None, **start)
        assert env.shape[0] == len(ENV_ACTIONS) + 1
    by_w = {round(w, 3): (b, v) for w, b, v in seen}
    mid = [bv for w, bv in by_w.items() if 0.159 < w < 0.17]
    low = [bv for w, bv in by_w.items() if w < 0.157]
    high = [bv for w, bv in by_w.items() if w > 0.2]
    assert mid and all(b == FOX_GOODWIN_BETA and v == 0.0 for b, v in mid)
    assert low and all(b > FOX_GOODWIN_BETA and v == 0.0 for b, v in low)
    assert high and all(b == FOX_GOODWIN_BETA and v == 1.0 for b, v in high)
    assert min_steps_per_period(FG, 0.165) <= 64 < min_steps_per_period(VC, 0.165)


def test_env_refuses_a_params_dict_that_contradicts_the_scheme():
    import gymnasium as gym

    import gear_env  # noqa: F401

    with pytest.raises(ValueError, match=r"params.velocity_correction = False conflicts with scheme='fox-goodwin-vc'"):
        gym.make("GearSpeedDemand-v1", params={"newmark_beta": 1 / 12, "velocity_correction": False})
    with pytest.raises(ValueError, match=r"params.velocity_correction = True conflicts with scheme='fox-goodwin'"):
        gym.make(
            "GearSpeedDemand-v1", scheme="fox-goodwin", params={"newmark_beta": 1 / 12, "velocity_correction": True}
        )
    env = gym.make("GearSpeedDemand-v1", scheme="fox-goodwin-vc", params=FG)  # a GearParams: the scheme wins
    assert env.unwrapped.config.params.velocity_correction
