"""``gear-env sweep``: a frequency sweep with motion classes, Lyapunov exponents and a bifurcation diagram."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep",
        help="sweep the meshing frequency: bifurcation diagram, motion classes, Lyapunov exponents",
        description="Sweep omega = Omega/omega_n over a uniform grid, warm-starting each point from the previous one.",
    )
    p.add_argument("--model", default="dynamic", choices=["constant", "dynamic"], help="backlash model")
    p.add_argument("--omega-min", type=float, default=0.05, help="lowest omega (default 0.05)")
    p.add_argument("--omega-max", type=float, default=3.0, help="highest omega (default 3)")
    p.add_argument("--points", type=int, default=300, help="grid points (default 300)")
    p.add_argument("--direction", default="forward", choices=["forward", "reverse"], help="sweep direction")
    p.add_argument("--transient", type=int, default=300, help="mesh periods discarded per omega (default 300)")
    p.add_argument("--periods", type=int, default=200, help="mesh periods recorded per omega (default 200)")
    p.add_argument(
        "--steps-per-period",
        type=int,
        default=None,
        help="Newmark steps per mesh period (default 192, more below omega 0.27)",
    )
    p.add_argument("--adaptive-steps", action="store_true", help="with --steps-per-period N: raise N below omega = 0.5")
    p.add_argument("--kappa", type=float, default=None, help="mesh-stiffness harmonic amplitude (default 0.2)")
    p.add_argument("--no-lyapunov", action="store_true", help="skip the Lyapunov exponents (about 30%% faster)")
    p.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1: serial)")
    p.add_argument("--executor", default=None, choices=["local", "dask"], help="local process pool or Dask")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--chunks", type=int, default=None, help="chunks of a parallel sweep (default 8 per worker)")
    p.add_argument(
        "--json", metavar="PATH", help="write omega, regime, amplitude_u, lyapunov, poincare_delta, ... as JSON"
    )
    p.add_argument("--out", metavar="PATH", help="write the full results as NetCDF (.nc)")
    p.add_argument("--plot", metavar="PATH", help="write the bifurcation diagram (PNG)")
    p.add_argument("--checkpoint", metavar="PATH", help="checkpoint file (default: <out>.ckpt.npz if --out is given)")
    p.add_argument("--resume", action="store_true", help="resume from the checkpoint instead of starting afresh")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import os

    import numpy as np

    from ..analysis import sweep
    from ..analysis.results import DRIFT_WARN
    from ..params import GearParams

    if args.points < 1:
        raise ValueError(f"--points must be >= 1, got {args.points}")
    if not (0 < args.omega_min <= args.omega_max):
        raise ValueError(f"need 0 < --omega-min <= --omega-max, got {args.omega_min} and {args.omega_max}")
    if args.executor == "dask" and not args.scheduler:
        raise ValueError("--executor dask needs --scheduler ADDRESS")
    for path in (args.json, args.out, args.plot):  # fail before the work, not after it
        if path:
            d = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(d):
                raise OSError(f"output folder {d!r} does not exist")
    ckpt = args.checkpoint or (f"{args.out}.ckpt.npz" if args.out else None)
    if args.resume and not ckpt:
        raise ValueError("--resume needs --checkpoint PATH or --out PATH")
    if ckpt and not args.resume and os.path.exists(ckpt):
        print(f"removing old checkpoint {ckpt} (use --resume to continue it)")
        os.unlink(ckpt)
    params = GearParams() if args.kappa is None else GearParams(kappa=args.kappa)
    omegas = np.linspace(args.omega_min, args.omega_max, args.points)
    res = sweep(
        omegas, model=args.model, direction=args.direction, transient=args.transient, periods=args.periods,
        params=params, steps_per_period=args.steps_per_period, lyapunov=not args.no_lyapunov,
        workers=args.workers, executor=args.executor, progress=not args.quiet, checkpoint=ckpt,
        scheduler=args.scheduler, chunks=args.chunks, adaptive_steps=args.adaptive_steps,
    )  # fmt: skip
    print(res.summary())
    for lo, hi, lab in res.intervals():
        print(f"  omega {lo:.4f} - {hi:.4f}: {lab}")
    late = res.unsettled()
    if late.size:
        shown = ", ".join(f"{w:.4f}" for w in late[:12]) + (", ..." if late.size > 12 else "")
        print(
            f"note: {late.size} point(s) still drifting at the end of their window (drift > {DRIFT_WARN:g}): "
            f"omega {shown}; their labels, and forward/reverse differences there, may be transients: "
            "rerun them with a longer --transient"
        )
    if args.out:
        res.save(args.out)
        print(f"wrote {args.out}")
    if args.json:
        res.to_json(args.json)
        print(f"wrote {args.json}")
    if args.plot:
        from ..plots.common import save_figure
        from ..plots.sweep import plot_bifurcation

        save_figure(plot_bifurcation(res), args.plot)
        print(f"wrote {args.plot}")
    return 0


__all__ = ["add_parser", "run"]
