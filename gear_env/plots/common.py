"""Shared plotting helpers: a non-interactive backend, atomic saving, and the labels every figure
uses (mathtext symbols with units, so that the figures say the same thing the same way)."""

from __future__ import annotations

import math
import os

import matplotlib

if not os.environ.get("MPLBACKEND"):
    matplotlib.use("Agg")

from typing import Any  # noqa: E402

from matplotlib import ticker  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ..io import atomic_write  # noqa: E402

B0 = "$b_0$"
"""Unit of displacements: half the nominal backlash b0 (Delta, U, B_d, X, Y are divided by it)."""
OMEGA = r"$\omega = \Omega/\omega_n$"
"""Axis label of the meshing frequency ratio (mesh frequency over the natural frequency)."""
S_DEF = r"$s = \omega_n t$"
"""Definition of the natural time s that the velocities are taken against."""
LYAPUNOV = r"largest Lyapunov exponent $\lambda_1$" + "\n" + r"[per unit of $\omega_n t$]"
"""Axis label of the largest Lyapunov exponent (rate per unit natural time)."""


def new_figure(width: float = 10.0, height: float = 6.0) -> Figure:
    """A figure not attached to pyplot's global state (safe in threads and loops)."""
    return Figure(figsize=(width, height), layout="constrained")


def save_figure(fig: Figure, path: str, dpi: int = 110) -> None:
    """Save ``fig`` as PNG to ``path`` atomically (the old file survives a failure)."""
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))


class _PlainLogFormatter(ticker.Formatter):
    """Log-axis tick labels as plain numbers (0.01, 2, 30); minor ticks labelled at 2, 3 and 5
    when the axis spans less than 1.5 decades, else not at all."""

    def __init__(self, minor: bool):
        self.minor = minor

    def __call__(self, x: float, pos: int | None = None) -> str:
        if not x > 0:
            return ""
        if self.minor:
            if self.axis is None:
                return ""
            lo, hi = sorted(abs(v) for v in self.axis.get_view_interval())
            if lo <= 0 or hi / lo > 10**1.5:
                return ""
            if round(x / 10 ** math.floor(math.log10(x) + 1e-9)) not in (2, 3, 5):
                return ""
        return f"{x:g}"


def plain_log_ticks(ax: Any, axis: str = "y") -> None:
    """Label a log axis with plain numbers (0.01, 2, 30) instead of matplotlib's ``2x10^0``."""
    a = ax.yaxis if axis == "y" else ax.xaxis
    a.set_major_formatter(_PlainLogFormatter(minor=False))
    a.set_minor_formatter(_PlainLogFormatter(minor=True))
