"""Helpers shared by the ``gear-env`` sub-commands: bounded number options, the model and
parameter options, output checks and memory estimates (every check runs before any work)."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from typing import Any

INT_MAX = 2**62
"""No integer option accepts more (fits an int64 with room to spare)."""


def int_range(lo: int, hi: int = INT_MAX) -> Callable[[str], int]:
    """An argparse ``type`` for an integer in [lo, hi]; argparse names the flag in its message."""

    def parse(text: str) -> int:
        try:
            v = int(text.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer in [{lo}, {hi}], got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer in [{lo}, {hi}], got {text}")
        return v

    parse.__name__ = "integer"
    return parse


def float_range(lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` for a finite float in [lo, hi] (``(lo, hi]`` with ``lo_open``)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        left = "(" if lo_open else "["
        if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo):
            raise argparse.ArgumentTypeError(f"must be a finite number in {left}{lo:g}, {hi:g}], got {text}")
        return v

    parse.__name__ = "number"
    return parse


# --------------------------------------------------------------------------------------------------
# the model and its parameters (simulate, sweep, stability)
# --------------------------------------------------------------------------------------------------
def add_model_options(p: argparse.ArgumentParser, steps: bool = True) -> None:
    """``--model``, the parameter options (:func:`add_params_options`) and (with ``steps``)
    ``--steps-per-period``; read back by :func:`params_from_args`."""
    p.add_argument("--model", default="dynamic", choices=["constant", "dynamic"], help="backlash model")
    add_params_options(p)
    if steps:
        p.add_argument(
            "--steps-per-period",
            type=int_range(8, 100_000),
            default=None,
            help="Newmark steps per mesh period, 8-100000 (default 192, more below omega 0.27; with --scheme "
            "fox-goodwin 88, more below omega 0.11)",
        )


def add_params_options(p: argparse.ArgumentParser) -> None:
    """``--kappa``, ``--params FILE``, ``--pair FILE`` and ``--harmonics N``: read back by :func:`params_from_args`."""
    p.add_argument("--kappa", type=float, default=None, help="mesh-stiffness harmonic amplitude (default 0.2)")
    p.add_argument(
        "--params",
        metavar="FILE.json",
        default=None,
        help="a JSON file holding an object of GearParams fields (SI; may hold stiffness_harmonics, te_harmonics)",
    )
    p.add_argument(
        "--pair",
        metavar="FILE.json",
        default=None,
        help="a JSON file holding a spur pair's geometry, an object of gear_env.sim.geometry.SpurPair keywords (SI): "
        "k_m0, stiffness harmonics, masses and inertias from the teeth; --params fields override them",
    )
    p.add_argument(
        "--harmonics",
        type=int_range(1, 64),
        default=16,
        help="stiffness harmonics taken from --pair, 1-64 (default 16)",
    )
    from ..sim.params import SCHEMES

    p.add_argument(
        "--scheme",
        choices=tuple(SCHEMES),
        default=None,
        help="Newmark scheme: paper (beta 1/4, default, unconditionally stable), fox-goodwin (beta 1/12: "
        "less error per step, stable above a step count that grows at low omega; GearParams.newmark_beta) or "
        "fox-goodwin-vc (beta 1/12 with the damping forces' velocity corrected: less error again at the same "
        "cost; GearParams.velocity_correction)",
    )


def scheme_text(params: Any) -> str:
    """The Newmark scheme of ``params`` for a command's printout: "paper (beta 1/4)", "fox-goodwin (beta 1/12)",
    "fox-goodwin-vc (beta 1/12)"."""
    from fractions import Fraction

    from ..sim.params import scheme_name

    b = params.newmark_beta
    name = scheme_name(b, params.velocity_correction)
    return f"{name} (beta {Fraction(b).limit_denominator(100)})" if name else f"beta {b:.6g}"


def params_from_args(args: argparse.Namespace) -> Any:
    """The :class:`~gear_env.sim.params.GearParams` the parameter options describe (a ValueError names the field)."""
    from ..io import read_json
    from ..sim.params import SCHEMES, GearParams

    fields: dict[str, Any] = {}
    if getattr(args, "params", None):
        fields = read_json(args.params, "--params")
        if not isinstance(fields, dict):
            raise ValueError(f"--params {args.params!r} must hold a JSON object of GearParams fields")
    if args.kappa is not None:
        if getattr(args, "pair", None) or "stiffness_harmonics" in fields:
            raise ValueError("--kappa cannot be combined with a stiffness series (--pair or stiffness_harmonics)")
        fields["kappa"] = args.kappa
    scheme = getattr(args, "scheme", None)
    if scheme is not None:
        if "newmark_beta" in fields or "velocity_correction" in fields:
            raise ValueError(
                "--scheme cannot be combined with newmark_beta or velocity_correction in --params: give one of them"
            )
        fields["newmark_beta"], fields["velocity_correction"] = SCHEMES[scheme]
    if getattr(args, "pair", None):
        from ..sim.geometry import SpurPair

        kw = read_json(args.pair, "--pair")
        if not isinstance(kw, dict):
            raise ValueError(f"--pair {args.pair!r} must hold a JSON object of SpurPair keywords")
        try:
            pair = SpurPair(**kw)
        except TypeError as exc:
            raise ValueError(f"--pair {args.pair!r}: {exc}") from None
        return GearParams.from_pair(pair, args.harmonics, **fields)
    return GearParams.from_dict(fields)


# --------------------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------------------
def check_outputs(args: argparse.Namespace, outputs: tuple[str, ...], inputs: tuple[str, ...] = ()) -> None:
    """Refuse (ValueError, exit 2) outputs that are devices/directories, that equal an input or each other.

    ``outputs``/``inputs`` are attribute names of ``args`` (``"json"`` -> option ``--json``)."""
    from ..io import check_outputs as _check

    def flag(name: str) -> str:
        return "--" + name.replace("_", "-")

    _check({flag(n): getattr(args, n, None) for n in outputs}, {flag(n): getattr(args, n, None) for n in inputs})


def writes(
    outputs: tuple[str, ...] = (), inputs: tuple[str, ...] = (), folders: tuple[str, ...] = ()
) -> Callable[[Callable[[argparse.Namespace], int]], Callable[[argparse.Namespace], int]]:
    """Decorator of a command's ``run(args)``: the writing rule of every command.

    Before the command starts, its output files (``outputs``) and folders (``folders``, created if
    missing) are checked (no device, directory, input or other output by any name: device and
    inode) and locked for the command's life (:func:`gear_env.io.hold_outputs`); a second writer is
    refused at once (exit 2). Names are attributes of ``args`` (``"json"`` -> ``--json``)."""
    import functools

    def flag(name: str) -> str:
        return "--" + name.replace("_", "-")

    def deco(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        @functools.wraps(run)
        def wrapped(args: argparse.Namespace) -> int:
            from ..io import hold_outputs

            with hold_outputs(
                {flag(n): getattr(args, n, None) for n in outputs},
                {flag(n): getattr(args, n, None) for n in inputs},
                {flag(n): getattr(args, n, None) for n in folders},
            ):
                return run(args)

        return wrapped

    return deco


# --------------------------------------------------------------------------------------------------
# memory
# --------------------------------------------------------------------------------------------------
def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return None


def check_memory(nbytes: float, what: str, fraction: float = 0.8) -> None:
    """Raise ValueError if an allocation of ``nbytes`` would not fit in ``fraction`` of the free memory.

    ``what`` names the options responsible (e.g. ``"--periods 1000000 at 192 steps/period"``)."""
    free = available_memory()
    if free is None:
        return
    if nbytes > fraction * free:
        raise ValueError(
            f"{what} needs about {nbytes / 2**30:.1f} GiB of memory, more than the {fraction * free / 2**30:.1f} GiB "
            "available; ask for less"
        )


def simulate_bytes(periods: int, transient: int, steps_per_period: int) -> float:
    """Estimated bytes a ``simulate`` run allocates: the recorded time series plus the Poincare rows."""
    from ..sim.kernels import N_PC, N_REC

    return 8.0 * ((periods * steps_per_period + 1) * N_REC + (periods + transient) * N_PC)


def sweep_bytes(points: int, periods: int) -> float:
    """Estimated bytes of a sweep's results: per point its Poincare rows, statistics and state."""
    from ..sim.kernels import N_PC, N_STATS

    return 8.0 * points * (4 * periods * N_PC + N_STATS + 64)


__all__ = [
    "add_model_options",
    "available_memory",
    "check_memory",
    "check_outputs",
    "writes",
    "float_range",
    "int_range",
    "add_params_options",
    "params_from_args",
    "simulate_bytes",
    "sweep_bytes",
]


# --------------------------------------------------------------------------------------------------
# which task a command evaluates on
# --------------------------------------------------------------------------------------------------
DEFAULT_ENV = "GearSpeed-v1"
"""The task ``gear-env evaluate/train/report`` run on when neither ``--env`` nor a run folder names one."""


def add_env_options(p: argparse.ArgumentParser) -> None:
    """``--env`` (default: the run folders' own task, else :data:`DEFAULT_ENV`) and ``--allow-other-env``."""
    from ..envs.tasks import TASK_SETTINGS

    ids = tuple(TASK_SETTINGS)
    p.add_argument(
        "--env",
        default=None,
        choices=ids,
        metavar="ID",
        help=f"task: {', '.join(ids)} (default: the task the --policy run folders were trained on, "
        f"else {DEFAULT_ENV}; --config settings override its own)",
    )
    p.add_argument(
        "--allow-other-env",
        action="store_true",
        help="evaluate a run folder on another task than the one it was trained on (refused by default)",
    )


def choose_env(env: str | None, policy_specs: list[str]) -> str:
    """The task to evaluate on: ``env`` if given, else the one task the run folders among ``policy_specs``
    were trained on (their config.json), else :data:`DEFAULT_ENV`. Run folders of different tasks without
    ``--env`` are refused (ValueError)."""
    if env is not None:
        return env
    try:
        from agents.registry import trained_env_id  # type: ignore[import-not-found]
    except ImportError:
        return DEFAULT_ENV
    found = {s: e for s in policy_specs if (e := trained_env_id(s.split("=", 1)[-1])) is not None}
    ids = sorted(set(found.values()))
    if len(ids) > 1:
        raise ValueError(
            "the --policy run folders were trained on different tasks "
            f"({', '.join(f'{s}: {e}' for s, e in found.items())}); choose one with --env"
        )
    if ids:
        print(f"  --env {ids[0]}: the task the run folder(s) were trained on (config.json)", flush=True)
        return ids[0]
    return DEFAULT_ENV
