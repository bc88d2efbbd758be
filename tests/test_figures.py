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
from gear_env.sim.simulator import simulate


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


# ------------------------------------------------------------------ what an engineer reads on the figures
def _texts(fig) -> list[str]:
    """Every string drawn on ``fig``: titles, axis labels, legends, annotations."""
    out = [t.get_text() for t in fig.texts]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    legends = list(fig.legends)
    for ax in fig.axes:
        out += [ax.get_title(loc) for loc in ("left", "center", "right")]
        out += [ax.get_xlabel(), ax.get_ylabel()] + ([ax.get_zlabel()] if hasattr(ax, "get_zlabel") else [])
        out += [t.get_text() for t in ax.texts]
        if ax.get_legend() is not None:
            legends.append(ax.get_legend())
    for leg in legends:
        out += [t.get_text() for t in leg.get_texts()] + [leg.get_title().get_text()]
    return [s for s in out if s]


ASCII_NAMES = ("omega", "Omega", "Delta", "delta", "Poincare", "psi", "alpha0", "b0", "mu=")


def _plain_words(text: str) -> str:
    """The text outside mathtext ($...$) segments."""
    return "".join(part for i, part in enumerate(text.split("$")) if i % 2 == 0)


def _nesting(text: str) -> int:
    depth = best = 0
    for ch in text:
        depth += ch == "("
        best = max(best, depth)
        depth -= ch == ")"
    return best


def _check_labels(fig) -> list[str]:
    texts = _texts(fig)
    assert texts
    bad = [t for t in texts if any(w in _plain_words(t) for w in ASCII_NAMES) or _nesting(t) > 1]
    return bad


def _draw(fig):
    """Draw ``fig`` on an Agg canvas (runs the constrained layout); returns the renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def _overlapping_boxes(fig) -> list[str]:
    """Figure-level legends and the title that overlap each other once drawn."""
    r = _draw(fig)
    boxes = [(f"legend {i}", leg.get_window_extent(r)) for i, leg in enumerate(fig.legends)]
    if fig._suptitle is not None:
        boxes.append(("title", fig._suptitle.get_window_extent(r)))
    return [f"{a} / {b}" for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1 :] if ba.overlaps(bb)]


def _fake_report():
    from types import SimpleNamespace

    from gear_env.envs.env_config import GearSpeedConfig

    w = list(np.linspace(1.9, 0.6, 27)) + [0.6 + 0.01 * k for k in range(173)]
    ep = SimpleNamespace(omega=w, vibration=list(np.linspace(1.2, 3.5, 200)), ret=12.5)
    return SimpleNamespace(config=GearSpeedConfig(), episodes={"ramp 0.3->2.4": [ep]}, seed=0)


def test_figure_labels_use_symbols_and_units(runs):
    """Labels in mathtext (omega, Delta, psi, b_0), Poincaré with its accent, no nested brackets."""
    from types import SimpleNamespace

    from gear_env.envs.bands import RegimeBands
    from gear_env.envs.env_config import GearSpeedConfig
    from gear_env.plots import plot_trajectory
    from gear_env.plots.env import EnvFrame, plot_evaluation, plot_steady_reward

    sm = default_stability_map("dynamic")
    sweep = SimpleNamespace(
        omega=np.array([1.0, 2.0]),
        amplitude={"bd": np.array([0.1, 0.2]), "psi": np.zeros(2), "U": np.array([0.3, 0.1])},
        poincare=np.zeros((2, 4, 14)),
    )
    smap = SimpleNamespace(
        omegas=np.array([1.0, 2.0]), reward=np.array([0.2, -1.0]), best_omega=1.0,
        terms={"chaos": np.array([0.0, 1.0]), "contact_loss": np.array([0.0, 0.7])},
    )  # fmt: skip
    bands = RegimeBands({"stable": [(0.5, 1.5)], "neimark-sacker": [(1.5, 2.5)]}, "shipped Floquet map, dynamic")
    frame = EnvFrame(GearSpeedConfig(), bands)
    frame.draw(np.array([[1.0, 0.0, 0.0, 1.0], [1.05, 0.1, 0.2, 1.5]]), np.array([[0.9, 0.01], [0.95, 0.02]]), False)
    figs = {
        "trajectory": plot_trajectory(runs["dynamic"][2.0]),
        "time histories": pa.plot_time_histories(runs, "bd", periods=3),
        "psi histories": pa.plot_time_histories(runs, "psi", periods=3),
        "phase portraits": pa.plot_phase_portraits(runs["dynamic"], title="dynamic backlash"),
        "amplitude-frequency": pa.plot_amplitude_frequency({"forward": sweep, "reverse": sweep}),
        "amplitude": pa.plot_amplitude_vs_omega({"dynamic": sweep}),
        "bifurcation": pa.plot_bifurcation({"dynamic backlash": sweep}),
        "stability": pa.plot_stability_map(sm),
        "multipliers": pa.plot_multipliers_complex(sm, [1.0, 2.0]),
        "evaluation": plot_evaluation(_fake_report(), bands),
        "steady reward": plot_steady_reward({"dynamic, 64 steps/period": smap}),
        "env frame": frame.fig,
    }
    bad = {name: _check_labels(fig) for name, fig in figs.items()}
    assert not any(bad.values()), bad
    clash = {name: _overlapping_boxes(fig) for name, fig in figs.items()}
    assert not any(clash.values()), clash
    # velocities name their unit and say what s is; the Poincaré axes say how often they sample
    texts = " ".join(_texts(figs["phase portraits"]))
    assert "$b_0$" in texts and r"$s = \omega_n t$" in texts and "once per mesh period" in texts
    traj = _texts(figs["trajectory"])
    assert any("transmission error" in t for t in traj) and any("B_d" in t for t in traj)  # legend: both curves


def test_overlap_checker_catches_a_legend_on_the_title():
    fig = Figure(layout="constrained")
    ax = fig.add_subplot()
    ax.plot([0, 1], label="a curve with a long label")
    fig.suptitle("a title long enough to meet the legend")
    fig.legend(loc="upper center")
    assert _overlapping_boxes(fig) == ["legend 0 / title"]


def test_figure_texts_checker_catches_ascii_labels():
    """The label checker fails on the labels the figures used to have."""
    fig = Figure()
    ax = fig.add_subplot()
    ax.set_xlabel("omega = Omega/omega_n")
    ax.set_title("schedules over regime bands (Floquet map of period-1 (dynamic, shipped))")
    assert _check_labels(fig) == ["schedules over regime bands (Floquet map of period-1 (dynamic, shipped))",
                                  "omega = Omega/omega_n"]  # fmt: skip
    ax.set_title("")
    ax.set_xlabel(r"$\omega = \Omega/\omega_n$")
    assert _check_labels(fig) == []


def test_evaluation_figure_states_rate_limit_and_reads_log_ticks_plainly():
    """The ramp's curve lags its command: the figure says why; the log axis reads 2, 3 (not 2x10^0);
    the legend sits beside the axes, not on the curves."""
    from gear_env.envs.bands import RegimeBands
    from gear_env.plots.env import plot_evaluation

    rep = _fake_report()
    fig = plot_evaluation(rep, RegimeBands({"stable": [(0.5, 1.5)]}, "steady_reward_map"))
    _draw(fig)
    top, bottom = fig.axes[:2]
    assert any(f"at most {rep.config.max_domega:g} per step" in t.get_text() for t in top.texts)
    labels = [t.get_text() for t in bottom.yaxis.get_ticklabels(minor=True) + bottom.yaxis.get_ticklabels()]
    assert any(lab in ("2", "3") for lab in labels) and not any("times" in lab for lab in labels), labels
    leg = top.get_legend().get_window_extent()
    assert leg.x0 >= top.get_window_extent().x1 - 1  # outside the axes: covers no curve


def test_poincare_map_of_a_periodic_orbit_is_not_blown_up_to_round_off():
    """A period-1 orbit's Poincaré points agree to round-off; the axes show a 0.1-wide window
    instead of an offset label such as 1e-11+1.43e-2."""
    n = 32
    phase = 2 * np.pi * np.arange(40 * n + 1) / n
    rng = np.random.default_rng(0)

    class PeriodOne:  # a period-1 orbit whose Poincaré samples differ by round-off only
        steps_per_period = n
        ch = {
            "delta": 1.0 + 0.1 * np.cos(phase) + 1e-13 * rng.standard_normal(phase.size),
            "ddelta": 0.0143 - 0.1 * np.sin(phase) + 1e-13 * rng.standard_normal(phase.size),
            "bd": np.full(phase.size, 1.03),
        }

        def __getitem__(self, name):
            return self.ch[name]

    fig = pa.plot_phase_portraits({1.0: PeriodOne()})
    ax = fig.axes[1]
    lo, hi = ax.get_ylim()
    assert hi - lo >= 0.1 - 1e-12
    _draw(fig)
    assert ax.yaxis.get_offset_text().get_text() == ""


def test_env_frame_draws_without_bands():
    from gear_env.envs.env_config import GearSpeedConfig
    from gear_env.plots.env import EnvFrame

    frame = EnvFrame(GearSpeedConfig())
    rgb = frame.draw(np.array([[1.0, 0.0, 0.0, 1.0]]), np.zeros((0, 2)), True)
    assert rgb.ndim == 3 and rgb.shape[2] == 3 and frame.fig.axes[0].get_legend() is None
