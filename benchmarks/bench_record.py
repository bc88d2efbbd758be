"""The JSON record a benchmark script writes with ``--json FILE`` (read by benchmarks/make_tables.py).

A record names the benchmark, the release (``gear_env.__version__``) and git commit it measured, the
date, the machine (CPU model and cores from /proc/cpuinfo and ``os``, Python, NumPy and numba
versions), the 1/5/15-minute load averages before and after the run, and the results: each a name,
a unit and the values measured (one per run, round or case; the tables show their range). Speed on
shared VMs drifts 1.5-2x over minutes, so the scripts time what they compare in one interleaved run
and the load is recorded with every number.

Usage inside a script::

    rec = Record("bench_tasks", argv)  # load average "before" taken here
    rec.add("GearSpeed-v1, single env", "steps/s", [1780.0, 1795.0])
    rec.write(path)  # load average "after" taken here; atomic write
"""

from __future__ import annotations

import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

SCHEMA = "gear-env-benchmark/1"
ROOT = Path(__file__).resolve().parents[1]


def cpu_model() -> str:
    """The CPU's model name with its family and model numbers from /proc/cpuinfo (``platform.processor()``
    or the architecture elsewhere), e.g. ``AMD EPYC (family 25 model 1)``."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if not line.strip():
                    break  # the first processor's block is enough
                key, _, value = line.partition(":")
                fields.setdefault(key.strip(), " ".join(value.split()))
    except OSError:
        pass
    name = fields.get("model name") or platform.processor() or platform.machine()
    if "cpu family" in fields and "model" in fields:
        name += f" (family {fields['cpu family']} model {fields['model']})"
    return name


def machine() -> dict[str, Any]:
    """CPU model, logical cores (and those this process may use), Python, NumPy and numba versions."""
    import numba
    import numpy as np

    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count() or 1,
        "usable_cores": usable or 1,
        "system": f"{platform.system()} {platform.machine()}",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }


def load_average() -> list[float] | None:
    """The 1, 5 and 15-minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def git_commit() -> str | None:
    """The checkout's commit (short hash, ``+dirty`` with uncommitted changes), None outside a git checkout."""
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=10
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


class Record:
    """One benchmark run's record: created at the start (load before), written at the end (load after)."""

    def __init__(self, benchmark: str, argv: Sequence[str] | None = None):
        import gear_env

        args = list(sys.argv[1:] if argv is None else argv)
        self.data: dict[str, Any] = {
            "schema": SCHEMA,
            "benchmark": benchmark,
            "command": " ".join(["python", f"benchmarks/{benchmark}.py", *_drop_json(args)]),
            "release": gear_env.__version__,
            "commit": git_commit(),
            "date": time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime()),
            "machine": machine(),
            "load": {"before": load_average(), "after": None},
            "results": [],
        }

    def add(self, name: str, unit: str, values: Sequence[float], note: str | None = None) -> None:
        """Add a result: ``values`` (finite numbers, one per run/round/case) in ``unit``."""
        vals = [float(v) for v in values]
        if not vals or not all(math.isfinite(v) for v in vals):
            raise ValueError(f"result {name!r}: values must be finite numbers, got {vals}")
        entry: dict[str, Any] = {"name": name, "unit": unit, "values": [_round(v) for v in vals]}
        if note:
            entry["note"] = note
        self.data["results"].append(entry)

    def write(self, path: str | os.PathLike) -> None:
        """Take the load average "after" and write the record atomically (temp file + rename)."""
        import json

        from gear_env.io import atomic_write_text

        self.data["load"]["after"] = load_average()
        atomic_write_text(path, json.dumps(self.data, indent=1) + "\n")
        print(f"record written: {os.fspath(path)}")


def check_json_target(path: str | None) -> None:
    """Refuse a ``--json`` target that is not a (new or existing) regular file before any work starts."""
    if path is None:
        return
    from gear_env.io import check_regular_target

    try:
        check_regular_target(path, "--json")
    except ValueError as exc:
        raise SystemExit(f"--json: {exc}") from None
    if not Path(path).resolve().parent.is_dir():
        raise SystemExit(f"--json: folder {str(Path(path).parent)!r} does not exist")


def _round(v: float) -> float:
    """Four significant digits: the records stay small and stable; the runs drift far more than that."""
    return float(f"{v:.4g}")


def _drop_json(args: list[str]) -> list[str]:
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
        elif a == "--json":
            skip = True
        elif not a.startswith("--json="):
            out.append(a)
    return out
