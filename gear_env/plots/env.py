"""Figures of the GearSpeed environment: the render frame and the evaluation plot."""

from __future__ import annotations

from typing import Any

import numpy as np

from .common import new_figure

BAND_COLORS = {
    "periodic": "#cfe8cf",
    "impacting": "#f6e3b4",
    "nonperiodic": "#f3c1c1",
    "stable": "#cfe8cf",
    "period-doubling": "#f6e3b4",
    "neimark-sacker": "#f3c1c1",
    "fold": "#d9c8ef",
    "unconverged": "#e0e0e0",
}
BAND_LABELS = {
    "periodic": "periodic, contact kept",
    "impacting": "periodic, impacting",
    "nonperiodic": "non-periodic",
    "stable": "period-1 stable",
    "period-doubling": "period-1 unstable (period doubling)",
    "neimark-sacker": "period-1 unstable (torus)",
    "fold": "period-1 unstable (fold)",
    "unconverged": "no period-1 orbit found",
}


def draw_bands(ax: Any, bands: Any, horizontal: bool = True) -> None:
    """Shade the regime bands (a :class:`gear_env.bands.RegimeBands`) across omega.

    ``horizontal=True`` shades horizontal strips (omega on the y axis). ``bands=None`` draws nothing.
    """
    if bands is None:
        return
    seen = set()
    for kind, intervals in bands.bands.items():
        color = BAND_COLORS.get(kind, "#dddddd")
        for lo, hi in intervals:
            label = BAND_LABELS.get(kind, kind) if kind not in seen else None
            seen.add(kind)
            if horizontal:
                ax.axhspan(lo, hi, color=color, lw=0, label=label, zorder=0)
            else:
                ax.axvspan(lo, hi, color=color, lw=0, label=label, zorder=0)


class EnvFrame:
    """Draws the env frame: omega history over the regime bands, the Poincare window, contact state.

    It draws what it is given; :class:`gear_env.render.EnvRenderer` (what ``env.render()`` uses)
    fetches the bands of the environment's configuration and hands them over.

    Args:
        config: the env's settings (an object with ``omega_min``, ``omega_max``, ``max_steps``,
            ``periods_per_step``, e.g. :class:`gear_env.env_config.GearSpeedConfig`).
        bands: regime bands to shade (a :class:`gear_env.bands.RegimeBands`), or None for none.
        human: show the figure in a matplotlib window (pyplot) instead of off-screen.
    """

    def __init__(self, config: Any, bands: Any = None, human: bool = False):
        self.config = config
        self.human = human
        self.bands = bands
        if human:
            import matplotlib.pyplot as plt

            plt.ion()
            self.fig = plt.figure(figsize=(8, 4.5))
        else:
            self.fig = new_figure(8, 4.5)
        self.fig.set_dpi(80)

    def draw(self, history: np.ndarray, poincare: np.ndarray, rgb: bool) -> np.ndarray | None:
        """Redraw; ``history`` rows (omega, chaos c, contact loss, F_peak/F_s) per step,
        ``poincare`` (W, 2) recent Poincare samples (Delta, dU/omega) [b0]."""
        cfg = self.config
        fig = self.fig
        fig.clear()
        gs = fig.add_gridspec(2, 2, width_ratios=(2.2, 1), height_ratios=(2, 1))
        ax = fig.add_subplot(gs[0, 0])
        draw_bands(ax, self.bands)
        t = np.arange(len(history))
        if len(history):
            ax.plot(t, history[:, 0], "k-", lw=1.5)
            ax.plot(t[-1:], history[-1:, 0], "ko")
        ax.set_xlim(0, max(cfg.max_steps, 1))
        ax.set_ylim(cfg.omega_min, cfg.omega_max)
        ax.set_ylabel("omega = Omega/omega_n")
        ax.set_title("speed schedule over regime bands", fontsize=9)
        ax.legend(loc="upper right", fontsize=6)
        ax2 = fig.add_subplot(gs[1, 0], sharex=ax)
        if len(history):
            ax2.plot(t, history[:, 2], color="tab:red", lw=1, label="contact loss")
            ax2.plot(t, history[:, 1], color="tab:purple", lw=1, label="chaos c")
        ax2.set_ylim(-0.05, 1.05)
        ax2.set_xlabel("env step")
        ax2.legend(loc="upper right", fontsize=6)
        ax3 = fig.add_subplot(gs[:, 1])
        if len(poincare):
            ax3.plot(poincare[:, 0], poincare[:, 1], ".", color="tab:blue", ms=4)
        ax3.set_xlabel("Delta [b0]")
        ax3.set_ylabel("dU/omega [b0]")
        state = "teeth in contact"
        if len(history):
            state = f"contact loss {history[-1, 2]:.0%}, c = {history[-1, 1]:.2f}"
        ax3.set_title(f"Poincare section\n{state}", fontsize=8)
        if self.human:
            fig.canvas.draw_idle()
            fig.canvas.flush_events()
        if not rgb:
            return None
        canvas = fig.canvas
        if not hasattr(canvas, "buffer_rgba"):
            from matplotlib.backends.backend_agg import FigureCanvasAgg

            canvas = FigureCanvasAgg(fig)
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()

    def close(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt

            plt.close(self.fig)


def plot_evaluation(report: Any, bands: Any):
    """omega(t) of the first episode of each policy over the regime bands; peak mesh force below.

    Args:
        report: :class:`gear_env.evaluation.EvaluationReport`.
        bands: :class:`gear_env.evaluation.RegimeBands`.

    Returns:
        a matplotlib Figure (save it with :func:`gear_env.plots.save_figure`).
    """
    cfg = report.config
    fig = new_figure(9, 6)
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    draw_bands(ax, bands)
    for name, eps in report.episodes.items():
        e = eps[0]
        t = np.arange(1, len(e.omega) + 1)
        (line,) = ax.plot(t, e.omega, lw=1.6, label=f"{name} (return {e.ret:.1f})")
        ax2.plot(t, e.vibration, lw=1, color=line.get_color())
    ax.set_ylim(cfg.omega_min, cfg.omega_max)
    ax.set_ylabel("omega = Omega/omega_n")
    ax.set_title(f"speed schedules (episode seed {report.seed}) over regime bands ({bands.source})", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    ax2.set_yscale("log")
    ax2.set_ylabel("peak mesh force / F_s")
    ax2.set_xlabel(f"env step ({cfg.periods_per_step} mesh periods)")
    return fig


def plot_steady_reward(maps: dict[str, Any]):
    """Steady reward per step against constant omega, one curve per map, main penalties below.

    Args:
        maps: label -> :class:`gear_env.evaluation.SteadyRewardMap`.
    """
    fig = new_figure(9, 6)
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    for label, m in maps.items():
        (line,) = ax.plot(m.omegas, m.reward, "-o", ms=2.5, lw=1.4, label=f"{label} (best omega {m.best_omega:.2f})")
        c = line.get_color()
        ax2.plot(m.omegas, m.terms["chaos"], "-", color=c, lw=1.2)
        ax2.plot(m.omegas, m.terms["contact_loss"], "--", color=c, lw=1.0)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_ylabel("steady reward per step")
    ax.set_title("GearSpeed-v0: reward of holding omega constant (default weights)", fontsize=9)
    ax.legend(fontsize=7)
    ax2.set_ylabel("chaos c (solid), contact loss (dashed)", fontsize=8)
    ax2.set_xlabel("omega = Omega/omega_n")
    return fig


__all__ = ["EnvFrame", "draw_bands", "plot_evaluation", "plot_steady_reward"]
