"""``gear-env report`` (also ``python -m gear_env.cli.report``): judge
policies against the targets of the RL result (docs/RESULTS.md). The computation is
:mod:`agents.report`; this module is its command line."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from .common import add_env_options, choose_env, int_range, writes

DESCRIPTION = (
    "Judge policies against the targets of the RL result: return vs the oracle, chaos once settled, settled "
    "omega inside the stable window of the simulator's own stability map. Writes OUT/rl_report.md, "
    "OUT/rl_report.json and OUT/rl_omega.png."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The report's options."""
    p.add_argument(
        "--policy", action="append", required=True, help="policy spec (agents.registry) or NAME=SPEC; repeatable"
    )
    add_env_options(p)
    p.add_argument("--config", help="environment settings JSON overriding the task's own (or a run folder)")
    p.add_argument("--episodes", type=int_range(1, 100_000), default=20, help="episodes per policy (default 20)")
    p.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0, help="seed of the first episode (default 0)")
    p.add_argument("--out", required=True, help="output folder")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="judge policies against the RL targets", description=DESCRIPTION)
    add_arguments(p)
    p.set_defaults(func=run)


@writes(folders=("out",), inputs=("config",))
def run(args: argparse.Namespace) -> int:
    import torch

    from agents.envs import load_config_file
    from agents.registry import resolve_policy
    from agents.report import compare, plot, to_markdown

    from ..envs.env_config import task_config
    from ..io import atomic_write_text

    torch.set_num_threads(1)
    env_id = choose_env(args.env, args.policy)
    cfg = task_config(env_id, load_config_file(args.config) if args.config else None)
    pols = {}
    oracle = "oracle"
    for item in args.policy:
        name, spec = item.split("=", 1) if "=" in item else (item, item)
        pols[name] = resolve_policy(spec, cfg, env_id=env_id, allow_other_env=args.allow_other_env)
        if spec == "oracle":
            oracle = name
    print(f"rolling out {len(pols)} policies x {args.episodes} episodes on {env_id}", flush=True)
    res = compare(pols, cfg, episodes=args.episodes, seed=args.seed, oracle=oracle)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    md = to_markdown(res)
    print(md)
    atomic_write_text(out / "rl_report.md", md + "\n")
    atomic_write_text(out / "rl_report.json", json.dumps(res, indent=1) + "\n")
    plot(res, str(out / "rl_omega.png"))
    print(f"wrote {out / 'rl_report.md'}, {out / 'rl_report.json'}, {out / 'rl_omega.png'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m agents.report``; exit code 2 on a usage or input error."""
    p = argparse.ArgumentParser(prog="python -m agents.report", description=DESCRIPTION)
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except (ValueError, OSError) as exc:
        print(f"report: error: {exc}", file=sys.stderr)
        return 2


__all__ = ["add_arguments", "add_parser", "main", "run"]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
