"""``gear-env simulate``: one run at a fixed meshing frequency, JSON summary and a figure."""

from __future__ import annotations

import argparse

from .common import add_model_options, check_memory, float_range, int_range, params_from_args, scheme_text, writes

MAX_PERIODS = 10_000_000
"""Upper bound of ``--periods`` and ``--transient`` (the memory estimate usually binds first)."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate at one meshing frequency",
        description="Simulate the gear pair at a fixed dimensionless meshing frequency omega = Omega/omega_n; "
        "print the amplitudes and the motion class read from the Poincare section.",
    )
    p.add_argument(
        "--omega", type=float_range(0.0, 1e3, lo_open=True), required=True, help="meshing frequency Omega/omega_n (> 0)"
    )
    p.add_argument("--periods", type=int_range(1, MAX_PERIODS), default=200, help="mesh periods recorded (default 200)")
    p.add_argument(
        "--transient", type=int_range(0, MAX_PERIODS), default=300, help="mesh periods discarded first (default 300)"
    )
    add_model_options(p)
    p.add_argument("--json", metavar="PATH", help="write the summary (amplitudes, Poincare points) as JSON")
    p.add_argument("--plot", metavar="PATH", help="write a PNG: time history, phase portrait, Poincare map")
    p.set_defaults(func=run)


@writes(outputs=("json", "plot"), inputs=("params", "pair"))
def run(args: argparse.Namespace) -> int:
    from ..analysis import classify_motion
    from ..sim.simulator import default_steps_per_period, simulate
    from .common import simulate_bytes

    params = params_from_args(args)
    nsp = args.steps_per_period or default_steps_per_period(args.omega, params)
    check_memory(
        simulate_bytes(args.periods, args.transient, nsp),
        f"--periods {args.periods} --transient {args.transient} at {nsp} steps/period",
    )
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
    motion = classify_motion(traj.poincare_rows[:, :10]).label if args.periods >= 2 else "(needs --periods >= 2)"
    print(
        f"omega={args.omega:g} model={args.model} periods={args.periods} transient={args.transient} "
        f"steps/period={n} scheme={scheme_text(params)}\n"
        f"amplitude U={d['amplitude_u']:.6g}  Delta={d['amplitude_delta']:.6g}  b_d={d['amplitude_bd']:.6g}  "
        f"psi={d['amplitude_psi']:.3g} rad  contact loss={d['contact_loss_fraction']:.3f}\n"
        f"motion: {motion} (from the Poincare section; `gear-env sweep` adds the Lyapunov exponent)"
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
