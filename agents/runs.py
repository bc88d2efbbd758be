"""Run folders: the files a training run writes and everything needed to read them back.

Layout of a run folder ``RUN_DIR``::

    RUN_DIR/
      config.json          exact environment config, PPO hyper-parameters, training options, versions,
                           observation/action spaces (format ``gear-env-run/1``)
      model.zip            final SB3 PPO model
      vecnormalize.pkl     VecNormalize statistics saved with the model (reloaded frozen)
      metrics.csv          one row per evaluation (timesteps, wall seconds, returns, settled omega...)
      metrics.json         the same rows plus a final summary (wall time, steps per second)
      checkpoints/         ckpt_<steps>.zip, ckpt_<steps>_vecnormalize.pkl, latest.json
      tb/                  TensorBoard event files (only if tensorboard is installed)

Every file is written atomically (temporary name, then ``os.replace``) so an interrupted run
never leaves a half-written model or checkpoint behind.
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gear_env.io import atomic_write, atomic_write_bytes, atomic_write_text

RUN_FORMAT = "gear-env-run/1"
CONFIG_FILE = "config.json"
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
METRICS_CSV = "metrics.csv"
METRICS_JSON = "metrics.json"
CHECKPOINT_DIR = "checkpoints"
LATEST_FILE = "latest.json"


class RunFolderError(ValueError):
    """A run folder is missing, incomplete, corrupt or incompatible (message says which and why)."""


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
        """Create the folder and its checkpoints/ subfolder (parents too)."""
        self.checkpoint_dir.mkdir(parents=True, exist_ok=True)

    # ---- config ------------------------------------------------------------------------------
    def write_config(self, data: Mapping[str, Any]) -> None:
        """Write config.json atomically (adds the format tag)."""
        payload = {"format": RUN_FORMAT, **data}
        atomic_write_text(
            self.config_path, json.dumps(payload, indent=2, sort_keys=False, default=_json_default) + "\n"
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
            data = json.loads(self.config_path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RunFolderError(f"corrupt run folder {str(self.path)!r}: cannot read {CONFIG_FILE}: {exc}") from exc
        if not isinstance(data, dict) or data.get("format") != RUN_FORMAT:
            raise RunFolderError(
                f"corrupt run folder {str(self.path)!r}: {CONFIG_FILE} has format "
                f"{data.get('format') if isinstance(data, dict) else type(data).__name__!r}, expected {RUN_FORMAT!r}"
            )
        for key in ("env_id", "env_config", "observation_space", "action_space"):
            if key not in data:
                raise RunFolderError(f"corrupt run folder {str(self.path)!r}: {CONFIG_FILE} lacks {key!r}")
        return data

    # ---- checkpoints -------------------------------------------------------------------------
    def checkpoint_paths(self, steps: int) -> tuple[Path, Path]:
        """(model zip, VecNormalize pickle) of the checkpoint at ``steps`` timesteps."""
        return self.checkpoint_dir / f"ckpt_{steps:09d}.zip", self.checkpoint_dir / f"ckpt_{steps:09d}_vecnormalize.pkl"

    def save_model(self, model: Any, vecnorm: Any, model_path: Path, vecnorm_path: Path) -> None:
        """Save an SB3 model and its VecNormalize atomically (each file complete or absent)."""

        def _w_model(tmp: str) -> None:
            buf = io.BytesIO()
            model.save(buf)
            Path(tmp).write_bytes(buf.getvalue())

        atomic_write(model_path, _w_model)
        if vecnorm is not None:
            atomic_write(vecnorm_path, vecnorm.save)

    def save_checkpoint(self, model: Any, vecnorm: Any, steps: int, keep: int = 3) -> Path:
        """Write a checkpoint (model + VecNormalize + step count) and point latest.json at it.

        latest.json is replaced last, so it always names a complete checkpoint. Older checkpoints
        beyond the ``keep`` most recent are deleted. Returns the model path."""
        self.checkpoint_dir.mkdir(parents=True, exist_ok=True)
        mpath, vpath = self.checkpoint_paths(steps)
        self.save_model(model, vecnorm, mpath, vpath)
        latest = {"steps": int(steps), "model": mpath.name, "vecnormalize": vpath.name if vecnorm is not None else None}
        atomic_write_text(self.checkpoint_dir / LATEST_FILE, json.dumps(latest) + "\n")
        self._prune(keep)
        return mpath

    def _prune(self, keep: int) -> None:
        zips = sorted(self.checkpoint_dir.glob("ckpt_*.zip"))
        for old in zips[: max(0, len(zips) - keep)]:
            for p in (old, old.with_name(old.stem + "_vecnormalize.pkl")):
                try:
                    p.unlink()
                except OSError:
                    pass

    def latest_checkpoint(self) -> tuple[int, Path, Path | None]:
        """(steps, model path, VecNormalize path or None) of the last complete checkpoint.

        Raises :class:`RunFolderError` when there is none or it is corrupt."""
        latest = self.checkpoint_dir / LATEST_FILE
        if not latest.is_file():
            raise RunFolderError(
                f"cannot resume: no checkpoint in {str(self.checkpoint_dir)!r} ({LATEST_FILE} missing)"
            )
        try:
            data = json.loads(latest.read_text(encoding="utf-8"))
            steps = int(data["steps"])
            mpath = self.checkpoint_dir / str(data["model"])
            vpath = self.checkpoint_dir / str(data["vecnormalize"]) if data.get("vecnormalize") else None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RunFolderError(f"cannot resume: corrupt {str(latest)!r}: {exc}") from exc
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
        atomic_write_text(self.path / METRICS_CSV, buf.getvalue())
        payload = {"evaluations": list(rows), "summary": dict(summary)}
        atomic_write_text(self.path / METRICS_JSON, json.dumps(payload, indent=2, default=_json_default) + "\n")

    def read_metrics(self) -> dict[str, Any]:
        """metrics.json as a dict ({} if absent)."""
        p = self.path / METRICS_JSON
        if not p.is_file():
            return {}
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise RunFolderError(f"corrupt {str(p)!r}: {exc}") from exc


def export_policy(run_dir: str | os.PathLike, dest: str | os.PathLike, use_best: bool = False) -> Path:
    """Copy the files needed to evaluate a run's policy (no checkpoints, no TensorBoard logs) to ``dest``.

    This is how ``gear_env/data/pretrained/`` is made: config.json, env_config.json, model.zip,
    vecnormalize.pkl and metrics.json. ``use_best`` takes best_model.zip/best_vecnormalize.pkl
    (the best evaluation during training) instead of the final model. Returns ``dest``."""
    src = RunFolder(run_dir)
    src.read_config()  # validates the folder
    out = Path(dest)
    out.mkdir(parents=True, exist_ok=True)
    pairs = [(CONFIG_FILE, CONFIG_FILE), ("env_config.json", "env_config.json"), (METRICS_JSON, METRICS_JSON)]
    if use_best:
        pairs += [("best_model.zip", MODEL_FILE), ("best_vecnormalize.pkl", VECNORM_FILE)]
    else:
        pairs += [(MODEL_FILE, MODEL_FILE), (VECNORM_FILE, VECNORM_FILE)]
    for a, b in pairs:
        p = src.path / a
        if not p.is_file():
            raise RunFolderError(f"cannot export {str(src.path)!r}: {a} is missing")
        atomic_write_bytes(out / b, p.read_bytes())
    return out


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
    "RunFolder",
    "RunFolderError",
    "check_space_compatible",
    "export_policy",
    "space_to_dict",
    "versions",
]
