"""The results object of a sweep: arrays per omega, NetCDF save/load, DataFrame and JSON views.

File format (``SweepResult.save``): NetCDF-4 (HDF5) written with xarray (engine ``netcdf4``, or
``h5netcdf`` when netCDF4 is not installed), atomically.
Global attributes ``format = "gear-env-sweep"`` and ``format_version`` (currently 1) identify it;
``config`` holds the sweep settings and ``params`` the physical parameters as JSON; ``checksum``
is a SHA-256 over all data variables, so a truncated or altered file is rejected on load instead
of being read partially. Dimensions: ``omega`` (n), ``record`` (recorded mesh periods),
``pc`` (the 14 Poincare columns of ``kernels.PC_*``), ``state`` (10).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ..sim import kernels as K
from ..sim.params import GearParams
from ..sim.simulator import STATE_NAMES, stats_amplitude
from ..untrusted import refuse

FORMAT_NAME = "gear-env-sweep"
FORMAT_VERSION = 1
AMPLITUDE_NAMES = ("U", "delta", "bd", "psi", "force")
PC_NAMES = STATE_NAMES + ("Delta", "B_d", "psi", "force")
LYAPUNOV_UNITS = "1 per unit natural time (omega_n t)"
DRIFT_WARN = 0.1
"""Default :meth:`SweepResult.unsettled` threshold: settled tori drift by < 0.05 in the sweeps of
docs/RESULTS.md, decaying transients near the torus edges by 0.05-0.4."""


_PERIOD_LABEL = re.compile(r"period-([0-9]{1,6})")


def check_label(path: str, j: int, regime: str, period: int, max_period: int) -> None:
    """A motion label of a results or checkpoint file: ``period-N`` with period N in [1, max_period],
    or ``quasi-periodic`` / ``chaotic`` with period 0 (FileFormatError naming the point otherwise)."""
    m = _PERIOD_LABEL.fullmatch(regime)
    if m is not None:
        if int(m.group(1)) != period or not 1 <= period <= max(1, max_period):
            raise refuse(path, f"period[{j}]", f"{period} does not fit label {regime!r} (max period {max_period})")
    elif regime in ("quasi-periodic", "chaotic"):
        if period != 0:
            raise refuse(path, f"period[{j}]", f"must be 0 for {regime!r}, got {period}")
    else:
        raise refuse(path, f"regime[{j}]", f"unknown motion label {regime[:40]!r}")


MAX_RESULTS_BYTES = 1024**3
"""Largest results file read: its variables' declared sizes in all (1 GiB), checked before loading."""


class ResultsFileError(FileFormatError):
    """A results file is missing data, truncated, corrupt or of an incompatible format version."""


@dataclass
class SweepResult:
    """Everything a sweep records, one entry per meshing frequency (in the order of ``omega``
    as given, whatever the sweep direction).

    Attributes:
        omega: (n,) meshing frequencies Omega/omega_n.
        model: ``"constant"`` or ``"dynamic"``.
        direction: ``"forward"`` (increasing omega) or ``"reverse"``.
        params: the physical parameters.
        regime: n labels ``"period-N"``, ``"quasi-periodic"`` or ``"chaotic"``.
        period: (n,) int, N for periodic motions, 0 otherwise.
        lyapunov: (n,) largest Lyapunov exponent per unit natural time, or None if not computed.
        poincare: (n, periods, 14) Poincare samples (columns ``PC_*``: 10 states, Delta, B_d,
            psi, force) of the last recorded window.
        amplitude: name -> (n,) half peak-to-peak of ``U``, ``delta``, ``bd``, ``psi``, ``force``.
        contact_loss: (n,) fraction of time with the teeth apart or in back contact.
        final_states: (n, 10) state at the end of each omega (b0 units).
        steps_per_period: (n,) Newmark steps per mesh period used at each omega.
        n_clusters: (n,) Poincare clusters; converged: (n,) False if a periodic orbit was still
            being approached at the end; drive_impacts / back_impacts: (n,) per mesh period.
        transient, periods: mesh periods discarded / recorded per omega.
        meta: free-form settings (JSON-serialisable).
    """

    omega: np.ndarray
    model: str
    direction: str
    params: GearParams
    regime: list[str]
    period: np.ndarray
    lyapunov: np.ndarray | None
    poincare: np.ndarray
    amplitude: dict[str, np.ndarray]
    contact_loss: np.ndarray
    final_states: np.ndarray
    steps_per_period: np.ndarray
    n_clusters: np.ndarray
    converged: np.ndarray
    drive_impacts: np.ndarray
    back_impacts: np.ndarray
    transient: int
    periods: int
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.omega)

    # views ---------------------------------------------------------------------------------
    def poincare_of(self, name: str = "Delta") -> np.ndarray:
        """(n, periods) Poincare samples of one column (a state name, ``Delta``, ``B_d``,
        ``psi`` or ``force``; ``delta``/``bd`` are accepted as aliases)."""
        alias = {"delta": "Delta", "bd": "B_d"}
        col = alias.get(name, name)
        if col not in PC_NAMES:
            raise ValueError(f"name must be one of {list(PC_NAMES)}, got {name!r}")
        return self.poincare[:, :, PC_NAMES.index(col)]

    def drift(self, name: str = "U") -> np.ndarray:
        """(n,) how much the recorded motion still changed during its window, per omega.

        The Poincare samples of one column (default ``U``) are split into two halves of the
        recorded periods (the last 2h samples, h a multiple of the period of a period-N point);
        the drift is the larger of the change of their
        spread (max - min) and of their mean, over the U amplitude (half peak-to-peak; at least
        1e-3 b0). A settled periodic motion gives ~0 (its samples recur), a settled torus a few
        percent (its two halves sample the same invariant circle), a transient that is still
        decaying or growing more: near a bifurcation, read forward/reverse differences only where
        both sweeps have a small drift (``DRIFT_WARN``; docs/RESULTS.md, "Hysteresis and dwell
        time"). Not meaningful for chaotic motion, whose spread fluctuates. Dimensionless.
        """
        p = self.poincare_of(name)
        out = np.zeros(len(self))
        for i in range(len(self)):
            # halves of equal length; for a period-N point a multiple of N, so that each half
            # holds whole cycles of the orbit (else the means differ by up to spread/h)
            per = int(self.period[i]) if self.period[i] > 0 else 1
            h = (p.shape[1] // 2) // per * per or p.shape[1] // 2
            if h == 0:
                continue
            a, b = p[i, p.shape[1] - 2 * h : p.shape[1] - h], p[i, p.shape[1] - h :]
            spread = abs((b.max() - b.min()) - (a.max() - a.min()))
            out[i] = max(spread, abs(b.mean() - a.mean())) / max(float(self.amplitude["U"][i]), 1e-3)
        return out

    def unsettled(self, threshold: float | None = None) -> np.ndarray:
        """Omegas of non-chaotic points whose :meth:`drift` exceeds ``threshold`` (default
        ``DRIFT_WARN``): rerun them with a longer transient before trusting their label or a
        forward/reverse difference."""
        thr = DRIFT_WARN if threshold is None else float(threshold)
        if not (thr > 0 and math.isfinite(thr)):
            raise ValueError(f"threshold must be finite and > 0, got {threshold!r}")
        keep = (self.drift() > thr) & np.array([r != "chaotic" for r in self.regime], dtype=bool)
        return np.sort(self.omega[keep])

    def to_dataframe(self):  # -> pandas.DataFrame
        """One row per omega: omega, regime, period, lyapunov, amplitudes, contact loss, ..."""
        import pandas as pd

        data: dict[str, Any] = {
            "omega": self.omega,
            "regime": self.regime,
            "period": self.period,
            "lyapunov": self.lyapunov if self.lyapunov is not None else [None] * len(self),
        }
        for k in AMPLITUDE_NAMES:
            data[f"amplitude_{k.lower()}"] = self.amplitude[k]
        data.update(
            contact_loss=self.contact_loss,
            drive_impacts=self.drive_impacts,
            back_impacts=self.back_impacts,
            n_clusters=self.n_clusters,
            converged=self.converged,
            drift=self.drift(),
            steps_per_period=self.steps_per_period,
        )
        return pd.DataFrame(data)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict: omega, regime, period, amplitude_u (and the other amplitudes),
        lyapunov (or null), contact_loss, poincare_delta and poincare_u (lists of lists), settings."""
        d: dict[str, Any] = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "model": self.model,
            "direction": self.direction,
            "transient": self.transient,
            "periods": self.periods,
            "units": "displacements in b0 (half backlash); force in k_m0 b0; psi in rad; lyapunov " + LYAPUNOV_UNITS,
            "omega": self.omega.tolist(),
            "regime": list(self.regime),
            "period": self.period.tolist(),
            "lyapunov": None if self.lyapunov is None else self.lyapunov.tolist(),
        }
        for k in AMPLITUDE_NAMES:
            d[f"amplitude_{k.lower()}"] = self.amplitude[k].tolist()
        d["contact_loss"] = self.contact_loss.tolist()
        d["converged"] = [bool(c) for c in self.converged]
        d["steps_per_period"] = self.steps_per_period.tolist()
        d["poincare_delta"] = self.poincare_of("Delta").tolist()
        d["poincare_u"] = self.poincare_of("U").tolist()
        d["params"] = self.params.to_dict()
        d["meta"] = self.meta
        return d

    def to_json(self, path: str) -> None:
        """Write :meth:`to_json_dict` atomically."""
        from ..io import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_json_dict()))

    def intervals(self) -> list[tuple[float, float, str]]:
        """Runs of equal regime along increasing omega: [(omega_first, omega_last, label), ...]."""
        idx = np.argsort(self.omega, kind="stable")
        out: list[tuple[float, float, str]] = []
        for i in idx:
            w, lab = float(self.omega[i]), self.regime[i]
            if out and out[-1][2] == lab:
                out[-1] = (out[-1][0], w, lab)
            else:
                out.append((w, w, lab))
        return out

    def summary(self) -> str:
        """Counts of each regime and the omega intervals of non-period-1 motion, as text."""
        from collections import Counter

        c = Counter(self.regime)
        parts = [f"{k}: {v}" for k, v in sorted(c.items(), key=lambda kv: -kv[1])]
        return f"{len(self)} points ({self.model}, {self.direction}) -> " + ", ".join(parts)

    # file I/O ------------------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        out = {
            "omega": np.asarray(self.omega, float),
            "regime": np.asarray(self.regime, dtype=object),
            "period": np.asarray(self.period, np.int64),
            "poincare": np.asarray(self.poincare, float),
            "contact_loss": np.asarray(self.contact_loss, float),
            "final_states": np.asarray(self.final_states, float),
            "steps_per_period": np.asarray(self.steps_per_period, np.int64),
            "n_clusters": np.asarray(self.n_clusters, np.int64),
            "converged": np.asarray(self.converged, np.int8),
            "drive_impacts": np.asarray(self.drive_impacts, float),
            "back_impacts": np.asarray(self.back_impacts, float),
        }
        if self.lyapunov is not None:
            out["lyapunov"] = np.asarray(self.lyapunov, float)
        for k in AMPLITUDE_NAMES:
            out[f"amplitude_{k}"] = np.asarray(self.amplitude[k], float)
        return out

    def save(self, path: str) -> None:
        """Write a self-describing NetCDF-4 file atomically (see the module docstring)."""
        import xarray as xr

        from ..io import atomic_write

        arr = self._arrays()
        dims = {
            "poincare": ("omega", "record", "pc"),
            "final_states": ("omega", "state"),
        }
        coords = {"omega": arr["omega"], "pc": list(PC_NAMES), "state": list(STATE_NAMES)}
        data_vars = {}
        for k, v in arr.items():
            if k == "omega":
                continue
            data_vars[k] = (dims.get(k, ("omega",)), v.astype(str) if k == "regime" else v)
        ds = xr.Dataset(data_vars, coords=coords)
        ds["lyapunov" if "lyapunov" in ds else "omega"].attrs["units"] = LYAPUNOV_UNITS if "lyapunov" in ds else "1"
        config = {
            "model": self.model,
            "direction": self.direction,
            "transient": int(self.transient),
            "periods": int(self.periods),
            "n": len(self),
            "has_lyapunov": self.lyapunov is not None,
            "meta": self.meta,
        }
        ds.attrs.update(
            format=FORMAT_NAME,
            format_version=FORMAT_VERSION,
            config=json.dumps(config),
            params=json.dumps(self.params.to_dict()),
            checksum=_checksum(arr),
            description="gear-env sweep results: Poincare samples, amplitudes, motion class per omega",
        )

        def _w(tmp: str) -> None:
            ds.to_netcdf(tmp, engine=_engine(), format="NETCDF4")  # type: ignore[call-overload]

        atomic_write(path, _w)

    @classmethod
    def load(cls, path: str) -> SweepResult:
        """Read a file written by :meth:`save`.

        Raises:
            FileNotFoundError: no such file.
            ResultsFileError (a ValueError): not a sweep file, an incompatible format version,
                or truncated/corrupt data (checksum mismatch). Nothing is returned partially.
        """
        import xarray as xr

        from ..io import parse_json_text
        from ..untrusted import open_regular, want_int, want_str

        p = Path(path)
        if not p.exists():
            raise FileNotFoundError(f"results file {str(p)!r} does not exist")
        try:
            os.close(open_regular(p, "results file")[0])  # a FIFO, device or folder is refused, never waited on
        except ValueError as exc:
            raise ResultsFileError(str(exc)) from None
        try:
            with xr.open_dataset(p, engine=_engine()) as ds0:
                # the declared sizes first: nothing is read into memory before they are bounded
                total = sum(int(v.size) * v.dtype.itemsize for v in ds0.variables.values())
                if total > MAX_RESULTS_BYTES:
                    raise ResultsFileError(
                        f"results file {str(p)!r} declares {total:,} bytes of data; the limit is {MAX_RESULTS_BYTES:,}"
                    )
                _check_format(ds0.attrs, p)  # before loading: another file's data is never inflated
                ds = ds0.load()
        except ResultsFileError:
            raise
        except Exception as exc:  # h5py/netCDF raise many types on a damaged file
            raise ResultsFileError(f"results file {str(p)!r} is truncated or not a NetCDF-4 file: {exc}") from exc
        try:
            config = parse_json_text(str(ds.attrs["config"]), f"results file {str(p)!r}: config")
            params = GearParams.from_dict(parse_json_text(str(ds.attrs["params"]), f"results file {str(p)!r}: params"))
            if not isinstance(config, dict):
                raise ValueError("config is not a JSON object")
            arr = {str(k): ds[k].values for k in ds.data_vars}
            arr["omega"] = ds["omega"].values
            arr["regime"] = np.asarray([str(s) for s in arr["regime"]], dtype=object)
            n = len(arr["omega"])
            for k, a in arr.items():
                if a.shape[:1] != (n,):
                    raise ValueError(f"{k} has shape {a.shape}, expected {n} points")
            for j in range(n):
                check_label(str(p), j, str(arr["regime"][j]), int(arr["period"][j]), 1_000_000)
            want_str(config["model"], str(p), "config.model", choices=("constant", "dynamic"))
            want_str(config["direction"], str(p), "config.direction", choices=("forward", "reverse"))
            want_int(config["transient"], 0, 10**9, str(p), "config.transient")
            want_int(config["periods"], 1, 10**9, str(p), "config.periods")
            if not isinstance(config.get("meta", {}), dict):
                raise ValueError("config.meta is not a JSON object")
        except ResultsFileError:
            raise
        except (KeyError, ValueError, TypeError, AttributeError, OverflowError) as exc:
            raise ResultsFileError(f"results file {str(p)!r} is incomplete or corrupt: {exc}") from None
        if config.get("has_lyapunov") and "lyapunov" not in arr:
            raise ResultsFileError(f"results file {str(p)!r} is incomplete: lyapunov missing")
        if len(arr["omega"]) != config.get("n"):
            raise ResultsFileError(f"results file {str(p)!r} holds {len(arr['omega'])} of {config.get('n')} points")
        if _checksum(arr) != ds.attrs.get("checksum"):
            raise ResultsFileError(f"results file {str(p)!r} is corrupt: checksum mismatch")
        return cls(
            omega=arr["omega"].astype(float),
            model=config["model"],
            direction=config["direction"],
            params=params,
            regime=[str(s) for s in arr["regime"]],
            period=arr["period"].astype(int),
            lyapunov=arr.get("lyapunov"),
            poincare=arr["poincare"],
            amplitude={k: arr[f"amplitude_{k}"] for k in AMPLITUDE_NAMES},
            contact_loss=arr["contact_loss"],
            final_states=arr["final_states"],
            steps_per_period=arr["steps_per_period"].astype(int),
            n_clusters=arr["n_clusters"].astype(int),
            converged=arr["converged"].astype(bool),
            drive_impacts=arr["drive_impacts"],
            back_impacts=arr["back_impacts"],
            transient=int(config["transient"]),
            periods=int(config["periods"]),
            meta=config.get("meta", {}),
        )


def _check_format(attrs: Any, p: Path) -> None:
    """ResultsFileError unless the attributes name a gear-env sweep file of this format version."""
    if attrs.get("format") != FORMAT_NAME:
        raise ResultsFileError(f"{str(p)!r} is not a gear-env sweep file (format={_short(attrs.get('format'))})")
    try:
        ver = int(attrs.get("format_version", -1))
    except (TypeError, ValueError, OverflowError):
        ver = -1
    if ver != FORMAT_VERSION:
        raise ResultsFileError(
            f"{str(p)!r} has format_version {ver}; this gear-env reads version {FORMAT_VERSION} only"
        )


def _short(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def _engine() -> str:
    """xarray engine for NetCDF-4 files: netcdf4 if installed, else h5netcdf (needs h5py)."""
    try:
        import netCDF4  # noqa: F401

        return "netcdf4"
    except ImportError:
        return "h5netcdf"


def _checksum(arr: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for k in sorted(arr):
        v = arr[k]
        h.update(k.encode())
        if v.dtype == object or v.dtype.kind in "US":
            h.update("\x00".join(str(s) for s in v.tolist()).encode())
        elif v.dtype.kind == "b":
            h.update(np.ascontiguousarray(v.astype(np.int8)).tobytes())
        elif v.dtype.kind in "iu":
            h.update(np.ascontiguousarray(v.astype(np.int64)).tobytes())
        else:
            h.update(np.ascontiguousarray(v.astype(np.float64)).tobytes())
    return h.hexdigest()


@dataclass
class PointResult:
    """What one omega of a sweep produces (the unit of work that chunks return)."""

    omega: float
    regime: str
    period: int
    lyapunov: float | None
    poincare: np.ndarray
    stats: np.ndarray
    final_state: np.ndarray
    steps_per_period: int
    n_clusters: int
    converged: bool
    periods_recorded: int

    def amplitude(self, name: str) -> float:
        """Half peak-to-peak of a channel over the recorded periods (see ``stats_amplitude``)."""
        return stats_amplitude(self.stats, name)

    @property
    def contact_loss(self) -> float:
        s = self.stats
        return float((s[K.ST_SEP_TIME] + s[K.ST_BACK_TIME]) / max(s[K.ST_TIME], 1e-300))


def assemble(
    omegas: np.ndarray,
    points: list[PointResult],
    model: str,
    direction: str,
    params: GearParams,
    transient: int,
    periods: int,
    lyapunov: bool,
    meta: dict[str, Any] | None = None,
) -> SweepResult:
    """Build a :class:`SweepResult` from per-omega results (in the order of ``omegas``)."""
    n = len(points)
    amp = {k: np.array([p.amplitude(k) for p in points]) for k in AMPLITUDE_NAMES}
    lyap = None
    if lyapunov:
        vals = [p.lyapunov for p in points]
        if any(v is None or not math.isfinite(v) for v in vals):
            raise ValueError("internal error: a Lyapunov exponent is missing")
        lyap = np.array(vals, float)
    return SweepResult(
        omega=np.asarray(omegas, float),
        model=model,
        direction=direction,
        params=params,
        regime=[p.regime for p in points],
        period=np.array([p.period for p in points], int),
        lyapunov=lyap,
        poincare=np.stack([p.poincare for p in points]) if n else np.empty((0, periods, K.N_PC)),
        amplitude=amp,
        contact_loss=np.array([p.contact_loss for p in points]),
        final_states=np.stack([p.final_state for p in points]) if n else np.empty((0, K.NSTATE)),
        steps_per_period=np.array([p.steps_per_period for p in points], int),
        n_clusters=np.array([p.n_clusters for p in points], int),
        converged=np.array([p.converged for p in points], bool),
        drive_impacts=np.array([p.stats[K.ST_DRIVE_IMPACTS] / p.periods_recorded for p in points]),
        back_impacts=np.array([p.stats[K.ST_BACK_IMPACTS] / p.periods_recorded for p in points]),
        transient=transient,
        periods=periods,
        meta=dict(meta or {}),
    )
