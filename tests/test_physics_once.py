"""The equations of motion are written once (``kernels/mesh.py``) and every path takes them from
there: the explicit accelerations, the Newton residual and its Jacobian, the SIMD lanes, the static
equilibrium and the tangent map. Checked two ways: against the independent ``reference.py`` on
random states, and by reading the source (the constants of the equations are read nowhere else)."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from gear_env.sim import batch_kernels as BK
from gear_env.sim import kernels as K
from gear_env.sim.params import GearParams, model_code
from gear_env.sim.reference import RefConsts, reference_initial_state, rhs
from gear_env.sim.simulator import NEWTON_MAX_ITER, NEWTON_TOL

PKG = Path(__file__).resolve().parents[1] / "gear_env"

# the step constants that enter the equations of motion (kernels.layout K_*)
EOM_CONSTANTS = {"K_IEP", "K_IEG", "K_C_P", "K_C_G", "K_K_P", "K_K_G", "K_EXT_P", "K_EXT_G", "K_XIM2", "K_FS"}
# where they may be named: their definition, the package's re-export, and the one model file
EOM_HOME = {"sim/kernels/layout.py", "sim/kernels/__init__.py", "sim/kernels/mesh.py"}


def _random_states(rng, n):
    """States spread over the three contact regions (U of a few b0), phases and frequencies."""
    for _ in range(n):
        x = rng.normal(scale=[0.3] * 4 + [1.5] + [0.3] * 5)
        yield x, rng.uniform(0.0, 2.0 * math.pi), rng.uniform(0.2, 3.0)


def test_equation_of_motion_constants_are_read_only_in_kernels_mesh():
    """No module but kernels/mesh.py names a constant of the equations of motion, and no module
    indexes the step constants by position (``k[8]``): a second copy of the equations would have
    to do one or the other."""
    named, positional = [], []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            name = node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else None
            if name in EOM_CONSTANTS and rel not in EOM_HOME:
                named.append(f"{rel}:{node.lineno} {name}")
            if (
                isinstance(node, ast.Subscript)
                and isinstance(node.value, ast.Name)
                and node.value.id == "k"
                and isinstance(node.slice, ast.Constant)
                and isinstance(node.slice.value, int)
            ):
                positional.append(f"{rel}:{node.lineno}")
    assert named == [] and positional == [], (named, positional)
    # and the paths that need them call the leaves
    newmark = (PKG / "sim/kernels/newmark.py").read_text(encoding="utf-8")
    assert "eom_residual_t(" in newmark and "force_gradient_t(" in newmark and "bearing_t(" in newmark
    assert "K.newton_iter_t(" in (PKG / "sim/batch_kernels.py").read_text(encoding="utf-8")
    tangent = (PKG / "analysis/tangent.py").read_text(encoding="utf-8")
    assert "K.force_direction_t(" in tangent and "K.backlash_slopes(" in tangent


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_accel_is_minus_the_residual_and_the_reference_solves_the_residual(model):
    """On random states: accel is -r(0, q, v) bit for bit, and the reference's accelerations
    (reference.rhs, written independently) make the one residual vanish to 1e-12."""
    p = GearParams()
    c = K.readonly(p.consts)
    k = K.step_consts(c)
    code = model_code(model)
    ref = RefConsts.from_params(p)
    regions = set()
    for x, phi, w in _random_states(np.random.default_rng(11), 40):
        ce, se, kk = K.excitation(phi, c)
        s = tuple(float(v) for v in x)
        delta, ddelta, bd, f, region, sp, cp, *_ = K.mesh_t(s, ce, se, w, k, code)
        regions.add(region)
        F = K.force_t(ddelta, f, kk, k)
        wdir = K.force_direction_t(sp, cp, K.friction_t(ce, se, k), k)
        a = np.zeros(5)
        F_acc = K.accel(x[:5], x[5:], ce, se, w, kk, c, code, np.zeros(K.GEO_SIZE), a)
        r0 = np.array(K.eom_residual_t((0.0,) * 5, s, F, wdir, k))
        assert F_acc == F
        np.testing.assert_array_equal(a, -r0)
        a_ref = rhs(0.0, np.concatenate([x, [phi]]), w, ref, model)[5:10]
        r = np.array(K.eom_residual_t(tuple(a_ref), s, F, wdir, k))
        assert np.max(np.abs(r)) < 1e-12 * (1.0 + np.max(np.abs(a_ref))), (r, a_ref)
    assert regions == {-1, 0, 1}


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("friction", [0.0, 0.1])
@pytest.mark.parametrize("phi0", [0.0, 1.3])
def test_static_equilibrium_is_at_rest_under_the_one_residual(model, friction, phi0):
    """static_equilibrium solves r(0, q, 0) = 0 (kappa = 0, TE frozen at phi0): accel there is
    zero to round-off, and without friction it is the reference's A10 state at phi0 = 0."""
    p = GearParams(kappa=0.0, friction=friction)
    c = K.readonly(p.consts)
    code = model_code(model)
    x = np.zeros(10)
    K.static_equilibrium(c, code, phi0, x)
    ce, se, kk = K.excitation(phi0, c)
    a = np.zeros(5)
    K.accel(x[:5], x[5:], ce, se, 0.0, kk, c, code, np.zeros(K.GEO_SIZE), a)
    assert np.max(np.abs(a)) < 1e-12, a
    assert np.all(x[5:] == 0.0)
    if friction == 0.0 and phi0 == 0.0:
        np.testing.assert_allclose(x, reference_initial_state(p, model), rtol=1e-12, atol=1e-12)


def test_backlash_law_leaves_agree():
    """backlash, backlash_branch, backlash_slopes and backlash_inverse state one law: f on the
    selected branch, its slopes by central differences, and the inverse on the drive side."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        bd = rng.uniform(0.2, 2.0)
        delta = rng.uniform(-3.0, 3.0)
        f, region = K.backlash(delta, bd)
        assert f == K.backlash_branch(delta, bd, region)
        sd, sb = K.backlash_slopes(delta, bd, region)
        h = 1e-6
        dd = (K.backlash_branch(delta + h, bd, region) - K.backlash_branch(delta - h, bd, region)) / (2 * h)
        db = (K.backlash_branch(delta, bd + h, region) - K.backlash_branch(delta, bd - h, region)) / (2 * h)
        assert abs(dd - sd) < 1e-8 and abs(db - sb) < 1e-8
        if region == 1:
            assert abs(K.backlash_inverse(f, bd) - delta) < 1e-14
    assert K.backlash(1.0, 1.0) == (0.0, 1) and K.backlash_branch(1.0, 1.0, 1) == 0.0


def test_constant_model_newton_jacobian_is_exact():
    """The constant model is piecewise linear: with the Jacobian assembled from the leaves exact,
    one Newton iteration from a poor guess lands on the solution of the step whenever the
    contact region does not change (``max_iter = 1``, no step splitting needed)."""
    p = GearParams(kappa=0.3, e_m1=0.0, T_p=220.0, T_g=300.0)  # a large static load: stays in contact
    c = K.readonly(p.consts)
    x = np.zeros(10)
    K.static_equilibrium(c, 0, 0.0, x)
    a = np.array([0.3, -0.2, 0.1, 0.05, -0.4])  # not the acceleration of x
    work = np.zeros(K.WORK_SIZE)
    w = 1.2
    dphi = 2 * np.pi / 64
    for i in range(64):
        ce, se, kk = K.excitation(dphi * (i + 1), c)
        st, F, region, delta, bd, split = K.newmark_step(x, a, dphi * i, dphi, ce, se, kk, w, w, c, 0, work, 1, 0.0)
        assert st == K.OK and split == 0 and region == 1
        a_end = np.zeros(5)
        K.accel(x[:5], x[5:], ce, se, w, kk, c, 0, np.zeros(K.GEO_SIZE), a_end)
        np.testing.assert_allclose(a, a_end, rtol=0, atol=1e-12)
        a += np.array([0.3, -0.2, 0.1, 0.05, -0.4])  # a poor guess again for the next step


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_simd_lanes_end_on_the_reference_accelerations(model):
    """The SIMD path from random states: after a mesh period its end accelerations are the
    reference's right-hand side at its end state, in every lane, to the Newton tolerance (the
    dynamic model accepts a last update that moves the positions by < DQ_LINEAR = 1e-4 b0, which
    leaves ~1e-9 in the accelerations)."""
    p = GearParams()
    code = model_code(model)
    ref = RefConsts.from_params(p)
    rng = np.random.default_rng(3)
    n = 12
    X = np.array([x for x, _, _ in _random_states(rng, n)]) * 0.3
    X[:, 4] += 1.5  # mostly in drive contact, some apart
    A = np.zeros((n, 5))
    W = np.linspace(0.4, 2.8, n)
    C = np.tile(p.consts, (n, 1))
    pc = np.zeros((n, 1, K.N_PC))
    st = np.zeros((n, K.N_STATS))
    status = np.full(n, -1, np.int64)
    el = np.zeros(n)
    BK.integrate_stats_lanes(X, A, W, W, 1, 96, C, code, pc, st, status, el, NEWTON_MAX_ITER, NEWTON_TOL)
    assert (status == K.OK).all()
    for e in range(n):
        a_ref = rhs(0.0, np.concatenate([X[e], [0.0]]), W[e], ref, model)[5:10]
        np.testing.assert_allclose(A[e], a_ref, rtol=1e-8, atol=1e-8)
