"""``gear-env demo``: a one-minute tour - simulate, classify, draw, and evaluate speed schedules."""

from __future__ import annotations

import argparse
import os
import time


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="short demo: simulate, classify, draw figures, evaluate schedules/policies",
        description=(
            "Simulate the gear pair (dynamic backlash) at a quiet and at a rough speed, classify the motion "
            "(Poincare section + Lyapunov exponent), draw figures, then evaluate speed schedules, a "
            "vibration-feedback baseline and the shipped pretrained PPO policy on GearSpeed-v0."
        ),
    )
    p.add_argument("--out", default="demo_out", help="folder for the figures and tables (default demo_out)")
    p.add_argument("--episodes", type=int, default=3, help="evaluation episodes per policy (default 3)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..analysis import classify_motion, largest_lyapunov
    from ..analysis.stability import default_stability_map
    from ..env_config import GearSpeedConfig
    from ..evaluation import evaluate_policies
    from ..io import atomic_write_text
    from ..params import GearParams
    from ..plots import plot_trajectory, save_figure
    from ..plots.analysis import plot_stability_map
    from ..schedules import SpeedSchedule
    from ..simulator import GearSimulator

    t0 = time.time()
    os.makedirs(args.out, exist_ok=True)
    p = GearParams()
    print(
        f"gear-env demo: Table 1 spur pair, omega_n = {p.omega_n:.1f} rad/s ({p.omega_n / 6.283185:.0f} Hz), "
        f"omega = 1 is the pinion at {p.pinion_rpm(1.0):.0f} rpm\n"
    )
    print("1. simulate (dynamic backlash, 300 transient + 200 recorded mesh periods, Newmark-beta)")
    for omega in (1.2, 2.0):
        sim = GearSimulator(p, "dynamic", omega=omega)
        sim.advance(300)
        state = sim.state
        traj = sim.record(200)
        lam = largest_lyapunov(omega, "dynamic", p, state=state, periods=200)
        cls = classify_motion(traj.poincare_rows[:, :10], lyapunov=lam)
        path = os.path.join(args.out, f"trajectory_omega{omega:g}.png")
        save_figure(plot_trajectory(traj), path)
        print(
            f"   omega = {omega:g}: {cls.label:15s} amplitude U = {traj.amplitude('U'):.3f} b0, "
            f"Delta = {traj.amplitude('delta'):.3f} b0, contact loss {traj.contact_loss_fraction:.0%}, "
            f"Lyapunov {lam:+.4f} per omega_n t  -> {path}"
        )
    smap = default_stability_map("dynamic")
    path = os.path.join(args.out, "stability_dynamic.png")
    save_figure(plot_stability_map(smap), path)
    stable = ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in smap.stable_intervals())
    print(f"\n2. Floquet stability map of the period-1 orbit: stable on {stable}  -> {path}")

    print(f"\n3. evaluate speed policies on GearSpeed-v0 ({args.episodes} episodes each, same seeds)")
    cfg = GearSpeedConfig()
    policies: dict[str, object] = {
        "constant 1.2": SpeedSchedule.constant(1.2, cfg),
        "ramp 0.3->2.4": SpeedSchedule.ramp(0.3, 2.4, cfg.max_steps, cfg),
    }
    try:
        from agents.registry import resolve_policy  # type: ignore[import-not-found]

        for spec in ("hill-climber", "pretrained"):
            try:
                policies[spec] = resolve_policy(spec, cfg)
            except (ValueError, OSError) as exc:
                print(f"   ({spec} skipped: {exc})")
    except ImportError:
        print("   (agents package not importable: baselines and the pretrained policy skipped)")
    report = evaluate_policies(policies, cfg, episodes=args.episodes, seed=0)
    table = report.to_markdown()
    print(table)
    md = os.path.join(args.out, "evaluation.md")
    png = os.path.join(args.out, "evaluation.png")
    atomic_write_text(md, table + "\n")
    report.plot(png)
    print(f"   -> {md}, {png}")
    print(f"\ndone in {time.time() - t0:.0f} s. Next: gear-env --help, README.md, docs/")
    return 0
