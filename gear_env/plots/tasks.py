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


def plot_task_scores(
    scores: dict[str, dict[str, tuple[float, float]]],
    highlight: str = "",
    reference: str = "oracle",
    title: str = "",
):
    """Return of each policy as a percentage of the reference policy's, one panel per task.

    Args:
        scores: {task id: {policy label: (mean return in % of the reference, 95 % CI half-width in %)}},
            policies in the order to draw (top to bottom). Bars and error bars are clipped to [0, 135] %;
            the number in each label is the unclipped value.
        highlight: label of the policy drawn in a strong colour (the learned one).
        reference: the policy the percentages are of (drawn as a line at 100 %).
        title: figure title.

    Returns:
        a matplotlib Figure.
    """
    n = max(len(scores), 1)
    rows = max((len(v) for v in scores.values()), default=1)
    fig = new_figure(4.6 * n + 0.4, 0.42 * rows + 1.5)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, (task, pols) in zip(axes, scores.items()):
        labels = list(pols)
        y = np.arange(len(labels))[::-1]
        means = np.array([pols[k][0] for k in labels])
        halves = np.array([pols[k][1] for k in labels])
        colors = ["#c0392b" if k == highlight else ("#7f8c8d" if k == reference else "#5d8aa8") for k in labels]
        xmax = 135.0
        bars = np.clip(means, 0.0, xmax)
        err = np.vstack([np.minimum(halves, bars), np.minimum(halves, xmax - bars)])  # kept inside the axes
        ax.barh(y, bars, xerr=err, color=colors, height=0.65, capsize=2, ecolor="0.3")
        ax.axvline(100.0, color="k", lw=0.8, ls="--")
        ax.set_yticks(y, [f"{k}  {m:.1f} %" for k, m in zip(labels, means)], fontsize=8)
        ax.set_xlim(0.0, xmax)
        ax.set_xlabel(f"return, % of the {reference}'s (same seeds)")
        ax.set_title(task, fontsize=10)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig
