"""``gear-env evaluate`` and gear_env.evaluation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gear_env.cli import main
from gear_env.envs.schedules import SpeedSchedule
from gear_env.evaluation import evaluate_policies, regime_bands

FAST = dict(max_steps=12, periods_per_step=8, warmup_periods=16)


def test_evaluate_cli_writes_table_json_markdown_plot(tmp_path, capsys):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps(FAST))
    sched = tmp_path / "slow.csv"
    sched.write_text("time,omega\n0,0.8\n10,1.2\n")
    out_json, out_md, out_png = tmp_path / "r.json", tmp_path / "r.md", tmp_path / "r.png"
    rc = main(
        [
            "evaluate", "--schedule", str(sched), "--schedule", "constant:1.2", "--episodes", "2", "--seed", "3",
            "--config", str(cfg), "--json", str(out_json), "--markdown", str(out_md), "--plot", str(out_png),
        ]
    )  # fmt: skip
    assert rc == 0
    text = capsys.readouterr().out
    assert "| slow |" in text and "| constant 1.2 |" in text and "throughput" in text
    data = json.loads(out_json.read_text())
    pol = data["policies"]["constant 1.2"]
    for key in ("return_mean", "throughput_mean", "chaotic_fraction", "contact_loss_fraction", "settled_omega"):
        assert key in pol
    assert len(pol["settled_omega"]) == 2
    assert data["seed"] == 3 and data["config"]["max_steps"] == 12
    assert out_md.read_text().startswith("| policy |")
    assert out_png.read_bytes()[:4] == b"\x89PNG"


def test_evaluate_cli_errors(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("0,1\n5,0\n")
    assert main(["evaluate", "--schedule", str(bad)]) == 2
    assert "bad.csv" in capsys.readouterr().err
    assert main(["evaluate"]) == 2
    assert "at least one" in capsys.readouterr().err
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"max_stepz": 3}))
    assert main(["evaluate", "--schedule", "constant:1", "--config", str(cfg)]) == 2
    assert "valid keys" in capsys.readouterr().err


def test_evaluate_cli_policy_without_agents_package(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "agents.registry", None)  # import fails
    assert main(["evaluate", "--policy", "ppo:model.zip", "--episodes", "1"]) == 2
    assert "policy specs need the agents package" in capsys.readouterr().err


def test_evaluate_policies_same_seeds_and_metrics():
    pols = {"a": SpeedSchedule.constant(1.2, FAST), "b": SpeedSchedule.constant(1.2, FAST)}
    rep = evaluate_policies(pols, FAST, episodes=3, seed=1)
    ra = [e.ret for e in rep.episodes["a"]]
    assert ra == [e.ret for e in rep.episodes["b"]]  # same seeds -> same episodes
    e = rep.episodes["a"][0]
    assert e.steps == 12 and len(e.omega) == 12
    assert 0 <= e.chaotic_fraction <= 1 and 0 <= e.contact_loss <= 1
    assert e.settled_omega == pytest.approx(np.mean(e.omega[-3:]))
    mean, half = rep.summary("a")["ret"]
    assert mean == pytest.approx(np.mean(ra)) and half > 0
    with pytest.raises(ValueError, match="episodes"):
        evaluate_policies(pols, FAST, episodes=0)
    with pytest.raises(ValueError, match="predict"):
        evaluate_policies({"x": object()}, FAST, episodes=1)


@pytest.mark.parametrize("params", [None, {"kappa": 0.21}])
def test_regime_bands_cover_the_range(params):
    b = regime_bands(dict(FAST, params=params), points=12)
    spans = sorted(iv for ivs in b.bands.values() for iv in ivs)
    assert spans[0][0] == pytest.approx(0.1) and spans[-1][1] == pytest.approx(3.0)
    if params is None:  # default parameters: the shipped Floquet map
        assert "Floquet" in b.source and b.bands["stable"]
    else:  # own steady runs: the chaotic band exists
        assert b.source == "steady_reward_map" and b.bands["nonperiodic"]
