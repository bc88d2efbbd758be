"""The torque fluctuation (GearParams.T_p1, T_g1), the involute backlash law (backlash_law="involute") and ROSS's
force direction (mesh_force_direction="gradient"), issue 28 item 5: off, the paper's model bit for bit; on, the
load term against the exact linear response, all three against the independent solve_ivp integrator, the law
against its formula, the static balance of the gradient force; the entry points that refuse them; ROSS's
test_mesh_with_backlash rebuilt."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gear_env import GearParams, GearSimulator, simulate
from gear_env.sim import kernels as K
from gear_env.sim.integration import integrate
from gear_env.sim.linear import backlash_gradient, matrices, mesh_vector
from gear_env.sim.params import C_NT, FORCE_GRADIENT, LAW_INVOLUTE, kernel_code, model_code, refuse_extensions
from gear_env.sim.reference import RefConsts, reference_initial_state, reference_poincare, rhs
from gear_env.sim.simulator import default_initial_state, simulate_batch

TORQUE = dict(T_p1=10.0, T_g1=8.0, phi_Tp=0.4, phi_Tg=-1.1, torque_order=3.0)


def test_defaults_leave_the_paper_model_untouched():
    p = GearParams()
    # amplitudes 0: the phases and the order do not reach the kernels; the law "paper" is the paper's code
    q = GearParams(T_p1=0.0, T_g1=0.0, phi_Tp=0.3, phi_Tg=2.0, torque_order=2.0, backlash_law="paper")
    assert np.array_equal(p.consts, q.consts) and not q.torque_fluctuates
    assert p.consts[C_NT] == 0.0 and GearParams(T_g1=1.0).consts[C_NT] == 1.0
    assert kernel_code("dynamic", p) == model_code("dynamic") == 1
    assert kernel_code("dynamic", GearParams(backlash_law="involute")) == 1 | LAW_INVOLUTE
    assert kernel_code("dynamic", GearParams(mesh_force_direction="gradient")) == 1 | FORCE_GRADIENT
    both = GearParams(backlash_law="involute", mesh_force_direction="gradient")
    assert kernel_code("constant", both) == 0  # B_d = B_c, psi = alpha0: no law, the gradient is the LOA
    # the dict of the paper's parameters is what it was; the new fields appear only when set and round-trip
    new = {"T_p1", "T_g1", "phi_Tp", "phi_Tg", "torque_order", "backlash_law", "mesh_force_direction"}
    assert not new & set(p.to_dict())
    r = GearParams(backlash_law="involute", mesh_force_direction="gradient", **TORQUE)
    assert GearParams.from_dict(r.to_dict()) == r and r.to_dict()["backlash_law"] == "involute"


@pytest.mark.parametrize("record", [False, True])
@pytest.mark.parametrize("code", [0, 1])
def test_torque_path_with_zero_amplitude_is_bit_identical(code, record):
    """The kernels' torque path (C_NT = 1, both amplitudes 0) gives the constant-torque run bit for bit: the
    path changes nothing but the U row's load, and a zero fluctuation adds exactly 0."""
    p = GearParams()
    c = p.consts.copy()
    c[C_NT] = 1.0
    c = K.readonly(c)
    out = []
    for consts in (p.consts, c):
        x = default_initial_state(p, "dynamic" if code else "constant")
        a = np.zeros(K.NDOF)
        r = integrate(x, a, consts, code, 1.3, 1.3, 6, 64, record=record)
        out.append(r.record if record else np.concatenate([x, r.poincare.ravel(), r.stats]))
    assert np.array_equal(out[0], out[1])


def _fit(phase: np.ndarray, y: np.ndarray, nu: float, ph: float) -> complex:
    """Complex amplitude c of y ~ mean + Im(c exp(i (nu phase + ph))) = mean + Re(c) sin(.) + Im(c) cos(.)."""
    arg = nu * phase + ph
    A = np.column_stack([np.ones_like(arg), np.sin(arg), np.cos(arg)])
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    return complex(coef[1], coef[2])


def test_torque_term_against_the_exact_linear_response():
    """In permanent contact without TE and stiffness variation (constant model) the equations are linear:
    the mesh force's response to the pinion torque's fluctuation is g.q + 2 xi_m g.q' with
    (K - W^2 M + i W C) q = A_p e_U, W = nu omega (natural time). Near mode 1 (0.32), so the inertia,
    damping, amplitude, frequency and phase of the term all show."""
    p = GearParams(kappa=0.0, e_m1=0.0, T_p1=0.5, phi_Tp=0.7, torque_order=20.0)  # nu_p = 20/55
    omega = 0.8
    nu = p.torque_order / p.z_p
    w = nu * omega  # 0.291, below mode 1
    sim = GearSimulator(p, "constant", 192, omega)
    sim.advance(150)  # the start's transient (mode 1, zeta 0.024) decays below 1e-6
    tr = sim.record(11)  # 4 torque cycles
    assert np.all(tr["region"] == 1)
    M, C, Kmat = matrices(p, "constant")
    g = mesh_vector(p)
    amp = p.m_e * p.r_bp * p.T_p1 / (p.J_p * p.k_m0 * p.length_scale)
    q = np.linalg.solve(Kmat - w * w * M + 1j * w * C, amp * np.eye(5)[4])
    expected = (1.0 + 2.0 * p.xi_m * 1j * w) * (g @ q)  # complex amplitude of F on exp(i W s)
    # the record's phase restarts at 0: the torque phase there is phi_Tp + 2 pi nu * 150
    ph = p.phi_Tp + 2.0 * math.pi * nu * 150
    got = _fit(tr.phase, tr["force"], nu, ph)  # the load is A_p sin(.) = Im(A_p e^{i .}): F = Im(expected e^{i .})
    assert abs(got - expected) < 2e-4 * abs(expected), (got, expected)
    assert abs(expected) > 3.0 * amp  # the resonance amplifies: a quasi-static law would be off by far


def test_torque_and_law_agree_with_solve_ivp():
    """The dynamic model with both torques fluctuating and the involute law, against the independent integrator
    of gear_env/sim/reference.py (its own statement of the load and of the law), through contact loss."""
    p = GearParams(backlash_law="involute", **TORQUE)
    sim = GearSimulator(p, "dynamic", None, 2.8)
    st = sim.advance(12)
    ref = reference_poincare(2.8, "dynamic", p, transient=0, periods=12)
    assert ref.events >= 8
    assert np.max(np.abs(st.poincare[:, :10] - ref.states)) < 1e-3
    assert np.max(np.abs(st.poincare[:, 11] - ref.bd)) < 1e-4
    # the terms are not negligible here: without them the trajectory is elsewhere
    off = GearSimulator(GearParams(), "dynamic", None, 2.8).advance(12)
    assert np.max(np.abs(off.poincare[:, :10] - ref.states)) > 1e-2


@pytest.mark.parametrize("law", ["paper", "involute"])
def test_gradient_force_accelerations_against_the_reference(law):
    """With mesh_force_direction="gradient" the kernels' accelerations (kernels.accel, the one residual) on random
    states in all three contact regions equal reference.rhs, whose force direction is the central-difference
    gradient of its own Delta - region B_d."""
    p = GearParams(backlash_law=law, mesh_force_direction="gradient", kappa=0.15)
    c = K.readonly(p.consts)
    code = kernel_code("dynamic", p)
    ref = RefConsts.from_params(p)
    rng = np.random.default_rng(5)
    regions = set()
    for _ in range(40):
        x = np.concatenate([rng.normal(0.0, 2.0, 4), rng.normal(0.0, 1.6, 1), rng.normal(0.0, 0.5, 5)])
        phi, w = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.3, 3.0)
        ce, se, kk = K.excitation(phi, c)
        geo = np.zeros(K.GEO_SIZE)
        a = np.zeros(5)
        K.accel(x[:5], x[5:], ce, se, w, kk, c, code, geo, a)
        delta, _dd, bd, _f, region = K.mesh_state(x[:5], x[5:], ce, se, w, c, code, np.zeros(K.GEO_SIZE))
        regions.add(region)
        a_ref = rhs(0.0, np.concatenate([x, [phi]]), w, ref, "dynamic")[5:10]
        assert np.max(np.abs(a - a_ref)) < 1e-8 * (1.0 + np.max(np.abs(a_ref))), (a, a_ref)
        line = np.zeros(5)
        K.accel(x[:5], x[5:], ce, se, w, kk, K.readonly(p.replace(mesh_force_direction="line_of_action").consts),
                code & ~FORCE_GRADIENT, np.zeros(K.GEO_SIZE), line)  # fmt: skip
        if region != 0:
            assert np.max(np.abs(line[:4] - a[:4])) > 1e-3 * np.max(np.abs(a[:4]))  # the direction matters
    assert regions == {-1, 0, 1}


def test_gradient_force_trajectory_against_solve_ivp():
    """The gradient force through contact loss, error-controlled with located contact changes (the force's
    direction jumps where the teeth part, by 2 xi_m Delta' dB_d/dq, as in ROSS: fixed steps converge there
    at first order only, 1e-3 at the default 192 steps), against the reference: 1e-5 at tol 1e-7."""
    p = GearParams(backlash_law="involute", mesh_force_direction="gradient")
    ref = reference_poincare(2.8, "dynamic", p, transient=0, periods=6)
    st = GearSimulator(p, "dynamic", None, 2.8, tol=1e-7).advance(6)
    assert ref.events >= 6
    assert np.max(np.abs(st.poincare[:, :10] - ref.states)) < 3e-5


def test_torque_phase_carries_across_intervals():
    """advance(7) then record(8) continues the torque cycle where a single record(15) has it."""
    p = GearParams(**TORQUE)
    one = GearSimulator(p, "dynamic", 96, 1.1).record(15)
    sim = GearSimulator(p, "dynamic", 96, 1.1)
    sim.advance(7)
    two = sim.record(8)
    assert np.max(np.abs(one.states[-1] - two.states[-1])) < 1e-9
    # a phase restarted at 0 would be far off
    lost = GearSimulator(p, "dynamic", 96, 1.1, initial_state=one.states[7 * 96]).record(8)
    assert np.max(np.abs(lost.states[-1] - one.states[-1])) > 1e-4


def test_involute_law_against_its_formula():
    """B_d = B_c + R (inv alpha_d - inv alpha0) at random centre positions; its gradient by central
    differences; to first order in the centre separation eps, B_d - B_c = eps sin(alpha0), where the
    paper's law has tan(alpha0) (the linearisation in gear_env.sim.linear follows the law)."""
    p = GearParams(backlash_law="involute")
    c = p.consts
    b0 = p.length_scale
    R = (p.r_bp + p.r_bg) / b0
    a0 = p.alpha0
    rng = np.random.default_rng(28)
    geo = np.zeros(K.GEO_SIZE)
    for _ in range(20):
        q = np.concatenate([rng.normal(0.0, 3.0, 4), [0.0]])
        K.geometry(q, c, LAW_INVOLUTE, geo)
        ad = math.hypot(p.a0 / b0 - q[0] + q[2], q[1] - q[3])
        al = math.acos(R / ad)
        assert geo[1] == pytest.approx(p.b_c / b0 + R * ((math.tan(al) - al) - (math.tan(a0) - a0)), abs=1e-12)
        for i in range(4):
            e = np.zeros(5)
            e[i] = 1e-4
            hi, lo = np.zeros(K.GEO_SIZE), np.zeros(K.GEO_SIZE)
            K.geometry(q + e, c, LAW_INVOLUTE, hi)
            K.geometry(q - e, c, LAW_INVOLUTE, lo)
            assert geo[2 + i] == pytest.approx((hi[1] - lo[1]) / 2e-4, abs=1e-8)
    eps = 1e-3  # b0: the gear moves away from the pinion along the centre line
    for law, code, slope in (("involute", LAW_INVOLUTE, math.sin(a0)), ("paper", 1, math.tan(a0))):
        K.geometry(np.array([0.0, 0.0, eps, 0.0, 0.0]), GearParams(backlash_law=law).consts, code, geo)
        assert (geo[1] - 1.0) / eps == pytest.approx(slope, rel=1e-5)
        assert backlash_gradient(GearParams(backlash_law=law))[2] == pytest.approx(slope, rel=1e-12)


def test_involute_law_moves_the_backlash_by_cos_alpha():
    """Same run, the two laws: the backlash's increase over B_c differs by the ratio sin/tan = cos(alpha0) (the
    centres barely move differently)."""
    p = GearParams(T_p=400.0, T_g=400.0 * 75 / 55)  # a load that spreads the centres visibly
    rise = {}
    for law in ("paper", "involute"):
        tr = simulate(1.2, "dynamic", periods=5, transient=50, params=p.replace(backlash_law=law))
        rise[law] = float(np.mean(tr["bd"])) - 1.0
    assert rise["involute"] / rise["paper"] == pytest.approx(math.cos(p.alpha0), rel=2e-3)


def test_gradient_force_static_balance():
    """With the mesh force along the gradient of Delta - B_d the bearings carry, along the line of centres, the
    line of action's F sin(alpha0) plus F dB_d/d(separation) = F sin(alpha0) (involute law, to first order):
    twice the paper's. The kernels' A10 state against that and against the reference's own static solve."""
    for law, slope in (("involute", "sin"), ("paper", "tan")):
        p = GearParams(T_p=400.0, T_g=400.0 * 75 / 55, backlash_law=law, mesh_force_direction="gradient")
        x = default_initial_state(p, "dynamic")
        assert np.max(np.abs(x - reference_initial_state(p, "dynamic"))) < 1e-9
        a = p.alpha0
        fs = p.dimensionless()["F_s"]
        extra = math.sin(a) if slope == "sin" else math.tan(a)
        lam = p.k_p / p.k_m0
        assert x[0] == pytest.approx(-fs * (math.sin(a) + extra) / lam, rel=1e-2)  # first order: psi, curvature
        loa = default_initial_state(p.replace(mesh_force_direction="line_of_action"), "dynamic")
        assert loa[0] == pytest.approx(-fs * math.sin(a) / lam, rel=1e-3)
        assert x[1] == pytest.approx(loa[1], rel=1e-3)  # across the line of centres: the same


def test_bad_inputs_name_the_field():
    with pytest.raises(ValueError, match=r"backlash_law must be one of \('paper', 'involute'\)"):
        GearParams(backlash_law="ross")
    with pytest.raises(ValueError, match=r"mesh_force_direction must be one of \('line_of_action', 'gradient'\)"):
        GearParams(mesh_force_direction="ross")
    with pytest.raises(ValueError, match=r"T_p1 must be in \[0, 1e\+07\]"):
        GearParams(T_p1=-1.0)
    with pytest.raises(ValueError, match=r"torque_order must be in \(0, 1000\]"):
        GearParams(torque_order=0.0)
    with pytest.raises(ValueError, match=r"phi_Tg must be a real number"):
        GearParams(phi_Tg="1")
    with pytest.raises(ValueError, match="tol .* does not take a torque fluctuation"):
        GearSimulator(GearParams(T_p1=1.0), tol=1e-6)


def test_entry_points_that_cannot_carry_them_refuse():
    from gear_env.analysis.continuation import OrbitMap
    from gear_env.analysis.floquet import PeriodMap
    from gear_env.envs.env_config import GearSpeedConfig

    for p, word in (
        (GearParams(T_p1=1.0), "torque fluctuation"),
        (GearParams(backlash_law="involute"), "backlash law"),
        (GearParams(mesh_force_direction="gradient"), "force direction"),
    ):
        with pytest.raises(ValueError, match=word):
            refuse_extensions(p, "x")
        with pytest.raises(ValueError, match=f"simulate_batch .*{word}"):
            simulate_batch([1.0], periods=1, transient=0, params=p)
        with pytest.raises(ValueError, match=f"Floquet analysis .*{word}"):
            PeriodMap(1.0, "dynamic", p)
        with pytest.raises(ValueError, match=f"continuation .*{word}"):
            OrbitMap("dynamic", p, 1)
        with pytest.raises(ValueError, match=word):
            GearSpeedConfig(params=p)


def _ross_backlash_module():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import ross_backlash
    finally:
        sys.path.pop(0)
    return ross_backlash


def test_benchmark_port_of_ross_square_wave():
    """benchmarks/ross_backlash.py's port of ROSS's square-wave stiffness gives ROSS's waveform on ROSS's grid
    (Mesh.stiffness_range of the test pair, ROSS 3.1: levels, duty and mean pinned from ROSS)."""
    rb = _ross_backlash_module()
    g = rb.pitch_geometry()
    assert g["contact_ratio"] == pytest.approx(1.5568383033751572, rel=1e-12)  # ROSS Mesh.contact_ratio
    assert g["k_mean"] == pytest.approx(518946101.12505233, rel=1e-12)  # ROSS Mesh.stiffness
    assert g["Ip"] == pytest.approx(0.03652841951988386, rel=1e-12)
    k = rb.ross_square_wave(np.linspace(0.0, 2.0 * np.pi, 1000), g["contact_ratio"], g["k_mean"])
    assert k.min() == pytest.approx(360052847.88424814, rel=1e-10)
    assert k.max() == pytest.approx(645431408.7837703, rel=1e-10)
    assert k.mean() == pytest.approx(518723327.74438244, rel=1e-10)
    assert int(np.sum(k > k.mean())) == 556 and k[0] == k.min() and k[1] == k.max()


def test_ross_case_means():
    """ROSS's test_mesh_with_backlash rebuilt (the comparison docs/VALIDATION.md shows): with ROSS's law and force
    direction every asserted mean within 2 % (measured: 0.13 % at most), and the parts that move too (centre
    distance, bearing x); with the paper's force direction the TE and backlash are 10-12 % low and the bearings
    carry half ROSS's separating force, as the static balance says."""
    rb = _ross_backlash_module()
    res = rb.comparison()
    rows = {r["quantity"]: r for r in res["rows"]}
    for r in res["rows"]:
        assert abs(r["rel_ross"]) < 0.02, r
    for q in ("mesh force [N]", "mesh stiffness [N/m]", "centre distance [m]", "pressure angle [rad]"):
        assert abs(rows[q]["rel_involute"]) < 0.02, rows[q]
    for q in ("transmission error [m]", "backlash [m]"):
        assert -0.12 < rows[q]["rel_involute"] < -0.09, rows[q]
    shift = {r["quantity"]: r for r in res["shifts"]}
    for r in res["shifts"]:
        assert r["ross"] / r["ref"] == pytest.approx(1.0, rel=0.02), r
    assert shift["bearing x_1 [m]"]["involute"] / shift["bearing x_1 [m]"]["ref"] == pytest.approx(0.5, rel=0.01)
    assert shift["bearing y_1 [m]"]["involute"] / shift["bearing y_1 [m]"]["ref"] == pytest.approx(1.0, rel=0.01)
    assert res["static"]["ROSS gradient"]["backlash [m]"] == pytest.approx(rows["backlash [m]"]["ref"], rel=1e-3)
    # with ROSS's force, the paper's law moves the TE and backlash by 1.5-3 % (slope and separation both grow)
    for q in ("transmission error [m]", "backlash [m]"):
        assert 0.015 < rows[q]["rel_paper_law"] < 0.03, rows[q]
    # along the line of action the paper's law raises the backlash's rise by 1/cos(alpha0)
    b = shift["backlash [m] minus nominal"]
    assert b["paper"] / b["involute"] == pytest.approx(1.0 / math.cos(math.radians(20.0)), rel=2e-3)
