"""Issue 18 items 4-5 in the command line: say what is happening, no misleading footer, motion class."""

from __future__ import annotations

import json

from gear_env.cli import main as cli

FAST = {"steps_per_period": 32, "periods_per_step": 4, "max_steps": 4, "warmup_periods": 8}


def test_evaluate_help_lists_the_policy_names(capsys):
    assert cli(["evaluate", "--help"]) == 0
    out = "".join(capsys.readouterr().out.split())  # argparse wraps lines, also at hyphens
    for name in ("pretrained", "oracle", "constant-best", "hill-climber", "random[:SEED]", "RUN_DIR"):
        assert name in out


def test_evaluate_says_what_it_does_before_the_work(monkeypatch, capsys):
    import gear_env.evaluation as ev

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(ev, "evaluate_policies", stop)
    assert cli(["evaluate", "--schedule", "constant:1.2", "--episodes", "3", "--seed", "5"]) == 130
    out = capsys.readouterr().out
    assert "evaluating 1 policy x 3 episode(s) on GearSpeed-v1, seeds 5..7" in out  # the default task
    assert "rolling out" in out


def test_one_episode_has_no_confidence_interval_footer(tmp_path, capsys):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(FAST))
    md = tmp_path / "t.md"
    assert (
        cli(["evaluate", "--schedule", "constant:1.2", "--episodes", "1", "--config", str(cfg), "--markdown", str(md)])
        == 0
    )
    out = capsys.readouterr().out
    assert "95 %" not in out and "one episode: no confidence interval" in out
    assert "95 %" not in md.read_text()
    assert cli(["evaluate", "--schedule", "constant:1.2", "--episodes", "2", "--config", str(cfg)]) == 0
    assert "± = 95 % confidence interval" in capsys.readouterr().out


def test_simulate_prints_the_motion_class(capsys):
    argv = ["simulate", "--omega", "1.2", "--periods", "8", "--transient", "20", "--steps-per-period", "32"]
    assert cli(argv) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("motion: "))
    from gear_env.analysis import classify_motion
    from gear_env.sim.simulator import simulate

    traj = simulate(1.2, periods=8, transient=20, steps_per_period=32)
    assert line.split()[1] == classify_motion(traj.poincare_rows[:, :10]).label
