"""What changes when the mesh stiffness comes from the teeth instead of one cosine (docs/GEOMETRY.md).

    python examples/geometry_study.py --out docs/figures        # ~3-6 min on 1 core
    python examples/geometry_study.py --quick --out /tmp/geo    # coarse grids, under a minute

The paper's pair (55/75 teeth, module 2 mm, 20 deg) with bores 40/50 mm at the face width that
gives the paper's k_m0 = 7.74e8 N/m (37.85 mm), Table 1's masses and inertias, so omega_n and the
dimensionless axes are those of every other result; two excitations:

* ``cosine``: the default k_m0 (1 + 0.2 cos phi) (MODEL.md's kappa = 0.2);
* ``teeth``: the potential-energy waveform of ``gear_env.sim.geometry`` as 16 harmonics.

It writes three figures into ``--out``:

* ``geometry_waveform.png``: the healthy waveform over three mesh periods, its 16-harmonic series,
  the cosine, and the waveform with a 1.5 mm crack (45 deg) on pinion tooth 0;
* ``geometry_bifurcation.png``: forward sweeps of the dynamic model, one panel per excitation;
* ``geometry_amplitude.png``: the U amplitude of both sweeps against omega;

and prints the period-1 stability windows (Floquet maps), the non-period-1 bands of the sweeps,
the omegas where the teeth's amplitude exceeds the cosine's by a factor > 2, and the U amplitudes
of both at the superharmonic resonances of the mesh mode (omega = w_mode / n, driven by the n-th
stiffness harmonic) and between them, with Table 1's TE and with a 100x smaller one.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from gear_env import GearParams, simulate
from gear_env.analysis.stability import stability_map
from gear_env.analysis.sweep import sweep
from gear_env.plots.analysis import plot_bifurcation
from gear_env.plots.common import new_figure, save_figure
from gear_env.sim.geometry import SpurPair, ToothCrack
from gear_env.sim.linear import natural_frequencies

PAIR = dict(module=2e-3, teeth=(55, 75), face_width=0.03785, bore=(0.04, 0.05))
TABLE1 = dict(J_p=0.041, J_g=0.079, m_p=1.53, m_g=3.01)


def excitations() -> dict[str, GearParams]:
    """The two parameter sets compared (the same pair, two stiffness excitations)."""
    pair = SpurPair(**PAIR)
    return {"cosine": GearParams(), "teeth": GearParams.from_pair(pair, 16, **TABLE1)}


def waveform_figure(path: str) -> None:
    pair = SpurPair(**PAIR)
    cracked = SpurPair(**PAIR, crack=ToothCrack(depth=1.5e-3, angle_deg=45.0, on="pinion"))
    geo = excitations()["teeth"]
    x = np.linspace(0.0, 3.0, 3000, endpoint=False)
    fig = new_figure(9, 4)
    ax = fig.subplots()
    ax.plot(x, pair.mesh_stiffness(x) / 1e8, color="k", lw=1.5, label="healthy teeth (potential energy)")
    ax.plot(x, cracked.mesh_stiffness(x) / 1e8, color="tab:red", lw=1, label="1.5 mm crack (45 deg) on pinion tooth 0")
    ax.plot(x, geo.k_m0 * geo.stiffness_factor(2 * np.pi * x) / 1e8, color="tab:blue", lw=0.8, ls="--",
            label="16 harmonics (the kernels' input)")  # fmt: skip
    ax.plot(x, 7.74 * (1 + 0.2 * np.cos(2 * np.pi * x)), color="tab:green", lw=1, label="k_m0 (1 + 0.2 cos phi)")
    ax.set_xlabel("mesh phase [mesh periods]; 0 = a tooth pair enters contact")
    ax.set_ylabel("mesh stiffness [1e8 N/m]")
    ax.set_title("55/75, m 2 mm, 20 deg, b 37.85 mm, bores 40/50 mm (mean 7.74e8 N/m)", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/figures", help="folder for the three PNG files")
    ap.add_argument("--quick", action="store_true", help="coarse grids (a smoke run)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    waveform_figure(os.path.join(args.out, "geometry_waveform.png"))
    ex = excitations()
    pair = SpurPair(**PAIR)
    k0, kap, _ = pair.stiffness_harmonics(6)
    print(f"teeth: k_m0 = {k0:.4e} N/m, kappa_1..6 = {', '.join(f'{v:.3f}' for v in kap)}")
    print("natural frequencies (constant model, w/omega_n):",
          ", ".join(f"{w:.3f}" for w in natural_frequencies(ex["teeth"], "constant")))  # fmt: skip
    points, transient, periods = (60, 100, 60) if args.quick else (300, 300, 200)
    omegas = np.linspace(0.05, 3.0, points)
    sweeps = {}
    for name, p in ex.items():
        m = stability_map("dynamic", p, points=points, cache=False, progress=None)
        print(f"{name:6s} period-1 stable (dynamic, Floquet): "
              + ", ".join(f"[{lo:.3f}, {hi:.3f}]" for lo, hi in m.stable_intervals()))  # fmt: skip
        sw = sweep(omegas, "dynamic", params=p, transient=transient, periods=periods, progress=False)
        sweeps[name] = sw
        bands = [(lo, hi, lab) for lo, hi, lab in sw.intervals() if lab != "period-1"]
        print(f"{name:6s} sweep: {sw.summary()}")
        print(f"{name:6s} non-period-1 bands: " + "; ".join(f"{lab} [{lo:.3f}, {hi:.3f}]" for lo, hi, lab in bands))
    fig = plot_bifurcation({f"{k}: dynamic backlash, forward sweep": v for k, v in sweeps.items()})
    save_figure(fig, os.path.join(args.out, "geometry_bifurcation.png"))
    amp = {k: np.asarray(sw.amplitude["U"]) for k, sw in sweeps.items()}  # half peak-to-peak of U
    fig = new_figure(9, 4)
    ax = fig.subplots()
    for k, a in amp.items():
        ax.semilogy(omegas, np.maximum(a, 1e-6), label=k)
    ax.set_xlabel("omega = Omega / omega_n")
    ax.set_ylabel("U amplitude (half peak-to-peak) [b0]")
    ax.legend()
    save_figure(fig, os.path.join(args.out, "geometry_amplitude.png"))
    ratio = amp["teeth"] / np.maximum(amp["cosine"], 1e-9)
    hot = omegas[ratio > 2.0]
    print("teeth/cosine amplitude ratio > 2 at omega:", ", ".join(f"{w:.3f}" for w in hot) or "none")
    # superharmonic resonances: the n-th stiffness harmonic drives the mesh mode at omega = w_mode / n;
    # with Table 1's TE (E1 = 0.5 b0) the TE dominates the forcing, so also with a 100x smaller TE
    w_mode = natural_frequencies(ex["teeth"], "constant")[-1]
    for scale in (1.0, 0.01):
        for w in (w_mode / 4, w_mode / 3, 1.2, w_mode / 2, 2.0):
            a = {k: simulate(w, "dynamic", periods=100, transient=transient, params=p.with_te_scale(scale))
                 .amplitude("U") for k, p in ex.items()}  # fmt: skip
            print(f"TE x{scale:g}, omega {w:.3f}: U amplitude cosine {a['cosine']:.2e}, teeth {a['teeth']:.2e} b0 "
                  f"(x{a['teeth'] / a['cosine']:.2f})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
