"""``python -m gear_env.evaluation`` (also ``python -m gear_env.cli.steady``): print the steady
reward of constant speeds (:func:`gear_env.steady_map.steady_reward_map`) for some models and
step counts, and optionally write it as JSON and as a figure."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence

import numpy as np


def build_parser(prog: str = "python -m gear_env.evaluation") -> argparse.ArgumentParser:
    """The argument parser of the steady reward map command."""
    ap = argparse.ArgumentParser(prog=prog, description="Steady reward of constant speeds.")
    ap.add_argument("--models", default="dynamic,constant", help="comma-separated backlash models")
    ap.add_argument("--steps-per-period", default="64", help="comma-separated Newmark steps per mesh period")
    ap.add_argument("--step", type=float, default=0.05, help="omega grid step (default 0.05)")
    ap.add_argument("--json", metavar="PATH", help="write the maps as JSON")
    ap.add_argument("--plot", metavar="PNG", help="write the curves")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    args = build_parser().parse_args(argv)
    from ..io import hold_outputs

    with hold_outputs({"--json": args.json, "--plot": args.plot}):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    from ..env_config import GearSpeedConfig
    from ..steady_map import steady_reward_map

    cfg = GearSpeedConfig()
    w = np.round(np.arange(cfg.omega_min, cfg.omega_max + 1e-9, args.step), 6)
    maps = {}
    for model in args.models.split(","):
        for nsp in args.steps_per_period.split(","):
            label = f"{model}, {nsp} steps/period"
            maps[label] = steady_reward_map({"model": model, "steps_per_period": int(nsp)}, w)
            print(f"## {label}: best constant omega {maps[label].best_omega:.2f}\n")
            print(maps[label].to_markdown() + "\n")
    if args.json:
        from ..io import atomic_write_text

        atomic_write_text(args.json, json.dumps({k: m.to_dict() for k, m in maps.items()}, indent=1))
    if args.plot:
        from ..plots.common import save_figure
        from ..plots.env import plot_steady_reward

        save_figure(plot_steady_reward(maps), args.plot)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
