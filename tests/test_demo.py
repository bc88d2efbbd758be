"""The README's demo command runs end to end and writes its figures and table."""

from gear_env.cli import main


def test_demo_runs(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert "period-1" in out  # omega = 1.2 is a stable period-1 orbit
    assert "quasi-periodic" in out or "chaotic" in out  # omega = 2.0 lies in the torus band
    for name in ("trajectory_omega1.2.png", "trajectory_omega2.png", "stability_dynamic.png", "tasks.png"):
        assert (tmp_path / name).stat().st_size > 0
    # the tasks that matter lead: v1 and Demand, the learned policy against fixed-best and the oracle
    assert out.index("GearSpeed-v1") < out.index("GearSpeedDemand-v0")
    for env_id in ("GearSpeed-v1", "GearSpeedDemand-v0"):
        table = (tmp_path / f"{env_id}.md").read_text()
        for row in ("| learned (shipped policy) |", "| fixed-best |", "| oracle |"):
            assert row in table, (env_id, row)
        assert "% of oracle" in table
    assert "demand delivered" in (tmp_path / "GearSpeedDemand-v0.md").read_text()
    assert "GearSpeed-v0" not in out.split("GearSpeed-v0, the first version")[0]  # v0 only as history, at the end


def test_demo_picks_up_policies_through_the_registry_by_name(monkeypatch, tmp_path, capsys):
    """A scripted policy the registry knows appears in the task steps; one it does not know is left out."""
    import agents.registry as registry
    from gear_env.cli import demo

    real = registry.resolve_policy

    def resolve(spec, config=None, env_id=None):
        if spec == "my-script":
            return real("constant:1.2", config)
        return real(spec, config, env_id=env_id)

    monkeypatch.setattr(registry, "resolve_policy", resolve)
    monkeypatch.setattr(demo, "DEMO_POLICIES", ("my-script", "not-a-policy", "oracle"))
    scores = demo.task_demo(3, "GearSpeed-v1", 1, str(tmp_path))
    assert set(scores) == {"my-script", "oracle"}
    assert scores["oracle"] == (100.0, 0.0)


def test_demo_demand_step_compares_the_policy_with_every_fixed_speed(capsys):
    """Step 5: the shipped GearSpeedDemand-v0 policy and every fixed speed on the two pairs; a fixed speed
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
