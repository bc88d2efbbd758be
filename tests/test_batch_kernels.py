"""The SIMD lanes kernel (batch_kernels) against the scalar batch kernel: the same numbers, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from gear_env.sim import batch_kernels as BK
from gear_env.sim import kernels as K
from gear_env.sim.params import GearParams, model_code
from gear_env.sim.simulator import NEWTON_MAX_ITER, NEWTON_TOL, default_initial_state


def _systems(n, model, seed, friction_rows=(), kappas=(0.2,)):
    """n systems at the A10 initial state (velocities perturbed), constants per row."""
    rng = np.random.default_rng(seed)
    C = np.empty((n, GearParams().consts.size))
    X = np.empty((n, K.NSTATE))
    for i in range(n):
        p = GearParams(kappa=kappas[i % len(kappas)], friction=0.05 if i in friction_rows else 0.0)
        C[i] = p.consts
        X[i] = default_initial_state(p, model)
        X[i, 5:] += rng.normal(0.0, 0.05, 5)
    return X, np.zeros((n, K.NDOF)), C


def _run(fn, code, X, A, W0, W1, C, periods, n_steps, max_iter=NEWTON_MAX_ITER):
    n = X.shape[0]
    pc = np.zeros((n, periods, K.N_PC))
    st = np.zeros((n, K.N_STATS))
    status = np.full(n, -1, np.int64)
    el = np.zeros(n)
    fn(X, A, W0, W1, periods, n_steps, C, code, pc, st, status, el, max_iter, NEWTON_TOL)
    return dict(X=X, A=A, poincare=pc, stats=st, status=status, elapsed=el)


def _compare(n, model, W0, W1, periods=6, n_steps=64, X=None, repeats=2, max_iter=NEWTON_MAX_ITER, **kw):
    code = model_code(model)
    X0, A0, C = _systems(n, model, seed=n, **kw)
    if X is not None:
        X0 = X
    xa, aa, xb, ab = X0.copy(), A0.copy(), X0.copy(), A0.copy()
    for _ in range(repeats):  # a second interval starts from the state the first one left
        ra = _run(K.integrate_stats_batch, np.full(n, code, np.int64), xa, aa, W0, W1, C, periods, n_steps, max_iter)
        rb = _run(BK.integrate_stats_lanes, code, xb, ab, W0, W1, C, periods, n_steps, max_iter)
        for key in ra:
            np.testing.assert_array_equal(ra[key], rb[key], err_msg=f"{model}: {key} differs")
    return ra


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_lanes_kernel_is_bit_identical_to_the_scalar_batch_kernel(model):
    # 19 systems: one full block of 16 and a padded block of 3; omega from 0.25 (long steps, many
    # scalar redos) over the impacting band to 3, constant and ramping, two kappas and friction in
    # two rows (those steps are always redone by the scalar path)
    n = 19
    W0 = np.linspace(0.25, 3.0, n)
    W1 = W0.copy()
    W1[::2] += 0.04
    W1[1::4] -= 0.03
    r = _compare(n, model, W0, W1, friction_rows=(3, 17), kappas=(0.2, 0.35))
    assert (r["status"] == K.OK).all()
    assert r["stats"][:, K.ST_DRIVE_IMPACTS].sum() > 0  # some rows do separate and re-impact


def test_lanes_kernel_failures_match_the_scalar_kernel():
    # row 1 explodes at once (divergence), row 4 is NaN (Newton fails); the others are unaffected
    n = 6
    X0, _, _ = _systems(n, "dynamic", seed=n)
    X0[1, 5:] = 4e5
    X0[4, 0] = np.nan
    W0 = np.full(n, 1.2)
    r = _compare(n, "dynamic", W0, W0 + 0.01, X=X0, repeats=1)
    assert r["status"].tolist() == [K.OK, K.DIVERGED, K.OK, K.OK, K.NEWTON_FAILED, K.OK]


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_lanes_kernel_split_steps_match_the_scalar_kernel(model):
    # max_iter=1: contact changes need splitting, in both blocks (16 + 3 rows, omega 0.4-0.94);
    # the lanes kernel stops at each, the split step is taken from Python (_split_lane) and the
    # kernel goes on; row 5 is NaN (its split fails too), row 7 explodes (diverges, or its
    # Newton fails first)
    n = 19
    X0, _, _ = _systems(n, model, seed=n)
    X0[5, 0] = np.nan
    X0[7, 5:] = 4e5
    W0 = 0.4 + 0.06 * (np.arange(n) % 10)
    r = _compare(n, model, W0, W0 + 0.02, X=X0, periods=20, n_steps=32, max_iter=1)
    splits = r["stats"][:, K.ST_SPLITS]
    assert r["status"][5] == K.NEWTON_FAILED and r["status"][7] in (K.DIVERGED, K.NEWTON_FAILED)
    assert (splits[:16] > 0).sum() >= 4 and (splits[16:] > 0).any()
    assert (r["status"] == K.OK).sum() == n - 2


def test_lanes_kernel_handles_odd_step_counts_and_one_row():
    W0 = np.array([0.9])
    _compare(1, "dynamic", W0, W0 + 0.02, periods=3, n_steps=17)
    W0 = np.linspace(0.5, 2.5, 5)
    _compare(5, "constant", W0, W0, periods=3, n_steps=33)


def test_lane_layout_matches_the_scalar_kernel():
    # the lanes kernel copies the scalar kernel's step constants row by row: same length
    assert len(K.step_consts(GearParams().consts)) == BK.N_K
    assert BK.N_ROWS > BK.Q_WA and BK.LANES % BK.PAD == 0


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_simulate_batch_equals_one_simulator_per_omega(model):
    from gear_env import GearSimulator, simulate_batch

    omegas = [0.4, 1.2, 1.5, 2.8, 0.9]
    got = simulate_batch(omegas, model=model, periods=8, transient=12, steps_per_period=64)
    assert [g.omega_start for g in got] == omegas
    for w, g in zip(omegas, got):
        sim = GearSimulator(model=model, steps_per_period=64, omega=w)
        sim.advance(12)
        ref = sim.advance(8)
        np.testing.assert_array_equal(g.poincare, ref.poincare)
        np.testing.assert_array_equal(g.stats, ref.stats)
        assert g.duration == ref.duration
        assert g.amplitude("U") == ref.amplitude("U")


def test_simulate_batch_rejects_bad_input_and_reports_divergence(monkeypatch):
    from gear_env import SimulationDivergedError, simulate_batch

    with pytest.raises(ValueError, match=r"omegas\[1\]"):
        simulate_batch([1.0, float("nan")])
    with pytest.raises(ValueError, match="omegas"):
        simulate_batch([])
    with pytest.raises(ValueError, match="periods"):
        simulate_batch([1.0], periods=0)
    with pytest.raises(ValueError, match="model"):
        simulate_batch([1.0], model="rigid")
    # the default step count follows the smallest omega
    assert simulate_batch([0.1, 2.0], periods=1, transient=0)[1].stats[K.ST_STEPS] > 192
    # a blow-up of the second system in its third recorded period (injected): the exception
    # names its omega and the period counted from the start, transient included
    real = BK.integrate_stats_lanes

    def failing(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol):
        done = real(X, A, W0, W1, n_periods, n_steps, C, dynamic, poincare, stats, status, elapsed, max_iter, tol)
        if n_periods == 5:
            status[1] = K.DIVERGED
            done[1] = 2
        return done

    monkeypatch.setattr(BK, "integrate_stats_lanes", failing)
    with pytest.raises(SimulationDivergedError, match=r"period 6 at omega=1.2:.*exceeded.*\(system 1 of 2\)"):
        simulate_batch([0.8, 1.2], periods=5, transient=4)


def test_simulate_batch_one_parameter_set_per_system():
    """A parameter study in one call: each row equals its own GearSimulator, bit for bit, and a
    single omega is shared by every parameter set."""
    from gear_env import GearSimulator, simulate_batch

    ps = [GearParams(kappa=k) for k in (0.1, 0.2, 0.3)] + [GearParams(b_c=3e-5), GearParams(xi_m=0.05)]
    got = simulate_batch(1.5, model="dynamic", periods=6, transient=10, steps_per_period=64, params=ps)
    assert len(got) == len(ps) and all(g.omega_start == 1.5 for g in got)
    for p, g in zip(ps, got):
        sim = GearSimulator(p, "dynamic", 64, 1.5)
        sim.advance(10)
        ref = sim.advance(6)
        np.testing.assert_array_equal(g.poincare, ref.poincare)
        np.testing.assert_array_equal(g.stats, ref.stats)
    # the parameter sets really differ: kappa moves the response
    assert len({round(g.amplitude("delta"), 9) for g in got[:3]}) == 3
    # one omega per parameter set
    two = simulate_batch([1.2, 2.8], periods=3, transient=2, steps_per_period=64, params=ps[:2])
    for w, p, g in zip((1.2, 2.8), ps[:2], two):
        ref = GearSimulator(p, "dynamic", 64, w)
        ref.advance(2)
        np.testing.assert_array_equal(g.poincare, ref.advance(3).poincare)


def test_simulate_batch_rejects_bad_parameter_lists():
    from gear_env import simulate_batch

    with pytest.raises(ValueError, match="params has 2 entries but there are 3 omegas"):
        simulate_batch([1.0, 1.2, 1.4], params=[GearParams(), GearParams()])
    with pytest.raises(ValueError, match=r"params\[1\] must be a GearParams, got dict"):
        simulate_batch(1.0, params=[GearParams(), {"kappa": 0.1}])
    with pytest.raises(ValueError, match="empty"):
        simulate_batch(1.0, params=[])
    with pytest.raises(ValueError, match="params must be a GearParams or a list"):
        simulate_batch(1.0, params="kappa=0.1")


def test_parameter_study_example_runs(tmp_path):
    """examples/parameter_study.py (simulate_batch with one GearParams per system) runs and writes
    its table and figure."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "parameter_study.py"
    png = tmp_path / "study.png"
    out = subprocess.run(
        [sys.executable, str(script), "--quick", "--kappas", "0.1", "0.3", "--plot", str(png)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert "16 runs of 60 + 40 mesh periods" in out.stdout
    assert "| 0.1 |" in out.stdout and "| 0.3 |" in out.stdout
    assert png.stat().st_size > 10_000


def test_simulate_batch_ramps_equal_advance_with_omega_end():
    """omega_end: the recorded periods ramp, bit for bit as GearSimulator.advance(omega_end=...)."""
    from gear_env import GearSimulator, simulate_batch

    starts, ends = [0.6, 1.2, 2.0], [1.2, 0.9, 2.6]
    got = simulate_batch(starts, periods=6, transient=5, steps_per_period=64, omega_end=ends)
    for w0, w1, g in zip(starts, ends, got):
        sim = GearSimulator(None, "dynamic", 64, w0)
        sim.advance(5)
        ref = sim.advance(6, omega_end=w1)
        assert (g.omega_start, g.omega_end) == (w0, w1)
        np.testing.assert_array_equal(g.poincare, ref.poincare)
        np.testing.assert_array_equal(g.stats, ref.stats)
        assert g.duration == ref.duration
    shared = simulate_batch(starts, periods=2, transient=0, steps_per_period=64, omega_end=1.0)
    assert [g.omega_end for g in shared] == [1.0, 1.0, 1.0]
    # the default step count follows the smallest omega, omega_end included
    low = simulate_batch([1.0], periods=1, transient=0, omega_end=0.1)[0]
    assert low.stats[K.ST_STEPS] > 192
    with pytest.raises(ValueError, match=r"omega_end\[1\]"):
        simulate_batch(starts, omega_end=[1.0, float("nan"), 1.0])
    with pytest.raises(ValueError, match="omega_end must be one value or 3 values"):
        simulate_batch(starts, omega_end=[1.0, 1.1])


def test_simulate_batch_from_given_initial_states():
    """initial_states replaces the A10 start: each row equals GearSimulator(initial_state=row),
    bit for bit; one omega with n states makes n systems; one state is shared by all omegas."""
    from gear_env import GearSimulator, simulate_batch

    rng = np.random.default_rng(3)
    x0 = default_initial_state(GearParams(), "dynamic")
    starts = x0 + rng.normal(0.0, 0.3, (5, 10)) * np.r_[np.zeros(4), 1.0, np.zeros(4), 1.0]
    got = simulate_batch(2.4, periods=4, transient=6, steps_per_period=64, initial_states=starts)
    assert len(got) == 5 and all(g.omega_start == 2.4 for g in got)
    for row, g in zip(starts, got):
        sim = GearSimulator(model="dynamic", steps_per_period=64, omega=2.4, initial_state=row)
        sim.advance(6)
        ref = sim.advance(4)
        np.testing.assert_array_equal(g.poincare, ref.poincare)
        np.testing.assert_array_equal(g.stats, ref.stats)
    assert len({g.poincare[-1, 4] for g in got}) == 5  # the starts really differ
    # one state shared by several omegas, and the A10 state given explicitly is the default
    shared = simulate_batch([0.9, 1.7], periods=3, transient=2, steps_per_period=64, initial_states=x0)
    default = simulate_batch([0.9, 1.7], periods=3, transient=2, steps_per_period=64)
    for a, b in zip(shared, default):
        np.testing.assert_array_equal(a.poincare, b.poincare)


def test_simulate_batch_rejects_bad_initial_states():
    from gear_env import simulate_batch

    x0 = default_initial_state(GearParams(), "dynamic")
    with pytest.raises(ValueError, match=r"initial_states must have shape \(10,\) or \(n, 10\).*got \(9,\)"):
        simulate_batch(1.0, initial_states=x0[:9])
    with pytest.raises(ValueError, match=r"initial_states must have shape.*got \(2, 3, 10\)"):
        simulate_batch(1.0, initial_states=np.zeros((2, 3, 10)))
    bad = np.stack([x0, x0])
    bad[1, 6] = np.inf
    with pytest.raises(ValueError, match=r"initial_states\[1\] must be finite"):
        simulate_batch(1.0, initial_states=bad)
    with pytest.raises(ValueError, match="initial_states must be numbers"):
        simulate_batch(1.0, initial_states=["a"] * 10)
    with pytest.raises(ValueError, match="initial_states has 2 entries but there are 3 systems"):
        simulate_batch([1.0, 1.2, 1.4], initial_states=np.stack([x0, x0]))
    with pytest.raises(ValueError, match="initial_states must be real"):
        simulate_batch(1.0, initial_states=x0 + 0j)
    with pytest.raises(ValueError, match=r"initial_states must be numbers of shape \(10,\) or \(n, 10\)"):
        simulate_batch(1.0, initial_states=[x0.tolist(), x0.tolist()[:5]])  # ragged
    # a Fortran-ordered array gives the same result as a C-ordered one (it is copied to C order)
    two = np.stack([x0, x0 + 0.01])
    a = simulate_batch(1.0, periods=2, transient=0, steps_per_period=32, initial_states=np.asfortranarray(two))
    b = simulate_batch(1.0, periods=2, transient=0, steps_per_period=32, initial_states=two)
    np.testing.assert_array_equal(a[1].poincare, b[1].poincare)


def test_basins_example_runs(tmp_path):
    """examples/basins.py (simulate_batch from given initial states) finds the two motions at
    omega 2.41, tabulates the quiet share and writes the basin map."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "basins.py"
    png = tmp_path / "basins.png"
    out = subprocess.run(
        [sys.executable, str(script), "--quick", "--plot", str(png)], capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "64 starts of 500 + 100 mesh periods" in out.stdout
    rows = [line for line in out.stdout.splitlines() if "b0 in U" in line]
    shares = [float(line.rsplit("|", 2)[1].strip().rstrip("%")) for line in rows]
    assert len(shares) == 3 and shares[0] >= shares[2]  # nearer starts stay quiet at least as often
    assert 0.0 < shares[2] < 100.0  # both motions are reached from the grid
    assert png.stat().st_size > 10_000


def test_hysteresis_dwell_example_runs():
    """examples/hysteresis_dwell.py --quick: the dynamic model's torus-end hysteresis shrinks when
    the dwell per point grows from 300 to 2,000 mesh periods, and the held torus is reported."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "hysteresis_dwell.py"
    out = subprocess.run([sys.executable, str(script), "--quick"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    row = next(line for line in out.stdout.splitlines() if line.startswith("| torus end | dynamic |"))
    short, long_ = row.split("|")[3:5]

    def width(cell: str) -> float:  # total width of the omega ranges in a cell
        spans = re.findall(r"(\d\.\d+)(?:-(\d\.\d+))?", cell)
        return sum(float(b or a) - float(a) + 0.01 for a, b in spans)

    assert 0.0 < width(long_) < width(short)
    assert "| dynamic, 2.410 |" in out.stdout


@pytest.mark.parametrize("model", ["constant", "dynamic"])
@pytest.mark.parametrize("max_iter", [NEWTON_MAX_ITER, 1])
def test_lanes_kernel_takes_a_step_count_per_system(model, max_iter):
    # steps_per_period="auto" in the vector env: rows of different step counts in one call, each bit for bit what it
    # gives alone (the scalar kernel, row by row); both blocks mixed (16 + 3 rows), lanes that finish early, split
    # steps (max_iter=1), a NaN row and an exploding one, and kink-correcting rows (K_LOC) among plain ones; the first
    # block has 6 lanes at 64 steps, which move into 8 columns once the others finish (batch_kernels._compact, then
    # split steps and the divergence check on moved lanes), the second pattern 10, which do not fit. The last two
    # patterns take the environments' classes, 32 and 64 (and 16 in the second block): compacted (6 at 64) and not (10)
    for hi, lo, tail in (
        (64, 48, [32, 48, 32]),
        (48, 64, [32, 48, 32]),
        (64, 32, [64, 32, 16]),
        (32, 64, [16, 32, 64]),
    ):
        NS = np.where(np.arange(19) % 3 == 0, hi, lo)
        NS[16:] = tail
        _check_step_counts(model, max_iter, NS)


def _check_step_counts(model, max_iter, NS):
    from gear_env.sim.params import C_LOC, CONTACTS_CORRECTED

    n = 19
    code = model_code(model)
    X0, A0, C = _systems(n, model, seed=5)
    C[1::2, C_LOC] = CONTACTS_CORRECTED
    X0[5, 0] = np.nan
    X0[7, 5:] = 4e5
    W0 = 0.4 + 0.13 * (np.arange(n) % 12)
    W1 = W0 + np.where(np.arange(n) % 2 == 0, 0.03, -0.02)
    xa, aa, xb, ab = X0.copy(), A0.copy(), X0.copy(), A0.copy()
    for _ in range(2):
        rb = _run(BK.integrate_stats_lanes, code, xb, ab, W0, W1, C, 5, NS, max_iter)
        for i in range(n):
            ra = _run(
                K.integrate_stats_batch, np.full(1, code, np.int64), xa[i : i + 1], aa[i : i + 1], W0[i : i + 1],
                W1[i : i + 1], C[i : i + 1], 5, int(NS[i]), max_iter,
            )  # fmt: skip
            for key in ra:
                np.testing.assert_array_equal(ra[key][0], rb[key][i], err_msg=f"{model}: row {i} ({NS[i]}): {key}")
    assert rb["status"][5] == K.NEWTON_FAILED and rb["status"][7] != K.OK
    assert (rb["status"] == K.OK).sum() == n - 2
    assert (rb["stats"][:, K.ST_STEPS][rb["status"] == K.OK] == (5 * NS)[rb["status"] == K.OK]).all()
