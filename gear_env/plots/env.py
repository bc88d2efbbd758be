"""Figures of the GearSpeed environment: the render frame and the evaluation plot."""

from __future__ import annotations

from typing import Any

import numpy as np

from .common import B0, OMEGA, new_figure, plain_log_ticks

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
    """Shade the regime bands (a :class:`gear_env.envs.bands.RegimeBands`) across omega.

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

    It draws what it is given; :class:`gear_env.envs.render.EnvRenderer` (what ``env.render()`` uses)
    fetches the bands of the environment's configuration and hands them over.

    Args:
        config: the env's settings (an object with ``omega_min``, ``omega_max``, ``max_steps``,
            ``periods_per_step``, e.g. :class:`gear_env.envs.env_config.GearSpeedConfig`).
        bands: regime bands to shade (a :class:`gear_env.envs.bands.RegimeBands`), or None for none.
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
        ax.set_ylabel(OMEGA)
        ax.set_title("speed over the regime bands", fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=6)
        ax2 = fig.add_subplot(gs[1, 0], sharex=ax)
        if len(history):
            ax2.plot(t, history[:, 2], color="tab:red", lw=1, label="contact loss")
            ax2.plot(t, history[:, 1], color="tab:purple", lw=1, label="chaos c")
        ax2.set_ylim(-0.05, 1.05)
        ax2.set_xlabel(f"env step ({cfg.periods_per_step} mesh periods)")
        ax2.legend(loc="upper right", fontsize=6)
        ax3 = fig.add_subplot(gs[:, 1])
        if len(poincare):
            ax3.plot(poincare[:, 0], poincare[:, 1], ".", color="tab:blue", ms=4)
        ax3.set_xlabel(f"$\\Delta$ [{B0}]")
        ax3.set_ylabel(f"$dU/d\\tau$ [{B0}]  ($\\tau = \\Omega t$)")
        state = "teeth in contact"
        if len(history):
            state = f"contact loss {history[-1, 2]:.0%}, c = {history[-1, 1]:.2f}"
        ax3.set_title(f"Poincaré section ({len(poincare)} periods)\n{state}", fontsize=8)
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

    The curves are the plant's omega, not the policies' commands: omega starts at the episode's
    initial value and moves at most ``max_domega`` per step, so a schedule's curve lags its
    command (a ramp may never meet its own start); the figure says so.

    Args:
        report: :class:`gear_env.evaluation.report.EvaluationReport`.
        bands: :class:`gear_env.envs.bands.RegimeBands`, or None for no shading.

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
    ax.set_ylabel(OMEGA)
    readable = {"steady_reward_map": "steady runs at constant $\\omega$"}
    fig.suptitle(f"$\\omega$ of each policy's first episode, seed {report.seed}", fontsize=10)
    if bands is not None:
        ax.set_title(f"bands: {readable.get(bands.source, bands.source)}", fontsize=8)
    # policies and bands beside the axes (inside, they would cover the curves), the rate limit below
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    ax.text(
        1.01,
        0.0,
        "The curves are the plant's $\\omega$, not the\n"
        "command: it starts at the episode's initial\n"
        f"$\\omega$ and changes by at most {cfg.max_domega:g} per step\n"
        "(rate limit), so a schedule's curve lags\n"
        "its command and may never meet its start.",
        transform=ax.transAxes,
        ha="left",
        va="bottom",
        fontsize=7,
    )
    ax2.set_yscale("log")
    plain_log_ticks(ax2)
    ax2.set_ylabel("peak mesh force\n/ static force $F_s$")
    ax2.set_xlabel(f"env step ({cfg.periods_per_step} mesh periods)")
    return fig


def plot_steady_reward(maps: dict[str, Any]):
    """Steady reward per step against constant omega, one curve per map, main penalties below.

    Args:
        maps: label -> :class:`gear_env.envs.steady_map.SteadyRewardMap`.
    """
    from matplotlib.lines import Line2D

    fig = new_figure(9, 6.4)
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    for label, m in maps.items():
        (line,) = ax.plot(
            m.omegas, m.reward, "-o", ms=2.5, lw=1.4, label=f"{label} (best $\\omega$ = {m.best_omega:.2f})"
        )
        c = line.get_color()
        ax2.plot(m.omegas, m.terms["chaos"], "-", color=c, lw=1.2)
        ax2.plot(m.omegas, m.terms["contact_loss"], "--", color=c, lw=1.0)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_ylabel("steady reward per step")
    fig.suptitle("GearSpeed-v0: steady reward of holding $\\omega$ constant (default weights)", fontsize=10)
    # below the panels: inside, the legend covered the dips of the curves
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=7, frameon=False)
    styles = [
        Line2D([], [], color="k", ls="-", lw=1.2, label="chaos indicator c"),
        Line2D([], [], color="k", ls="--", lw=1.0, label="contact-loss fraction"),
    ]
    ax2.legend(handles=styles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    ax2.set_ylabel("fraction (0 to 1)", fontsize=8)
    ax2.set_xlabel(OMEGA)
    return fig


__all__ = ["EnvFrame", "draw_bands", "plot_evaluation", "plot_steady_reward"]
