"""Kernel-level checks: geometry, backlash, accelerations vs the independent reference RHS,
Newmark step equilibrium, energy conservation and period elongation of undamped linear Newmark,
and the free-vibration period through a dead zone."""

import math

import numpy as np
import pytest

from gear_env import GearParams, GearSimulator, default_initial_state
from gear_env.sim import kernels as K
from gear_env.sim.linear import matrices, modes, natural_frequencies
from gear_env.sim.reference import RefConsts, mesh_geometry, rhs


def test_backlash_dead_zone():
    assert K.backlash(1.5, 1.0) == (0.5, 1)
    assert K.backlash(0.3, 1.0) == (0.0, 0)
    assert K.backlash(-0.99, 1.0) == (0.0, 0)
    assert K.backlash(-2.0, 1.0) == (-1.0, -1)
    assert K.backlash(1.0, 1.0) == (0.0, 1)  # boundary belongs to the contact region


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_geometry_matches_reference(model):
    p = GearParams()
    c = p.consts
    code = 0 if model == "constant" else 1
    k = RefConsts.from_params(p)
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.normal(scale=0.5, size=5)
        out = np.zeros(K.GEO_SIZE)
        K.geometry(q, c, code, out)
        psi, bd = mesh_geometry(q, k, model)
        assert abs(out[0] - psi) < 1e-13
        assert abs(out[1] - bd) < 1e-11
        if model == "dynamic":
            # derivative entries vs central differences of the reference geometry
            for j in range(4):
                dq = np.zeros(5)
                dq[j] = 1e-5
                bp, bm = mesh_geometry(q + dq, k, model)[1], mesh_geometry(q - dq, k, model)[1]
                pp, pm = mesh_geometry(q + dq, k, model)[0], mesh_geometry(q - dq, k, model)[0]
                assert abs(out[2 + j] - (bp - bm) / 2e-5) < 1e-6
                assert abs(out[7 + j] - (pp - pm) / 2e-5) < 1e-9


def test_psi_invariant_along_line_of_action():
    """MODEL.md sec. 6: a relative centre displacement along the LOA leaves psi at alpha0."""
    p = GearParams()
    k = RefConsts.from_params(p)
    a = p.alpha0
    for t in (-3.0, -0.5, 0.7, 5.0):
        q = np.array([t * math.sin(a), -t * math.cos(a), 0.0, 0.0, 0.0])
        out = np.zeros(K.GEO_SIZE)
        K.geometry(q, p.consts, 1, out)
        assert abs(out[0] - a) < 1e-13
        # moving the pinion by t along g brings the centres closer by t sin(a0):
        # B_d changes by -t sin(a0) tan(a0) (dB_d/dk = sin a0 tan a0 = 0.1245, MODEL.md sec. 5)
        assert abs((1.0 - out[1]) / t - math.sin(a) * math.tan(a)) < 1e-3
        assert abs(mesh_geometry(q, k, "dynamic")[0] - a) < 1e-13


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_accel_matches_reference_rhs(model):
    p = GearParams()
    code = 0 if model == "constant" else 1
    k = RefConsts.from_params(p)
    rng = np.random.default_rng(2)
    for _ in range(30):
        x = rng.normal(scale=[0.3] * 4 + [1.5] + [0.3] * 5)
        phi = rng.uniform(0, 2 * np.pi)
        w = rng.uniform(0.2, 3.0)
        ce, se, kk = K.excitation(phi, p.consts)
        a = np.zeros(5)
        geo = np.zeros(K.GEO_SIZE)
        F = K.accel(x[:5], x[5:], ce, se, w, kk, p.consts, code, geo, a)
        ref = rhs(0.0, np.concatenate([x, [phi]]), w, k, model)
        assert np.allclose(a, ref[5:10], rtol=1e-12, atol=1e-12)
        assert np.isfinite(F)


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_newmark_step_satisfies_equation_of_motion_at_step_end(model):
    """Sherman-Morrison Newton: the end-of-step acceleration is the RHS at the end state."""
    p = GearParams()
    code = 0 if model == "constant" else 1
    k = RefConsts.from_params(p)
    x = default_initial_state(p, model)
    a = np.zeros(5)
    work = np.zeros(K.WORK_SIZE)
    w = 2.8
    K.start_step(x, a, 0.0, w, p.consts, code, work)
    n = 32
    dphi = 2 * np.pi / n
    for i in range(3 * n):  # crosses contact changes (loss of contact from A10 at omega = 2.8)
        phi_b = dphi * (i + 1)
        ce, se, kk = K.excitation(phi_b, p.consts)
        st, F, region, delta, bd, split = K.newmark_step(
            x, a, dphi * i, dphi, ce, se, kk, w, w, p.consts, code, work, 30, 1e-13
        )
        assert st == K.OK
        ref = rhs(0.0, np.concatenate([x, [phi_b]]), w, k, model)
        assert np.allclose(a, ref[5:10], rtol=1e-9, atol=1e-9), (i, a, ref[5:10])
        # the Newton residual (kernels.newmark) and the explicit accelerations (kernels.mesh.accel)
        # state the same equations of motion
        a_explicit = np.zeros(5)
        K.accel(x[0:5], x[5:10], ce, se, w, kk, p.consts, code, np.zeros(K.GEO_SIZE), a_explicit)
        assert np.allclose(a, a_explicit, rtol=1e-11, atol=1e-11), (i, a, a_explicit)


def _linear_params(**kw):
    """Undamped, unforced (kappa = 0, e_m1 = 0) with a large static load: stays in contact."""
    base = dict(xi_m=0.0, xi_p=0.0, xi_g=0.0, kappa=0.0, e_m1=0.0, T_p=220.0, T_g=300.0)
    base.update(kw)
    return GearParams(**base)


def test_undamped_linear_newmark_conserves_energy():
    p = _linear_params()
    M, _, Kmat = matrices(p)
    xs = default_initial_state(p, "constant")
    x0 = xs.copy()
    x0[4] += 0.05
    x0[5:] = [0.01, -0.02, 0.015, 0.0, 0.03]
    sim = GearSimulator(p, "constant", 16, 0.9, x0)
    tr = sim.record(50)
    assert np.all(tr["region"] == 1)  # linear: always in drive-side contact
    dq = tr.states[:, :5] - xs[:5]
    v = tr.states[:, 5:]
    energy = 0.5 * np.einsum("ni,ij,nj->n", v, M, v) + 0.5 * np.einsum("ni,ij,nj->n", dq, Kmat, dq)
    assert energy[0] > 1e-4
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-11


@pytest.mark.parametrize("mode_index", [0, 4])
@pytest.mark.parametrize("n_steps", [8, 16, 64])
def test_newmark_period_elongation(mode_index, n_steps):
    """Average-acceleration Newmark: T_num/T = (w h/2)/atan(w h/2), exactly for a linear mode."""
    p = _linear_params()
    w_all, phi = modes(p)
    wm = w_all[mode_index]
    shape = phi[:, mode_index]
    M, _, _ = matrices(p)
    xs = default_initial_state(p, "constant")
    x0 = xs.copy()
    x0[:5] += 0.05 * shape / np.max(np.abs(shape))
    omega = 0.7
    sim = GearSimulator(p, "constant", n_steps, omega, x0)
    tr = sim.record(30)
    assert np.all(tr["region"] == 1)
    h = 2 * np.pi / (n_steps * omega)
    eta = (tr.states[:, :5] - xs[:5]) @ (M @ shape) / (shape @ M @ shape)
    # exact discrete recurrence eta_{n+1} + eta_{n-1} = 2 cos(w_num h) eta_n
    cos_wh = np.sum(eta[1:-1] * (eta[2:] + eta[:-2])) / (2 * np.sum(eta[1:-1] ** 2))
    w_num = math.acos(cos_wh) / h
    expected = (wm * h / 2) / math.atan(wm * h / 2)
    assert abs(wm / w_num - expected) < 1e-9 * expected
    # the other modes stay unexcited (modal decoupling is exact for the linear scheme)
    resid = tr.states[:, :5] - xs[:5] - np.outer(eta, shape)
    assert np.max(np.abs(resid)) < 1e-10


def _crossing_periods(s, u):
    i = np.where((u[:-1] < 0) & (u[1:] >= 0))[0]
    tc = s[i] - u[i] * (s[i + 1] - s[i]) / (u[i + 1] - u[i])
    return np.diff(tc)


@pytest.mark.parametrize("v_gap", [0.5, 0.2])
def test_free_vibration_period_through_dead_zone(v_gap):
    """Period = 2 pi / omega_c + 4 B / v_gap (rigid bearings, no damping, no torque, no TE)."""
    p = GearParams(k_p=1e14, k_g=1e14, xi_m=0.0, xi_p=0.0, xi_g=0.0, kappa=0.0, e_m1=0.0, T_p=0.0, T_g=0.0)
    wn = natural_frequencies(p)
    wc = wn[np.argmin(np.abs(wn - 1.0))]  # the torsional (mesh) mode, ~1 with rigid bearings
    x0 = np.zeros(10)
    x0[9] = v_gap  # start mid-gap, moving towards the drive side
    sim = GearSimulator(p, "constant", 4096, 0.2, x0)
    tr = sim.record(6)
    reg = tr["region"]
    assert (reg == 1).any() and (reg == -1).any() and (reg == 0).any()
    T = _crossing_periods(tr.s, tr["U"])
    assert len(T) >= 5
    expected = 2 * np.pi / wc + 4 * 1.0 / v_gap
    assert np.max(np.abs(T - expected)) / expected < 2e-5


def test_integrate_split_steps_match_step_by_step():
    """The fallback of the stats and the recording loops for steps that Newton does not finish
    (split into sub-steps, taken outside the hot loop) gives, bit for bit, what stepping one
    step at a time with ``newmark_step`` gives. ``max_iter=1`` makes contact changes need it."""
    p = GearParams()
    c = K.readonly(p.consts)
    w, n, periods = 0.5, 32, 200
    x = default_initial_state(p, "constant")
    a = np.zeros(5)
    pc = np.zeros((periods, K.N_PC))
    st = np.zeros(K.N_STATS)
    status, done, _ = K.integrate_stats(x, a, 0.0, w, w, periods, n, c, 0, pc, st, 1, 1e-10, True)
    assert (status, done) == (K.OK, periods)
    assert st[K.ST_SPLITS] >= 10  # the fallback ran
    xo = default_initial_state(p, "constant")
    ao = np.zeros(5)
    rec = np.zeros((periods * n + 1, K.N_REC))
    assert K.integrate_record(xo, ao, 0.0, w, w, periods, n, c, 0, rec, 1, 1e-10)[:2] == (K.OK, periods * n + 1)
    xr = default_initial_state(p, "constant")
    ar = np.zeros(5)
    work = np.zeros(K.WORK_SIZE)
    K.start_step(xr, ar, 0.0, w, c, 0, work)
    tab = K._excitation_table(0.0, n, c)
    dphi = 2 * np.pi / n
    splits = sep = 0.0
    for j in range(periods * n):
        m = (j + 1) % n
        st_j, F, region, delta, bd, split = K.newmark_step(
            xr, ar, dphi * j, dphi, tab[m, 0], tab[m, 1], tab[m, 2], w, w, c, 0, work, 1, 1e-10
        )
        assert st_j == K.OK
        splits += split
        sep += region == 0
        assert np.array_equal(rec[j + 1, :10], xr) and rec[j + 1, K.REC_FORCE] == F, j
        if m == 0:
            assert np.array_equal(pc[(j + 1) // n - 1, :10], xr), j
            assert pc[(j + 1) // n - 1, K.PC_FORCE] == F
    assert np.array_equal(x, xr) and np.array_equal(a, ar)
    assert st[K.ST_SPLITS] == splits and st[K.ST_STEPS] == periods * n
    assert st[K.ST_SEP_TIME] == pytest.approx(sep * dphi / w, rel=1e-12)


def test_integrate_split_steps_dynamic_model_during_a_ramp():
    """The re-entry after a split step, in the case where it matters: the dynamic model (whose
    Newton guess is an extrapolation, except right after a split) while omega ramps (the step's
    coefficients change every step). Reference: the single loop the kernels used to run, written
    in Python from the same step functions (try the step; split it if Newton fails; guess;
    next), compared bit for bit with both kernels."""
    p = GearParams()
    c = K.readonly(p.consts)
    w0, w1, n, periods, max_iter = 2.3, 2.5, 32, 6, 1
    x = default_initial_state(p, "dynamic")
    a = np.zeros(5)
    pc = np.zeros((periods, K.N_PC))
    st = np.zeros(K.N_STATS)
    assert K.integrate_stats(x, a, 0.0, w0, w1, periods, n, c, 1, pc, st, max_iter, 1e-10, True)[:2] == (K.OK, periods)
    assert st[K.ST_SPLITS] >= 20
    xo = default_initial_state(p, "dynamic")
    ao = np.zeros(5)
    rec = np.zeros((periods * n + 1, K.N_REC))
    assert K.integrate_record(xo, ao, 0.0, w0, w1, periods, n, c, 1, rec, max_iter, 1e-10)[0] == K.OK

    xr = default_initial_state(p, "dynamic")
    ar = np.zeros(5)
    K.start_step(xr, ar, 0.0, w0, c, 1, np.zeros(K.WORK_SIZE))
    k = K.step_consts(c)
    tab = K._excitation_table(0.0, n, c)
    total = periods * n
    dphi = 2 * np.pi / n
    ww = (w1 * w1 - w0 * w0) / total
    s = tuple(xr) + tuple(ar)
    g = tuple(ar)
    wa, hc = w0, K.step_coeffs(dphi / w0, k)
    splits = 0
    for j in range(total):
        wb, hc = K.omega_step_t(j, wa, hc, w0, ww, dphi, k)
        m = (j + 1) % n
        ok, s1, F, *_ = K.newmark_try_t(s, g, tab[m, 0], tab[m, 1], tab[m, 2], wb, hc, k, 1, max_iter, 1e-10)
        split = not ok
        if split:
            code, s1, F, *_ = K.split_step_t(s, dphi * j, dphi, wa, wb, c, k, 1, max_iter, 1e-10)
            assert code == K.OK
        splits += split
        g = K.guess_t(s, s1, split)
        s = s1
        assert np.array_equal(rec[j + 1, :10], s[:10]), j
        if m == 0:
            assert np.array_equal(pc[(j + 1) // n - 1, :10], s[:10]) and pc[(j + 1) // n - 1, K.PC_FORCE] == F
        wa = wb
    assert splits == st[K.ST_SPLITS]
    assert np.array_equal(x, s[:10]) and np.array_equal(a, s[10:]) and np.array_equal(xo, x)


@pytest.mark.parametrize(("model", "max_iter"), [(0, 1), (1, 1), (1, 0)])
def test_lazy_entry_matches_the_compiled_loop_bit_for_bit(model, max_iter):
    """``integrate_stats_lazy`` (the single-system entry: a Python loop over ``stats_segment`` and
    ``split_resume``) gives ``integrate_stats``'s numbers bit for bit: with many split steps
    (max_iter=1) during a ramp, and when a step fails even split (max_iter=0: nothing converges)."""
    p = GearParams()
    c = K.readonly(p.consts)
    name = "dynamic" if model else "constant"
    w0, w1, n, periods = (2.3, 2.5, 32, 6) if model else (0.5, 0.55, 32, 200)  # both: many splits
    out = []
    for f in (K.integrate_stats, K.integrate_stats_lazy):
        x = default_initial_state(p, name)
        a = np.zeros(5)
        pc = np.zeros((periods, K.N_PC))
        st = np.full(K.N_STATS, 7.0)
        res = f(x, a, 0.0, w0, w1, periods, n, c, model, pc, st, max_iter, 1e-10, model == 1)
        out.append((res, x, a, pc, st))
    (r0, *arrays0), (r1, *arrays1) = out
    assert r0 == r1
    assert r0[0] == (K.OK if max_iter else K.NEWTON_FAILED)
    for u, v in zip(arrays0, arrays1, strict=True):
        np.testing.assert_array_equal(u, v)
    if max_iter:
        assert arrays0[3][K.ST_SPLITS] - (0.0 if model == 1 else 7.0) >= 10  # (stats not reset for model 0)


@pytest.mark.parametrize(
    ("speed", "max_iter", "status"),
    [(4e5, 2, K.DIVERGED), (1e3, 1, K.NEWTON_FAILED)],
    ids=["diverges-in-the-split-step", "fails-after-earlier-splits"],
)
def test_lazy_entry_ends_in_split_resume_like_the_compiled_loop(monkeypatch, speed, max_iter, status):
    """The interval ends inside ``split_resume`` (the split step diverges, or fails after earlier split
    steps went through): the lazy entry reports the same status, periods, time, state, accelerations,
    Poincare rows and statistics as ``integrate_stats``, and the state it returns is finite."""
    from gear_env.sim.kernels import drivers as D

    p = GearParams()
    c = K.readonly(p.consts)
    seen: list = []
    real = D.split_resume

    def spy(*args):
        seen.append(real(*args))
        return seen[-1]

    out = []
    for f in (K.integrate_stats, K.integrate_stats_lazy):
        x = default_initial_state(p, "dynamic")
        x[5:] = speed  # velocities far from the orbit: Newton needs more than max_iter iterations
        a, pc, st = np.zeros(5), np.zeros((4, K.N_PC)), np.zeros(K.N_STATS)
        if f is K.integrate_stats_lazy:  # spy on the Python loop's calls (the compiled loop is opaque)
            monkeypatch.setattr(D, "split_resume", spy)
        res = f(x, a, 0.0, 1.2, 1.2, 4, 32, c, 1, pc, st, max_iter, 1e-10, True)
        out.append((res, x, a, pc, st))
    (r0, *arrays0), (r1, *arrays1) = out
    assert r0 == r1 and r0[0] == status
    assert seen and seen[-1] == r1  # the interval ended in split_resume's own return
    for u, v in zip(arrays0, arrays1, strict=True):
        np.testing.assert_array_equal(u, v)
    assert np.all(np.isfinite(arrays1[0])) and np.all(np.isfinite(arrays1[1]))


# every name gear_env.sim.kernels had when it was one file (kernels.py, before the split into a package);
# other modules and branches import them from gear_env.sim.kernels
_NAMES_BEFORE_SPLIT = """
BETA C_A0 C_ALPHA0 C_BC C_COS_A0 C_E1 C_EPS_G C_EPS_P C_FS C_GG C_GP C_KAPPA C_MU C_PHI_E C_PHI_K C_R C_SIG_G
C_SIG_P C_SIN_A0 C_XI_BG C_XI_BP C_XI_M DIVERGED DIVERGENCE_LIMIT DQ_LINEAR FRICTION_SHARPNESS GAMMA GEO_SIZE
MAX_SPLIT_LEVEL NDOF NEWTON_BAD NEWTON_DONE NEWTON_FAILED NEWTON_MORE NSTATE N_PC N_REC N_STATS OK PC_BD PC_DELTA
PC_FORCE PC_PSI REC_BD REC_DELTA REC_FORCE REC_OMEGA REC_PHI REC_PSI REC_REGION REC_S ST_BACK_IMPACTS ST_BACK_TIME
ST_BD_MAX ST_BD_MIN ST_DRIVE_IMPACTS ST_D_MAX ST_D_MIN ST_F_MAX ST_F_MIN ST_F_SQ ST_F_SUM ST_PSI_MAX ST_PSI_MIN
ST_SEP_TIME ST_SPLITS ST_STEPS ST_TIME ST_TR_MAX ST_TR_SQ ST_U_MAX ST_U_MIN TWO_PI WORK_SIZE _acc_init _acc_step
_acc_store _diverged_t _excitation_table _integrate_stats_batch _poincare_store_t _record_row_t _stats_init accel
backlash corrector_t excitation friction_t geometry geometry_t guess_t integrate_record integrate_stats
integrate_stats_batch integrate_stats_tab kernel kernel_inline load_t mesh_state mesh_t newmark_step newmark_step_t
newmark_try_t newton_iter_t newton_start_t njit omega_step_t psi_t readonly runtime_int runtime_true split_step_t
start_step static_equilibrium step_coeffs step_consts store_t
""".split()


def test_kernels_package_keeps_every_name_of_the_single_module():
    missing = [n for n in _NAMES_BEFORE_SPLIT if not hasattr(K, n)]
    assert missing == []
    # the same objects as in the concern modules (one definition each, re-exported)
    from gear_env.sim.kernels import drivers, layout, mesh, newmark

    assert K.integrate_stats is drivers.integrate_stats and K.backlash is mesh.backlash
    assert K.newton_iter_t is newmark.newton_iter_t and K.ST_F_MAX == layout.ST_F_MAX


def test_named_step_constants_hold_what_their_names_say():
    p = GearParams(friction=0.1)
    d = p.dimensionless()
    k = K.step_consts(p.consts)
    assert len(k) == K.N_K
    assert k[K.K_IEP] == 1.0 / d["eps_p"] and k[K.K_IEG] == 1.0 / d["eps_g"]
    assert k[K.K_C_P] == 2.0 * d["xi_p"] * d["sigma_p"] and k[K.K_K_G] == d["sigma_g"] ** 2
    assert k[K.K_XIM2] == 2.0 * d["xi_m"] and k[K.K_FS] == d["F_s"] and k[K.K_E1] == d["E1"]
    assert k[K.K_A0] == d["A0"] and k[K.K_R] == d["R"] and k[K.K_INV_R] == 1.0 / d["R"] and k[K.K_BC] == d["B_c"]
    assert k[K.K_SIN_A0] == math.sin(p.consts[K.C_ALPHA0]) and k[K.K_MU] == 0.1
    assert k[K.K_COS_PHI_E] == math.cos(p.consts[K.C_PHI_E])


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_linearised_kernel_model_is_linear_py(model):
    """The compiled model and linear.py state the same equations: the Jacobian of ``K.accel`` at
    the static equilibrium (kappa = 0, no TE, in contact) is -M^-1 K and -M^-1 C of
    ``linear.matrices``. For the dynamic model linear.py freezes psi = alpha0, so the comparison
    uses a vanishing static load (F_s -> 0 removes the F_s dpsi/dq terms it neglects)."""
    kw = dict(kappa=0.0, e_m1=0.0)
    if model == "dynamic":
        kw.update(T_p=22e-3, T_g=30e-3)  # F_s = 2.7e-5 b0: still in contact at the difference step
    p = _linear_params(**kw) if model == "constant" else GearParams(**kw)
    code = 0 if model == "constant" else 1
    c = p.consts
    x0 = np.zeros(10)
    K.static_equilibrium(c, code, 0.0, x0)
    M, C, Kmat = matrices(p, model)
    ce, se, kk = K.excitation(0.0, c)
    geo = np.zeros(K.GEO_SIZE)

    def acc(x):
        a = np.zeros(5)
        K.accel(x[0:5], x[5:10], ce, se, 1.0, kk, c, code, geo, a)
        return a

    h = 1e-7
    jac = np.empty((5, 10))
    for j in range(10):
        e = np.zeros(10)
        e[j] = h
        jac[:, j] = (acc(x0 + e) - acc(x0 - e)) / (2 * h)
    Minv = np.linalg.inv(M)
    np.testing.assert_allclose(jac[:, :5], -Minv @ Kmat, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(jac[:, 5:], -Minv @ C, rtol=1e-5, atol=1e-6)
