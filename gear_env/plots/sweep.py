"""Bifurcation diagram of a sweep: Poincare samples of Delta over omega, coloured by regime."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

from .common import B0, LYAPUNOV, OMEGA, new_figure

REGIME_COLORS = {"period-1": "tab:blue", "quasi-periodic": "tab:orange", "chaotic": "tab:red"}
"""Colours of the regimes; period-N (N > 1) are green."""


def regime_color(label: str) -> str:
    """Colour of a regime label."""
    return REGIME_COLORS.get(label, "tab:green")


def plot_bifurcation(result: Any, name: str = "Delta", ax: Any = None, lyapunov: bool = True) -> Figure:
    """Bifurcation diagram of ``result`` (a :class:`~gear_env.analysis.SweepResult`).

    Points whose motion was still changing during their window (``SweepResult.unsettled()``)
    are marked by a triangle at the bottom edge.

    Args:
        result: the sweep results.
        name: Poincare column plotted (``Delta`` [b0], ``U``, ``B_d``, ``psi``, ``force``...).
        ax: an existing Axes to draw into (then no Lyapunov panel), or None for a new figure.
        lyapunov: add a panel with the largest Lyapunov exponent (if computed).

    Returns:
        The matplotlib Figure.
    """
    show_lyap = ax is None and lyapunov and result.lyapunov is not None
    if ax is None:
        fig = new_figure(10.0, 7.0 if show_lyap else 5.0)
        if show_lyap:
            ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
        else:
            ax = fig.add_subplot(1, 1, 1)
    else:
        fig = ax.figure
    pts = result.poincare_of(name)
    om = np.asarray(result.omega)
    labels = list(result.regime)
    seen: set[str] = set()
    for lab in sorted(set(labels), key=lambda s: (s != "period-1", s)):
        idx = [i for i, g in enumerate(labels) if g == lab]
        key = lab if lab in REGIME_COLORS else "period-N (N>1)"
        x = np.repeat(om[idx], pts.shape[1])
        y = pts[idx].ravel()
        ax.scatter(x, y, s=0.6, color=regime_color(lab), label=None if key in seen else key, rasterized=True)
        seen.add(key)
    late = result.unsettled() if hasattr(result, "unsettled") else np.zeros(0)
    if late.size:  # points whose motion was still changing during the window (SweepResult.drift)
        ax.scatter(late, np.full(late.size, 0.015), transform=ax.get_xaxis_transform(), marker="^", s=16,
                   color="0.25", label="still drifting: longer transient", zorder=3)  # fmt: skip
    tex = {"Delta": "$\\Delta$", "delta": "$\\Delta$", "U": "$U$", "B_d": "$B_d$", "bd": "$B_d$", "psi": "$\\psi$"}
    unit = {"psi": "rad", "force": "$k_{m0} b_0$"}
    ax.set_ylabel(f"Poincaré samples of {tex.get(name, name)} [{unit.get(name, B0)}]")
    ax.set_title(f"Bifurcation diagram, {result.model} backlash, {result.direction} sweep")
    leg = ax.legend(loc="best", markerscale=8, fontsize=8)
    for handle, text in zip(leg.legend_handles, leg.get_texts()):  # the markerscale is for the dots
        if text.get_text().startswith("still drifting") and hasattr(handle, "set_sizes"):
            handle.set_sizes([16.0])
    leg.set_title("regime")
    if show_lyap:
        ax2.plot(om, result.lyapunov, ".-", ms=2, lw=0.6, color="k")
        ax2.axhline(0.0, color="0.6", lw=0.6)
        ax2.set_ylabel(LYAPUNOV, fontsize=8)
        ax2.set_xlabel(OMEGA)
    else:
        ax.set_xlabel(OMEGA)
    return fig
