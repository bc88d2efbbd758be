"""``gear-env continuation``: JSON layout, figure, validation, a failing run still writes."""

from __future__ import annotations

import json

import pytest

from gear_env.cli import main
from gear_env.plots.continuation import plot_frequency_response


def test_continuation_json_layout_and_plot(tmp_path, capsys):
    out = tmp_path / "c.json"
    png = tmp_path / "c.png"
    rc = main(["continuation", "--model", "constant", "--omega-min", "1.5", "--omega-max", "1.8",
               "--json", str(out), "--plot", str(png), "--quiet"])  # fmt: skip
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["complete"] is True and d["omega_range"] == [1.5, 1.8]
    (b,) = d["branches"]
    n = len(b["omega"])
    assert b["period"] == 1 and n > 3
    for key in ("omega", "amplitude_u", "max_multiplier", "stable"):
        assert len(b[key]) == n, key
    assert b["stable"][0] is True and b["stable"][-1] is False  # the torus onset near 1.637
    types = [x["type"] for x in d["bifurcations"]]
    assert "neimark-sacker" in types
    ns = [x for x in d["bifurcations"] if x["type"] == "neimark-sacker"][0]
    assert ns["branch"] == 0 and abs(ns["omega"] - 1.637) < 0.006
    assert all(t in ("fold", "period-doubling", "neimark-sacker", "grazing") for t in types)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "neimark-sacker" in capsys.readouterr().out
    assert d["map"] == "located"


def test_unlocated_option_runs_the_old_map(tmp_path, capsys):
    """``--unlocated``: the map of 0.4.0 (recorded in the JSON); near the torus onset both maps put the
    Neimark-Sacker point within 1e-4 of each other (no grazing there), but not bit for bit."""
    pts = {}
    for flag in ([], ["--unlocated"]):
        out = tmp_path / f"c{len(flag)}.json"
        rc = main(["continuation", "--model", "constant", "--omega-min", "1.5", "--omega-max", "1.8",
                   "--json", str(out), "--quiet", *flag])  # fmt: skip
        assert rc == 0
        d = json.loads(out.read_text())
        assert d["map"] == ("unlocated" if flag else "located")
        pts[bool(flag)] = [x["omega"] for x in d["bifurcations"] if x["type"] == "neimark-sacker"][0]
    assert abs(pts[True] - pts[False]) < 1e-4 and pts[True] != pts[False]


@pytest.mark.parametrize(
    "extra, word",
    [
        (["--omega-min", "-1"], "--omega-min"),
        (["--omega-min", "2", "--omega-max", "1"], "--omega-min and --omega-max"),
        (["--omega-max", "nan"], "--omega-max"),
        (["--max-period", "0"], "--max-period"),
        (["--tol", "0.1"], "--tol"),
        (["--ds-max", "5"], "--ds-max"),
        (["--time-limit", "0"], "--time-limit"),
        (["--sweep-points", "-3"], "--sweep-points"),
    ],
)
def test_bad_arguments_name_the_option(extra, word, capsys):
    assert main(["continuation", *extra]) == 2
    err = capsys.readouterr().err
    assert word in err


def test_output_paths_are_checked_before_work(tmp_path, capsys):
    assert main(["continuation", "--json", str(tmp_path)]) == 2  # a folder
    assert "--json" in capsys.readouterr().err
    f = tmp_path / "same"
    assert main(["continuation", "--json", str(f), "--plot", str(f)]) == 2
    assert "different" in capsys.readouterr().err
    assert main(["continuation", "--plot", str(tmp_path / "nope" / "x.png")]) == 2
    assert not f.exists()


def test_a_failing_continuation_writes_what_it_has(tmp_path, capsys):
    """A branch stopped by the time limit: exit code 1, a message naming omega, the JSON written."""
    out = tmp_path / "c.json"
    out.write_text("old")
    rc = main(["continuation", "--model", "dynamic", "--omega-min", "1.0", "--omega-max", "2.5",
               "--time-limit", "0.05", "--json", str(out), "--quiet"])  # fmt: skip
    assert rc == 1
    err = capsys.readouterr().err
    assert "time limit reached at omega=" in err
    d = json.loads(out.read_text())
    assert d["complete"] is False and len(d["branches"][0]["omega"]) >= 1
    assert d["messages"]


def test_plot_takes_plain_data():
    data = {
        "branches": [
            {"period": 1, "omega": [0.1, 0.2, 0.3, 0.4], "amplitude_u": [1, 2, 3, 2],
             "amplitude_delta": [1, 1, 1, 1], "stable": [True, True, False, False]},
        ],
        "bifurcations": [{"omega": 0.25, "type": "fold", "amplitude_u": 2.5, "amplitude_delta": 1}],
    }  # fmt: skip
    fig = plot_frequency_response({"constant": data}, {"constant": {"omega": [0.1], "amplitude_u": [1.0]}})
    ax = fig.axes[0]
    styles = [ln.get_linestyle() for ln in ax.get_lines()]
    assert "-" in styles and "--" in styles
    with pytest.raises(ValueError, match="results"):
        plot_frequency_response({})


def test_default_run_follows_the_cascade_to_max_period_and_exits_0(tmp_path, capsys):
    """The default command (dynamic model, [0.05, 3], --max-period 8) succeeds: the two period-4
    branches that stop at the same orbit near omega 0.4392 (a grazing corner, from both ends) are
    recognised as one branch, and every branch is complete. With --max-period 2 the period doublings
    of the period-2 branch are notes, not branches, and the run still exits 0."""
    out = tmp_path / "c.json"
    assert main(["continuation", "--json", str(out), "--quiet"]) == 0
    d = json.loads(out.read_text())
    assert d["complete"] is True
    assert all("no period-8 branch found" in m for m in d["messages"])  # switching tried, not a branch failure
    assert all(b["complete"] for b in d["branches"])
    met = [b for b in d["branches"] if b["stop_reason"].startswith("met branch")]
    assert len(met) == 2 and {b["period"] for b in met} == {4}
    assert abs(met[0]["omega"][-1] - met[1]["omega"][-1]) < 1e-3
    assert max(b["period"] for b in d["branches"]) <= 8
    out2 = tmp_path / "c2.json"
    rc = main(["continuation", "--omega-min", "0.05", "--omega-max", "0.7", "--max-period", "2", "--json", str(out2),
               "--quiet"])  # fmt: skip
    assert rc == 0
    d2 = json.loads(out2.read_text())
    assert max(b["period"] for b in d2["branches"]) == 2 and d2["complete"] is True
    assert any("period-4 branch is not followed (max_period=2)" in n for n in d2["notes"])
    assert "note: period doubling" in capsys.readouterr().out
