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


def test_demo_demand_step_compares_the_policy_with_every_fixed_speed(capsys):
    """Step 4: the shipped GearSpeedDemand-v0 policy and every fixed speed on the two pairs; a fixed speed
    settles at itself on both (it cannot tell them apart), and the printed verdict follows the numbers."""
    import numpy as np

    from gear_env.cli.demo import DEMO_FIXED, DEMO_PLANTS, demand_demo

    out = demand_demo(1)
    labels = [p[0] for p in DEMO_PLANTS]
    assert set(out) == {"learned (pretrained)", *(f"fixed {w:g}" for w in DEMO_FIXED)}
    for w in DEMO_FIXED:
        assert all(abs(out[f"fixed {w:g}"][lb][1] - w) < 0.01 for lb in labels)
    assert all(np.isfinite(r) for r, _ in out["learned (pretrained)"].values())
    best = max(np.mean([r for r, _ in out[f"fixed {w:g}"].values()]) for w in DEMO_FIXED)
    learned = np.mean([r for r, _ in out["learned (pretrained)"].values()])
    text = capsys.readouterr().out
    assert ("it beats every fixed speed" in text) == (learned > best)
