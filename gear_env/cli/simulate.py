"""``gear-env simulate``: one run at a fixed meshing frequency, JSON summary and a figure."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate at one meshing frequency",
        description="Simulate the gear pair at a fixed dimensionless meshing frequency omega = Omega/omega_n.",
    )
    p.add_argument("--omega", type=float, required=True, help="meshing frequency Omega/omega_n (> 0)")
    p.add_argument("--model", default="dynamic", choices=["constant", "dynamic"], help="backlash model")
    p.add_argument("--periods", type=int, default=200, help="mesh periods recorded (default 200)")
    p.add_argument("--transient", type=int, default=300, help="mesh periods discarded first (default 300)")
    p.add_argument("--kappa", type=float, default=None, help="mesh-stiffness harmonic amplitude (default 0.2)")
    p.add_argument(
        "--steps-per-period",
        type=int,
        default=None,
        help="Newmark steps per mesh period (default 192, more below omega 0.27)",
    )
    p.add_argument("--json", metavar="PATH", help="write the summary (amplitudes, Poincare points) as JSON")
    p.add_argument("--plot", metavar="PATH", help="write a PNG: time history, phase portrait, Poincare map")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..params import GearParams
    from ..simulator import simulate

    params = GearParams() if args.kappa is None else GearParams(kappa=args.kappa)
    traj = simulate(
        args.omega,
        model=args.model,
        periods=args.periods,
        transient=args.transient,
        steps_per_period=args.steps_per_period,
        params=params,
    )
    n = traj.steps_per_period
    d = traj.to_dict()
    print(
        f"omega={args.omega:g} model={args.model} periods={args.periods} transient={args.transient} "
        f"steps/period={n}\n"
        f"amplitude U={d['amplitude_u']:.6g}  Delta={d['amplitude_delta']:.6g}  b_d={d['amplitude_bd']:.6g}  "
        f"psi={d['amplitude_psi']:.3g} rad  contact loss={d['contact_loss_fraction']:.3f}"
    )
    if args.json:
        traj.to_json(args.json)
        print(f"wrote {args.json}")
    if args.plot:
        from ..plots import plot_trajectory, save_figure

        fig = plot_trajectory(traj)
        save_figure(fig, args.plot)
        print(f"wrote {args.plot}")
    return 0


__all__ = ["add_parser", "run"]
