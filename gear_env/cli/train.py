"""``gear-env train`` and ``python train.py``: the command line of PPO training on the gear tasks.

Argument parsing lives here; the training itself is :func:`agents.ppo.train` (see docs/TRAINING.md).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import Any

from ..envs.tasks import TASK_SETTINGS
from .common import int_range

GEAR_ENV_ID = "GearSpeed-v1"  # the default task (gear_env.cli.common.DEFAULT_ENV)
GEAR_ENV_IDS = tuple(TASK_SETTINGS)
MAX_NUM_ENVS = 1024  # the same bound as agents.ppo.MAX_NUM_ENVS (checked again there)
MAX_TIMESTEPS = 10**12
DEFAULT_NUM_ENVS = 16
DEFAULT_EVAL_EPISODES = 16  # agents.ppo.TrainOptions.eval_episodes

DESCRIPTION = (
    "Train SB3 PPO on a gear task (default GearSpeed-v1; vector env, VecNormalize, checkpoints, --resume). Writes "
    "a run folder: "
    "model.zip, vecnormalize.npz, config.json, metrics.csv/json, checkpoints/. Nothing in a run folder is "
    "unpickled when it is loaded (docs/TRAINING.md)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Register the training options on ``p`` (shared by train.py and ``gear-env train``)."""
    p.add_argument("--out", required=True, metavar="RUN_DIR", help="run folder to create (or resume)")
    p.add_argument(
        "--timesteps",
        type=int_range(1, MAX_TIMESTEPS),
        default=None,
        help="total environment steps, rounded up to whole rollouts of n_steps x num-envs (default 700000, "
        "or n_timesteps of --hyperparams)",
    )
    p.add_argument(
        "--num-envs",
        type=int_range(1, MAX_NUM_ENVS),
        default=None,
        help=f"sub-environments in the vector env, 1-{MAX_NUM_ENVS} (default 16; with --resume the stored value)",
    )
    p.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0, help="random seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue RUN_DIR from its last checkpoint")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing run in RUN_DIR (its models, checkpoints and metrics are deleted)",
    )
    p.add_argument("--config", metavar="FILE.json", help="environment config (JSON object of GearSpeedConfig fields)")
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override one env config field (JSON value)"
    )
    p.add_argument("--model", choices=["constant", "dynamic"], help="backlash model of the environment")
    p.add_argument("--randomize-params", action="store_true", help="randomise the physics parameters per episode")
    p.add_argument("--demand", metavar="PROFILE", help="demand profile of the environment (name or file)")
    p.add_argument(
        "--env",
        "--env-id",
        dest="env_id",
        choices=GEAR_ENV_IDS,
        default=None,
        metavar="ID",
        help=f"task: {', '.join(GEAR_ENV_IDS)} (default {GEAR_ENV_ID})",
    )
    p.add_argument(
        "--hyperparams",
        metavar="PPO.yml",
        help="take the PPO hyper-parameters, n_envs, n_timesteps and env_kwargs of the task from an rl-zoo3 "
        "file (agents/hyperparams/ppo.yml); explicit options win",
    )
    p.add_argument(
        "--eval-freq",
        type=int_range(0, MAX_TIMESTEPS),
        default=50_000,
        help="evaluate every N total steps (0 = only at the end)",
    )
    p.add_argument(
        "--eval-episodes",
        type=int_range(1, 100_000),
        default=None,
        help="episodes per evaluation, which also choose the distillation's kept round (default 16, or the "
        "eval_episodes of --hyperparams' DistillCallback; with --resume the stored value)",
    )
    p.add_argument(
        "--checkpoint-freq",
        type=int_range(0, MAX_TIMESTEPS),
        default=50_000,
        help="checkpoint every N total steps (0 = off)",
    )
    p.add_argument("--ppo", action="append", default=[], metavar="KEY=VALUE", help="PPO hyper-parameter (JSON value)")
    p.add_argument(
        "--distill",
        type=int_range(0, 1000),
        default=0,
        metavar="N",
        help="first fit the policy to the privileged episode oracle by N DAgger iterations (agents/distill.py; "
        "their environment steps count in --timesteps, whose default is then 0: distillation only)",
    )
    p.add_argument(
        "--distill-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="distillation setting: episodes (per iteration, default 100), epochs (20), learning_rate (1e-3), "
        "final_lr_fraction (1.0), batch_size (256), quantile (null: squared error; q in (0, 1): pinball loss)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-tensorboard", action="store_true", help="no TensorBoard logs")
    p.add_argument("--quiet", action="store_true", help="print only errors")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train a PPO speed-scheduling agent", description=DESCRIPTION)
    add_arguments(p)
    p.set_defaults(func=run)


def _demand(text: str) -> Any:
    """--demand: a preset name of GearSpeedConfig.demand, or a JSON/CSV file of (t_steps, omega) rows."""
    from ..io import read_json, read_limited

    if not os.path.isfile(text):
        if os.sep in text or os.path.lexists(text) or text.lower().endswith((".json", ".csv", ".txt")):
            from ..untrusted import open_regular

            os.close(open_regular(text, "--demand")[0])  # a FIFO, folder or missing file: refused by name
        return text  # a preset name; GearSpeedConfig validates it
    if text.lower().endswith(".json"):
        return read_json(text, "--demand")
    raw = read_limited(text, "--demand").decode("utf-8-sig", errors="replace")
    rows = []
    for i, line in enumerate(raw.splitlines()):
        cells = [c.strip() for c in line.replace(";", ",").split(",") if c.strip()]
        if not cells or cells[0].startswith("#"):
            continue
        try:
            rows.append([float(cells[0]), float(cells[1])])
        except (ValueError, IndexError):
            if i == 0:
                continue  # header row
            raise ValueError(f"--demand: line {i + 1} of {text!r} is not 't_steps,omega': {line!r}") from None
    if not rows:
        raise ValueError(f"--demand {text!r} holds no 't_steps,omega' rows")
    return rows


def _kv(items: Sequence[str], what: str) -> dict[str, Any]:
    """KEY=VALUE options with JSON values (a bare word stays a string), depth and size bounded."""
    from ..io import parse_json_text

    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"{what}: expected KEY=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        if len(v) > 10_000:
            raise ValueError(f"{what} {k.strip()}: value longer than 10000 characters")
        try:
            out[k.strip()] = parse_json_text(v, f"{what} {k.strip()}")
        except ValueError as exc:
            if "is not valid JSON" not in str(exc):
                raise
            out[k.strip()] = v
    return out


def options_from_args(args: argparse.Namespace) -> Any:
    """Build :class:`agents.ppo.TrainOptions` from parsed command-line arguments."""
    from agents.envs import load_config_file
    from agents.ppo import TrainOptions
    from agents.runs import RunFolder

    env_cfg: dict[str, Any] = load_config_file(args.config) if args.config else {}
    if args.model:
        env_cfg["model"] = args.model
    if args.randomize_params:
        env_cfg["randomize_params"] = True
    if args.demand:
        env_cfg["demand"] = _demand(args.demand)
    env_cfg.update(_kv(args.set, "--set"))
    explicit_env = bool(args.config or args.model or args.randomize_params or args.demand or args.set)
    env_id = args.env_id or GEAR_ENV_ID
    timesteps, num_envs_arg = args.timesteps, args.num_envs
    zoo_ppo: dict[str, Any] = {}
    zoo_distill: dict[str, Any] = {}
    eval_episodes = args.eval_episodes
    if getattr(args, "hyperparams", None):
        from agents.hyperparams import load_zoo_entry

        zoo = load_zoo_entry(args.hyperparams, env_id)
        zoo_ppo = zoo["ppo"]
        zoo_distill = dict(zoo.get("distill", {}))
        env_cfg = {**zoo["env_kwargs"], **env_cfg}
        timesteps = zoo.get("n_timesteps") if timesteps is None else timesteps
        num_envs_arg = zoo.get("n_envs") if num_envs_arg is None else num_envs_arg
    ppo = {**zoo_ppo, **_kv(args.ppo, "--ppo")}
    num_envs = int(num_envs_arg) if num_envs_arg is not None else DEFAULT_NUM_ENVS
    if args.resume:
        stored = RunFolder(args.out).read_config()
        if args.num_envs is None:  # continue with the stored number of sub-environments
            num_envs = int(stored.get("train", {}).get("num_envs", DEFAULT_NUM_ENVS))
        if not explicit_env:  # resume with the stored environment unless the user asked for something else
            env_cfg, env_id = dict(stored["env_config"]), stored["env_id"]
        ppo = {**dict(stored.get("ppo", {})), **ppo}  # stored hyper-parameters, explicit --ppo on top (checked)
        if eval_episodes is None:
            eval_episodes = stored.get("train", {}).get("eval_episodes")
    distill = int(getattr(args, "distill", 0) or 0)
    distill_params = _kv(getattr(args, "distill_set", []) or [], "--distill-set")
    if zoo_distill and not distill:  # the zoo entry's DistillCallback: the same distillation
        distill = zoo_distill.pop("iterations", 12)
        stops = zoo_distill.pop("stop", True)
        zoo_eval = zoo_distill.pop("eval_episodes", None)
        if eval_episodes is None:  # the callback's evaluation choosing the kept round (TrainOptions checks it)
            eval_episodes = zoo_eval
        zoo_distill.pop("verbose", None)
        distill_params = {**zoo_distill, **distill_params}
        if stops and args.timesteps is None:
            timesteps = None  # distillation only, as the callback's stop=True
        elif not stops and timesteps is None:
            timesteps = 700_000
    if args.resume:
        stored_distill = dict(RunFolder(args.out).read_config().get("distill", {}))
        distill = int(stored_distill.pop("iterations", 0))  # done already: resuming continues with PPO
        distill_params = stored_distill
    if timesteps is None and distill:
        timesteps = 0  # distillation only
    return TrainOptions(
        out=args.out,
        env_id=env_id,
        env_config=env_cfg,
        timesteps=700_000 if timesteps is None else int(timesteps),
        num_envs=num_envs,
        seed=args.seed,
        eval_freq=args.eval_freq,
        eval_episodes=DEFAULT_EVAL_EPISODES if eval_episodes is None else eval_episodes,
        checkpoint_freq=args.checkpoint_freq,
        resume=args.resume,
        overwrite=args.overwrite,
        ppo=ppo,
        progress_bar=not args.no_progress,
        tensorboard=not args.no_tensorboard,
        verbose=0 if args.quiet else 1,
        distill=distill,
        distill_params=distill_params,
    )


def run(args: argparse.Namespace) -> int:
    """Run training from parsed arguments; 0 on success, 130 after Ctrl-C (checkpoint written)."""
    from agents.ppo import train

    if args.resume and args.overwrite:
        raise ValueError("--resume and --overwrite exclude each other")
    opts = options_from_args(args)
    try:
        train(opts)
    except KeyboardInterrupt:
        return 130
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``python train.py`` (the same options as ``gear-env train``)."""
    p = argparse.ArgumentParser(
        prog="train.py", description="Train a PPO speed-scheduling agent on a gear task (same as `gear-env train`)."
    )
    add_arguments(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point of train.py; returns the exit code (2 on a usage/config error)."""
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except (ValueError, OSError) as exc:
        print(f"train: error: {exc}", file=sys.stderr)
        return 2


__all__ = ["add_arguments", "add_parser", "build_parser", "main", "options_from_args", "run"]
