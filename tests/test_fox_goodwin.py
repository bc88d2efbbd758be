"""The Newmark beta as a setting (``GearParams.newmark_beta``): the paper's 1/4 stays the default bit for
bit; Fox-Goodwin's 1/12 is more accurate per step against the independent event-located reference, its
stability limit is enforced before any work with a message naming the field and the steps needed, and the
tangent map (Floquet) follows the scheme."""

from __future__ import annotations

import math

import numpy as np
import pytest
from env_runs import env_run

from gear_env import GearParams, GearSimulator, simulate, simulate_batch
from gear_env.sim.linear import min_steps_per_period, natural_frequencies, newmark_step_limit
from gear_env.sim.params import C_BETA, FOX_GOODWIN_BETA, NEWMARK_BETA
from gear_env.sim.reference import reference_poincare

FG = GearParams(newmark_beta=FOX_GOODWIN_BETA)


def test_default_beta_is_the_papers_and_stays_out_of_the_dict():
    p = GearParams()
    assert p.newmark_beta == NEWMARK_BETA == 0.25 and p.consts[C_BETA] == 0.25
    assert "newmark_beta" not in p.to_dict()  # stored files and cache keys of the paper's model unchanged
    d = FG.to_dict()
    assert d["newmark_beta"] == FOX_GOODWIN_BETA and GearParams.from_dict(d) == FG


@pytest.mark.parametrize("bad", [0.0, 0.05, 0.3, 0.5, -0.25, float("nan"), "1/12", True])
def test_beta_outside_its_range_is_refused_naming_the_field(bad):
    with pytest.raises(ValueError, match="newmark_beta"):
        GearParams(newmark_beta=bad)


def test_step_limit_is_sqrt6_over_the_highest_frequency_with_margin():
    assert newmark_step_limit(GearParams()) == math.inf
    h = newmark_step_limit(FG)
    w_top = max(natural_frequencies(FG, m)[-1] for m in ("constant", "dynamic"))
    # the limit uses the peak stiffness (1 + kappa), so it is below the mean-stiffness one
    assert 0.6 * math.sqrt(6.0) / w_top < h < 0.9 * math.sqrt(6.0) / w_top
    assert min_steps_per_period(GearParams(), 0.01) == 1
    assert min_steps_per_period(FG, 0.3) == math.ceil(2 * math.pi / (0.3 * h))


def test_unstable_step_counts_are_refused_before_any_work():
    n_min = min_steps_per_period(FG, 0.1)
    with pytest.raises(ValueError, match=rf"newmark_beta.*steps_per_period >= {n_min}"):
        GearSimulator(FG, "dynamic", 64, 0.1)
    with pytest.raises(ValueError, match="steps_per_period = 64 is unstable"):
        simulate_batch([1.0, 0.1], "constant", periods=2, transient=0, steps_per_period=64, params=FG)
    sim = GearSimulator(FG, "dynamic", 64, 1.0)
    with pytest.raises(ValueError, match="unstable"):
        sim.advance(2, omega_end=0.1)  # a ramp down to an unstable omega
    assert sim.periods_done == 0
    with pytest.raises(ValueError, match="tol .*newmark_beta"):
        GearSimulator(FG, "dynamic", None, 1.0, tol=1e-3)
    GearSimulator(FG, "dynamic", n_min, 0.1).advance(2)  # the floor it names is accepted
    GearSimulator(FG, "dynamic", None, 0.1).advance(2)  # the automatic step count is always stable


def test_paper_beta_results_are_bit_identical_to_an_explicit_quarter():
    a = simulate(1.3, "dynamic", periods=5, transient=20, steps_per_period=96)
    b = simulate(1.3, "dynamic", periods=5, transient=20, steps_per_period=96, params=GearParams(newmark_beta=0.25))
    assert np.array_equal(a.data, b.data)


def _errors(model, omega, n_steps, periods=10):
    start = GearSimulator(GearParams(), model, 512, omega)
    start.advance(300)
    x0 = start.state
    ref = reference_poincare(omega, model, None, 0, periods, initial_state=x0, rtol=1e-12, atol=1e-13)
    out = {}
    for name, p in (("aa", GearParams()), ("fg", FG)):
        iv = GearSimulator(p, model, n_steps, omega, x0).advance(periods)
        out[name] = float(np.max(np.abs(iv.poincare[:, :10] - ref.states)))
    return out


@pytest.mark.parametrize(
    "model, omega, gain",
    [("constant", 0.8, 5.0), ("dynamic", 1.0, 5.0), ("constant", 1.5, 4.0), ("dynamic", 1.3, 5.0),
     ("dynamic", 2.6, 0.8), ("constant", 0.3, 0.8)],
)  # fmt: skip
def test_fox_goodwin_against_the_reference_at_equal_steps(model, omega, gain):
    """Period-1 orbits in permanent contact (constant 0.8, dynamic 1.3) and impacting (the others): at 64
    steps per mesh period Fox-Goodwin's Poincare error against DOP853 with located contact changes is 7-10x
    below the paper's scheme's at omega 0.8-1.5 (``gain`` asserts 4-5x) and about the same (within 1.25x) at
    omega 2.6 and 0.3, where the contact changes inside steps and the slow modes set the error; everywhere
    within the environments' 1e-3 b0 bound (docs/SIMULATOR.md, "Fox-Goodwin")."""
    e = _errors(model, omega, 64)
    assert e["fg"] * gain <= e["aa"], e
    assert e["fg"] < 1e-3, e


def test_fox_goodwin_converges_at_second_order():
    """Error ratio per doubling of the steps near 4 (second order with damping; an undamped linear system
    would give 16)."""
    e1 = _errors("constant", 0.8, 48)["fg"]
    e2 = _errors("constant", 0.8, 96)["fg"]
    assert 2.8 < e1 / e2 < 6.0, (e1, e2)


def test_floquet_tangent_follows_the_scheme():
    """The exact Jacobian of the Fox-Goodwin map equals central differences of that map (so Floquet
    multipliers and continuation are those of the scheme actually run)."""
    from gear_env.analysis import tangent as TG
    from gear_env.sim import kernels as K
    from gear_env.sim.params import model_code

    c = K.readonly(np.ascontiguousarray(FG.consts))
    sim = GearSimulator(FG, "dynamic", 96, 0.8)
    sim.advance(200)
    x0 = sim.state
    jac = np.zeros((10, 10))

    def run(x, want_jac):
        y = np.array(x, float)
        pc = np.zeros((1, 10))
        info = np.zeros(TG.N_INFO)
        j = jac if want_jac else np.zeros((10, 10))
        assert TG.tangent_map(y, 0.8, 1, 96, c, model_code("dynamic"), 12, 1e-12, j, pc, info, 0) == K.OK
        return y

    run(x0, True)
    fd = np.zeros((10, 10))
    for i in range(10):
        d = np.zeros(10)
        d[i] = 1e-6
        fd[:, i] = (run(x0 + d, False) - run(x0 - d, False)) / 2e-6
    assert np.max(np.abs(jac - fd)) < 1e-5 * max(1.0, np.max(np.abs(fd)))


# ---------------------------------------------------------------------------------------------- environments
ENV_ACTIONS = np.array([-1.0, -1.0, 0.2, 0.35, -0.1, 0.5], np.float32)  # set-points down to omega_min, then up


@pytest.mark.parametrize("n", [3, 9])  # 9 rows: the SIMD lanes
def test_env_with_fox_goodwin_keeps_its_steps_and_moves_beta_at_low_omega(n, monkeypatch):
    """GearSpeedDemand-v0 with Fox-Goodwin at the default 64 steps, set-points down to the lowest speeds,
    where beta 1/12 is unstable at 64 steps: every call takes 64 steps, the rows at low omega a larger,
    stable beta for that interval (the others 1/12), the plant's beta is restored after each call, and each
    row's numbers are those of the single env bit for bit."""
    from gear_env.envs.env_core import GearSpeedCore as EnvCore

    counts, moved = [], []
    fixed = EnvCore._integrate_fixed

    def spy(self, rows, w0, w1, periods, nsp):
        counts.append(nsp)
        b = self.C[rows, C_BETA]
        moved.append(b.max() > FOX_GOODWIN_BETA)
        w = np.minimum(w0, w1)
        # the stable limit holds for every row in the call
        for bi, wi in zip(b.tolist(), np.atleast_1d(w).tolist()):
            assert min_steps_per_period(GearParams(newmark_beta=bi), wi) <= nsp
        return fixed(self, rows, w0, w1, periods, nsp)

    monkeypatch.setattr(EnvCore, "_integrate_fixed", spy)
    kw = {"params": FG.to_dict(), "omega_min": 0.05, "initial_omega": (0.06, 0.5)}
    obs, vec = env_run("GearSpeedDemand-v0", 40, ENV_ACTIONS, n, **kw)
    assert np.isfinite(obs).all()
    assert set(counts) == {64} and any(moved) and not all(moved)  # beta moved for the low-omega rows only
    assert (vec._core.C[:, C_BETA] == FOX_GOODWIN_BETA).all()
    for i in (0, n - 1):
        so, _ = env_run("GearSpeedDemand-v0", 40 + i, ENV_ACTIONS, None, **kw)
        np.testing.assert_array_equal(obs[i], so)


def test_stable_beta_is_the_scheme_where_stable_and_just_stable_below():
    from gear_env.sim.linear import stable_beta

    assert stable_beta(FG, 0.3, 64) == FOX_GOODWIN_BETA  # stable: untouched
    assert stable_beta(GearParams(), 0.01, 16) == NEWMARK_BETA
    prev = FOX_GOODWIN_BETA
    for w in (0.15, 0.12, 0.1, 0.06, 0.03):
        b = stable_beta(FG, w, 64)
        assert prev < b < NEWMARK_BETA  # rises towards 1/4 as omega falls
        assert min_steps_per_period(GearParams(newmark_beta=b), w) == 64  # just stable (with the margin)
        assert min_steps_per_period(GearParams(newmark_beta=b - 1e-3), w) > 64
        prev = b


@pytest.mark.parametrize("model", ["constant", "dynamic"])
def test_moved_beta_is_at_least_as_accurate_as_the_papers_at_low_omega(model):
    """At omega 0.1 (64 Fox-Goodwin steps unstable) the beta the environments take is stable and its error
    against 4096 steps is below the paper's scheme at the same 64 steps (measured 6e-5 against 1e-4 b0)."""
    from gear_env.sim.linear import stable_beta

    w = 0.1
    sim = GearSimulator(GearParams(), model, 1024, w)
    sim.advance(100)
    x0 = sim.state
    ref = GearSimulator(GearParams(), model, 4096, w, x0).advance(10).poincare[:, :10]
    b = stable_beta(FG, w, 64)
    e_moved = np.abs(GearSimulator(GearParams(newmark_beta=b), model, 64, w, x0).advance(10).poincare[:, :10] - ref)
    e_paper = np.abs(GearSimulator(GearParams(), model, 64, w, x0).advance(10).poincare[:, :10] - ref)
    assert e_moved.max() < 0.8 * e_paper.max() and e_moved.max() < 1e-3


def test_env_refuses_tol_with_fox_goodwin_naming_the_fields():
    import gymnasium as gym

    with pytest.raises(ValueError, match="tol .*newmark_beta"):
        gym.make("GearSpeedDemand-v0", params=FG.to_dict(), tol=1e-3)


def test_analysis_entry_points_refuse_unstable_step_counts_before_any_work():
    """Every analysis that takes a fixed step count checks it against the scheme's limit at each omega."""
    from gear_env.analysis import largest_lyapunov, sweep
    from gear_env.analysis.continuation import OrbitMap as ContMap
    from gear_env.analysis.floquet import PeriodMap
    from gear_env.analysis.stability import stability_map

    calls = [
        lambda: sweep([0.1, 1.0], "dynamic", params=FG, steps_per_period=64, transient=1, periods=4),
        lambda: largest_lyapunov(0.1, "dynamic", params=FG, steps_per_period=64),
        lambda: stability_map(
            "dynamic", params=FG, omega_min=0.1, omega_max=1.0, points=5, steps_per_period=64, cache=False
        ),  # fmt: skip
        lambda: PeriodMap(0.1, "dynamic", FG, 1, 64),
        lambda: ContMap("dynamic", FG, 1, 64).steps(0.1),
    ]
    for call in calls:
        with pytest.raises(ValueError, match="newmark_beta"):
            call()


def test_integrate_refuses_buffers_the_kernels_would_overrun():
    """``sim.integration.integrate`` indexes its buffers unchecked in numba: a Poincare buffer shorter than the
    periods (or a wrong state shape) is refused, naming the argument, before any kernel runs."""
    from gear_env.sim import kernels as K
    from gear_env.sim.integration import integrate

    c = GearParams().consts
    x, a = np.zeros(K.NSTATE), np.zeros(K.NDOF)
    with pytest.raises(ValueError, match="poincare must have shape"):
        integrate(x, a, c, 1, 1.0, 1.0, 48, 64, poincare=np.zeros((24, K.N_PC)))
    with pytest.raises(ValueError, match="stats must have shape"):
        integrate(x, a, c, 1, 1.0, 1.0, 2, 64, stats=np.zeros(3))
    with pytest.raises(ValueError, match="a must have shape"):
        integrate(np.zeros((2, K.NSTATE)), np.zeros(K.NDOF), np.tile(c, (2, 1)), 1, np.ones(2), np.ones(2), 2, 64)
    with pytest.raises(ValueError, match="consts"):
        integrate(np.zeros((2, K.NSTATE)), np.zeros((2, K.NDOF)), np.tile(c, (3, 1)), 1, np.ones(2), np.ones(2), 2, 64)
    run = integrate(x, a, c, 1, 1.0, 1.0, 2, 64, poincare=np.zeros((2, K.N_PC)))  # the right shapes run
    assert run.status == K.OK


def test_integrate_keeps_the_excitation_table_and_the_same_numbers():
    """The one-state path of ``integrate`` keeps each (step count, constants) excitation table between calls: its
    results are those of ``kernels.integrate_stats_lazy`` bit for bit, and other constants (a Fox-Goodwin beta,
    another kappa) and step counts get a table of their own."""
    from gear_env.sim import integration as I
    from gear_env.sim import kernels as K

    sim = GearSimulator(GearParams(), "dynamic", 64, 1.1)
    sim.advance(50)
    x0, a0 = sim.x.copy(), sim.a.copy()
    for params, nsp in ((GearParams(), 64), (GearParams(), 96), (GearParams(newmark_beta=FOX_GOODWIN_BETA), 64),
                        (GearParams(kappa=0.4), 64)):  # fmt: skip
        c = K.readonly(params.consts)
        x, a = x0.copy(), a0.copy()
        run = I.integrate(x, a, c, 1, 1.1, 1.3, 7, nsp)
        xl, al = x0.copy(), a0.copy()
        pl, sl = np.empty((7, K.N_PC)), np.empty(K.N_STATS)
        ref = K.integrate_stats_lazy(xl, al, 0.0, 1.1, 1.3, 7, nsp, c, 1, pl, sl, I.NEWTON_MAX_ITER, I.NEWTON_TOL, True)
        assert (run.status, run.done, run.elapsed) == tuple(ref)
        assert np.array_equal(x, xl) and np.array_equal(a, al) and np.array_equal(run.poincare, pl)
        assert np.array_equal(run.stats, sl)
        assert (nsp, c.tobytes()) in I._TABLES


def test_automatic_step_count_follows_the_scheme():
    """``steps_per_period=None`` under Fox-Goodwin: 88 steps per mesh period, the stability floor where that is
    higher (omega < ~0.11); the paper's scheme keeps 192 (more below 0.27). Every entry point that takes None uses
    it, a batch of mixed schemes takes the larger count, and the stability map's cache key tells the two apart."""
    from gear_env.analysis.floquet import PeriodMap
    from gear_env.analysis.stability import cache_key
    from gear_env.analysis.sweep import SweepConfig, steps_for
    from gear_env.sim.simulator import FOX_GOODWIN_STEPS_PER_PERIOD, default_steps_per_period

    assert FOX_GOODWIN_STEPS_PER_PERIOD == 88
    for w in (0.12, 0.3, 1.0, 2.9):
        assert default_steps_per_period(w, FG) == 88
        assert default_steps_per_period(w) == default_steps_per_period(w, GearParams()) == max(192, math.ceil(
            2 * math.pi / (0.12 * w)))  # fmt: skip
    for w in (0.05, 0.08, 0.1):
        assert default_steps_per_period(w, FG) == min_steps_per_period(FG, w) > 88
    assert GearSimulator(FG, "dynamic", None, 1.2).steps_per_period == 88
    sim = GearSimulator(FG, "constant", None, 1.0)
    sim.advance(2, 0.1)  # a ramp down: the count of the interval's lowest omega, stable there
    assert sim.steps_per_period == min_steps_per_period(FG, 0.1)
    assert PeriodMap(1.2, "dynamic", FG).steps == 88 and PeriodMap(1.2, "dynamic").steps == 192
    assert steps_for(1.2, params=FG) == 88 and steps_for(1.2) == 192

    def one(params, n):
        s = GearSimulator(params, "constant", n, 1.0)
        return s.advance(2).poincare

    alone = simulate_batch([1.0, 1.2], "constant", periods=2, transient=0, params=FG)
    assert np.array_equal(alone[0].poincare, one(FG, 88))
    mixed = simulate_batch([1.0], "constant", periods=2, transient=0, params=[FG, GearParams()])
    assert np.array_equal(mixed[0].poincare, one(FG, 192))  # the paper row's 192 for both rows
    grid = np.linspace(0.3, 1.0, 5)
    assert cache_key(FG, "dynamic", grid, None) != cache_key(FG, "dynamic", grid, 88)
    from gear_env.sim.simulator import auto_steps_rule

    assert auto_steps_rule(GearParams()) == "auto(max(192, 2 pi / (0.12 omega)))"  # the paper's keys: as before
    kw = dict(model="dynamic", direction="forward", transient=1, periods=2, steps_per_period=None,
              adaptive_steps=False, lyapunov=False)  # fmt: skip
    assert "auto_steps" in SweepConfig(params=FG, **kw).fingerprint()
    assert "auto_steps" not in SweepConfig(params=GearParams(), **kw).fingerprint()  # paper checkpoints resume


def test_a_rounded_one_twelfth_is_fox_goodwin_and_the_range_is_named_exactly(capsys):
    """0.083333 (what a user copies from a printout) is Fox-Goodwin; just outside the range is refused with the
    bounds written as 1/12 and 1/4, so that the printed bound is not itself refused. The CLI names the scheme."""
    for b in (0.0833333, 0.083333, FOX_GOODWIN_BETA + 5e-7):
        p = GearParams(newmark_beta=b)
        assert p.newmark_beta == FOX_GOODWIN_BETA and p == FG
    assert GearParams(newmark_beta=0.0834).newmark_beta == 0.0834  # a beta of its own, not snapped
    for bad in (0.0833, 0.08, 0.2500001):
        with pytest.raises(ValueError, match=r"newmark_beta must be in \[1/12, 1/4\] \(1/12 = 0.08333333333333333"):
            GearParams(newmark_beta=bad)
    from gear_env.cli import main

    assert main(["simulate", "--omega", "1.2", "--periods", "2", "--transient", "2", "--scheme", "fox-goodwin"]) == 0
    assert "steps/period=88 scheme=fox-goodwin (beta 1/12)" in capsys.readouterr().out
