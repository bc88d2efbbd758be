"""``gear-env evaluate``: compare speed schedules and policies on one task (default: the run folders' own,
else GearSpeed-v1)."""

from __future__ import annotations

import argparse
import json
import sys
import time

from ..envs.tasks import TASK_SETTINGS
from .common import add_env_options, choose_env, int_range, writes

TASK_IDS = tuple(TASK_SETTINGS)


def _policy_names() -> str:
    try:
        from agents.registry import NAMES  # type: ignore[import-not-found]
    except ImportError:  # the agents package is not installed: schedules only
        return "(needs the agents package)"
    return ", ".join(NAMES) + ", or a training run folder RUN_DIR (also RUN_DIR/best_model.zip)"


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="evaluate speed schedules / policies on one task (default GearSpeed-v1)",
        description=(
            "Roll out speed schedules (CSV/JSON files of (time in env steps, omega) points, or built-ins "
            "constant:W, ramp:W0:W1:STEPS, piecewise:T0=W0,T1=W1,...) and policies on the same episode seeds; "
            "print a table of return, throughput, chaotic fraction, contact loss and impacts. "
            "Run folders are read without unpickling anything (docs/TRAINING.md: what is safe to load)."
        ),
    )
    p.add_argument("--schedule", action="append", default=[], metavar="FILE|SPEC", help="a schedule (repeatable)")
    p.add_argument(
        "--policy",
        action="append",
        default=[],
        metavar="SPEC",
        help=f"a policy (repeatable): {_policy_names()}",
    )
    p.add_argument("--episodes", type=int_range(1, 100_000), default=5, help="episodes per policy (default 5)")
    p.add_argument(
        "--seed", type=int_range(0, 2**32 - 1), default=0, help="seed of the first episode, 0-4294967295 (default 0)"
    )
    add_env_options(p)
    p.add_argument("--config", metavar="CONFIG.json", help="JSON object of environment settings")
    p.add_argument("--json", metavar="PATH", help="write the results as JSON")
    p.add_argument("--markdown", metavar="PATH", help="write the table as Markdown")
    p.add_argument("--plot", metavar="PATH", help="write a PNG: omega(t) over the regime bands, vibration below")
    p.set_defaults(func=run)


@writes(outputs=("json", "markdown", "plot"), inputs=("config", "schedule", "policy"))
def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    if not args.schedule and not args.policy:
        raise ValueError("give at least one --schedule FILE|SPEC or --policy SPEC")
    if args.seed + args.episodes - 1 > 2**32 - 1:
        raise ValueError(f"--seed + --episodes - 1 must be <= {2**32 - 1} (episode k uses seed --seed + k)")
    n = len(args.schedule) + len(args.policy)
    args.env = choose_env(args.env, args.policy)
    print(
        f"evaluating {n} polic{'y' if n == 1 else 'ies'} x {args.episodes} episode(s) on {args.env}, "
        f"seeds {args.seed}..{args.seed + args.episodes - 1} "
        "(a fresh numba cache first compiles for 10-30 s, longer under load)",
        flush=True,
    )
    from ..envs.env_config import task_config
    from ..envs.schedules import SpeedSchedule
    from ..evaluation import evaluate_policies
    from ..io import atomic_write_text, read_json

    data = None
    if args.config:
        data = read_json(args.config, "--config", max_bytes=1024 * 1024)
        if not isinstance(data, dict):
            raise ValueError(f"--config {args.config!r} must hold a JSON object of settings")
    cfg = task_config(args.env, data)
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
            print(f"  loading policy {spec}", flush=True)
            policies[spec] = resolve_policy(spec, cfg, env_id=args.env, allow_other_env=args.allow_other_env)
    print(f"  rolling out ({time.perf_counter() - t0:.1f} s so far)", flush=True)
    report = evaluate_policies(policies, cfg, episodes=args.episodes, seed=args.seed)
    table = report.to_markdown()
    if args.episodes == 1:  # no interval from one episode: do not announce one
        table = table.replace("; ± = 95 % confidence interval (t).", " (one episode: no confidence interval).")
    print(table)
    print(f"done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
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
