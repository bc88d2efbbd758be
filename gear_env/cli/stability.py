"""``gear-env stability``: Floquet stability map of the period-1 orbit over omega."""

from __future__ import annotations

import argparse

from .common import add_model_options, float_range, int_range, params_from_args, scheme_text, writes


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stability",
        help="Floquet stability map of the period-1 orbit over omega",
        description=(
            "Continue the period-1 orbit over a uniform omega grid by shooting, compute its Floquet "
            "multipliers, and print the intervals where it is stable or loses stability by period "
            "doubling or a Neimark-Sacker (torus) bifurcation. Cached in $GEAR_ENV_CACHE or ~/.cache/gear-env."
        ),
    )
    p.add_argument(
        "--omega-min", type=float_range(0.0, 1e3, lo_open=True), default=0.05, help="lowest omega (default 0.05)"
    )
    p.add_argument(
        "--omega-max", type=float_range(0.0, 1e3, lo_open=True), default=3.0, help="highest omega (default 3.0)"
    )
    p.add_argument(
        "--points", type=int_range(2, 100_000), default=None, help="grid points (default 296: a step of 0.01)"
    )
    add_model_options(p)
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the cache (always compute)")
    p.add_argument("--json", metavar="PATH", help="write the map (grid, multipliers, labels, intervals) as JSON")
    p.add_argument("--plot", metavar="PATH", help="write a PNG of max|multiplier| and the multipliers over omega")
    p.set_defaults(func=run)


@writes(outputs=("json", "plot"), inputs=("params", "pair"))
def run(args: argparse.Namespace) -> int:
    from ..analysis.stability import DEFAULT_POINTS, stability_map

    params = params_from_args(args)
    m = stability_map(
        args.model,
        params,
        args.omega_min,
        args.omega_max,
        DEFAULT_POINTS if args.points is None else args.points,
        args.steps_per_period,
        cache=not args.no_cache,
    )
    print(
        f"model={m.model} omega in [{m.omega[0]:g}, {m.omega[-1]:g}], {len(m.omega)} points, "
        f"scheme={scheme_text(params)}"
    )
    print("period-1 orbit:")
    for lo, hi, lab in m.intervals():
        print(f"  [{lo:.3f}, {hi:.3f}]  {lab}")
    for w, a, b in m.bifurcations():
        print(f"  omega = {w:.4f}: {a} -> {b}")
    if args.json:
        m.save(args.json)
        print(f"wrote {args.json}")
    if args.plot:
        from ..plots.analysis import plot_stability_map
        from ..plots.common import save_figure

        save_figure(plot_stability_map(m), args.plot)
        print(f"wrote {args.plot}")
    return 0


__all__ = ["add_parser", "run"]
