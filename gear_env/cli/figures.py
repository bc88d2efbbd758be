"""``gear-env figures``: regenerate the paper's figures (5-11) and the stability map for both models.

Files written to ``--out`` (PNG):

====================================  ================================================================
fig05_backlash.png                    B_d time histories at omega = 1, 2, 3 (both models; constant = B_c)
fig06_meshing_angle.png               psi time histories at omega = 1, 2, 3 (both models)
fig06b_meshing_angle_friction.png     the same, dynamic model with the tooth-friction extension (mu = 0.05)
fig07_amplitude_frequency.png         amplitudes of B_d and psi vs omega, forward and reverse (dynamic)
fig08_phase_<model>.png               phase portraits and Poincare maps at omega = 1, 2, 3
fig09_amplitude.png                   amplitude of U vs omega, both models (forward sweep)
fig10_waterfall_<model>.png           3-D amplitude spectrum of Delta over omega
fig11_bifurcation.png                 Poincare samples of Delta over omega, both models
fig12_stability_<model>.png           max |Floquet multiplier|, critical angle, Lyapunov exponent
summary.json                          the numbers behind the figures (intervals, regimes)
====================================  ================================================================
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .common import writes

MODELS = ("constant", "dynamic")
EXTENSION_FRICTION = 0.05
"""Tooth friction coefficient of the psi-fluctuation extension figure (fig06b)."""


@dataclass(frozen=True)
class FigureSettings:
    """Grids and run lengths of ``gear-env figures`` (``quick`` for a smoke test in seconds)."""

    omega_min: float = 0.05
    omega_max: float = 3.0
    points: int = 296
    transient: int = 300
    periods: int = 100
    steps_per_period: int | None = None  # None: default_steps_per_period(omega)
    waterfall_points: int = 59
    waterfall_periods: int = 64
    history_periods: int = 30
    lyapunov: bool = True
    stability_points: int = 296

    @classmethod
    def quick(cls) -> FigureSettings:
        return cls(
            points=10,
            transient=20,
            periods=8,
            steps_per_period=32,
            waterfall_points=4,
            waterfall_periods=8,
            history_periods=4,
            lyapunov=False,
            stability_points=10,
        )


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "figures",
        help="regenerate the paper's figures and the stability map",
        description="Regenerate Figs. 5-11 of the paper and the Floquet stability map for both backlash models.",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument("--quick", action="store_true", help="coarse grids and short runs (a smoke test, seconds)")
    p.add_argument("--workers", type=int, default=1, help="worker processes for the sweeps (default 1)")
    p.add_argument("--points", type=int, default=None, help="omega grid points of the sweeps (default 296)")
    p.add_argument("--gravity", type=float, default=0.0, help="gravity [m/s^2] (default 0, the paper's model)")
    p.add_argument(
        "--friction", type=float, default=0.0, help="tooth friction coefficient for all figures (default 0, the paper)"
    )
    p.add_argument("--dpi", type=int, default=110, help="PNG resolution (default 110)")
    p.set_defaults(func=run)


def _log(msg: str, t0: float) -> None:
    print(f"[{time.time() - t0:6.1f} s] {msg}", flush=True)


def generate_figures(
    out: str,
    settings: FigureSettings | None = None,
    workers: int = 1,
    params: Any = None,
    verbose: bool = True,
    dpi: int = 110,
) -> dict[str, Any]:
    """Compute everything and write the PNGs into ``out``; returns the summary dict (also saved as
    ``summary.json``)."""
    from ..analysis import sweep
    from ..analysis.spectrum import waterfall
    from ..analysis.stability import stability_map
    from ..io import atomic_write_text
    from ..plots import analysis as pa
    from ..plots.common import save_figure
    from ..sim.params import GearParams
    from ..sim.simulator import simulate

    s = settings or FigureSettings()
    p = params if params is not None else GearParams()
    os.makedirs(out, exist_ok=True)
    t0 = time.time()
    written: list[str] = []

    def save(fig: Any, name: str) -> None:
        path = os.path.join(out, name)
        save_figure(fig, path, dpi=dpi)
        written.append(path)
        if verbose:
            _log(f"wrote {path}", t0)

    grid = np.linspace(s.omega_min, s.omega_max, s.points)
    common = dict(
        transient=s.transient, periods=s.periods, params=p, steps_per_period=s.steps_per_period, workers=workers
    )
    summary: dict[str, Any] = {"settings": s.__dict__, "params": p.to_dict(), "models": {}}

    # time histories at omega = 1, 2, 3 (Figs. 5, 6, 8)
    runs: dict[str, dict[float, Any]] = {m: {} for m in MODELS}
    for m in MODELS:
        for w in (1.0, 2.0, 3.0):
            runs[m][w] = simulate(w, m, s.history_periods * 10, s.transient, s.steps_per_period, p)
    save(pa.plot_time_histories(runs, "bd", periods=s.history_periods), "fig05_backlash.png")
    save(pa.plot_time_histories(runs, "psi", periods=s.history_periods), "fig06_meshing_angle.png")
    if p.friction == 0.0:  # the documented extension that makes psi fluctuate (docs/RESULTS.md)
        pf = p.replace(friction=EXTENSION_FRICTION)
        fr = {w: simulate(w, "dynamic", s.history_periods * 10, s.transient, s.steps_per_period, pf) for w in (1, 2, 3)}
        lab = f"dynamic backlash, tooth friction $\\mu$ = {EXTENSION_FRICTION:g}"
        fig = pa.plot_time_histories({lab: fr}, "psi", s.history_periods)
        save(fig, "fig06b_meshing_angle_friction.png")
    for m in MODELS:
        save(pa.plot_phase_portraits(runs[m], title=f"{m} backlash"), f"fig08_phase_{m}.png")

    # sweeps (Figs. 7, 9, 11, 12)
    fwd: dict[str, Any] = {}
    for m in MODELS:
        if verbose:
            _log(f"forward sweep, {m} model, {len(grid)} points", t0)
        fwd[m] = sweep(grid, m, "forward", lyapunov=s.lyapunov, progress=False, **common)
    if verbose:
        _log("reverse sweep, dynamic model", t0)
    rev = sweep(grid, "dynamic", "reverse", lyapunov=False, progress=False, **common)
    save(
        pa.plot_amplitude_frequency({"forward": fwd["dynamic"], "reverse": rev}, ("bd", "psi")),
        "fig07_amplitude_frequency.png",
    )
    save(pa.plot_amplitude_vs_omega(fwd, "U"), "fig09_amplitude.png")
    save(pa.plot_bifurcation({f"{m} backlash": fwd[m] for m in MODELS}), "fig11_bifurcation.png")

    # waterfall (Fig. 10)
    wgrid = np.linspace(max(s.omega_min, 0.1), s.omega_max, s.waterfall_points)
    for m in MODELS:
        wf = waterfall(wgrid, m, "delta", s.waterfall_periods, s.transient, p, s.steps_per_period, max_multiple=3.0)
        save(pa.plot_waterfall(wf, title=f"{m} backlash: spectrum of $\\Delta$"), f"fig10_waterfall_{m}.png")

    # Floquet stability map with the Lyapunov exponent (the figure the paper lacks)
    for m in MODELS:
        sm = stability_map(m, p, s.omega_min, s.omega_max, s.stability_points, s.steps_per_period)
        save(pa.plot_stability_map(sm, fwd[m] if s.lyapunov else None), f"fig12_stability_{m}.png")
        regimes = fwd[m].regime
        summary["models"][m] = {
            "stability_intervals": [list(t) for t in sm.intervals()],
            "bifurcations": [list(t) for t in sm.bifurcations()],
            "forward_regimes": _regime_runs(fwd[m].omega, regimes),
        }
    summary["models"]["dynamic"]["reverse_regimes"] = _regime_runs(rev.omega, rev.regime)
    summary["files"] = [os.path.basename(f) for f in written]
    atomic_write_text(os.path.join(out, "summary.json"), json.dumps(summary, indent=1))
    if verbose:
        _log(f"done: {len(written)} figures and summary.json in {out}", t0)
    return summary


def _regime_runs(omega: Any, regime: Any) -> list[list[Any]]:
    """Compress per-omega labels into [omega_first, omega_last, label] runs (sorted by omega)."""
    w = np.asarray(omega, dtype=float)
    o = np.argsort(w, kind="stable")
    out: list[list[Any]] = []
    for i in o:
        lab = str(regime[i])
        if out and out[-1][2] == lab:
            out[-1][1] = float(w[i])
        else:
            out.append([float(w[i]), float(w[i]), lab])
    return out


@writes(folders=("out",))
def run(args: argparse.Namespace) -> int:
    from ..sim.params import GearParams

    s = FigureSettings.quick() if args.quick else FigureSettings()
    if args.points is not None:
        if args.points < 2:
            raise ValueError(f"--points must be an integer >= 2, got {args.points}")
        s = FigureSettings(**{**s.__dict__, "points": args.points})
    if args.workers < 1:
        raise ValueError(f"--workers must be an integer >= 1, got {args.workers}")
    if not 10 <= args.dpi <= 600:
        raise ValueError(f"--dpi must be in [10, 600], got {args.dpi}")
    generate_figures(args.out, s, args.workers, GearParams(gravity=args.gravity, friction=args.friction), dpi=args.dpi)
    return 0


__all__ = ["FigureSettings", "add_parser", "generate_figures", "run"]
