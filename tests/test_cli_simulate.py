"""``gear-env simulate``: JSON keys and values, figure, clean errors."""

import json

import numpy as np

from gear_env import simulate
from gear_env.cli import main


def test_simulate_json_and_plot(tmp_path, capsys):
    out = tmp_path / "run.json"
    png = tmp_path / "run.png"
    args = ["simulate", "--omega", "1.2", "--model", "dynamic", "--periods", "20", "--transient", "30"]
    rc = main([*args, "--steps-per-period", "64", "--json", str(out), "--plot", str(png)])
    assert rc == 0
    d = json.loads(out.read_text())
    for key in ("omega", "model", "poincare_delta", "poincare_u", "amplitude_u", "amplitude_delta", "steps_per_period"):
        assert key in d, key
    assert d["omega"] == 1.2 and d["model"] == "dynamic" and d["steps_per_period"] == 64
    assert len(d["poincare_delta"]) == 20 and len(d["poincare_u"]) == 20
    # same numbers as the Python API
    tr = simulate(1.2, "dynamic", periods=20, transient=30, steps_per_period=64)
    assert np.allclose(d["poincare_u"], tr.poincare("U"), rtol=0, atol=1e-12)
    assert abs(d["amplitude_u"] - tr.amplitude("U")) < 1e-12
    assert abs(d["amplitude_delta"] - tr.amplitude("delta")) < 1e-12
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "amplitude" in capsys.readouterr().out


def test_simulate_kappa_and_default_steps(tmp_path):
    out = tmp_path / "k.json"
    rc = main(["simulate", "--omega", "0.8", "--model", "constant", "--periods", "3", "--transient", "0",
               "--kappa", "0.1", "--json", str(out)])  # fmt: skip
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["steps_per_period"] == 192 and d["params"]["kappa"] == 0.1  # default_steps_per_period(0.8)


def test_simulate_bad_arguments_exit_2(tmp_path, capsys):
    assert main(["simulate", "--omega", "-1", "--periods", "2", "--transient", "0"]) == 2
    assert "omega" in capsys.readouterr().err
    assert main(["simulate", "--omega", "1", "--periods", "0", "--transient", "0"]) == 2
    assert "periods" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
