"""Frequency-response curves from continuation data (the standard figure of gear-dynamics papers).

Takes plain data (the JSON layout of ``gear-env continuation`` / ``ContinuationResult.to_json_dict``
and, optionally, of ``gear-env sweep --json``); imports no analysis or environment code.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .common import new_figure

MARKERS = {"fold": ("o", "tab:red"), "period-doubling": ("s", "tab:purple"),
           "neimark-sacker": ("D", "tab:green"), "grazing": ("^", "tab:orange")}  # fmt: skip
PERIOD_COLORS = {1: "black", 2: "tab:blue", 4: "tab:cyan", 8: "tab:olive", 16: "tab:brown"}


def _runs(stable: np.ndarray) -> list[tuple[int, int, bool]]:
    """Maximal runs [i, j] (inclusive, overlapping by one point) of equal stability."""
    out = []
    i = 0
    n = len(stable)
    while i < n - 1:
        j = i + 1
        while j < n - 1 and stable[j] == stable[i]:
            j += 1
        out.append((i, j, bool(stable[i])))
        i = j
    return out


def _draw(ax: Any, result: Mapping[str, Any], key: str, sweep: Mapping[str, Any] | None) -> None:
    if sweep is not None and key in sweep:
        ax.plot(sweep["omega"], sweep[key], ".", color="0.6", ms=3, zorder=1)
    for br in result.get("branches", []):
        w = np.asarray(br["omega"], float)
        a = np.asarray(br[key], float)
        st = np.asarray(br["stable"], bool)
        col = PERIOD_COLORS.get(int(br["period"]), "tab:gray")
        if len(w) == 1:
            ax.plot(w, a, "." if st[0] else "x", color=col)
        for i, j, s in _runs(st):
            ax.plot(w[i : j + 1], a[i : j + 1], "-" if s else "--", color=col, lw=1.4 if s else 1.0, zorder=2)
    for bp in result.get("bifurcations", []):
        m, c = MARKERS.get(bp["type"], ("x", "k"))
        y = bp.get(key)
        if y is not None:
            ax.plot([bp["omega"]], [y], m, color=c, ms=5, mfc="none", mew=1.3, zorder=3)
    ax.grid(alpha=0.3)


def plot_frequency_response(
    results: Mapping[str, Mapping[str, Any]],
    sweeps: Mapping[str, Mapping[str, Any]] | None = None,
    title: str = "",
) -> Figure:
    """Amplitude of U and of Delta against omega for each model (columns).

    Args:
        results: ``{model: continuation JSON dict}`` (``branches`` with ``omega``, ``amplitude_u``,
            ``amplitude_delta``, ``stable``, ``period``; ``bifurcations`` with ``omega``, ``type``,
            ``amplitude_u``, ``amplitude_delta``).
        sweeps: optional ``{model: sweep JSON dict}`` (``omega``, ``amplitude_u``,
            ``amplitude_delta``), drawn as grey points under the branches.
        title: figure title.

    Returns:
        Figure: stable branches solid, unstable dashed, coloured by period (black 1, blue 2, cyan
        4, ...); bifurcations marked (fold circle, period-doubling square, Neimark-Sacker diamond,
        grazing triangle). Amplitudes are half peak-to-peak in b0.
    """
    if not results:
        raise ValueError("results must hold at least one model's continuation data")
    models = list(results)
    fig = new_figure(5.2 * len(models), 6.4)
    axes = fig.subplots(2, len(models), sharex="col", squeeze=False)
    for k, m in enumerate(models):
        sw = None if sweeps is None else sweeps.get(m)
        _draw(axes[0, k], results[m], "amplitude_u", sw)
        _draw(axes[1, k], results[m], "amplitude_delta", sw)
        axes[0, k].set_title(f"{m} backlash")
        axes[1, k].set_xlabel(r"$\omega = \Omega/\omega_n$")
    axes[0, 0].set_ylabel(r"U amplitude [$b_0$]")
    axes[1, 0].set_ylabel(r"$\Delta$ amplitude [$b_0$]")
    handles = [Line2D([], [], color="k", ls="-", label="stable"), Line2D([], [], color="k", ls="--", label="unstable")]
    periods = sorted({int(b["period"]) for r in results.values() for b in r.get("branches", [])})
    handles += [Line2D([], [], color=PERIOD_COLORS.get(p, "tab:gray"), label=f"period {p}") for p in periods]
    handles += [Line2D([], [], ls="none", marker=m, color=c, mfc="none", label=t) for t, (m, c) in MARKERS.items()]
    if sweeps:
        handles.append(Line2D([], [], ls="none", marker=".", color="0.6", label="forward sweep"))
    axes[0, -1].legend(handles=handles, fontsize=7, loc="upper right")
    if title:
        fig.suptitle(title)
    return fig


__all__ = ["plot_frequency_response"]
