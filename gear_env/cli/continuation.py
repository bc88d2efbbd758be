"""``gear-env continuation``: branches of periodic orbits over omega, their bifurcations, and the
frequency-response figure."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

from .common import add_params_options, params_from_args, writes


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "continuation",
        help="pseudo-arclength continuation of periodic orbits over omega, with bifurcations",
        description=(
            "Follow the period-1 orbit over [omega-min, omega-max] by pseudo-arclength continuation "
            "(through folds, unstable parts kept), locate folds, period-doubling, Neimark-Sacker and "
            "grazing points, and switch onto the period-doubled branches. Writes the branches and "
            "bifurcations as JSON and, with --plot, the frequency-response curves."
        ),
    )
    p.add_argument("--model", default="dynamic", choices=["constant", "dynamic", "both"], help="backlash model")
    p.add_argument("--omega-min", type=float, default=0.05, help="lowest omega (default 0.05)")
    p.add_argument("--omega-max", type=float, default=3.0, help="highest omega (default 3.0)")
    p.add_argument("--json", metavar="PATH", help="write branches and bifurcations as JSON")
    p.add_argument("--plot", metavar="PATH", help="write the frequency-response figure (PNG)")
    p.add_argument(
        "--max-period",
        type=int,
        default=8,
        help="follow a period-doubling cascade up to orbits of this period (8); a period doubling beyond it is "
        "reported as a note, and the run still exits 0",
    )
    p.add_argument("--max-switches", type=int, default=8, help="at most this many branch switches per model (8)")
    p.add_argument("--tol", type=float, default=1e-9, help="Newton tolerance on |P^N(x) - x| (1e-9)")
    p.add_argument("--ds-max", type=float, default=0.04, help="largest arclength step (0.04)")
    p.add_argument("--time-limit", type=float, default=None, help="seconds per model; stop at the last point then")
    add_params_options(p)
    p.add_argument(
        "--sweep-points",
        type=int,
        default=0,
        help="also run a forward sweep on this many omegas and draw its amplitudes under the branches (0: none)",
    )
    p.add_argument(
        "--unlocated",
        action="store_true",
        help="continue on the unlocated discrete map (contact changes inside a step; multipliers from the "
        "crossing-corrected tangent), as 0.4.0 did; default: contact changes located inside the step",
    )
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=run)


def _check_args(args: argparse.Namespace) -> None:
    """Validate the arguments before any work; messages name the option."""

    def finite_pos(v: Any, name: str) -> None:
        if v is None or not math.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")

    finite_pos(args.omega_min, "--omega-min")
    finite_pos(args.omega_max, "--omega-max")
    if not 1e-3 <= args.omega_min < args.omega_max <= 100:
        raise ValueError(
            f"--omega-min and --omega-max must satisfy 0.001 <= omega-min < omega-max <= 100, "
            f"got {args.omega_min!r} and {args.omega_max!r}"
        )
    if not 1 <= args.max_period <= 256:
        raise ValueError(f"--max-period must be an integer in [1, 256], got {args.max_period!r}")
    if not 0 <= args.max_switches <= 1000:
        raise ValueError(f"--max-switches must be an integer in [0, 1000], got {args.max_switches!r}")
    finite_pos(args.tol, "--tol")
    if args.tol > 1e-4:
        raise ValueError(f"--tol must be in (0, 1e-4], got {args.tol!r}")
    finite_pos(args.ds_max, "--ds-max")
    if args.ds_max > 1:
        raise ValueError(f"--ds-max must be in (0, 1], got {args.ds_max!r}")
    if args.ds_max < 0.01:
        raise ValueError(f"--ds-max must be >= 0.01 (the initial step), got {args.ds_max!r}")
    if args.time_limit is not None:
        finite_pos(args.time_limit, "--time-limit")
    if args.sweep_points < 0 or args.sweep_points > 100_000:
        raise ValueError(f"--sweep-points must be an integer in [0, 100000], got {args.sweep_points!r}")
    outs = [(n, v) for n, v in (("--json", args.json), ("--plot", args.plot)) if v]
    for name, path in outs:
        pth = Path(path)
        if pth.exists() and not pth.is_file():
            raise ValueError(f"{name} {path!r} exists and is not a regular file")
        if not pth.parent.exists() and str(pth.parent):
            raise ValueError(f"{name}: folder {str(pth.parent)!r} does not exist")
    if len(outs) == 2 and os.path.abspath(args.json) == os.path.abspath(args.plot):
        raise ValueError("--json and --plot must be different files")


def run(args: argparse.Namespace) -> int:
    _check_args(args)
    return _run(args)


@writes(outputs=("json", "plot"), inputs=("params", "pair"))
def _run(args: argparse.Namespace) -> int:
    from ..analysis.continuation import continue_orbits
    from ..io import atomic_write_text

    params = params_from_args(args)
    models = ["constant", "dynamic"] if args.model == "both" else [args.model]
    results: dict[str, dict[str, Any]] = {}
    complete = True

    def progress(period: int, omega: float, n: int) -> None:
        if not args.quiet and n % 25 == 0:
            print(f"  period {period}: omega = {omega:.4f} ({n} points)", file=sys.stderr)

    for m in models:
        r = continue_orbits(
            m, args.omega_min, args.omega_max, params, tol=args.tol, ds_max=args.ds_max,
            max_period=args.max_period, max_switches=args.max_switches, time_limit=args.time_limit,
            progress=progress, located=not args.unlocated,
        )  # fmt: skip
        d = r.to_json_dict()
        d["elapsed_s"] = r.elapsed
        results[m] = d
        complete &= r.complete
        print(f"{m}: {len(r.branches)} branch(es), {len(r.bifurcations)} bifurcation(s), {r.elapsed:.1f} s")
        for k, b in enumerate(r.branches):
            print(f"  branch {k}: period {b.period}, omega {b.omega.min():.4f}..{b.omega.max():.4f}, "
                  f"{len(b.omega)} points; {b.stop_reason}")  # fmt: skip
        for bp in r.bifurcations:
            mus = ", ".join(f"{complex(x):.3f}" for x in bp.multipliers)
            print(f"  omega = {bp.omega:.5f}  {bp.type:16s} branch {bp.branch} (period {bp.period}), mu = {mus}")
        for note in r.notes:
            print(f"  note: {note}")
        for msg in r.messages:
            print(f"gear-env continuation: {m}: {msg}", file=sys.stderr)
    sweeps = None
    if args.sweep_points > 0:
        import numpy as np

        from ..analysis import sweep

        sweeps = {}
        for m in models:
            s = sweep(np.linspace(args.omega_min, args.omega_max, args.sweep_points), model=m, params=params,
                      lyapunov=False, progress=not args.quiet)  # fmt: skip
            sweeps[m] = {"omega": s.omega.tolist(), "amplitude_u": s.amplitude["U"].tolist(),
                         "amplitude_delta": s.amplitude["delta"].tolist(), "regime": list(s.regime)}  # fmt: skip
    if args.json:
        out: dict[str, Any]
        if len(models) == 1:
            out = dict(results[models[0]])
        else:  # one list of branches; "branch" indexes it, "model" says whose
            out = {"model": "both", "branches": [], "bifurcations": [], "messages": [], "notes": []}
            out["complete"] = complete
            for m in models:
                off = len(out["branches"])
                out["branches"] += [dict(b, model=m) for b in results[m]["branches"]]
                out["bifurcations"] += [dict(b, model=m, branch=b["branch"] + off) for b in results[m]["bifurcations"]]
                out["messages"] += [f"{m}: {x}" for x in results[m]["messages"]]
                out["notes"] += [f"{m}: {x}" for x in results[m]["notes"]]
                out["models"] = models
        out["omega_range"] = [args.omega_min, args.omega_max]
        out["params"] = params.to_dict()
        if sweeps is not None:
            out["sweeps"] = sweeps
        atomic_write_text(args.json, json.dumps(out, indent=1))
        print(f"wrote {args.json}")
    if args.plot:
        from ..plots.common import save_figure
        from ..plots.continuation import plot_frequency_response

        save_figure(plot_frequency_response(results, sweeps), args.plot)
        print(f"wrote {args.plot}")
    if not complete:
        print("gear-env continuation: some branches stopped early (see above); what was found is written",
              file=sys.stderr)  # fmt: skip
        return 1
    return 0


__all__ = ["add_parser", "run"]
