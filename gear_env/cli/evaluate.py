"""``gear-env evaluate``: compare speed schedules (and trained policies) on GearSpeed-v0."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="evaluate speed schedules / policies on GearSpeed-v0",
        description=(
            "Roll out speed schedules (CSV/JSON files of (time in env steps, omega) points, or built-ins "
            "constant:W, ramp:W0:W1:STEPS, piecewise:T0=W0,T1=W1,...) and policies on the same episode seeds; "
            "print a table of return, throughput, chaotic fraction, contact loss and impacts."
        ),
    )
    p.add_argument("--schedule", action="append", default=[], metavar="FILE|SPEC", help="a schedule (repeatable)")
    p.add_argument(
        "--policy",
        action="append",
        default=[],
        metavar="SPEC",
        help="a policy spec resolved by agents.registry (repeatable)",
    )
    p.add_argument("--episodes", type=int, default=5, help="episodes per policy (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first episode (default 0)")
    p.add_argument(
        "--env", default="GearSpeed-v0", metavar="ID",
        help="task: GearSpeed-v0 (default), GearSpeed-v1 or GearSpeedDemand-v0 (--config settings override its own)",
    )  # fmt: skip
    p.add_argument("--config", metavar="CONFIG.json", help="JSON object of environment settings")
    p.add_argument("--json", metavar="PATH", help="write the results as JSON")
    p.add_argument("--markdown", metavar="PATH", help="write the table as Markdown")
    p.add_argument("--plot", metavar="PATH", help="write a PNG: omega(t) over the regime bands, vibration below")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..env_config import GearSpeedConfig
    from ..evaluation import evaluate_policies
    from ..io import atomic_write_text
    from ..schedules import SpeedSchedule
    from ..tasks import task_config

    cfg = task_config(args.env, GearSpeedConfig.from_json(args.config).to_dict() if args.config else None)
    if not args.schedule and not args.policy:
        raise ValueError("give at least one --schedule FILE|SPEC or --policy SPEC")
    policies: dict[str, object] = {}
    for spec in args.schedule:
        s = SpeedSchedule.from_spec(spec, cfg)
        name = s.name if s.name not in policies else spec
        policies[name] = s
    if args.policy:
        try:
            from agents.registry import resolve_policy  # type: ignore[import-not-found]
        except ImportError as exc:
            raise ValueError(f"policy specs need the agents package (agents.registry): {exc}") from None
        for spec in args.policy:
            policies[spec] = resolve_policy(spec, cfg, env_id=args.env)
    report = evaluate_policies(policies, cfg, episodes=args.episodes, seed=args.seed)
    table = report.to_markdown()
    print(table)
    if args.json:
        atomic_write_text(args.json, json.dumps(report.to_json_dict(), indent=1))
        print(f"wrote {args.json}")
    if args.markdown:
        atomic_write_text(args.markdown, table + "\n")
        print(f"wrote {args.markdown}")
    if args.plot:
        report.plot(args.plot)
        print(f"wrote {args.plot}")
    return 0


__all__ = ["add_parser", "run"]
