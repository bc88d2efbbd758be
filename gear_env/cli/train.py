"""``gear-env train``: PPO training on GearSpeed-v0 (the same code as the top-level ``train.py``).

The implementation lives in :mod:`agents.ppo`; see docs/TRAINING.md.
"""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    from agents.ppo import add_arguments

    p = sub.add_parser(
        "train",
        help="train a PPO speed-scheduling agent",
        description="Train SB3 PPO on GearSpeed-v0 (vector env, VecNormalize, checkpoints, --resume). "
        "Writes a run folder: model.zip, vecnormalize.pkl, config.json, metrics.csv/json, checkpoints/.",
    )
    add_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from agents.ppo import run_from_args

    return run_from_args(args)


__all__ = ["add_parser", "run"]
