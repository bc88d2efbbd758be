"""The README's demo command runs end to end and writes its figures and table."""

from gear_env.cli import main


def test_demo_runs(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert "period-1" in out  # omega = 1.2 is a stable period-1 orbit
    assert "quasi-periodic" in out or "chaotic" in out  # omega = 2.0 lies in the torus band
    for name in ("trajectory_omega1.2.png", "trajectory_omega2.png", "stability_dynamic.png", "evaluation.md"):
        assert (tmp_path / name).stat().st_size > 0
    assert "constant 1.2" in (tmp_path / "evaluation.md").read_text()
