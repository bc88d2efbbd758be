"""The learned operating window: delivered speed against demanded speed, over plants of a family."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .common import new_figure


def plot_learned_window(
    curves: Sequence[dict[str, Any]],
    floquet_window: tuple[float, float] | None = None,
    paper_window: tuple[float, float] = (0.4, 1.9),
    title: str = "",
):
    """Delivered omega against demanded omega, one panel per plant, its quiet window shaded.

    Args:
        curves: one dict per plant: ``label`` (str), ``demand`` (m,) demanded omega, ``delivered`` (m,)
            settled omega the policy delivered, ``quiet`` list of (lo, hi) omega intervals where the plant's
            steady motion is quiet (periodic, teeth in contact, no impacts), optionally ``oracle`` (m,) the
            oracle's settled omega, optionally ``fixed`` (m,) the settled omega of a schedule that does not know
            the plant (the same for every plant).
        floquet_window: stable interval of the nominal plant's period-1 orbit (Floquet map) containing
            the best speed, drawn as a bar beside the panels.
        paper_window: the paper's stable window [0.4, 1.9], drawn as a bar beside the panels.

    Returns:
        a matplotlib Figure.
    """
    n = len(curves)
    cols = min(3, max(n, 1))
    rows = int(np.ceil(n / cols))
    fig = new_figure(3.6 * cols + 1.2, 3.2 * rows + 0.4)
    gs = fig.add_gridspec(rows, cols + 1, width_ratios=[1.0] * cols + [0.28])
    ref = None
    for k, c in enumerate(curves):
        ax = fig.add_subplot(gs[k // cols, k % cols], sharey=ref)
        ref = ref or ax
        for j, (lo, hi) in enumerate(c.get("quiet", [])):
            ax.axhspan(
                lo, hi, color="tab:green", alpha=0.18, lw=0, label="quiet window (steady map)" if j == 0 else None
            )
        d = np.asarray(c["demand"], float)
        ax.plot(d, d, color="0.6", lw=0.8, ls=":", label="delivered = demanded")
        if c.get("oracle") is not None:
            ax.plot(d, c["oracle"], color="tab:gray", lw=1.2, ls="--", label="oracle")
        if c.get("fixed") is not None:
            ax.plot(d, c["fixed"], color="tab:red", lw=1.0, ls="-.", label="fixed-best (same for every plant)")
        ax.plot(d, c["delivered"], color="tab:blue", lw=1.8, marker=".", ms=4, label="learned policy")
        ax.set_title(c["label"], fontsize=9)
        ax.set_xlabel("demanded omega")
        if k % cols == 0:
            ax.set_ylabel("delivered omega (settled)")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, loc="upper left")
    bar = fig.add_subplot(gs[:, cols], sharey=ref)
    if floquet_window is not None:
        bar.bar(
            0, floquet_window[1] - floquet_window[0], bottom=floquet_window[0], width=0.8, color="tab:orange", alpha=0.6
        )
    bar.bar(1, paper_window[1] - paper_window[0], bottom=paper_window[0], width=0.8, color="tab:purple", alpha=0.5)
    if ref is not None:
        bar.set_ylim(ref.get_ylim())
    bar.set_xlim(-0.6, 1.6)
    bar.set_xticks([0, 1], ["Floquet\n(nominal)", "paper"], fontsize=8)
    bar.tick_params(axis="y", labelleft=False, labelright=True)
    bar.set_title("stable\nwindows", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


__all__ = ["plot_learned_window"]
