"""PPO training on GearSpeed-v0: set-up, callbacks, run folder, resume, and the command line.

``python train.py ...`` and ``gear-env train ...`` run :func:`main` / :func:`train` here.

What a run does (see :mod:`agents.runs` for the folder layout):

* builds ``num_envs`` sub-environments in the native vector env (one numba call per step) behind its
  stable-baselines3 adapter, wrapped in ``VecNormalize`` (observations and rewards normalised in
  training; the statistics are saved with the model and reloaded frozen for evaluation);
* trains SB3 PPO (MLP policy, one torch thread), logging to TensorBoard if it is installed and
  showing a progress bar if tqdm and rich are installed;
* evaluates the deterministic policy every ``eval_freq`` steps on separately seeded environments
  (metrics.csv / metrics.json) and writes a checkpoint (model + statistics + step count,
  atomically) every ``checkpoint_freq`` steps;
* on Ctrl-C writes a checkpoint and exits with code 130; ``--resume`` continues from the last
  checkpoint with the step count carried on.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.io import atomic_write_text

from .envs import GEAR_ENV_ID, config_to_dict, load_config_file, make_config, make_sb3_vec_env
from .runs import RunFolder, RunFolderError, check_space_compatible, space_to_dict, versions

EVAL_SEED_OFFSET = 1_000_003
"""Evaluation episodes during training use seeds seed + EVAL_SEED_OFFSET + i (never training seeds)."""

PPO_DEFAULTS: dict[str, Any] = {
    "learning_rate": 3e-4,
    "n_steps": 256,  # per sub-environment
    "batch_size": 256,
    "n_epochs": 10,
    # 0.999, not 0.98-0.99: from omega ~2.9 the way to the best window crosses ~17 steps of non-periodic
    # motion (reward ~ -1.4 each); with gamma <= 0.995 staying at omega = 3 (reward ~ +0.05) has about the
    # same or a larger *discounted* value, although it loses half of the episode return (docs/RESULTS.md)
    "gamma": 0.999,
    "gae_lambda": 0.98,
    "clip_range": 0.2,
    "ent_coef": 0.01,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "net_arch": [64, 64],
    "log_std_init": 0.0,
    "use_sde": False,
    "sde_sample_freq": -1,
}
"""PPO hyper-parameters (SB3 names; ``net_arch`` and ``log_std_init`` go to policy_kwargs)."""


@dataclass(frozen=True)
class TrainOptions:
    """Options of one training run (validated in ``__post_init__``).

    ``timesteps`` is the total number of environment steps (over all sub-environments), also when
    resuming; ``eval_freq`` and ``checkpoint_freq`` are in total environment steps."""

    out: str
    env_id: str = GEAR_ENV_ID
    env_config: Mapping[str, Any] = field(default_factory=dict)
    timesteps: int = 700_000
    num_envs: int = 16
    seed: int = 0
    eval_freq: int = 50_000
    eval_episodes: int = 16
    checkpoint_freq: int = 50_000
    keep_checkpoints: int = 3
    resume: bool = False
    overwrite: bool = False
    ppo: Mapping[str, Any] = field(default_factory=dict)
    progress_bar: bool = True
    tensorboard: bool = True
    verbose: int = 1

    def __post_init__(self) -> None:
        for name, lo in (("timesteps", 1), ("num_envs", 1), ("eval_episodes", 1), ("keep_checkpoints", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
        for name in ("eval_freq", "checkpoint_freq", "seed"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ValueError(f"{name} must be an integer >= 0 (0 = off for frequencies), got {v!r}")
        unknown = set(self.ppo) - set(PPO_DEFAULTS)
        if unknown:
            raise ValueError(f"unknown PPO hyper-parameter(s) {sorted(unknown)}; valid: {sorted(PPO_DEFAULTS)}")

    def ppo_params(self) -> dict[str, Any]:
        """The PPO hyper-parameters with the defaults filled in."""
        return {**PPO_DEFAULTS, **dict(self.ppo)}


# --------------------------------------------------------------------------------------------------
# callbacks
# --------------------------------------------------------------------------------------------------
def _callbacks(run: RunFolder, opts: TrainOptions, eval_venv: Any, state: dict[str, Any]) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class CheckpointAndEval(BaseCallback):
        """Checkpoint every ``checkpoint_freq`` and evaluate every ``eval_freq`` total steps."""

        def _on_training_start(self) -> None:
            n = self.model.num_timesteps
            self.next_ckpt = _next_multiple(n, opts.checkpoint_freq)
            self.next_eval = _next_multiple(n, opts.eval_freq)

        def _on_step(self) -> bool:
            n = self.model.num_timesteps
            if opts.eval_freq and n >= self.next_eval:
                self.next_eval = _next_multiple(n, opts.eval_freq)
                self.evaluate()
            if opts.checkpoint_freq and n >= self.next_ckpt:
                self.next_ckpt = _next_multiple(n, opts.checkpoint_freq)
                run.save_checkpoint(self.model, self.model.get_env(), n, keep=opts.keep_checkpoints)
            return True

        def evaluate(self) -> dict[str, Any]:
            row = evaluate_model(
                self.model, self.model.get_env(), eval_venv, opts.eval_episodes, seed=opts.seed + EVAL_SEED_OFFSET
            )
            row["wall_seconds"] = round(state["wall_before"] + time.perf_counter() - state["t0"], 3)
            state["rows"].append(row)
            for k, v in row.items():
                if k != "timesteps" and isinstance(v, (int, float)):
                    self.logger.record(f"eval/{k}", v)
            if row["return_mean"] > state.get("best_return", -math.inf):
                state["best_return"] = row["return_mean"]
                run.save_model(
                    self.model, self.model.get_env(), run.path / "best_model.zip", run.path / "best_vecnormalize.pkl"
                )
            run.write_metrics(state["rows"], _summary(state, self.model.num_timesteps, opts))
            if opts.verbose:
                so = row.get("settled_omega_mean")
                print(
                    f"[eval] steps={row['timesteps']} return={row['return_mean']:.3f}+-{row['return_std']:.3f}"
                    + (f" settled_omega={so:.3f}" if so is not None else ""),
                    flush=True,
                )
            return row

    return CheckpointAndEval()


def _next_multiple(n: int, freq: int) -> int:
    return (n // freq + 1) * freq if freq else sys.maxsize


def evaluate_model(
    model: Any, train_vecnorm: Any, eval_venv: Any, episodes: int, seed: int | None = None
) -> dict[str, Any]:
    """Deterministic evaluation of ``model`` on ``eval_venv`` with the (frozen) observation
    statistics of ``train_vecnorm``; mean/std of the raw episode return and of the settled omega.

    ``seed`` reseeds the evaluation environments first, so every evaluation sees the same episodes."""
    from stable_baselines3.common.vec_env import VecNormalize

    from .rollout import run_episodes
    from .trained import TrainedPolicy

    vn = train_vecnorm if isinstance(train_vecnorm, VecNormalize) else None
    policy = TrainedPolicy(model, _frozen_copy(vn) if vn is not None else None)
    if seed is not None:
        eval_venv.seed(int(seed))
    eps = run_episodes(policy, eval_venv, episodes, deterministic=True)
    rets = np.array([e["return"] for e in eps])
    row: dict[str, Any] = {
        "timesteps": int(model.num_timesteps),
        "return_mean": float(rets.mean()),
        "return_std": float(rets.std()),
        "episodes": len(eps),
    }
    so = [e["settled_omega"] for e in eps if e["settled_omega"] is not None]
    if so:
        row["settled_omega_mean"] = float(np.mean(so))
        row["settled_omega_std"] = float(np.std(so))
    cf = [e["chaotic_fraction"] for e in eps if e["chaotic_fraction"] is not None]
    if cf:
        row["chaotic_fraction_mean"] = float(np.mean(cf))
    return row


def _frozen_copy(vn: Any) -> Any:
    """A detached copy of the observation statistics of a VecNormalize (not updated by evaluation)."""
    import copy

    from stable_baselines3.common.vec_env import VecNormalize

    c = VecNormalize.__new__(VecNormalize)
    c.obs_rms = copy.deepcopy(vn.obs_rms)
    c.clip_obs = vn.clip_obs
    c.epsilon = vn.epsilon
    c.norm_obs = vn.norm_obs
    c.norm_obs_keys = getattr(vn, "norm_obs_keys", None)
    c.training = False
    c.norm_reward = False
    return c


def _summary(state: dict[str, Any], steps: int, opts: TrainOptions) -> dict[str, Any]:
    wall = state["wall_before"] + time.perf_counter() - state["t0"]
    done_here = steps - state["steps_at_start"]
    return {
        "timesteps": int(steps),
        "wall_seconds": round(wall, 3),
        "steps_per_second_this_session": round(done_here / max(1e-9, time.perf_counter() - state["t0"]), 1),
        "num_envs": opts.num_envs,
        "seed": opts.seed,
        "sessions": state["sessions"],
        "best_eval_return": state.get("best_return"),
        "finished": bool(state.get("finished", False)),
        "interrupted": bool(state.get("interrupted", False)),
    }


# --------------------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------------------
def _interrupt_on_sigterm() -> Any:
    """Make SIGTERM behave like Ctrl-C during training (so `kill PID` also leaves a checkpoint).

    Returns a function that restores the previous handler. No-op outside the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def _raise(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, _raise)
    return lambda: signal.signal(signal.SIGTERM, old)


def _check_resume(stored: Mapping[str, Any], opts: TrainOptions, env_config: dict[str, Any], run_dir: Path) -> None:
    problems = []
    if stored.get("env_id") != opts.env_id:
        problems.append(f"env_id {stored.get('env_id')!r} vs {opts.env_id!r}")
    if stored.get("env_config") != env_config:
        a, b = stored.get("env_config") or {}, env_config
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        problems.append(f"environment config differs in {diff}")
    if stored.get("ppo") != json.loads(json.dumps(opts.ppo_params())):
        a, b = stored.get("ppo") or {}, json.loads(json.dumps(opts.ppo_params()))
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        problems.append(f"PPO hyper-parameters differ in {diff}")
    tr = stored.get("train", {})
    if tr.get("num_envs") != opts.num_envs:
        problems.append(f"num_envs {tr.get('num_envs')} vs {opts.num_envs}")
    if problems:
        raise RunFolderError(
            f"cannot resume {str(run_dir)!r} with an incompatible configuration: {'; '.join(problems)} "
            "(stored vs requested). Resume with the stored settings (omit --config/env flags) "
            "or train into a new --out."
        )


def train(opts: TrainOptions) -> dict[str, Any]:
    """Train (or resume) a PPO run as described by ``opts``; returns the summary dict.

    Raises :class:`KeyboardInterrupt` after writing a checkpoint if interrupted, and
    :class:`~agents.runs.RunFolderError` (a ValueError) for run-folder problems."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    run = RunFolder(opts.out)
    env_config = config_to_dict(make_config(opts.env_id, dict(opts.env_config)))
    ppo_params = opts.ppo_params()
    start_steps = 0
    wall_before = 0.0
    rows: list[dict[str, Any]] = []
    sessions = 1
    if opts.resume:
        stored = run.read_config()
        _check_resume(stored, opts, env_config, run.path)
        start_steps, ckpt_model, ckpt_vn = run.latest_checkpoint()
        old = run.read_metrics()
        rows = [r for r in old.get("evaluations", []) if r.get("timesteps", 0) <= start_steps]
        summ = old.get("summary", {})
        wall_before = float(summ.get("wall_seconds", 0.0)) if summ.get("timesteps", 0) >= start_steps else 0.0
        sessions = int(summ.get("sessions", 1)) + 1
        if start_steps >= opts.timesteps:
            raise ValueError(
                f"--resume: the last checkpoint is at {start_steps} steps, which already reaches --timesteps "
                f"{opts.timesteps}; ask for more timesteps to continue"
            )
    else:
        if run.config_path.exists() and not opts.overwrite:
            raise RunFolderError(
                f"{str(run.path)!r} already holds a run; use --resume to continue it, --overwrite to replace it, "
                f"or choose another --out"
            )
        run.create()

    venv = make_sb3_vec_env(opts.env_id, env_config, opts.num_envs, opts.seed)
    eval_n = min(opts.eval_episodes, 8)
    eval_venv = make_sb3_vec_env(opts.env_id, env_config, eval_n, None)
    try:
        if opts.resume:
            from .trained import load_ppo_model

            venv = VecNormalize.load(str(ckpt_vn), venv) if ckpt_vn is not None else VecNormalize(venv)
            venv.training = True
            venv.norm_reward = True
            check_space_compatible(stored["observation_space"], venv.observation_space, "observation", run.path)
            model = load_ppo_model(ckpt_model)
            model.set_env(venv)
            model.num_timesteps = start_steps
            if opts.tensorboard and importlib.util.find_spec("tensorboard") is not None:
                model.tensorboard_log = str(run.tb_dir)
        else:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=True, clip_obs=10.0, gamma=ppo_params["gamma"])
            kw = {k: v for k, v in ppo_params.items() if k not in ("net_arch", "log_std_init")}
            tb = str(run.tb_dir) if opts.tensorboard and importlib.util.find_spec("tensorboard") is not None else None
            model = PPO(
                "MlpPolicy",
                venv,
                policy_kwargs={"net_arch": list(ppo_params["net_arch"]), "log_std_init": ppo_params["log_std_init"]},
                tensorboard_log=tb,
                seed=opts.seed,
                device="cpu",
                verbose=0,
                **kw,
            )
            run.write_config(
                {
                    "env_id": opts.env_id,
                    "env_config": env_config,
                    "ppo": json.loads(json.dumps(ppo_params)),
                    "train": {
                        "timesteps": opts.timesteps,
                        "num_envs": opts.num_envs,
                        "seed": opts.seed,
                        "eval_freq": opts.eval_freq,
                        "eval_episodes": opts.eval_episodes,
                        "checkpoint_freq": opts.checkpoint_freq,
                    },
                    "vecnormalize": True,
                    "observation_space": space_to_dict(venv.observation_space),
                    "action_space": space_to_dict(venv.action_space),
                    "versions": versions(),
                    "command": " ".join(sys.argv),
                }
            )
            # the bare environment settings, usable as `gear-env evaluate --config RUN_DIR/env_config.json`
            atomic_write_text(run.path / "env_config.json", json.dumps(env_config, indent=2) + "\n")
        state: dict[str, Any] = {
            "rows": rows,
            "t0": time.perf_counter(),
            "wall_before": wall_before,
            "steps_at_start": start_steps,
            "sessions": sessions,
        }
        if rows:
            state["best_return"] = max(r["return_mean"] for r in rows)
        cb = _callbacks(run, opts, eval_venv, state)
        progress = opts.progress_bar and all(importlib.util.find_spec(m) is not None for m in ("tqdm", "rich"))
        restore = _interrupt_on_sigterm()
        try:
            model.learn(
                total_timesteps=opts.timesteps - start_steps,
                callback=cb,
                reset_num_timesteps=not opts.resume,
                progress_bar=progress,
                tb_log_name="PPO",
            )
        except KeyboardInterrupt:
            steps = int(model.num_timesteps)
            path = run.save_checkpoint(model, venv, steps, keep=opts.keep_checkpoints)
            state["interrupted"] = True
            run.write_metrics(state["rows"], _summary(state, steps, opts))
            print(f"\ninterrupted at {steps} steps; checkpoint {path} (continue with --resume)", file=sys.stderr)
            raise
        finally:
            restore()
        steps = int(model.num_timesteps)
        run.save_checkpoint(model, venv, steps, keep=opts.keep_checkpoints)
        if not state["rows"] or state["rows"][-1]["timesteps"] != steps:
            cb.evaluate()
        run.save_model(model, venv, run.model_path, run.vecnorm_path)
        state["finished"] = True
        summary = _summary(state, steps, opts)
        summary["final_eval"] = state["rows"][-1]
        run.write_metrics(state["rows"], summary)
        if opts.verbose:
            print(
                f"trained {steps} steps in {summary['wall_seconds']:.1f} s wall "
                f"({summary['steps_per_second_this_session']:.0f} steps/s); run folder {run.path}",
                flush=True,
            )
        return summary
    finally:
        venv.close()
        eval_venv.close()


# --------------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------------
def add_arguments(p: argparse.ArgumentParser) -> None:
    """Register the training options on ``p`` (shared by train.py and ``gear-env train``)."""
    p.add_argument("--out", required=True, metavar="RUN_DIR", help="run folder to create (or resume)")
    p.add_argument("--timesteps", type=int, default=None, help="total environment steps (default 700000)")
    p.add_argument("--num-envs", type=int, default=None, help="sub-environments in the vector env (default 16)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue RUN_DIR from its last checkpoint")
    p.add_argument("--overwrite", action="store_true", help="replace an existing run in RUN_DIR")
    p.add_argument("--config", metavar="FILE.json", help="environment config (JSON object of GearSpeedConfig fields)")
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override one env config field (JSON value)"
    )
    p.add_argument("--model", choices=["constant", "dynamic"], help="backlash model of the environment")
    p.add_argument("--randomize-params", action="store_true", help="randomise the physics parameters per episode")
    p.add_argument("--demand", metavar="PROFILE", help="demand profile of the environment (name or file)")
    p.add_argument(
        "--env", "--env-id", dest="env_id", default=None, metavar="ID",
        help="task: GearSpeed-v0 (default), GearSpeed-v1 or GearSpeedDemand-v0",
    )  # fmt: skip
    p.add_argument(
        "--hyperparams", metavar="PPO.yml",
        help="take the PPO hyper-parameters, n_envs, n_timesteps and env_kwargs of the task from an rl-zoo3 "
        "file (agents/hyperparams/ppo.yml); explicit options win",
    )  # fmt: skip
    p.add_argument("--eval-freq", type=int, default=50_000, help="evaluate every N total steps (0 = only at the end)")
    p.add_argument("--eval-episodes", type=int, default=16, help="episodes per evaluation (default 16)")
    p.add_argument("--checkpoint-freq", type=int, default=50_000, help="checkpoint every N total steps (0 = off)")
    p.add_argument("--ppo", action="append", default=[], metavar="KEY=VALUE", help="PPO hyper-parameter (JSON value)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-tensorboard", action="store_true", help="no TensorBoard logs")
    p.add_argument("--quiet", action="store_true", help="print only errors")


def _demand(text: str) -> Any:
    """--demand: a preset name of GearSpeedConfig.demand, or a JSON/CSV file of (t_steps, omega) rows."""
    if not os.path.isfile(text):
        return text  # a preset name; GearSpeedConfig validates it
    try:
        raw = Path(text).read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"--demand: cannot read {text!r}: {exc}") from exc
    if text.lower().endswith(".json"):
        try:
            return json.loads(raw)
        except json.JSONDecodeError as exc:
            raise ValueError(f"--demand: {text!r} is not valid JSON: {exc}") from exc
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
    return rows


def _kv(items: Sequence[str], what: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"{what}: expected KEY=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def options_from_args(args: argparse.Namespace) -> TrainOptions:
    """Build :class:`TrainOptions` from parsed command-line arguments."""
    env_cfg: dict[str, Any] = load_config_file(args.config) if args.config else {}
    explicit_env = bool(args.config)
    if args.model:
        env_cfg["model"] = args.model
    if args.randomize_params:
        env_cfg["randomize_params"] = True
    if args.demand:
        env_cfg["demand"] = _demand(args.demand)
    env_cfg.update(_kv(args.set, "--set"))
    explicit_env = explicit_env or bool(args.model or args.randomize_params or args.demand or args.set)
    env_id = args.env_id or GEAR_ENV_ID
    timesteps, num_envs = args.timesteps, args.num_envs
    zoo_ppo: dict[str, Any] = {}
    if getattr(args, "hyperparams", None):
        from .hyperparams import load_zoo_entry

        zoo = load_zoo_entry(args.hyperparams, env_id)
        zoo_ppo = zoo["ppo"]
        env_cfg = {**zoo["env_kwargs"], **env_cfg}
        timesteps = zoo.get("n_timesteps") if timesteps is None else timesteps
        num_envs = zoo.get("n_envs") if num_envs is None else num_envs
    if args.resume and not explicit_env:
        # resume with the stored environment unless the user asked for something else
        stored = RunFolder(args.out).read_config()
        env_cfg = dict(stored["env_config"])
        env_id = stored["env_id"]
    ppo = {**zoo_ppo, **_kv(args.ppo, "--ppo")}
    if args.resume:  # stored hyper-parameters, with any explicit --ppo on top (checked for compatibility)
        ppo = {**dict(RunFolder(args.out).read_config().get("ppo", {})), **ppo}
    return TrainOptions(
        out=args.out,
        env_id=env_id,
        env_config=env_cfg,
        timesteps=700_000 if timesteps is None else int(timesteps),
        num_envs=16 if num_envs is None else int(num_envs),
        seed=args.seed,
        eval_freq=args.eval_freq,
        eval_episodes=args.eval_episodes,
        checkpoint_freq=args.checkpoint_freq,
        resume=args.resume,
        overwrite=args.overwrite,
        ppo=ppo,
        progress_bar=not args.no_progress,
        tensorboard=not args.no_tensorboard,
        verbose=0 if args.quiet else 1,
    )


def run_from_args(args: argparse.Namespace) -> int:
    """Run training from parsed arguments; 0 on success, 130 after Ctrl-C (checkpoint written)."""
    opts = options_from_args(args)
    try:
        train(opts)
    except KeyboardInterrupt:
        return 130
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="train.py",
        description="Train a PPO speed-scheduling agent on GearSpeed-v0 (same as `gear-env train`).",
    )
    add_arguments(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point of train.py; returns the exit code (2 on a usage/config error)."""
    args = build_parser().parse_args(argv)
    try:
        return run_from_args(args)
    except (ValueError, OSError) as exc:
        print(f"train: error: {exc}", file=sys.stderr)
        return 2


__all__ = ["PPO_DEFAULTS", "TrainOptions", "add_arguments", "evaluate_model", "main", "run_from_args", "train"]

if __name__ == "__main__":  # pragma: no cover
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.exit(main())
