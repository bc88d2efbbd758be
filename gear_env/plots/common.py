"""Shared plotting helpers: a non-interactive backend and atomic saving."""

from __future__ import annotations

import os

import matplotlib

if not os.environ.get("MPLBACKEND"):
    matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402

from ..io import atomic_write  # noqa: E402


def new_figure(width: float = 10.0, height: float = 6.0) -> Figure:
    """A figure not attached to pyplot's global state (safe in threads and loops)."""
    return Figure(figsize=(width, height), layout="constrained")


def save_figure(fig: Figure, path: str, dpi: int = 110) -> None:
    """Save ``fig`` as PNG to ``path`` atomically (the old file survives a failure)."""
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
