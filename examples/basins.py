"""How robust is a quiet motion where two steady motions coexist? A basin map in one SIMD call.

    python examples/basins.py                        # omega = 2.41, dynamic model, 24 x 24 starts
    python examples/basins.py --plot basins.png      # and the basin map
    python examples/basins.py --quick                # 8 x 8 starts, short runs (seconds)

Forward and reverse sweeps differ (hysteresis) where two attractors coexist. With 4,000 mesh
periods per point the dynamic model's band is omega ~2.40-2.42 (docs/RESULTS.md, "Hysteresis and
dwell time"): a quiet period-1 motion (U amplitude 0.03 b0, the reverse sweep's branch) and the
loud torus (0.16 b0, reached from the static equilibrium A10). This script settles both, then
starts a grid of systems from the quiet motion's Poincare point displaced in (U, U') by up to
``--span`` b0 and runs them all with ``simulate_batch(..., initial_states=...)``, every start an
independent system stepped together with the others. A start counts as quiet if its final U
amplitude (the paper's half peak-to-peak, b0 units) is below the geometric mean of the two
attractors' amplitudes. With the defaults (AMD VM, ~13 s) 67 % of the starts within 0.0125 b0
stay quiet, 33 % within 0.025 b0 and 9 % within 0.05 b0: just above the stability boundary of
period-1 the quiet motion's basin is thin, a band about +/-0.03 b0 wide in U and +/-0.008 in U',
so a small disturbance sends the gears to the loud motion. (The Floquet map with located contact
changes puts that boundary at 2.4131, so at 2.41 the period-1 orbit is in fact weakly unstable,
|mu| = 1.00014: over the 3,000-period window the map shows a slow escape from a marginal orbit.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gear_env import GearSimulator, simulate_batch
from gear_env.analysis.classify import classify_motion


def follow(model: str, start: float, omega: float, step: float, periods: int) -> GearSimulator:
    """A simulator brought to ``omega`` by continuation from ``start`` in steps of ``step``."""
    n = max(1, round(abs(start - omega) / step))
    sim = GearSimulator(model=model, omega=start)
    for w in np.linspace(start, omega, n + 1):
        sim.omega = float(w)
        sim.advance(periods)
    return sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--omega", type=float, default=2.41)
    ap.add_argument("--model", default="dynamic", choices=["constant", "dynamic"])
    ap.add_argument("--approach", type=float, default=2.6, help="continuation start of the quiet motion (default 2.6)")
    ap.add_argument("--span", type=float, default=0.05, help="largest displacement of U and U' [b0] (default 0.05)")
    ap.add_argument("--grid", type=int, default=24, help="starts per axis (default 24)")
    ap.add_argument("--settle", type=int, default=3000, help="mesh periods before a motion is judged (default 3000)")
    ap.add_argument("--quick", action="store_true", help="8 x 8 starts, 500 settling periods")
    ap.add_argument("--plot", metavar="PNG", help="write the basin map")
    args = ap.parse_args()
    n, settle = (8, 500) if args.quick else (args.grid, args.settle)
    periods = 100

    # the two motions: by continuation (as a reverse sweep) and from the static equilibrium
    sim = follow(args.model, args.approach, args.omega, 0.02, 200)
    sim.advance(settle)
    anchor = sim.state
    refs = {"quiet": sim.advance(periods), "loud": simulate_batch(args.omega, args.model, periods, settle)[0]}
    amps = {name: st.amplitude("U") for name, st in refs.items()}
    print(f"omega = {args.omega}, {args.model} model, after {settle} mesh periods:")
    print(f"  by continuation from {args.approach}: U amplitude {amps['quiet']:.3f} b0, "
          f"{classify_motion(refs['quiet'].poincare[:, :10]).label}")  # fmt: skip
    print(f"  from the static equilibrium: U amplitude {amps['loud']:.3f} b0, "
          f"{classify_motion(refs['loud'].poincare[:, :10]).label}")  # fmt: skip
    if not amps["loud"] > 1.2 * amps["quiet"]:
        print("the two starts end on motions of about the same size: no coexisting quiet motion here")
        return

    d = np.linspace(-args.span, args.span, n)
    starts = np.repeat(anchor[None, :], n * n, axis=0)
    starts[:, 4] += np.repeat(d, n)  # U
    starts[:, 9] += np.tile(d, n)  # U'
    t = time.perf_counter()
    runs = simulate_batch(args.omega, args.model, periods, settle, initial_states=starts)
    print(f"{n * n} starts of {settle} + {periods} mesh periods in {time.perf_counter() - t:.1f} s (SIMD batch)")
    cut = float(np.sqrt(amps["quiet"] * amps["loud"]))
    quiet = np.array([r.amplitude("U") < cut for r in runs])
    print(f"\n| starts within | stay quiet (U amplitude < {cut:.3f} b0) |")
    print("|---|---:|")
    for frac in (0.25, 0.5, 1.0):
        near = (np.abs(starts[:, 4] - anchor[4]) <= frac * args.span + 1e-12) & (
            np.abs(starts[:, 9] - anchor[9]) <= frac * args.span + 1e-12
        )
        print(f"| {frac * args.span:g} b0 in U and U' ({near.sum()} starts) | {quiet[near].mean():.1%} |")

    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from gear_env.io import atomic_write

        img = quiet.reshape(n, n).T.astype(float)  # rows: U', columns: U
        fig, ax = plt.subplots(figsize=(5.2, 4.4))
        ext = [anchor[4] - args.span, anchor[4] + args.span, anchor[9] - args.span, anchor[9] + args.span]
        ax.imshow(img, origin="lower", extent=ext, aspect="auto", cmap="coolwarm_r", vmin=0, vmax=1)
        ax.plot(anchor[4], anchor[9], "k+", ms=10, label="Poincaré point of the quiet motion")
        ax.set_xlabel("$U$ at the start [$b_0$]")
        ax.set_ylabel("$dU/ds$ at the start [$b_0$],  $s = \\omega_n t$")
        ax.set_title(
            f"$\\omega$ = {args.omega}, after {settle} mesh periods: blue = stays quiet "
            f"(amplitude of $U$ {amps['quiet']:.3f} $b_0$),\nred = ends on the loud motion ({amps['loud']:.2f} $b_0$)",
            fontsize=8,
        )
        ax.legend(fontsize=7, loc="upper right")
        fig.tight_layout()
        atomic_write(args.plot, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
