"""``gear-env sweep``: a frequency sweep with motion classes, Lyapunov exponents and a bifurcation diagram."""

from __future__ import annotations

import argparse

from .common import add_model_options, check_memory, check_outputs, float_range, int_range, params_from_args

MAX_POINTS = 1_000_000
"""Upper bound of ``--points`` (the memory estimate may bind first)."""
MAX_PERIODS = 1_000_000
"""Upper bound of ``--transient`` and ``--periods`` per point."""
MAX_WORKERS = 1024
"""Upper bound of ``--workers``."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep",
        help="sweep the meshing frequency: bifurcation diagram, motion classes, Lyapunov exponents",
        description="Sweep omega = Omega/omega_n over a uniform grid, warm-starting each point from the previous one.",
    )
    p.add_argument(
        "--omega-min", type=float_range(0.0, 1e3, lo_open=True), default=0.05, help="lowest omega (default 0.05)"
    )
    p.add_argument(
        "--omega-max", type=float_range(0.0, 1e3, lo_open=True), default=3.0, help="highest omega (default 3)"
    )
    p.add_argument(
        "--points", type=int_range(1, MAX_POINTS), default=300, help=f"grid points, 1-{MAX_POINTS} (default 300)"
    )
    p.add_argument("--direction", default="forward", choices=["forward", "reverse"], help="sweep direction")
    p.add_argument(
        "--transient",
        type=int_range(1, MAX_PERIODS),
        default=300,
        help="mesh periods discarded per omega (default 300)",
    )
    p.add_argument(
        "--periods", type=int_range(4, MAX_PERIODS), default=200, help="mesh periods recorded per omega (default 200)"
    )
    add_model_options(p)
    p.add_argument("--adaptive-steps", action="store_true", help="with --steps-per-period N: raise N below omega = 0.5")
    p.add_argument("--no-lyapunov", action="store_true", help="skip the Lyapunov exponents (about 30%% faster)")
    p.add_argument(
        "--workers",
        type=int_range(1, MAX_WORKERS),
        default=1,
        help=f"parallel worker processes, 1-{MAX_WORKERS} (default 1: serial)",
    )
    p.add_argument("--executor", default=None, choices=["local", "dask"], help="local process pool or Dask")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument(
        "--chunks",
        type=int_range(1, MAX_POINTS),
        default=None,
        help="chunks of a parallel sweep (default 8 per worker)",
    )
    p.add_argument(
        "--json", metavar="PATH", help="write omega, regime, amplitude_u, lyapunov, poincare_delta, ... as JSON"
    )
    p.add_argument("--out", metavar="PATH", help="write the full results as NetCDF (.nc)")
    p.add_argument("--plot", metavar="PATH", help="write the bifurcation diagram (PNG)")
    p.add_argument("--checkpoint", metavar="PATH", help="checkpoint file (default: <out>.ckpt.npz if --out is given)")
    p.add_argument("--resume", action="store_true", help="continue the finished points of the checkpoint")
    p.add_argument(
        "--restart",
        action="store_true",
        help="discard an existing checkpoint (its finished points are lost) and start afresh",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import os
    from contextlib import ExitStack

    import numpy as np

    from ..analysis import sweep
    from ..analysis.results import DRIFT_WARN
    from ..io import OutputLock
    from .common import sweep_bytes

    if not args.omega_min <= args.omega_max:
        raise ValueError(f"need --omega-min <= --omega-max, got {args.omega_min} and {args.omega_max}")
    if args.executor == "dask" and not args.scheduler:
        raise ValueError("--executor dask needs --scheduler ADDRESS")
    if args.resume and args.restart:
        raise ValueError("--resume and --restart exclude each other")
    ckpt = args.checkpoint or (f"{args.out}.ckpt.npz" if args.out else None)
    if args.resume and not ckpt:
        raise ValueError("--resume needs --checkpoint PATH or --out PATH")
    args.checkpoint = ckpt
    check_outputs(args, ("out", "json", "plot", "checkpoint"), ("params", "pair"))  # before the work, not after it
    params = params_from_args(args)
    check_memory(sweep_bytes(args.points, args.periods), f"--points {args.points} with --periods {args.periods}")
    with ExitStack() as locks:
        # one sweep per output at a time: a second one with the same --out (or checkpoint) is refused
        for name in ("checkpoint", "out", "json", "plot"):
            path = getattr(args, name)
            if path:
                locks.enter_context(OutputLock(path, f"--{name}"))
        if ckpt and os.path.exists(ckpt) and not args.resume:
            if not args.restart:
                raise ValueError(
                    f"checkpoint {ckpt!r} holds the finished points of an earlier sweep; continue it with --resume, "
                    "or discard it with --restart"
                )
            print(f"--restart: removing the old checkpoint {ckpt}")
            os.unlink(ckpt)
        omegas = np.linspace(args.omega_min, args.omega_max, args.points)
        res = sweep(
            omegas, model=args.model, direction=args.direction, transient=args.transient, periods=args.periods,
            params=params, steps_per_period=args.steps_per_period, lyapunov=not args.no_lyapunov,
            workers=args.workers, executor=args.executor, progress=not args.quiet, checkpoint=ckpt,
            scheduler=args.scheduler, chunks=args.chunks, adaptive_steps=args.adaptive_steps,
            keep_checkpoint=True,
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
        try:
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
        except BaseException:
            if ckpt:
                print(
                    f"the results could not all be written; every point is kept in {ckpt}: "
                    "rerun the same command with --resume to write them without recomputing",
                    flush=True,
                )
            raise
        if ckpt and os.path.exists(ckpt):  # every result is saved: the checkpoint has served
            os.unlink(ckpt)
    return 0


__all__ = ["add_parser", "run"]
