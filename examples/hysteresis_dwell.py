"""Is a forward/reverse sweep difference a coexistence of attractors or a transient? Vary the dwell.

    python examples/hysteresis_dwell.py            # both models, both torus edges, dwell 300/4000/12000 (~1 min)
    python examples/hysteresis_dwell.py --quick    # one band, short dwells (seconds)

A continuation sweep spends ``transient`` mesh periods at each omega before it records. Near a
bifurcation transients decay slowly, so a forward and a reverse sweep can differ only because the
dwell is too short. This script sweeps the torus onset (omega 1.55-1.75) and end (2.30-2.50) on a
0.01 grid in both directions with growing dwells and prints where the U amplitudes of the two
directions differ by more than 20 %. Then it holds the torus branch (continuation from 2.25) at a
few omegas near its end for 200,000 mesh periods and prints the U amplitude (half peak-to-peak,
b0 units) over three windows: a persistent torus beside the stable period-1 orbit is bistability;
one that collapses onto the orbit was a transient. The tables are those of docs/RESULTS.md,
"Hysteresis and dwell time".
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gear_env import GearSimulator
from gear_env.analysis.sweep import sweep


def hysteresis(model: str, omegas: np.ndarray, dwell: int, periods: int = 200, rel: float = 0.2) -> list[float]:
    """Omegas where the forward and reverse sweeps' U amplitudes differ by more than ``rel``."""
    amp = {}
    for d in ("forward", "reverse"):
        r = sweep(omegas, model=model, direction=d, transient=dwell, periods=periods, lyapunov=False, progress=False)
        amp[d] = np.asarray(r.amplitude["U"])
    diff = np.abs(amp["forward"] - amp["reverse"]) > rel * np.minimum(amp["forward"], amp["reverse"])
    return [float(w) for w in omegas[diff]]


def hold(model: str, omega: float, windows: int, window: int, start: float = 2.25) -> list[float]:
    """U amplitude over consecutive windows of ``window`` mesh periods at ``omega``, reached by
    continuation from ``start`` in steps of 0.01 (300 periods each)."""
    sim = GearSimulator(model=model, omega=start)
    for w in np.linspace(start, omega, max(1, round(abs(omega - start) / 0.01)) + 1):
        sim.omega = float(w)
        sim.advance(300)
    return [sim.advance(window).amplitude("U") for _ in range(windows)]


def fmt(ws: list[float]) -> str:
    """A list of grid omegas as contiguous ranges, e.g. '2.36-2.45, 2.5'."""
    if not ws:
        return "none"
    out, lo, prev = [], ws[0], ws[0]
    for w in [*ws[1:], None]:
        if w is not None and abs(w - prev - 0.01) < 1e-6:
            prev = w
            continue
        out.append(f"{lo:g}" if lo == prev else f"{lo:g}-{prev:g}")
        if w is not None:
            lo = prev = w
    return ", ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="dynamic model, torus end, dwell 300 and 2000, short hold")
    args = ap.parse_args()
    t0 = time.perf_counter()
    models = ("dynamic",) if args.quick else ("constant", "dynamic")
    bands = {"torus end": (2.30, 2.50)} if args.quick else {"torus onset": (1.55, 1.75), "torus end": (2.30, 2.50)}
    dwells = (300, 2000) if args.quick else (300, 4000, 12000)
    print("| band | model | " + " | ".join(f"{d:,} periods per point" for d in dwells) + " |")
    print("|---|---|" + "---|" * len(dwells))
    for band, (lo, hi) in bands.items():
        omegas = np.round(np.arange(lo, hi + 1e-9, 0.01), 3)
        for model in models:
            cells = [fmt(hysteresis(model, omegas, d)) for d in dwells]
            print(f"| {band} | {model} | " + " | ".join(cells) + " |", flush=True)

    windows, window = (4, 500) if args.quick else (40, 5000)
    runs = [("dynamic", 2.41)] if args.quick else [("dynamic", 2.41), ("dynamic", 2.415), ("constant", 2.42)]
    picks = (0, 1, windows - 1) if args.quick else (0, 4, windows - 1)
    heads = " / ".join(f"{i * window:,}-{(i + 1) * window:,}" for i in picks)
    print(f"\n| model, omega | U amplitude [b0] over mesh periods {heads} |")
    print("|---|---|")
    for model, w in runs:
        amps = hold(model, w, windows, window)
        print(f"| {model}, {w:.3f} | " + " / ".join(f"{amps[i]:.3f}" for i in picks) + " |", flush=True)
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
