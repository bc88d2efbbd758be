"""``python -m gear_env.evaluation`` (also ``python -m gear_env.cli.steady``): print the steady
reward of constant speeds (:func:`gear_env.envs.steady_map.steady_reward_map`) for some models and
step counts, and optionally write it as JSON and as a figure."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np


def _steps(text: str) -> str:
    """The ``--steps-per-period`` list, checked: comma-separated integers in [8, 100000]."""
    try:
        out = [int(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not all(8 <= n <= 100_000 for n in out):
        raise argparse.ArgumentTypeError(f"steps per period must be integers in [8, 100000], got {text}")
    return text


def _step(text: str) -> float:
    """The ``--step`` of the omega grid: a number in [0.001, 10]."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 1e-3 <= v <= 10.0:  # NaN fails too
        raise argparse.ArgumentTypeError(f"must be a number in [0.001, 10], got {text}")
    return v


def _models(text: str) -> str:
    """The ``--models`` list, checked: comma-separated ``dynamic`` / ``constant``."""
    out = text.split(",")
    for m in out:
        if m not in ("dynamic", "constant"):
            raise argparse.ArgumentTypeError(f"models are dynamic and constant, got {m!r}")
    return text


def build_parser(prog: str = "python -m gear_env.evaluation") -> argparse.ArgumentParser:
    """The argument parser of the steady reward map command."""
    ap = argparse.ArgumentParser(prog=prog, description="Steady reward of constant speeds.")
    ap.add_argument("--models", type=_models, default="dynamic,constant", help="comma-separated backlash models")
    ap.add_argument(
        "--steps-per-period", type=_steps, default="64", help="comma-separated Newmark steps per mesh period"
    )
    ap.add_argument("--step", type=_step, default=0.05, help="omega grid step, 0.001-10 (default 0.05)")
    ap.add_argument("--json", metavar="PATH", help="write the maps as JSON")
    ap.add_argument("--plot", metavar="PNG", help="write the curves")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    from ..io import hold_outputs

    try:
        with hold_outputs({"--json": args.json, "--plot": args.plot}):
            return _run(args)
    except (ValueError, OSError) as exc:  # one line naming the option or file, exit 2 (as gear-env)
        print(f"{ap.prog}: error: {exc}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from ..envs.env_config import GearSpeedConfig
    from ..envs.steady_map import steady_reward_map

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
