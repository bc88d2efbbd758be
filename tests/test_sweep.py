"""Sweeps: argument checks, warm starts, results file round trip and damage, checkpoint resume, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gear_env.analysis import SweepResult, sweep
from gear_env.analysis.results import ResultsFileError
from gear_env.analysis.sweep import SweepConfig, run_point, steps_for
from gear_env.sim.params import GearParams

FAST = dict(transient=40, periods=24, progress=False, steps_per_period=64)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"omegas": []}, "omegas"),
        ({"omegas": [1.0, float("nan")]}, "omegas"),
        ({"omegas": [1.0, float("inf")]}, "omegas"),
        ({"omegas": [[1.0, 2.0]]}, "omegas"),
        ({"omegas": [0.0]}, "omegas"),
        ({"direction": "up"}, "direction"),
        ({"transient": 0}, "transient"),
        ({"transient": -5}, "transient"),
        ({"transient": 2.5}, "transient"),
        ({"transient": True}, "transient"),
        ({"periods": 2}, "periods"),
        ({"model": "rigid"}, "model"),
        ({"workers": 0}, "workers"),
        ({"params": {"kappa": 0.2}}, "params"),
    ],
)
def test_invalid_arguments_name_the_argument(kwargs, word):
    args = {"omegas": [1.0, 1.1], **FAST, **kwargs}
    with pytest.raises(ValueError, match=word):
        sweep(**args)


def test_forward_and_reverse_warm_start_from_previous_point():
    grid = [1.1, 1.0, 1.2]  # results come back in the given order
    p = GearParams()
    for direction, order in (("forward", [1, 0, 2]), ("reverse", [2, 0, 1])):
        r = sweep(grid, model="constant", direction=direction, lyapunov=False, **FAST)
        assert list(r.omega) == grid and r.direction == direction
        cfg = SweepConfig("constant", direction, 40, 24, p, 64, False, False)
        x = None
        for i in order:  # the chain a slowly swept machine follows
            pr = run_point(cfg, grid[i], x)
            np.testing.assert_array_equal(pr.final_state, r.final_states[i])
            np.testing.assert_array_equal(pr.poincare, r.poincare[i])
            x = pr.final_state
    assert r.lyapunov is None


def test_results_without_exponents_round_trip(tmp_path):
    r = sweep([1.0, 1.1], model="constant", lyapunov=False, **FAST)
    r.save(str(tmp_path / "n.nc"))
    back = SweepResult.load(str(tmp_path / "n.nc"))
    assert back.lyapunov is None and back.regime == r.regime
    assert r.to_json_dict()["lyapunov"] is None and r.to_dataframe()["lyapunov"].isna().all()


def test_sweep_contents_and_views():
    r = sweep([0.8, 1.2], model="dynamic", transient=300, periods=24, progress=False)
    assert r.regime == ["period-1", "period-1"] and list(r.period) == [1, 1]
    assert r.intervals() == [(0.8, 1.2, "period-1")]
    assert r.poincare.shape == (2, 24, 14) and r.final_states.shape == (2, 10)
    assert np.all(r.lyapunov < 0)
    assert set(r.amplitude) == {"U", "delta", "bd", "psi", "force"}
    assert np.all(r.amplitude["U"] > 0) and np.all((0 <= r.contact_loss) & (r.contact_loss <= 1))
    df = r.to_dataframe()
    assert list(df["omega"]) == [0.8, 1.2] and "amplitude_u" in df and "lyapunov" in df
    d = json.loads(json.dumps(r.to_json_dict()))
    for key in ("omega", "regime", "amplitude_u", "lyapunov", "poincare_delta"):
        assert len(d[key]) == 2
    assert len(d["poincare_delta"][0]) == 24


def test_steps_for_rule():
    # default: the simulator's rule, max(192, ceil(2 pi / (0.12 omega)))
    assert steps_for(1.0) == 192 and steps_for(0.2) == 262 and steps_for(0.05) == 1048
    assert steps_for(0.05, 128) == 128 and steps_for(0.05, 128, adaptive=True) == 1280
    assert steps_for(1.0, 128, adaptive=True) == 128


@pytest.fixture(scope="module")
def small_result():
    return sweep([0.5, 1.0, 2.0], model="constant", **FAST)


def test_save_load_round_trip(tmp_path, small_result):
    path = tmp_path / "r.nc"
    small_result.save(str(path))
    back = SweepResult.load(str(path))
    assert back.regime == small_result.regime and back.model == "constant"
    np.testing.assert_array_equal(back.poincare, small_result.poincare)
    np.testing.assert_array_equal(back.lyapunov, small_result.lyapunov)
    for k, v in small_result.amplitude.items():
        np.testing.assert_array_equal(back.amplitude[k], v)
    assert back.params == small_result.params and back.transient == 40 and back.periods == 24


def test_truncated_or_foreign_or_altered_files_are_refused(tmp_path, small_result):
    import netCDF4

    path = tmp_path / "r.nc"
    small_result.save(str(path))
    raw = path.read_bytes()
    for cut in (len(raw) // 2, len(raw) - 100):
        bad = tmp_path / f"cut{cut}.nc"
        bad.write_bytes(raw[:cut])
        with pytest.raises(ResultsFileError, match="truncated|corrupt|incomplete"):
            SweepResult.load(str(bad))
    with netCDF4.Dataset(path, "a") as ds:  # a version we do not know
        ds.format_version = 99
    with pytest.raises(ResultsFileError, match="format_version 99"):
        SweepResult.load(str(path))
    small_result.save(str(path))
    with netCDF4.Dataset(path, "a") as ds:  # data changed behind our back
        ds["lyapunov"][0] = 1.0
    with pytest.raises(ResultsFileError, match="checksum"):
        SweepResult.load(str(path))
    with pytest.raises(FileNotFoundError):
        SweepResult.load(str(tmp_path / "missing.nc"))


def test_interrupted_sweep_resumes_from_checkpoint(tmp_path):
    grid = np.linspace(0.9, 1.3, 6)
    ck = tmp_path / "sweep.ckpt.npz"
    full = sweep(grid, model="constant", **FAST)

    def interrupt(done):
        if done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sweep(grid, model="constant", checkpoint=str(ck), _on_point=interrupt, **FAST)
    assert ck.exists()
    with np.load(ck) as z:
        assert list(z["index"]) == [0, 1, 2]
    calls = []
    resumed = sweep(grid, model="constant", checkpoint=str(ck), _on_point=calls.append, **FAST)
    assert calls == [4, 5, 6]  # only the missing points ran
    assert resumed.regime == full.regime
    np.testing.assert_array_equal(resumed.poincare, full.poincare)
    np.testing.assert_array_equal(resumed.lyapunov, full.lyapunov)
    assert not ck.exists()  # removed after success


def test_checkpoint_of_another_sweep_is_refused(tmp_path):
    ck = tmp_path / "c.npz"

    def stop(done):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sweep([1.0, 1.1], model="constant", checkpoint=str(ck), _on_point=stop, **FAST)
    with pytest.raises(ValueError, match="different sweep"):
        sweep([1.0, 1.1], model="dynamic", checkpoint=str(ck), **FAST)
    with pytest.raises(ValueError, match="omega grid"):
        sweep([1.0, 1.2], model="constant", checkpoint=str(ck), **FAST)
    ck.write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(ValueError, match="corrupt"):
        sweep([1.0, 1.1], model="constant", checkpoint=str(ck), **FAST)


def test_cli_sweep_writes_json_netcdf_and_plot(tmp_path, capsys):
    from gear_env.cli import main

    js, nc, png = tmp_path / "o.json", tmp_path / "o.nc", tmp_path / "b.png"
    argv = ["sweep", "--model", "constant", "--omega-min", "0.9", "--omega-max", "2.0", "--points", "4",
            "--transient", "30", "--periods", "20", "--steps-per-period", "64", "--quiet",
            "--json", str(js), "--out", str(nc), "--plot", str(png)]  # fmt: skip
    assert main(argv) == 0
    d = json.loads(js.read_text())
    assert len(d["omega"]) == 4 and len(d["regime"]) == 4 and len(d["amplitude_u"]) == 4
    assert len(d["lyapunov"]) == 4 and np.shape(d["poincare_delta"]) == (4, 20)
    assert SweepResult.load(str(nc)).regime == d["regime"]
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert main(["sweep", "--points", "0", "--quiet"]) == 2
    assert "--points" in capsys.readouterr().err


def test_drift_flags_a_transient_and_not_a_settled_motion():
    """A reverse sweep from 2.50 down to 2.37 with 300 periods per point arrives at 2.37 on the
    slowly departing quiet motion (docs/RESULTS.md, "Hysteresis and dwell time"), and its first
    point (from the static equilibrium) is still settling: both drift. The period-1 points in
    between and at 1.2 recur and are not flagged; with 4,000 periods per point nothing is."""
    w = [1.2, *np.round(np.arange(2.37, 2.505, 0.01), 2)]
    short = sweep(w, model="dynamic", direction="reverse", transient=300, periods=200, lyapunov=False, progress=False)
    d = dict(zip(np.round(short.omega, 2), short.drift()))
    assert d[1.2] < 0.01  # settled period-1 (3e-4 here: it follows 2.37 after 300 periods)
    assert d[2.37] > 0.1 and d[2.5] > 0.1
    assert max(d[x] for x in np.round(np.arange(2.41, 2.495, 0.01), 2)) < 0.02
    flagged = list(np.round(short.unsettled(), 2))
    assert 2.37 in flagged and 2.5 in flagged and 1.2 not in flagged and 2.45 not in flagged
    long_ = sweep(w, model="dynamic", direction="reverse", transient=4000, periods=200, lyapunov=False, progress=False)
    assert long_.unsettled().size == 0
    assert "drift" in short.to_dataframe().columns
    from gear_env.plots.sweep import plot_bifurcation

    legend = [t.get_text() for t in plot_bifurcation(short, lyapunov=False).axes[0].get_legend().get_texts()]
    assert "still drifting: longer transient" in legend
    legend = [t.get_text() for t in plot_bifurcation(long_, lyapunov=False).axes[0].get_legend().get_texts()]
    assert "still drifting: longer transient" not in legend
    with pytest.raises(ValueError, match="threshold"):
        short.unsettled(threshold=-1.0)


def test_cli_sweep_notes_unsettled_points(capsys):
    from gear_env.cli import main

    args = ["sweep", "--omega-min", "2.37", "--omega-max", "2.50", "--points", "14", "--direction", "reverse",
            "--transient", "300", "--periods", "200", "--no-lyapunov", "--quiet"]  # fmt: skip
    assert main(args) == 0
    note = next(line for line in capsys.readouterr().out.splitlines() if "still drifting" in line)
    assert "2.3700" in note and "2.5000" in note and "2.4500" not in note and "--transient" in note


# states of the 300-point forward sweeps (``sweep(np.linspace(0.05, 3, 300), model=M)``) just before
# the point: two torus points the 200-period windows labelled chaotic, and a chaotic point
_TORUS_DYN_1905 = (1.9048494983277593, [0.026284067120993442, -0.07221488090635964, 0.033098516918254724,
                   -0.0909374278503412, 1.1708474613194406, 0.1752940570102414, -0.48161646340022785,
                   -0.07563023895828504, 0.20779237376584522, -0.04564380040712749])  # fmt: skip
_TORUS_CONST_2270 = (2.269899665551839, [-0.04455165165294724, 0.12240465691588134, 0.07461568389009074,
                     -0.20500490662518855, 1.2664269473472336, 0.1715264319927167, -0.47126499873960953,
                     -0.08205604235552869, 0.22544712350162718, 0.04897995749482172])  # fmt: skip
_CHAOS_DYN_0514 = (0.5137123745819399, [-0.0035280803182323774, 0.009693321008365724, -0.005095512710611638,
                   0.013999806112949098, 1.2670869527368647, -0.02845232822874247, 0.07817212933938104,
                   0.021974775794867226, -0.06037520029397545, 0.20362035627088415])  # fmt: skip


@pytest.mark.parametrize(
    "model, point, label",
    [("dynamic", _TORUS_DYN_1905, "quasi-periodic"), ("constant", _TORUS_CONST_2270, "quasi-periodic"),
     ("dynamic", _CHAOS_DYN_0514, "chaotic")],
)  # fmt: skip
def test_marginal_chaotic_labels_are_reexamined_over_longer_windows(model, point, label):
    """A chaotic label from an exponent within CHAOS_MARGIN bands of zero is re-examined with the
    perturbed copy running longer (issue 24): the torus points that fresh copies per window labelled
    chaotic (pooled exponents 0.0025 and 0.0023 then) are quasi-periodic, with an exponent inside the
    zero band of a pooled time of two windows at least; the weakly chaotic point at 0.514 stays chaotic."""
    omega, x = point
    cfg = SweepConfig(model, "forward", 300, 200, GearParams(), None, True, True)
    r = run_point(cfg, omega, np.array(x))
    assert r.regime == label
    if label == "chaotic":
        assert r.lyapunov > 5e-4
    else:
        from gear_env.analysis.classify import DEFAULT_LYAP_TOL, lyapunov_tolerance

        t_two_windows = 2 * 200 * 2 * np.pi / omega  # natural time of the first window and one confirmation
        assert abs(r.lyapunov) <= lyapunov_tolerance(t_two_windows, DEFAULT_LYAP_TOL)


# the dynamic model's point at omega = 2.3686 of the 300-point forward sweep, from the state the sweep's chain
# hands it (the final state of the point before): a torus, labelled chaotic while every Lyapunov window
# started a fresh perturbed copy
_TORUS_DYN_2369 = (2.368561872909699, [-0.04056360238897501, 0.11144758161544448, 0.06612153344917471,
                   -0.1816674200913217, 1.2592199867698317, 0.15973597508720835, -0.43887098462667073,
                   -0.0699710185350216, 0.19224379344121273, 0.09260954986813931])  # fmt: skip


def test_the_perturbed_copy_continues_across_windows_on_a_torus():
    """On a torus the separation's realignment adds a positive stretch of order 1 to every window that
    starts a fresh copy (0.56 per window here), which reads as weak chaos however many windows are pooled;
    the copy continued from window to window (``lyapunov_record(..., direction=)``) does not add it. The
    sweep's point there is quasi-periodic."""
    from gear_env.analysis.lyapunov import lyapunov_record, start_direction
    from gear_env.sim.params import model_code
    from gear_env.sim.simulator import default_steps_per_period

    omega, x0 = _TORUS_DYN_2369
    cfg = SweepConfig("dynamic", "forward", 300, 200, GearParams(), None, True, True)
    r = run_point(cfg, omega, np.array(x0))
    assert r.regime == "quasi-periodic"
    n = default_steps_per_period(omega)
    c, code = GearParams().consts, model_code("dynamic")
    sums = {}
    for mode in ("continued", "fresh"):
        x = np.array(r.final_state)
        u = start_direction(10)
        total = 0.0
        for k in range(10):
            kw = {"direction": u, "skip": None if k else 20} if mode == "continued" else {}
            total += lyapunov_record(x, omega, 200, n, c, code, 1e-8, **kw)[4]
        sums[mode] = total
        if mode == "continued":  # the record handed its final direction on, a unit vector
            assert abs(np.linalg.norm(u) - 1.0) < 1e-12 and not np.allclose(u, start_direction(10))
    assert sums["fresh"] > 4.0 and abs(sums["continued"]) < 3.0, sums
    # with a direction and no skip, nothing is skipped: the sum covers the whole record
    x = np.array(r.final_state)
    u = start_direction(10)
    *_, t_all, _, t_count = lyapunov_record(x, omega, 50, n, c, code, 1e-8, direction=u)
    assert t_count == pytest.approx(t_all)


def test_lyapunov_record_direction_and_skip_are_checked():
    """Bad ``direction`` or ``skip`` is refused before any work, naming the argument (the state is untouched)."""
    from gear_env.analysis.lyapunov import lyapunov_record
    from gear_env.sim.params import model_code

    x = np.full(10, 0.01)
    c, code = GearParams().consts, model_code("constant")
    frozen = np.ones(10)
    frozen.flags.writeable = False
    for d in (np.zeros(10), np.ones(9), np.full(10, np.nan), np.ones(10, dtype=int), (1.0,) * 10, frozen):
        with pytest.raises(ValueError, match="direction"):
            lyapunov_record(x, 1.0, 4, 16, c, code, 1e-8, direction=d)
    for skip in (-1, 4, 50, 2.5, True):
        with pytest.raises(ValueError, match="skip"):
            lyapunov_record(x, 1.0, 4, 16, c, code, 1e-8, skip=skip)
    assert np.all(x == 0.01)
