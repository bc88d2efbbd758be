"""Run folders: the files a training run writes and everything needed to read them back.

Layout of a run folder ``RUN_DIR``::

    RUN_DIR/
      config.json          exact environment config, PPO hyper-parameters, training options, versions,
                           observation/action spaces (format ``gear-env-run/1``)
      model.zip            final SB3 PPO model (loaded without unpickling: :func:`agents.trained.load_ppo_model`)
      vecnormalize.npz     VecNormalize statistics (plain arrays, no pickle; reloaded frozen)
      metrics.csv          one row per evaluation (timesteps, wall seconds, returns, settled omega...)
      metrics.json         the same rows plus a final summary (wall time, steps per second)
      checkpoints/         ckpt_<steps>.zip, ckpt_<steps>_vecnormalize.npz, latest.json
      tb/                  TensorBoard event files (only if tensorboard is installed)

Every file is written atomically (temporary name, then ``os.replace``) so an interrupted run
never leaves a half-written model or checkpoint behind. Nothing in a run folder is unpickled when
it is read: the statistics are a NumPy ``.npz`` read with ``allow_pickle=False``, the model zip is
read with every serialised entry replaced (see :mod:`agents.trained`), and ``latest.json`` may only
name checkpoint files inside ``checkpoints/``.
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gear_env.errors import FileFormatError
from gear_env.io import atomic_write, atomic_write_bytes, atomic_write_text, read_json
from gear_env.untrusted import (
    ArraySpec,
    check_keys,
    inside,
    read_npz,
    refuse,
    want_bool,
    want_int,
    want_num,
    want_str,
)

RUN_FORMAT = "gear-env-run/1"
CONFIG_FILE = "config.json"
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.npz"
LEGACY_VECNORM_SUFFIX = ".pkl"
"""Statistics pickled by older gear-env versions: never loaded (see :func:`convert_pickled_statistics`)."""
VECNORM_FORMAT = "gear-env-vecnormalize/1"
_CKPT_NAME = re.compile(r"ckpt_[0-9]{9}\.zip")
_CKPT_VN_NAME = re.compile(r"ckpt_[0-9]{9}_vecnormalize\.npz")
METRICS_CSV = "metrics.csv"
METRICS_JSON = "metrics.json"
CHECKPOINT_DIR = "checkpoints"
LATEST_FILE = "latest.json"
RUN_MARKER = ".gear-env-run"
"""Marker file a run folder carries from the moment ``train`` creates it (``--overwrite`` clears only run folders)."""
CONFIG_KEYS = (
    "format", "env_id", "env_config", "ppo", "train", "vecnormalize", "observation_space", "action_space",
    "versions", "command", "distill",
)  # fmt: skip
"""The keys of config.json (any other key is refused)."""
TRAIN_KEYS = ("timesteps", "num_envs", "seed", "eval_freq", "eval_episodes", "checkpoint_freq")
MAX_OBS_DIM = 4096
"""Most observation features of a stored run (statistics and spaces are bounded by it before allocating)."""
MAX_CHECKPOINT_STEPS = 10**12
"""Most steps a checkpoint index may name (the bound of ``train --timesteps``)."""


class RunFolderError(FileFormatError):
    """A run folder is missing, incomplete, corrupt or incompatible (message says which and why)."""


def is_run_folder(path: str | os.PathLike) -> bool:
    """True if ``path`` is a folder this package wrote a training run into (what ``--overwrite`` may clear).

    The rule: the folder carries the :data:`RUN_MARKER` file (written by every ``train`` since the
    marker was introduced), or, for folders of earlier releases, its config.json is a JSON object of
    format ``gear-env-run/1`` that passes the config.json checks, and it holds metrics.csv, metrics.json, model.zip or
    checkpoints/latest.json (the layout every earlier release wrote)."""
    p = Path(path)
    if not p.is_dir():
        return False
    if (p / RUN_MARKER).is_file():
        return True
    try:
        data = read_json(p / CONFIG_FILE, CONFIG_FILE, max_bytes=1024 * 1024)
    except (OSError, ValueError):
        return False
    if not isinstance(data, dict) or data.get("format") != RUN_FORMAT:
        return False
    try:  # a whole run config, not a stub naming the format (a forged one would let --overwrite clear the folder)
        _check_config(data, str(p / CONFIG_FILE))
    except (ValueError, KeyError, TypeError, AttributeError):
        return False
    layout = (METRICS_CSV, METRICS_JSON, MODEL_FILE, f"{CHECKPOINT_DIR}/{LATEST_FILE}")
    return any((p / q).is_file() for q in layout)


def versions() -> dict[str, str]:
    """Versions of the packages a trained model depends on (stored in config.json)."""
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in ("gear_env", "stable_baselines3", "torch", "gymnasium", "numpy", "numba"):
        mod = sys.modules.get(name)
        if mod is None:
            try:
                mod = __import__(name)
            except Exception:  # pragma: no cover - optional package
                continue
        out[name] = str(getattr(mod, "__version__", "?"))
    return out


def space_to_dict(space: Any) -> dict[str, Any]:
    """JSON description of a gymnasium Box/Discrete space (type, shape, dtype, bounds)."""
    d: dict[str, Any] = {"type": type(space).__name__, "shape": list(getattr(space, "shape", ()) or ())}
    dtype = getattr(space, "dtype", None)
    if dtype is not None:
        d["dtype"] = str(dtype)
    if hasattr(space, "low") and hasattr(space, "high"):
        d["low"] = [float(v) for v in space.low.ravel()]
        d["high"] = [float(v) for v in space.high.ravel()]
    if hasattr(space, "n"):
        d["n"] = int(space.n)
    return d


def space_from_dict(d: Mapping[str, Any]) -> Any:
    """The gymnasium Box/Discrete space a :func:`space_to_dict` description names (RunFolderError if not)."""
    from gymnasium import spaces

    try:
        if d.get("type") == "Box":
            shape = tuple(int(n) for n in d["shape"])
            if len(shape) > 8 or any(n < 0 for n in shape) or int(np.prod(shape)) > MAX_OBS_DIM:
                raise ValueError(f"implausible shape {shape}")
            dtype = np.dtype(str(d.get("dtype", "float32")))
            if dtype.kind != "f":
                raise ValueError(f"dtype {dtype} is not a float type")
            if not isinstance(d["low"], list) or not isinstance(d["high"], list):
                raise ValueError("low and high must be lists of numbers")
            low = np.asarray(d["low"], np.float64).reshape(shape)
            high = np.asarray(d["high"], np.float64).reshape(shape)
            return spaces.Box(low=low.astype(dtype), high=high.astype(dtype), shape=shape, dtype=dtype)
        if d.get("type") == "Discrete":
            return spaces.Discrete(want_int(d["n"], 1, 2**31, "space", "n"))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise RunFolderError(f"corrupt space description: {type(exc).__name__}: {str(exc)[:200]}") from None
    raise RunFolderError(f"unsupported space type {d.get('type')!r} in a run folder (Box or Discrete)")


def _check_config(data: Mapping[str, Any], path: str) -> None:
    """Types and ranges of a config.json (known keys only); RunFolderError naming the field."""
    try:
        check_keys(data, CONFIG_KEYS, path, "")
        from gear_env.envs.tasks import TASK_SETTINGS

        want_str(data["env_id"], path, "env_id", max_len=64, choices=tuple(TASK_SETTINGS))
        check_keys(data["env_config"], data["env_config"].keys() if isinstance(data["env_config"], dict) else (),
                   path, "env_config")  # fmt: skip
        for k in ("observation_space", "action_space"):
            check_keys(data[k], ("type", "shape", "dtype", "low", "high", "n"), path, k)
        if "vecnormalize" in data:
            want_bool(data["vecnormalize"], path, "vecnormalize")
        train = check_keys(data.get("train", {}), TRAIN_KEYS, path, "train")
        want_int(train.get("num_envs", 16), 1, 1024, path, "train.num_envs")
        for k in ("timesteps", "eval_freq", "checkpoint_freq"):
            if k in train:
                want_int(train[k], 0, MAX_CHECKPOINT_STEPS, path, f"train.{k}")
        if "seed" in train:
            want_int(train["seed"], 0, 2**32 - 1, path, "train.seed")
        if "eval_episodes" in train:
            want_int(train["eval_episodes"], 1, 100_000, path, "train.eval_episodes")
        # the hyper-parameters: an object here; their ranges are checked by agents.ppo.validate_ppo
        # when a run is resumed with them (TrainOptions), and clip_range/learning_rate when a model loads
        ppo = data.get("ppo", {})
        check_keys(ppo, ppo.keys() if isinstance(ppo, dict) else (), path, "ppo")
        for k in ("versions",):
            if k in data:
                check_keys(data[k], data[k].keys() if isinstance(data[k], dict) else (), path, k)
        if "command" in data:
            want_str(data["command"], path, "command", max_len=100_000)
        if "distill" in data:  # the DAgger warm start (agents.distill), recorded for the reader
            from .distill_config import DISTILL_DEFAULTS, check_distill

            d = check_keys(data["distill"], ("iterations", *DISTILL_DEFAULTS), path, "distill")
            check_distill(d.get("iterations"), {k: v for k, v in d.items() if k != "iterations"})
    except RunFolderError:
        raise
    except ValueError as exc:
        raise RunFolderError(str(exc)) from None


def check_space_compatible(saved: Mapping[str, Any], space: Any, what: str, run_dir: str | os.PathLike) -> None:
    """Raise :class:`RunFolderError` if ``space`` does not match the ``saved`` description.

    ``what`` is "observation" or "action" (for the message)."""
    now = space_to_dict(space)
    problems = []
    if saved.get("type") != now["type"]:
        problems.append(f"type {saved.get('type')} vs {now['type']}")
    if list(saved.get("shape", [])) != now["shape"]:
        problems.append(f"shape {tuple(saved.get('shape', []))} vs {tuple(now['shape'])}")
    elif "low" in saved and "low" in now:
        if saved["low"] != now["low"] or saved["high"] != now["high"]:
            problems.append("bounds differ")
    if problems:
        raise RunFolderError(
            f"the model in {str(run_dir)!r} was trained on another {what} layout "
            f"({'; '.join(problems)}; trained vs this environment). Evaluate it with the settings it was "
            f"trained on (e.g. `gear-env evaluate --config {str(run_dir)}/env_config.json`), or retrain."
        )


class RunFolder:
    """Paths and I/O of one run folder (see the module docstring for the layout)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)

    # ---- paths -------------------------------------------------------------------------------
    @property
    def config_path(self) -> Path:
        return self.path / CONFIG_FILE

    @property
    def model_path(self) -> Path:
        return self.path / MODEL_FILE

    @property
    def vecnorm_path(self) -> Path:
        return self.path / VECNORM_FILE

    @property
    def checkpoint_dir(self) -> Path:
        return self.path / CHECKPOINT_DIR

    @property
    def tb_dir(self) -> Path:
        return self.path / "tb"

    def create(self) -> None:
        """Create the folder, its run marker and its checkpoints/ subfolder (parents too)."""
        self.path.mkdir(parents=True, exist_ok=True)
        self.mark()
        self.confined(self.checkpoint_dir, CHECKPOINT_DIR).mkdir(exist_ok=True)

    def lock(self) -> Any:
        """Create the folder if missing and lock it for this process (:class:`gear_env.io.OutputLock`).

        A second process that locks the same folder, by any path (symbolic link included), gets a
        ValueError at once."""
        from gear_env.io import OutputLock

        if self.path.exists() and not self.path.is_dir():
            raise RunFolderError(f"run folder {str(self.path)!r} exists and is not a folder")
        self.path.mkdir(parents=True, exist_ok=True)
        return OutputLock(self.path, "run folder")

    def mark(self) -> None:
        """Write the run marker (:data:`RUN_MARKER`) if it is missing."""
        m = self._file(RUN_MARKER)
        if not m.is_file():
            atomic_write_text(m, f"{RUN_FORMAT}\n")

    # ---- config ------------------------------------------------------------------------------
    def write_config(self, data: Mapping[str, Any]) -> None:
        """Write config.json atomically (adds the format tag)."""
        payload = {"format": RUN_FORMAT, **data}
        atomic_write_text(
            self._file(CONFIG_FILE), json.dumps(payload, indent=2, sort_keys=False, default=_json_default) + "\n"
        )

    def read_config(self) -> dict[str, Any]:
        """Read and check config.json; :class:`RunFolderError` with the reason if missing or corrupt."""
        if not self.path.exists():
            raise RunFolderError(f"run folder {str(self.path)!r} does not exist")
        if not self.path.is_dir():
            raise RunFolderError(f"run folder {str(self.path)!r} is not a directory")
        if not self.config_path.is_file():
            raise RunFolderError(
                f"{str(self.path)!r} is not a run folder: {CONFIG_FILE} is missing "
                f"(expected files: {CONFIG_FILE}, {MODEL_FILE}, {VECNORM_FILE})"
            )
        try:
            data = read_json(self.config_path, CONFIG_FILE, max_bytes=1024 * 1024)
        except (OSError, ValueError) as exc:
            raise RunFolderError(f"corrupt run folder {str(self.path)!r}: cannot read {CONFIG_FILE}: {exc}") from exc
        if not isinstance(data, dict) or data.get("format") != RUN_FORMAT:
            raise RunFolderError(
                f"corrupt run folder {str(self.path)!r}: {CONFIG_FILE} has format "
                f"{data.get('format') if isinstance(data, dict) else type(data).__name__!r}, expected {RUN_FORMAT!r}"
            )
        for key in ("env_id", "env_config", "observation_space", "action_space"):
            if key not in data:
                raise RunFolderError(f"corrupt run folder {str(self.path)!r}: {CONFIG_FILE} lacks {key!r}")
        _check_config(data, str(self.config_path))
        return data

    def confined(self, path: Path, what: str) -> Path:
        """``path`` if it stays inside the run folder once symbolic links are resolved (RunFolderError if not)."""
        try:
            inside(self.path, path, what)
        except ValueError as exc:
            raise RunFolderError(str(exc)) from None
        return path

    def _file(self, name: str) -> Path:
        """A file of the run folder, refused if it (or checkpoints/) resolves outside the folder."""
        return self.confined(self.path / name, name)

    # ---- checkpoints -------------------------------------------------------------------------
    def checkpoint_paths(self, steps: int) -> tuple[Path, Path]:
        """(model zip, VecNormalize statistics) of the checkpoint at ``steps`` timesteps."""
        return self.checkpoint_dir / f"ckpt_{steps:09d}.zip", self.checkpoint_dir / f"ckpt_{steps:09d}_vecnormalize.npz"

    def save_model(self, model: Any, vecnorm: Any, model_path: Path, vecnorm_path: Path) -> None:
        """Save an SB3 model and its VecNormalize atomically (each file complete or absent)."""

        def _w_model(tmp: str) -> None:
            buf = io.BytesIO()
            model.save(buf)
            Path(tmp).write_bytes(buf.getvalue())

        self.confined(model_path, model_path.name)
        self.confined(vecnorm_path, vecnorm_path.name)
        atomic_write(model_path, _w_model)
        if vecnorm is not None:
            save_vecnormalize(vecnorm, vecnorm_path)

    def save_checkpoint(self, model: Any, vecnorm: Any, steps: int, keep: int = 3) -> Path:
        """Write a checkpoint (model + VecNormalize + step count) and point latest.json at it.

        latest.json is replaced last, so it always names a complete checkpoint. Older checkpoints
        beyond the ``keep`` most recent are deleted. Returns the model path."""
        self.confined(self.checkpoint_dir, CHECKPOINT_DIR).mkdir(parents=True, exist_ok=True)
        mpath, vpath = self.checkpoint_paths(steps)
        self.confined(mpath, mpath.name)
        self.confined(vpath, vpath.name)
        self.save_model(model, vecnorm, mpath, vpath)
        latest = {"steps": int(steps), "model": mpath.name, "vecnormalize": vpath.name if vecnorm is not None else None}
        atomic_write_text(self.confined(self.checkpoint_dir / LATEST_FILE, LATEST_FILE), json.dumps(latest) + "\n")
        self._prune(keep, int(steps))
        return mpath

    def _prune(self, keep: int, newest: int) -> None:
        """Delete the checkpoints older than the ``keep`` most recent up to ``newest`` steps.

        A checkpoint with more steps than ``newest`` cannot be this run's (it is left by an older
        run; :meth:`clear_checkpoints` removes those when a run is overwritten) and is never the
        reason the newest one is deleted."""
        zips = sorted(
            (int(p.name[5:14]), p) for p in self.checkpoint_dir.glob("ckpt_*.zip") if _CKPT_NAME.fullmatch(p.name)
        )
        mine = [p for n, p in zips if n <= newest]
        for old in mine[: max(0, len(mine) - keep)]:
            for q in [old] + [old.with_name(f"{old.stem}_vecnormalize{ext}") for ext in (".npz", ".pkl")]:
                try:
                    q.unlink()
                except OSError:
                    pass

    def clear(self) -> int:
        """Delete the files of an earlier run (models, statistics, metrics, checkpoints; ``--overwrite``).

        config.json is left to be replaced atomically by the new run; TensorBoard logs are kept.
        Returns the number of files deleted."""
        n = self.clear_checkpoints()
        names = (MODEL_FILE, "best_model.zip", METRICS_CSV, METRICS_JSON, "env_config.json")
        stats = ("vecnormalize", "best_vecnormalize")
        for name in names + tuple(f"{b}{ext}" for b in stats for ext in (".npz", ".pkl")):
            q = self.path / name
            if q.is_file() or q.is_symlink():
                q.unlink()
                n += 1
        return n

    def clear_checkpoints(self) -> int:
        """Delete every checkpoint file and latest.json (before a run is overwritten); returns the count."""
        n = 0
        if not self.checkpoint_dir.is_dir():
            return 0
        self.confined(self.checkpoint_dir, CHECKPOINT_DIR)
        for p in self.checkpoint_dir.iterdir():
            if p.name == LATEST_FILE or (p.name.startswith("ckpt_") and p.suffix in (".zip", ".npz", ".pkl")):
                p.unlink()
                n += 1
        return n

    def latest_checkpoint(self) -> tuple[int, Path, Path | None]:
        """(steps, model path, VecNormalize path or None) of the last complete checkpoint.

        Raises :class:`RunFolderError` when there is none or it is corrupt."""
        latest = self.checkpoint_dir / LATEST_FILE
        if not latest.is_file():
            raise RunFolderError(
                f"cannot resume: no checkpoint in {str(self.checkpoint_dir)!r} ({LATEST_FILE} missing)"
            )
        self.confined(self.checkpoint_dir, CHECKPOINT_DIR)
        lp = str(latest)
        try:
            data = check_keys(
                read_json(latest, "checkpoint index", max_bytes=64 * 1024), ("steps", "model", "vecnormalize"), lp, "",
                required=("steps", "model"),
            )  # fmt: skip
            steps = want_int(data["steps"], 0, MAX_CHECKPOINT_STEPS, lp, "steps")
            mname = want_str(data["model"], lp, "model", max_len=4096)
            vname = (
                want_str(data["vecnormalize"], lp, "vecnormalize", max_len=4096) if data.get("vecnormalize") else None
            )
        except (OSError, ValueError) as exc:
            raise RunFolderError(f"cannot resume: corrupt checkpoint index: {exc}") from None
        # latest.json names files of checkpoints/ only: a plain checkpoint name, never a path
        if not _CKPT_NAME.fullmatch(mname) or (vname is not None and not _CKPT_VN_NAME.fullmatch(vname)):
            raise RunFolderError(
                f"cannot resume: {str(latest)!r} names {mname!r}/{vname!r}; only checkpoint files of "
                f"{CHECKPOINT_DIR}/ (ckpt_<steps>.zip, ckpt_<steps>_vecnormalize.npz) are loaded"
            )
        if int(mname[5:14]) != steps or (vname is not None and int(vname[5:14]) != steps):
            raise RunFolderError(f"{lp!r}: steps: {steps} does not match the checkpoint it names ({mname!r})")
        mpath = self.checkpoint_dir / mname
        vpath = self.checkpoint_dir / vname if vname is not None else None
        for q in (mpath, vpath):
            if q is not None and q.is_symlink():
                raise RunFolderError(f"cannot resume: checkpoint file {str(q)!r} is a symbolic link; not loaded")
        if not mpath.is_file():
            raise RunFolderError(f"cannot resume: checkpoint model {str(mpath)!r} is missing")
        if vpath is not None and not vpath.is_file():
            raise RunFolderError(f"cannot resume: checkpoint statistics {str(vpath)!r} are missing")
        return steps, mpath, vpath

    # ---- metrics -----------------------------------------------------------------------------
    def write_metrics(self, rows: Sequence[Mapping[str, Any]], summary: Mapping[str, Any]) -> None:
        """Write metrics.csv (one row per evaluation) and metrics.json (rows + summary) atomically."""
        keys: list[str] = []
        for r in rows:
            for k in r:
                if k not in keys:
                    keys.append(k)
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=keys or ["timesteps"], lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in keys})
        atomic_write_text(self._file(METRICS_CSV), buf.getvalue())
        payload = {"evaluations": list(rows), "summary": dict(summary)}
        atomic_write_text(self._file(METRICS_JSON), json.dumps(payload, indent=2, default=_json_default) + "\n")

    def read_metrics(self) -> dict[str, Any]:
        """metrics.json as a dict ({} if absent)."""
        p = self._file(METRICS_JSON)
        if not p.is_file():
            return {}
        q = str(p)
        try:
            data = check_keys(read_json(p, METRICS_JSON), ("evaluations", "summary"), q, "")
            evals = data.get("evaluations", [])
            if not isinstance(evals, list):
                raise refuse(q, "evaluations", "must be a list")
            for i, row in enumerate(evals):
                check_keys(row, row.keys() if isinstance(row, dict) else (), q, f"evaluations[{i}]")
                want_int(row.get("timesteps", 0), 0, MAX_CHECKPOINT_STEPS, q, f"evaluations[{i}].timesteps")
                want_num(row.get("return_mean", 0.0), -1e300, 1e300, q, f"evaluations[{i}].return_mean")
            summ = check_keys(data.get("summary", {}), (data.get("summary") or {}).keys(), q, "summary")
            want_num(summ.get("wall_seconds", 0.0), 0.0, 1e12, q, "summary.wall_seconds")
            want_int(summ.get("timesteps", 0), 0, MAX_CHECKPOINT_STEPS, q, "summary.timesteps")
            want_int(summ.get("sessions", 1), 0, 10**9, q, "summary.sessions")
        except RunFolderError:
            raise
        except (OSError, ValueError) as exc:
            raise RunFolderError(f"corrupt metrics: {exc}") from None
        return data


def export_policy(run_dir: str | os.PathLike, dest: str | os.PathLike, use_best: bool = False) -> Path:
    """Copy the files needed to evaluate a run's policy (no checkpoints, no TensorBoard logs) to ``dest``.

    This is how ``gear_env/data/pretrained/`` is made: config.json, env_config.json, model.zip,
    vecnormalize.npz and metrics.json. ``use_best`` takes best_model.zip/best_vecnormalize.npz
    (the best evaluation during training) instead of the final model. Returns ``dest``."""
    src = RunFolder(run_dir)
    src.read_config()  # validates the folder
    out = Path(dest)
    out.mkdir(parents=True, exist_ok=True)
    pairs = [(CONFIG_FILE, CONFIG_FILE), ("env_config.json", "env_config.json"), (METRICS_JSON, METRICS_JSON)]
    if use_best:
        pairs += [("best_model.zip", MODEL_FILE), ("best_vecnormalize.npz", VECNORM_FILE)]
    else:
        pairs += [(MODEL_FILE, MODEL_FILE), (VECNORM_FILE, VECNORM_FILE)]
    for a, b in pairs:
        p = src.path / a
        if not p.is_file():
            raise RunFolderError(f"cannot export {str(src.path)!r}: {a} is missing")
        atomic_write_bytes(out / b, p.read_bytes())
    return out


# --------------------------------------------------------------------------------------------------
# normalisation statistics without pickles
# --------------------------------------------------------------------------------------------------
def save_vecnormalize(vecnorm: Any, path: str | os.PathLike) -> None:
    """Write the statistics of an SB3 ``VecNormalize`` as a NumPy ``.npz`` (no pickle), atomically."""
    arrays = {
        "format": np.array(VECNORM_FORMAT),
        "obs_mean": np.asarray(vecnorm.obs_rms.mean, np.float64),
        "obs_var": np.asarray(vecnorm.obs_rms.var, np.float64),
        "obs_count": np.array(float(vecnorm.obs_rms.count)),
        "ret_mean": np.asarray(vecnorm.ret_rms.mean, np.float64),
        "ret_var": np.asarray(vecnorm.ret_rms.var, np.float64),
        "ret_count": np.array(float(vecnorm.ret_rms.count)),
        "clip_obs": np.array(float(vecnorm.clip_obs)),
        "clip_reward": np.array(float(vecnorm.clip_reward)),
        "gamma": np.array(float(vecnorm.gamma)),
        "epsilon": np.array(float(vecnorm.epsilon)),
        "norm_obs": np.array(bool(vecnorm.norm_obs)),
        "norm_reward": np.array(bool(vecnorm.norm_reward)),
    }

    def _w(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    atomic_write(path, _w)


def read_vecnormalize_stats(path: str | os.PathLike) -> dict[str, Any]:
    """The statistics written by :func:`save_vecnormalize` as plain numbers and arrays.

    Read with ``allow_pickle=False``; a pickled file of an older gear-env is refused with the way to
    convert it. :class:`RunFolderError` if missing, corrupt or inconsistent."""

    p = Path(path)
    if p.suffix == LEGACY_VECNORM_SUFFIX or (not p.exists() and p.with_suffix(LEGACY_VECNORM_SUFFIX).is_file()):
        legacy = p if p.suffix == LEGACY_VECNORM_SUFFIX else p.with_suffix(LEGACY_VECNORM_SUFFIX)
        raise RunFolderError(
            f"{str(legacy)!r} holds pickled statistics (written by an older gear-env); gear-env no longer loads "
            "pickles, which can run code. If you wrote this run yourself, convert it once with "
            f'`python -c "from agents.runs import convert_pickled_statistics as c; c({str(legacy)!r})"`'
        )
    if not p.is_file():
        raise RunFolderError(f"normalisation statistics {str(p)!r} are missing")
    vec = ArraySpec("f", 1, MAX_OBS_DIM)
    scalar_f, scalar_b = ArraySpec("fi", 0, 1), ArraySpec("b", 0, 1)
    spec = {"format": ArraySpec("U", 0, 1), "obs_mean": vec, "obs_var": vec, "ret_mean": ArraySpec("f", None, 1),
            "ret_var": ArraySpec("f", None, 1)}  # fmt: skip
    spec.update({k: scalar_f for k in ("obs_count", "ret_count", "clip_obs", "clip_reward", "gamma", "epsilon")})
    spec.update(norm_obs=scalar_b, norm_reward=scalar_b)
    try:
        d = read_npz(p, "normalisation statistics", spec, max_total=1024 * 1024)
        if str(d["format"]) != VECNORM_FORMAT:
            raise refuse(p, "format", f"{str(d['format'])[:40]!r}, expected {VECNORM_FORMAT!r}")
        out = {k: np.asarray(d[k], np.float64) for k in ("obs_mean", "obs_var", "ret_mean", "ret_var")}
        for k in ("obs_count", "ret_count", "clip_obs", "clip_reward", "gamma", "epsilon"):
            out[k] = float(d[k])
            if not np.isfinite(out[k]) or out[k] < 0:
                raise refuse(p, k, f"must be a finite number >= 0, got {out[k]!r}")
        for k in ("norm_obs", "norm_reward"):
            out[k] = bool(d[k])
        if not out["epsilon"] > 0 or not out["clip_obs"] > 0 or out["gamma"] > 1:
            raise refuse(p, "epsilon/clip_obs/gamma", "need epsilon > 0, clip_obs > 0, gamma <= 1")
    except ValueError as exc:
        raise RunFolderError(f"corrupt normalisation statistics {exc}") from None
    if out["obs_mean"].shape != out["obs_var"].shape or out["obs_mean"].ndim != 1:
        raise RunFolderError(f"corrupt normalisation statistics {str(p)!r}: mean and variance shapes differ")
    finite = [out["obs_mean"], out["obs_var"], out["ret_mean"], out["ret_var"]]
    if not all(np.all(np.isfinite(a)) for a in finite) or np.any(out["obs_var"] < 0):
        raise RunFolderError(f"corrupt normalisation statistics {str(p)!r}: non-finite or negative values")
    return out


def convert_pickled_statistics(path: str | os.PathLike) -> Path:
    """Convert a ``*vecnormalize.pkl`` of an older gear-env that YOU trust into ``.npz``; returns the new path.

    This unpickles the file, which can run code: use it only on files you wrote yourself. Pass
    a run folder to convert every pickle in it (model, best model and checkpoints)."""
    import pickle

    p = Path(path)
    if p.is_dir():
        last = p
        for q in sorted(p.glob("*vecnormalize.pkl")) + sorted((p / CHECKPOINT_DIR).glob("*_vecnormalize.pkl")):
            last = convert_pickled_statistics(q)
        return last
    with open(p, "rb") as fh:
        vn = pickle.load(fh)  # noqa: S301 - explicitly trusted by the caller (see the docstring)
    dest = p.with_suffix(".npz")
    save_vecnormalize(vn, dest)
    return dest


def _json_default(obj: Any) -> Any:
    try:
        import numpy as np

        if isinstance(obj, np.generic):
            return obj.item()
        if isinstance(obj, np.ndarray):
            return obj.tolist()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (set, tuple)):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


__all__ = [
    "RUN_FORMAT",
    "convert_pickled_statistics",
    "read_vecnormalize_stats",
    "save_vecnormalize",
    "space_from_dict",
    "RunFolder",
    "RunFolderError",
    "check_space_compatible",
    "export_policy",
    "space_to_dict",
    "versions",
]
