"""Paper figures (gear_env.plots.analysis) and the ``gear-env figures`` / ``stability`` commands."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from gear_env.analysis.spectrum import waterfall
from gear_env.analysis.stability import default_stability_map
from gear_env.cli import main
from gear_env.plots import analysis as pa
from gear_env.simulator import simulate


@pytest.fixture(scope="module")
def runs():
    return {m: {w: simulate(w, m, 6, 10, 32) for w in (1.0, 2.0)} for m in ("constant", "dynamic")}


def test_time_history_and_phase_figures(runs):
    fig = pa.plot_time_histories(runs, "bd", periods=3)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    # the constant model's B_d is the constant half backlash: a flat line at 1
    line = fig.axes[0].lines[0]
    assert np.allclose(line.get_ydata(), 1.0)
    fig = pa.plot_time_histories(runs, "psi")
    assert np.allclose(fig.axes[0].lines[1].get_ydata(), 20.0)  # dynamic psi stays at alpha0 (MODEL.md 6)
    fig = pa.plot_phase_portraits(runs["dynamic"], title="dynamic")
    assert len(fig.axes) == 4
    with pytest.raises(ValueError):
        pa.plot_phase_portraits({})


def test_stability_and_waterfall_figures():
    sm = default_stability_map("dynamic")
    fig = pa.plot_stability_map(sm)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    fig = pa.plot_multipliers_complex(sm, [1.0, 2.0])
    assert len(fig.axes[0].lines) == 3
    wf = waterfall([1.0, 2.0], "constant", periods=4, transient=5, steps_per_period=32)
    assert isinstance(pa.plot_waterfall(wf), Figure)


def test_gear_env_stability_command(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GEAR_ENV_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "map.json"
    png = tmp_path / "map.png"
    assert main(["stability", "--model", "dynamic", "--json", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "neimark-sacker" in text and "period-doubling" in text
    d = json.loads(out.read_text())
    assert d["model"] == "dynamic" and len(d["omega"]) == 296
    assert any(lab == "stable" and lo <= 1.0 <= hi for lo, hi, lab in d["intervals"])
    assert png.stat().st_size > 1000
    assert main(["stability", "--model", "dynamic", "--points", "1"]) == 2  # clean error


def test_gear_env_figures_quick(tmp_path, monkeypatch):
    monkeypatch.setenv("GEAR_ENV_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "figs"
    assert main(["figures", "--out", str(out), "--quick"]) == 0
    names = sorted(p.name for p in out.glob("*.png"))
    expected = ["fig05_backlash.png", "fig06_meshing_angle.png", "fig06b_meshing_angle_friction.png"]
    expected += ["fig07_amplitude_frequency.png"]
    expected += [f"fig08_phase_{m}.png" for m in ("constant", "dynamic")] + ["fig09_amplitude.png"]
    expected += [f"fig10_waterfall_{m}.png" for m in ("constant", "dynamic")] + ["fig11_bifurcation.png"]
    expected += [f"fig12_stability_{m}.png" for m in ("constant", "dynamic")]
    assert names == sorted(expected)
    s = json.loads((out / "summary.json").read_text())
    assert set(s["models"]) == {"constant", "dynamic"}
    assert main(["figures", "--out", str(out), "--quick", "--workers", "0"]) == 2
