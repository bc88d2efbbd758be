"""``gear-env demo``: a short tour - simulate, classify, draw, then the two tasks that matter (GearSpeed-v1,
GearSpeedDemand-v0): the learned policies against the scripts, the best fixed speed and the oracle."""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from .common import int_range, writes


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="short demo: simulate, classify, draw figures, evaluate schedules/policies",
        description=(
            "Simulate the gear pair (dynamic backlash) at a quiet and at a rough speed, classify the motion "
            "(Poincare section + Lyapunov exponent), draw figures, then run the policies shipped for GearSpeed-v1 "
            "and GearSpeedDemand-v0 against the scripted policies, the best fixed speed and the oracle on the same "
            "seeds (tables and one figure of both tasks), and show the Demand policy finding each gear pair's own "
            "quiet window from its sensors."
        ),
    )
    p.add_argument("--out", default="demo_out", help="folder for the figures and tables (default demo_out)")
    p.add_argument(
        "--episodes", type=int_range(1, 1000), default=3, help="episodes per policy and task, 1-1000 (default 3)"
    )
    p.set_defaults(func=run)


@writes(folders=("out",))
def run(args: argparse.Namespace) -> int:
    from ..analysis import classify_motion, largest_lyapunov
    from ..analysis.stability import default_stability_map
    from ..plots import plot_trajectory, save_figure
    from ..plots.analysis import plot_stability_map
    from ..sim.params import GearParams
    from ..sim.simulator import GearSimulator

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

    scores: dict[str, dict[str, tuple[float, float]]] = {}
    for step, env_id in ((3, "GearSpeed-v1"), (4, "GearSpeedDemand-v0")):
        scores[env_id] = task_demo(step, env_id, args.episodes, args.out)
    if any(scores.values()):
        from ..plots.tasks import plot_task_scores

        path = os.path.join(args.out, "tasks.png")
        fig = plot_task_scores(
            {k: v for k, v in scores.items() if v},
            highlight=LEARNED,
            title=f"learned, scripted, best fixed and oracle; {args.episodes} episode(s) from seed {DEMO_SEED}",
        )
        save_figure(fig, path)
        print(f"\n   the figure of both tasks -> {path}")
    demand_demo(1)  # the scenario has no random draw: one episode per policy says it all
    print(
        "\nGearSpeed-v0, the first version of the task, is kept for history: "
        "gear-env evaluate --env GearSpeed-v0 --policy pretrained --policy oracle"
    )
    print(f"\ndone in {time.time() - t0:.0f} s. Next: gear-env --help, README.md, docs/")
    return 0


DEMO_SEED = 9001
"""First episode seed of the task steps (the seeds of docs/RESULTS.md, never used in training)."""
DEMO_POLICIES = (
    "pretrained",
    "fixed-best",
    "hill-climber",
    "edge-seeker",
    "identify-follow",
    "delayed-oracle:4",
    "oracle",
)
"""Policy specs the task steps show, in this order, each resolved through agents.registry by name; a spec the
registry does not know (or whose task it does not fit) is left out, so new scripted policies appear here by
being registered."""
LEARNED = "learned (shipped policy)"
MORE = {
    "GearSpeed-v1": "20 episodes and three training seeds: docs/RESULTS.md",
    "GearSpeedDemand-v0": "100 test episodes and five training seeds: docs/tasks/GearSpeedDemand-v0.md",
}
"""Where each task's fuller numbers are (the demo's few episodes are a glance)."""


def task_demo(step: int, env_id: str, episodes: int, out: str) -> dict[str, tuple[float, float]]:
    """Steps 3 and 4: the shipped policy of ``env_id`` against the scripted policies, the best fixed speed and
    the oracle on the same ``episodes`` seeds; prints the table (with % of the oracle, and on the Demand task
    the cost and the demand delivered), writes ``out/<env_id>.md`` and returns {label: (% of oracle, CI)}."""
    from ..envs.env_config import task_config
    from ..evaluation import evaluate_policies
    from ..io import atomic_write_text

    what = {
        "GearSpeed-v1": "hold the fastest quiet speed from any start (the task to start with)",
        "GearSpeedDemand-v0": "deliver the demanded speed on a gear pair drawn per episode (sensors tell them apart)",
    }[env_id]
    print(f"\n{step}. {env_id}: {what}; {episodes} episode(s) per policy, seeds {DEMO_SEED}..")
    cfg = task_config(env_id)
    try:
        from agents.registry import resolve_policy  # type: ignore[import-not-found]
    except ImportError as exc:
        print(f"   (skipped: the agents package is not importable: {exc})")
        return {}
    policies: dict[str, object] = {}
    for spec in DEMO_POLICIES:
        try:
            policies[LEARNED if spec == "pretrained" else spec] = resolve_policy(spec, cfg, env_id=env_id)
        except ValueError as exc:
            if "unknown policy" not in str(exc):
                print(f"   ({spec} skipped: {exc})")
        except (ImportError, OSError) as exc:
            print(f"   ({spec} skipped: {exc})")
    if "oracle" not in policies:
        print("   (skipped: no oracle to compare with)")
        return {}
    report = evaluate_policies(policies, cfg, episodes=episodes, seed=DEMO_SEED, reference="oracle")
    table = report.to_markdown()
    print(table)
    md = os.path.join(out, f"{env_id}.md")
    atomic_write_text(md, f"# {env_id}\n\n" + table + "\n")
    scores = {name: paired_percent(report, name) for name in policies}
    if LEARNED in scores:
        fixed = scores.get("fixed-best", (float("nan"), 0.0))[0]
        print(
            f"   the learned policy: {scores[LEARNED][0]:.1f} % of the oracle, the best fixed speed {fixed:.1f} % "
            f"({MORE.get(env_id, 'docs/RESULTS.md')})  -> {md}"
        )
    return scores


def paired_percent(report: Any, name: str, reference: str = "oracle") -> tuple[float, float]:
    """Mean return of ``name`` in % of the reference's, and the 95 % half-width of the paired per-seed
    differences in the same units (the spread of the starts cancels: both ran the same seeds)."""
    from ..evaluation.report import _ci95

    ret = np.array([e.ret for e in report.episodes[name]])
    ref = np.array([e.ret for e in report.episodes[reference]])
    scale = abs(float(ref.mean())) or 1.0
    mean, half = _ci95(ret - ref)
    return 100.0 + 100.0 * mean / scale, 100.0 * half / scale


DEMO_PLANTS = (
    ("light load x0.45, worn teeth (TE x1.9)", 0.45, 1.9),
    ("heavy load x1.45, precise teeth (TE x0.3)", 1.45, 0.3),
)
"""Two gear pairs of GearSpeedDemand-v0's family whose quiet windows end far apart (load, e_m1 factors)."""
DEMO_DEMAND = 1.8
DEMO_STEPS = 40
DEMO_FIXED = (1.15, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8)


def demand_demo(episodes: int = 1) -> dict[str, dict[str, tuple[float, float]]]:
    """Step 5 of the demo: the shipped GearSpeedDemand-v0 policy against every fixed speed on two plants.

    Each plant runs ``DEMO_STEPS`` steps with the demand held at ``DEMO_DEMAND`` from omega 1.2 (full
    load); the policy sees only its sensors and the demand. A fixed schedule cannot tell the plants
    apart, so the best one is the single speed with the best mean return over both. Returns
    {policy: {plant label: (mean return, mean settled omega)}}; prints the table.
    """
    from ..envs.env_config import task_config
    from ..evaluation import evaluate_policies

    print(
        f"\n5. GearSpeedDemand-v0 close up: the demand is omega {DEMO_DEMAND:g} on two gear pairs of the family; "
        "which speed is quiet depends on the pair"
    )
    try:
        from agents.registry import resolve_policy  # type: ignore[import-not-found]

        resolve_policy("pretrained", task_config("GearSpeedDemand-v0"), env_id="GearSpeedDemand-v0")
    except (ImportError, ValueError, OSError) as exc:
        print(f"   (skipped: the pretrained GearSpeedDemand-v0 policy is not available: {exc})")
        return {}
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for label, lf, ef in DEMO_PLANTS:
        cfg = task_config(
            "GearSpeedDemand-v0",
            {
                "plant_family": {"load": (lf, lf), "e_m1": (ef, ef)},
                "duty_cycle": None,
                "demand": [(0, DEMO_DEMAND), (DEMO_STEPS, DEMO_DEMAND)],
                "max_steps": DEMO_STEPS,
                "initial_omega": 1.2,
            },
        )
        pols = {"learned (pretrained)": resolve_policy("pretrained", cfg, env_id="GearSpeedDemand-v0")}
        pols.update({f"fixed {w:g}": resolve_policy(f"constant:{w:g}", cfg) for w in DEMO_FIXED})
        rep = evaluate_policies(pols, cfg, episodes=max(1, int(episodes)), seed=0)
        for name, eps in rep.episodes.items():
            ret = float(np.mean([e.ret for e in eps]))
            out.setdefault(name, {})[label] = (ret, float(np.mean([e.settled_omega for e in eps])))
    fixed = [k for k in out if k.startswith("fixed")]
    best = max(fixed, key=lambda k: float(np.mean([r for r, _ in out[k].values()])))
    labels = [p[0] for p in DEMO_PLANTS]
    print("   " + f"{'policy':22s}" + "".join(f"{lb:>44s}" for lb in labels) + f"{'mean return':>14s}")
    for name in ("learned (pretrained)", best):
        row = out[name]
        cells = "".join(f"{f'omega {row[lb][1]:.2f}, return {row[lb][0]:6.2f}':>44s}" for lb in labels)
        tag = name if name != best else f"{name} (best fixed)"
        print(f"   {tag:22s}{cells}{np.mean([row[lb][0] for lb in labels]):14.2f}")
    learned = out["learned (pretrained)"]
    spread = abs(learned[labels[1]][1] - learned[labels[0]][1])
    m_learned = float(np.mean([r for r, _ in learned.values()]))
    m_fixed = float(np.mean([r for r, _ in out[best].values()]))
    print(
        f"   A fixed schedule cannot tell the pairs apart: it holds one speed on both. The learned policy reads\n"
        f"   only its sensors and the demand; its settled speeds differ by {spread:.2f} between the pairs, and its\n"
        f"   mean return is {m_learned:.2f} against {m_fixed:.2f} for the best fixed speed "
        + ("(it beats every fixed speed)." if m_learned > m_fixed else "(it does not beat the best fixed speed yet:\n")
        + ("" if m_learned > m_fixed else "   docs/RESULTS.md, GearSpeedDemand-v0, says what it misses).")
    )
    return out
