"""The mesh stiffness from the teeth, side by side with ROSS (petrobras/ross) where ROSS runs.

For each pair of ``PAIRS`` (the ROSS test pair, the paper's pair and pairs chosen to span tooth
counts, modules, pressure angles and bores) it computes the 1000-point waveform
``linspace(0, one mesh period, 1000)`` with :class:`gear_env.sim.geometry.SpurPair` and with ROSS's
``Mesh(GearElementTVMS, GearElementTVMS)``, and prints contact ratio, max / min / mean and the
time of each, plus their ratio::

    python benchmarks/geometry_vs_ross.py [--ross-python /path/to/python] [--json out.json]

ROSS is not a dependency: it runs in the interpreter given by ``--ross-python`` (or the
``GEAR_ENV_ROSS_PYTHON`` environment variable; ROSS installs from its source on Python 3.11
with ``plotly<6``), else in this interpreter if it can import ``ross``; if neither can, the
ROSS columns are skipped. The reference values pinned in ``tests/test_geometry.py`` come from
this script (``--json``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from gear_env.io import atomic_write_text
from gear_env.sim.geometry import SpurPair

# (name, SpurPair keyword arguments); all SI
PAIRS: list[tuple[str, dict]] = [
    ("ROSS test 62/62", dict(module=2e-3, teeth=(62, 62), face_width=0.02, bore=(0.035, 0.035))),
    ("paper 55/75", dict(module=2e-3, teeth=(55, 75), face_width=0.0387, bore=(0.04, 0.05))),
    ("20/40 m3", dict(module=3e-3, teeth=(20, 40), face_width=0.025, bore=(0.02, 0.04))),
    ("31/47 m4 25deg", dict(module=4e-3, teeth=(31, 47), face_width=0.04, bore=(0.05, 0.08), pressure_angle_deg=25.0)),
    (
        "25/93 m1.5 aluminium",
        dict(
            module=1.5e-3,
            teeth=(25, 93),
            face_width=0.012,
            bore=(0.012, 0.05),
            youngs_modulus=70e9,
            poisson=0.33,
            density=2700.0,
        ),
    ),  # fmt: skip
    (
        "40/40 m5 c*=0.3",
        dict(module=5e-3, teeth=(40, 40), face_width=0.05, bore=(0.06, 0.06), tip_clearance_coeff=0.3),
    ),  # fmt: skip
]

# ROSS's grid: linspace(0, one mesh period, 1000); its last sample is the end of the period (the
# single-contact side of the jump), here phase 1 = phase 0 (double contact): take it just below 1
PHASES = np.linspace(0.0, 1.0, 1000)
PHASES[-1] = np.nextafter(1.0, 0.0)

_ROSS_CHILD = r"""
import json, sys, time
import numpy as np
from ross.materials import Material
from ross.multi_rotor.gear_element import GearElementTVMS
from ross.multi_rotor.mesh import Mesh
out = []
for kw in json.loads(sys.stdin.read()):
    mat = Material("m", rho=kw.get("density", 7810.0), E=kw.get("youngs_modulus", 206e9),
                   Poisson=kw.get("poisson", 0.3))
    t0 = time.perf_counter()
    gears = [GearElementTVMS(n=0, material=mat, width=kw["face_width"], bore_diameter=kw["bore"][i],
                             module=kw["module"], n_teeth=kw["teeth"][i],
                             pr_angle=np.radians(kw.get("pressure_angle_deg", 20.0)),
                             addendum_coeff=kw.get("addendum_coeff", 1.0),
                             tip_clearance_coeff=kw.get("tip_clearance_coeff", 0.25)) for i in range(2)]
    mesh = Mesh(gears[0], gears[1])
    dt = time.perf_counter() - t0
    out.append({"contact_ratio": float(mesh.contact_ratio), "hertzian": float(mesh.hertzian_stiffness),
                "k": [float(v) for v in mesh.stiffness_range], "seconds": dt,
                "mass": [g.m for g in gears], "Ip": [g.Ip for g in gears]})
print(json.dumps(out))
"""


def ross_python(cli: str | None) -> str | None:
    """The interpreter that can import ``ross`` (``cli``, ``$GEAR_ENV_ROSS_PYTHON``, this one), or None."""
    for exe in (cli, os.environ.get("GEAR_ENV_ROSS_PYTHON"), sys.executable):
        if not exe:
            continue
        probe = subprocess.run([exe, "-c", "import ross.multi_rotor.mesh"], capture_output=True, timeout=600)
        if probe.returncode == 0:
            return exe
    return None


def run_ross(exe: str, pairs: list[dict]) -> list[dict]:
    """ROSS's contact ratio, Hertzian stiffness and 1000-point waveform of each pair (one child process)."""
    res = subprocess.run([exe, "-c", _ROSS_CHILD], input=json.dumps(pairs), capture_output=True, text=True,
                         timeout=3600, check=True)  # fmt: skip
    return json.loads(res.stdout.strip().splitlines()[-1])


def ours(kw: dict) -> dict:
    """Our contact ratio, Hertzian stiffness, waveform and its time (best of 3)."""
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        pair = SpurPair(**kw)
        k = pair.mesh_stiffness(PHASES)
        best = min(best, time.perf_counter() - t0)
    return {
        "contact_ratio": pair.contact_ratio,
        "hertzian": pair.hertzian_stiffness,
        "k": k,
        "seconds": best,
        "mass": [pair.pinion.mass, pair.gear.mass],
        "Ip": [pair.pinion.polar_inertia, pair.gear.polar_inertia],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ross-python", default=None, help="a Python interpreter that can import ross")
    ap.add_argument("--json", default=None, help="write the values of both codes to this JSON file")
    args = ap.parse_args(argv)
    exe = ross_python(args.ross_python)
    ref = run_ross(exe, [kw for _, kw in PAIRS]) if exe else None
    if ref is None:
        print("ROSS not importable (give --ross-python or GEAR_ENV_ROSS_PYTHON): ROSS columns skipped")
    rows = []
    print(
        f"{'pair':22s} {'CR ours':>13s} {'dCR':>9s} {'max':>9s} {'min':>9s} {'mean':>9s}  {'ours s':>7s} {'ROSS s':>7s}"
    )
    for i, (name, kw) in enumerate(PAIRS):
        o = ours(kw)
        k = np.asarray(o["k"])
        row: dict = {"pair": name, "inputs": kw, "ours": {"contact_ratio": o["contact_ratio"],
                     "max": float(k.max()), "min": float(k.min()), "mean": float(k.mean()), "seconds": o["seconds"],
                     "first5": [float(v) for v in k[:5]]}}  # fmt: skip
        if ref is None:
            print(f"{name:22s} {o['contact_ratio']:13.10f} {'-':>9s} {k.max():9.3e} {k.min():9.3e} {k.mean():9.3e}"
                  f"  {o['seconds']:7.3f} {'-':>7s}")  # fmt: skip
        else:
            r = ref[i]
            kr = np.asarray(r["k"])
            row["ross"] = {"contact_ratio": r["contact_ratio"], "max": float(kr.max()), "min": float(kr.min()),
                           "mean": float(kr.mean()), "seconds": r["seconds"], "first5": r["k"][:5],
                           "hertzian": r["hertzian"], "mass": r["mass"], "Ip": r["Ip"]}  # fmt: skip
            rel = [k.max() / kr.max() - 1, k.min() / kr.min() - 1, k.mean() / kr.mean() - 1]
            print(f"{name:22s} {o['contact_ratio']:13.10f} {o['contact_ratio'] - r['contact_ratio']:9.1e} "
                  f"{rel[0]:+9.1e} {rel[1]:+9.1e} {rel[2]:+9.1e}  {o['seconds']:7.3f} {r['seconds']:7.2f}"
                  f"  (x{r['seconds'] / o['seconds']:.0f})")  # fmt: skip
        rows.append(row)
    if ref is not None:
        print("max/min/mean columns: ours / ROSS - 1")
    if args.json:
        atomic_write_text(args.json, json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
