"""PPO training on GearSpeed-v0: options, callbacks, run folder and resume.

``python train.py ...`` and ``gear-env train ...`` parse their arguments in
:mod:`gear_env.cli.train` and call :func:`train` here.

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

import importlib.util
import json
import math
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gear_env.io import atomic_write_text

from .envs import GEAR_ENV_ID, config_to_dict, make_config, make_sb3_vec_env
from .runs import RUN_MARKER, RunFolder, RunFolderError, check_space_compatible, is_run_folder, space_to_dict, versions
from .trained import evaluate_model

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


MAX_NUM_ENVS = 1024
"""Most sub-environments of one training run."""
MAX_TIMESTEPS = 10**12
"""Most environment steps of one training run."""


def _number(
    params: Mapping[str, Any], key: str, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False
) -> None:
    v = params[key]
    ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
    ok = ok and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"PPO hyper-parameter {key} must be a finite number in {rng}, got {v!r}")


def _integer(params: Mapping[str, Any], key: str, lo: int, hi: int) -> None:
    v = params[key]
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise ValueError(f"PPO hyper-parameter {key} must be an integer in [{lo}, {hi}], got {v!r}")


def validate_ppo(params: Mapping[str, Any], num_envs: int = 1) -> None:
    """Check PPO hyper-parameters (SB3 names) before any training; ``ValueError`` naming the key and range.

    ``params`` holds every key of :data:`PPO_DEFAULTS`; ``num_envs`` bounds ``batch_size`` (at most one
    rollout of ``n_steps * num_envs`` steps)."""
    unknown = set(params) - set(PPO_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown PPO hyper-parameter(s) {sorted(unknown)}; valid: {sorted(PPO_DEFAULTS)}")
    _number(params, "learning_rate", 0.0, 1.0, lo_open=True)
    _integer(params, "n_steps", 1, 1_000_000)
    _integer(params, "batch_size", 2, max(2, params["n_steps"] * num_envs))
    _integer(params, "n_epochs", 1, 10_000)
    _number(params, "gamma", 0.0, 1.0)
    _number(params, "gae_lambda", 0.0, 1.0)
    _number(params, "clip_range", 0.0, 10.0, lo_open=True)
    _number(params, "ent_coef", 0.0, 100.0)
    _number(params, "vf_coef", 0.0, 100.0)
    _number(params, "max_grad_norm", 0.0, 1e6, lo_open=True)
    _number(params, "log_std_init", -20.0, 5.0)
    if params["n_steps"] * num_envs < 2:
        raise ValueError(f"PPO needs n_steps * num_envs >= 2, got {params['n_steps']} * {num_envs}")
    arch = params["net_arch"]
    if (
        not isinstance(arch, (list, tuple))
        or len(arch) > 16
        or any(isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 4096 for n in arch)
    ):
        raise ValueError(
            f"PPO hyper-parameter net_arch must be a list of at most 16 layer sizes in [1, 4096], got {arch!r}"
        )
    if not isinstance(params["use_sde"], bool):
        raise ValueError(f"PPO hyper-parameter use_sde must be true or false, got {params['use_sde']!r}")
    _integer(params, "sde_sample_freq", -1, 1_000_000)


@dataclass(frozen=True)
class TrainOptions:
    """Options of one training run (validated in ``__post_init__``).

    ``timesteps`` is the total number of environment steps (over all sub-environments), also when
    resuming; ``eval_freq`` and ``checkpoint_freq`` are in total environment steps.

    ``distill`` > 0 first fits the actor to the privileged teacher by that many DAgger iterations
    (:mod:`agents.distill`; ``distill_params``: its ``DISTILL_DEFAULTS``); their environment steps count in
    ``timesteps``, and PPO trains only for what ``timesteps`` leaves after them (0: distillation only)."""

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
    distill: int = 0
    distill_params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from .distill_config import check_distill

        check_distill(self.distill, dict(self.distill_params))
        bounds = {
            "timesteps": (0 if self.distill else 1, MAX_TIMESTEPS),
            "num_envs": (1, MAX_NUM_ENVS),
            "eval_episodes": (1, 100_000),
            "keep_checkpoints": (1, 100_000),
            "eval_freq": (0, MAX_TIMESTEPS),
            "checkpoint_freq": (0, MAX_TIMESTEPS),
            "seed": (0, 2**32 - 1),
        }
        for name, (lo, hi) in bounds.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                off = " (0 = off)" if name.endswith("_freq") else ""
                raise ValueError(f"{name} must be an integer in [{lo}, {hi}]{off}, got {v!r}")
        validate_ppo(self.ppo_params(), self.num_envs)

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
            return _evaluate_and_record(self.model, run, opts, eval_venv, state, self.logger)

    return CheckpointAndEval()


def _evaluate_and_record(
    model: Any, run: RunFolder, opts: TrainOptions, eval_venv: Any, state: dict[str, Any], logger: Any = None
) -> dict[str, Any]:
    """One in-training evaluation: a metrics row, best_model.zip when it is the best so far, metrics.json."""
    row = evaluate_model(model, model.get_env(), eval_venv, opts.eval_episodes, seed=opts.seed + EVAL_SEED_OFFSET)
    row["wall_seconds"] = round(state["wall_before"] + time.perf_counter() - state["t0"], 3)
    state["rows"].append(row)
    if logger is not None:
        for k, v in row.items():
            if k != "timesteps" and isinstance(v, (int, float)):
                logger.record(f"eval/{k}", v)
    if row["return_mean"] > state.get("best_return", -math.inf):
        state["best_return"] = row["return_mean"]
        run.save_model(model, model.get_env(), run.path / "best_model.zip", run.path / "best_vecnormalize.npz")
    run.write_metrics(state["rows"], _summary(state, model.num_timesteps, opts))
    if opts.verbose:
        so = row.get("settled_omega_mean")
        print(
            f"[eval] steps={row['timesteps']} return={row['return_mean']:.3f}+-{row['return_std']:.3f}"
            + (f" settled_omega={so:.3f}" if so is not None else ""),
            flush=True,
        )
    return row


def _next_multiple(n: int, freq: int) -> int:
    return (n // freq + 1) * freq if freq else sys.maxsize


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
# training, in parts: where to start, the environments, the model, the learning, the end
# --------------------------------------------------------------------------------------------------
@dataclass
class _Start:
    """Where a run starts: from scratch (steps 0) or from its last checkpoint."""

    steps: int = 0
    model_path: Path | None = None
    vecnorm_path: Path | None = None
    rows: list[dict[str, Any]] = field(default_factory=list)
    wall_before: float = 0.0
    sessions: int = 1
    stored: dict[str, Any] = field(default_factory=dict)


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


def _start_point(run: RunFolder, opts: TrainOptions, env_config: dict[str, Any]) -> _Start:
    """Check the run folder and find where to start (creates it, or clears it with ``overwrite``)."""
    if not opts.resume:
        if run.config_path.exists() and not opts.overwrite:
            raise RunFolderError(
                f"{str(run.path)!r} already holds a run; use --resume to continue it, --overwrite to replace it, "
                f"or choose another --out"
            )
        if run.path.is_dir() and any(run.path.iterdir()) and not is_run_folder(run.path):
            raise RunFolderError(
                f"{str(run.path)!r} is not empty and is not a gear-env run folder (no {RUN_MARKER} marker, and no "
                "config.json of format gear-env-run/1 beside metrics, a model or checkpoints/latest.json); "
                "gear-env neither writes into it nor clears it: choose another --out"
            )
        if opts.overwrite and run.path.is_dir():
            n = run.clear()  # no stale checkpoint may outlive the run it belonged to
            if n and opts.verbose:
                print(f"--overwrite: removed {n} file(s) of the earlier run in {run.path}", flush=True)
        run.create()
        return _Start()
    stored = run.read_config()
    if not is_run_folder(run.path):
        raise RunFolderError(f"cannot resume {str(run.path)!r}: it is not a gear-env run folder")
    _check_resume(stored, opts, env_config, run.path)
    run.mark()  # a run folder of an earlier release gets its marker
    steps, mpath, vpath = run.latest_checkpoint()
    if stored.get("vecnormalize") and vpath is None:  # resuming would restart the statistics silently
        raise RunFolderError(
            f"cannot resume: {str(run.checkpoint_dir / 'latest.json')!r}: vecnormalize: names no statistics, but "
            f"the run normalises its observations ({str(run.path / 'config.json')!r}: vecnormalize)"
        )
    old = run.read_metrics()
    rows = [r for r in old.get("evaluations", []) if r.get("timesteps", 0) <= steps]
    summ = old.get("summary", {})
    wall_before = float(summ.get("wall_seconds", 0.0)) if summ.get("timesteps", 0) >= steps else 0.0
    if steps >= opts.timesteps:
        raise ValueError(
            f"--resume: the last checkpoint is at {steps} steps, which already reaches --timesteps "
            f"{opts.timesteps}; ask for more timesteps to continue"
        )
    start = _Start(steps, mpath, vpath, rows, wall_before, int(summ.get("sessions", 1)) + 1, stored)
    if opts.verbose:
        print(
            f"resuming {run.path} from checkpoint {mpath} at {steps:,} steps (session {start.sessions})",
            flush=True,
        )
    return start


def rollout_total(opts: TrainOptions, start_steps: int = 0) -> int:
    """The step count training really ends at: PPO learns in whole rollouts of n_steps x num_envs
    steps, so ``opts.timesteps`` is rounded up to the next whole rollout after ``start_steps``."""
    per = int(opts.ppo_params()["n_steps"]) * opts.num_envs
    return start_steps + -(-(opts.timesteps - start_steps) // per) * per


def _build_model(opts: TrainOptions, run: RunFolder, start: _Start, venv: Any) -> tuple[Any, Any]:
    """(model, VecNormalize-wrapped venv): a new PPO, or the checkpoint's (read without unpickling)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from .trained import load_ppo_model, load_vecnormalize

    ppo_params = opts.ppo_params()
    use_tb = opts.tensorboard and importlib.util.find_spec("tensorboard") is not None
    tb = str(run.confined(run.tb_dir, "tb")) if use_tb else None  # logs stay inside the run folder
    if start.model_path is None:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, clip_obs=10.0, gamma=ppo_params["gamma"])
        kw = {k: v for k, v in ppo_params.items() if k not in ("net_arch", "log_std_init")}
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
        return model, venv
    venv = load_vecnormalize(start.vecnorm_path, venv) if start.vecnorm_path is not None else VecNormalize(venv)
    venv.training = True
    venv.norm_reward = True
    check_space_compatible(start.stored["observation_space"], venv.observation_space, "observation", run.path)
    model = load_ppo_model(start.model_path, run_config=start.stored)
    model.set_env(venv)
    model.num_timesteps = start.steps
    if tb is not None:
        model.tensorboard_log = tb
    return model, venv


def _write_run_config(run: RunFolder, opts: TrainOptions, env_config: dict[str, Any], venv: Any) -> None:
    """config.json (everything needed to reload and resume) and env_config.json of a new run."""
    run.write_config(
        {
            "env_id": opts.env_id,
            "env_config": env_config,
            "ppo": json.loads(json.dumps(opts.ppo_params())),
            "train": {
                "timesteps": opts.timesteps,
                "num_envs": opts.num_envs,
                "seed": opts.seed,
                "eval_freq": opts.eval_freq,
                "eval_episodes": opts.eval_episodes,
                "checkpoint_freq": opts.checkpoint_freq,
            },
            "vecnormalize": True,
            **({"distill": {"iterations": opts.distill, **_distill_params(opts)}} if opts.distill else {}),
            "observation_space": space_to_dict(venv.observation_space),
            "action_space": space_to_dict(venv.action_space),
            "versions": versions(),
            "command": " ".join(sys.argv),
        }
    )
    # the bare environment settings, usable as `gear-env evaluate --config RUN_DIR/env_config.json`
    atomic_write_text(
        run.confined(run.path / "env_config.json", "env_config.json"), json.dumps(env_config, indent=2) + "\n"
    )


def _distill_params(opts: TrainOptions) -> dict[str, Any]:
    from .distill_config import DISTILL_DEFAULTS

    return {**DISTILL_DEFAULTS, **dict(opts.distill_params)}


def _distill(
    model: Any,
    venv: Any,
    run: RunFolder,
    opts: TrainOptions,
    env_config: dict[str, Any],
    eval_venv: Any,
    state: dict[str, Any],
) -> int:
    """The distillation phase of a new run (:mod:`agents.distill`): every iteration is evaluated like a PPO
    evaluation (metrics row, best_model.zip); a checkpoint is written once it is complete, so ``--resume``
    continues with PPO. Interrupted inside it, the run has no checkpoint: start it again with --overwrite."""
    from .distill import distill

    model.start_time = time.time_ns()  # as learn() would set it (a saved model carries it; the loader checks it)

    def after(it: int, steps: int) -> None:
        model.num_timesteps = steps
        _evaluate_and_record(model, run, opts, eval_venv, state)

    try:
        steps = distill(model, venv, opts.env_id, env_config, opts.distill, _distill_params(opts), seed=opts.seed,
                        on_iteration=after, verbose=opts.verbose)  # fmt: skip
    except KeyboardInterrupt:
        state["interrupted"] = True
        run.write_metrics(state["rows"], _summary(state, int(model.num_timesteps), opts))
        print("\ninterrupted during the distillation: no checkpoint (start again with --overwrite)", file=sys.stderr)
        raise
    model.num_timesteps = steps
    state["distilled_steps"] = steps
    run.save_checkpoint(model, venv, steps, keep=opts.keep_checkpoints)
    return steps


def _learn(
    model: Any, venv: Any, run: RunFolder, opts: TrainOptions, start: _Start, state: dict[str, Any], cb: Any
) -> int:
    """Run PPO up to ``state["total"]`` steps; on Ctrl-C/SIGTERM write a checkpoint and re-raise."""
    progress = opts.progress_bar and all(importlib.util.find_spec(m) is not None for m in ("tqdm", "rich"))
    if model.tensorboard_log is None:
        # without TensorBoard SB3 would make an empty SB3-<date> folder in the system temp directory on
        # every learn(); a logger with no outputs, rooted in the run folder, writes nothing anywhere
        from stable_baselines3.common.logger import configure

        model.set_logger(configure(str(run.path), []))
    restore = _interrupt_on_sigterm()
    try:
        model.learn(
            total_timesteps=state["total"] - start.steps,  # a whole number of rollouts: the bar ends at 100 %
            callback=cb,
            reset_num_timesteps=start.model_path is None and not state.get("distilled_steps"),
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
    return int(model.num_timesteps)


def _finish(
    model: Any, venv: Any, run: RunFolder, opts: TrainOptions, state: dict[str, Any], cb: Any
) -> dict[str, Any]:
    """Last checkpoint, final evaluation, model.zip + statistics, metrics; returns the summary."""
    steps = int(model.num_timesteps)
    run.save_checkpoint(model, venv, steps, keep=opts.keep_checkpoints)
    if not state["rows"] or state["rows"][-1]["timesteps"] != steps:
        _evaluate_and_record(model, run, opts, state["eval_venv"], state)
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


def train(opts: TrainOptions) -> dict[str, Any]:
    """Train (or resume) a PPO run as described by ``opts``; returns the summary dict.

    Raises :class:`KeyboardInterrupt` after writing a checkpoint if interrupted, and
    :class:`~agents.runs.RunFolderError` (a ValueError) for run-folder problems."""
    import torch

    torch.set_num_threads(1)
    run = RunFolder(opts.out)
    env_config = config_to_dict(make_config(opts.env_id, dict(opts.env_config)))
    with run.lock():  # one writer per run folder: a second train --out/--resume on it is refused at once
        return _train_locked(run, opts, env_config)


def _train_locked(run: RunFolder, opts: TrainOptions, env_config: dict[str, Any]) -> dict[str, Any]:
    """:func:`train` once the run folder is locked."""
    start = _start_point(run, opts, env_config)
    total = rollout_total(opts, start.steps)
    if total != opts.timesteps and opts.verbose:
        per = int(opts.ppo_params()["n_steps"]) * opts.num_envs
        print(
            f"note: PPO learns in whole rollouts of n_steps x num_envs = {per:,} steps; "
            f"--timesteps {opts.timesteps:,} is rounded up to {total:,}",
            flush=True,
        )
    venv = make_sb3_vec_env(opts.env_id, env_config, opts.num_envs, opts.seed)
    eval_venv = make_sb3_vec_env(opts.env_id, env_config, min(opts.eval_episodes, 8), None)
    try:
        model, venv = _build_model(opts, run, start, venv)
        if start.model_path is None:
            _write_run_config(run, opts, env_config, venv)
        state: dict[str, Any] = {
            "rows": start.rows,
            "t0": time.perf_counter(),
            "wall_before": start.wall_before,
            "steps_at_start": start.steps,
            "sessions": start.sessions,
            "total": total,
        }
        if start.rows:
            state["best_return"] = max(r["return_mean"] for r in start.rows)
        state["eval_venv"] = eval_venv
        cb = _callbacks(run, opts, eval_venv, state)
        if start.model_path is None and opts.distill:
            steps = _distill(model, venv, run, opts, env_config, eval_venv, state)
            state["total"] = rollout_total(opts, steps) if opts.timesteps > steps else steps
        if state["total"] > model.num_timesteps:
            _learn(model, venv, run, opts, start, state, cb)
        return _finish(model, venv, run, opts, state, cb)
    finally:
        venv.close()
        eval_venv.close()


__all__ = ["PPO_DEFAULTS", "TrainOptions", "evaluate_model", "rollout_total", "train", "validate_ppo"]
