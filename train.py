#!/usr/bin/env python
"""Train a PPO speed-scheduling agent on GearSpeed-v0 (the same as ``gear-env train``).

Example (the run reported in docs/RESULTS.md)::

    python train.py --out runs/ppo_default --timesteps 200000 --num-envs 8 --seed 0

See docs/TRAINING.md for every option, resuming, and evaluation.
"""

import os
import sys

from gear_env.cli.train import main

if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.exit(main())
