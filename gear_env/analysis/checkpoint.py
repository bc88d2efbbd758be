"""Checkpoint of an unfinished sweep: the finished points, written atomically, resumable.

The file is a NumPy ``.npz`` (no pickles) holding the sweep's fingerprint (settings and
parameters as JSON), the omega grid in sweep order, and the results of the finished points. A
checkpoint written by a different sweep is refused with a ValueError rather than mixed in.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..io import atomic_write
from .results import PointResult, check_label

CHECKPOINT_VERSION = 1
MAX_CHECKPOINT_BYTES = 1024**3
"""Largest sweep checkpoint read (declared uncompressed bytes of all its arrays; 1 GiB)."""
MIN_INTERVAL = 2.0
"""Seconds between two non-forced saves (a serial sweep saves after a point at most this often)."""


class Checkpoint:
    """Finished points of one sweep and the file they are saved to."""

    def __init__(self, path: str, fingerprint: dict[str, Any], omegas: np.ndarray):
        self.path = Path(path)
        self.fingerprint = fingerprint
        self.omegas = np.asarray(omegas, float)
        self.done: dict[int, PointResult] = {}
        self._last = 0.0
        self._dirty = False

    @classmethod
    def open(cls, path: str, fingerprint: dict[str, Any], omegas: np.ndarray) -> Checkpoint:
        """A checkpoint for this sweep; loads ``path`` if it exists (and must match)."""
        ck = cls(path, fingerprint, omegas)
        if ck.path.exists():
            ck._load()
        return ck

    def _load(self) -> None:
        """Read the file through the untrusted-file layer: members, dtypes and shapes checked before
        allocating, the fingerprint parsed with bounded JSON, every point's label and period checked."""
        from ..io import parse_json_text
        from ..sim import kernels as K
        from ..untrusted import ArraySpec, read_npz, refuse

        p = str(self.path)
        n_max = max(1, len(self.omegas))
        per = self.fingerprint.get("periods", 1) if isinstance(self.fingerprint.get("periods"), int) else 1
        rows = n_max * max(per, 1)
        n_grid = 1_000_000  # the most points of a sweep
        spec = {
            "version": ArraySpec("i", 0, 1),
            "fingerprint": ArraySpec("U", 0, 1, 4 * 2**20),
            "omegas": ArraySpec("f", 1, n_grid),
            "has_lyapunov": ArraySpec("b", 0, 1),
            "index": ArraySpec("i", 1, n_max),
            "omega": ArraySpec("f", 1, n_max),
            "regime": ArraySpec("U", 1, n_max, n_max * 4 * 64),
            "period": ArraySpec("i", 1, n_max),
            "lyapunov": ArraySpec("f", 1, n_max),
            "poincare": ArraySpec("f", 3, rows * K.N_PC),
            "stats": ArraySpec("f", 2, n_max * K.N_STATS),
            "final_state": ArraySpec("f", 2, n_max * K.NSTATE),
            "steps": ArraySpec("i", 1, n_max),
            "n_clusters": ArraySpec("i", 1, n_max),
            "converged": ArraySpec("b", 1, n_max),
            "periods_recorded": ArraySpec("i", 1, n_max),
        }

        def read(only: tuple[str, ...] | None) -> dict[str, np.ndarray]:
            try:
                return read_npz(self.path, "checkpoint", spec, max_total=MAX_CHECKPOINT_BYTES, only=only)
            except ValueError as exc:
                raise ValueError(f"corrupt checkpoint: {exc}; delete it to start afresh") from None

        data = read(("version", "fingerprint", "omegas"))  # first what identifies the sweep
        ver = int(data["version"])
        if ver != CHECKPOINT_VERSION:
            raise ValueError(f"checkpoint {p!r} has version {ver}, expected {CHECKPOINT_VERSION}; delete it")
        fp = parse_json_text(str(data["fingerprint"]), f"checkpoint {p!r}: fingerprint")
        if not isinstance(fp, dict):
            raise refuse(p, "fingerprint", "must be a JSON object")
        if fp != json.loads(json.dumps(self.fingerprint)):
            diff = sorted(k for k in set(fp) | set(self.fingerprint) if fp.get(k) != self.fingerprint.get(k))
            raise ValueError(
                f"checkpoint {p!r} belongs to a different sweep (differs in {diff}); delete it or use another path"
            )
        om = data["omegas"]
        if om.shape != self.omegas.shape or not np.array_equal(om, self.omegas):
            raise ValueError(f"checkpoint {p!r} belongs to a different omega grid; delete it or use another path")
        data = read(None)
        m = len(data["index"])
        for k in ("omega", "regime", "period", "lyapunov", "steps", "n_clusters", "converged", "periods_recorded"):
            if data[k].shape != (m,):
                raise refuse(p, k, f"has shape {data[k].shape}, expected ({m},) like index")
        if m and (
            data["poincare"].shape[0] != m or data["poincare"].shape[2] != K.N_PC
            or data["stats"].shape != (m, K.N_STATS) or data["final_state"].shape != (m, K.NSTATE)
        ):  # fmt: skip
            raise refuse(p, "poincare/stats/final_state", "shapes do not match the number of points")
        idx = data["index"]
        if m and (idx.min() < 0 or idx.max() >= len(self.omegas) or len(np.unique(idx)) != m):
            raise refuse(p, "index", f"must hold distinct point indices in [0, {len(self.omegas) - 1}]")
        if m and not np.array_equal(data["omega"], self.omegas[idx]):
            raise refuse(p, "omega", "does not match the omega grid at the stored indices")
        max_period = int(self.fingerprint.get("max_period", 64))
        has_lyap = bool(data["has_lyapunov"])
        for j, i in enumerate(idx.tolist()):
            regime, period = str(data["regime"][j]), int(data["period"][j])
            check_label(p, j, regime, period, max_period)
            for k in ("poincare", "stats", "final_state", "lyapunov", "omega"):
                if not np.all(np.isfinite(data[k][j])):
                    raise refuse(p, f"{k}[{j}]", "holds NaN or infinity")
            if not 1 <= int(data["steps"][j]) <= 10_000_000 or not 0 <= int(data["n_clusters"][j]) <= 10**9:
                raise refuse(p, f"steps/n_clusters[{j}]", "out of range")
            if not 0 <= int(data["periods_recorded"][j]) <= 10**9:
                raise refuse(p, f"periods_recorded[{j}]", "out of range")
            self.done[int(i)] = PointResult(
                omega=float(data["omega"][j]),
                regime=regime,
                period=period,
                lyapunov=float(data["lyapunov"][j]) if has_lyap else None,
                poincare=data["poincare"][j],
                stats=data["stats"][j],
                final_state=data["final_state"][j],
                steps_per_period=int(data["steps"][j]),
                n_clusters=int(data["n_clusters"][j]),
                converged=bool(data["converged"][j]),
                periods_recorded=int(data["periods_recorded"][j]),
            )

    def add(self, i: int, r: PointResult) -> None:
        self.done[int(i)] = r
        self._dirty = True

    def save(self, force: bool = True) -> None:
        """Write the finished points atomically (skipped if nothing changed, or if less than
        MIN_INTERVAL s passed since the last write and not ``force``)."""
        if not self._dirty:
            return
        now = time.monotonic()
        if not force and now - self._last < MIN_INTERVAL:
            return
        idx = sorted(self.done)
        pts = [self.done[i] for i in idx]
        has_lyap = bool(pts) and pts[0].lyapunov is not None
        arrays: dict[str, Any] = {
            "version": np.array(CHECKPOINT_VERSION),
            "fingerprint": np.array(json.dumps(self.fingerprint)),
            "omegas": self.omegas,
            "has_lyapunov": np.array(has_lyap),
            "index": np.array(idx, np.int64),
            "omega": np.array([p.omega for p in pts], float),
            "regime": np.array([p.regime for p in pts], dtype="U32"),
            "period": np.array([p.period for p in pts], np.int64),
            "lyapunov": np.array([p.lyapunov if has_lyap else 0.0 for p in pts], float),
            "poincare": np.stack([p.poincare for p in pts]) if pts else np.empty((0, 0, 0)),
            "stats": np.stack([p.stats for p in pts]) if pts else np.empty((0, 0)),
            "final_state": np.stack([p.final_state for p in pts]) if pts else np.empty((0, 0)),
            "steps": np.array([p.steps_per_period for p in pts], np.int64),
            "n_clusters": np.array([p.n_clusters for p in pts], np.int64),
            "converged": np.array([p.converged for p in pts], bool),
            "periods_recorded": np.array([p.periods_recorded for p in pts], np.int64),
        }

        def _w(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)

        atomic_write(self.path, _w)
        self._last = now
        self._dirty = False

    def remove(self) -> None:
        """Delete the file (after the sweep finished)."""
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
