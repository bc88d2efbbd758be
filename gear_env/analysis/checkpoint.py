"""Checkpoint of an unfinished sweep: the finished points, written atomically, resumable.

The file is a NumPy ``.npz`` (no pickles) holding the sweep's fingerprint (settings and
parameters as JSON), the omega grid in sweep order, and the results of the finished points. A
checkpoint written by a different sweep is refused with a ValueError rather than mixed in.
"""

from __future__ import annotations

import json
import os
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..io import atomic_write
from .results import PointResult

CHECKPOINT_VERSION = 1
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
        p = str(self.path)
        try:
            with np.load(self.path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise ValueError(f"checkpoint {p!r} is truncated or corrupt ({exc}); delete it to start afresh") from exc
        try:
            ver = int(data["version"])
            fp = json.loads(str(data["fingerprint"]))
            om = data["omegas"]
        except (KeyError, ValueError) as exc:
            raise ValueError(f"checkpoint {p!r} is not a gear-env sweep checkpoint ({exc})") from exc
        if ver != CHECKPOINT_VERSION:
            raise ValueError(f"checkpoint {p!r} has version {ver}, expected {CHECKPOINT_VERSION}; delete it")
        if fp != json.loads(json.dumps(self.fingerprint)):
            diff = sorted(k for k in set(fp) | set(self.fingerprint) if fp.get(k) != self.fingerprint.get(k))
            raise ValueError(
                f"checkpoint {p!r} belongs to a different sweep (differs in {diff}); delete it or use another path"
            )
        if om.shape != self.omegas.shape or not np.array_equal(om, self.omegas):
            raise ValueError(f"checkpoint {p!r} belongs to a different omega grid; delete it or use another path")
        has_lyap = bool(data["has_lyapunov"])
        for j, i in enumerate(data["index"].tolist()):
            self.done[int(i)] = PointResult(
                omega=float(data["omega"][j]),
                regime=str(data["regime"][j]),
                period=int(data["period"][j]),
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
