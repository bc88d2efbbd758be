"""Figures of the nonlinear analysis (the paper's Figs. 5-11 and the Floquet stability map).

Every function takes results objects and returns a ``matplotlib.figure.Figure`` (not attached to
pyplot); :func:`gear_env.plots.common.save_figure` writes it atomically. Units: displacements in b0
(half backlash), omega = Omega/omega_n, psi in degrees, frequencies in multiples of the mesh
frequency, velocities dDelta/ds and Lyapunov exponents per unit natural time s = omega_n t.

Sweep arguments are any object with the attributes of
:class:`gear_env.analysis.results.SweepResult` (``omega``, ``regime``, ``poincare`` (n, periods,
14), ``amplitude`` dict, ``lyapunov`` or None).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from ..sim import kernels as K
from .common import B0, LYAPUNOV, OMEGA, S_DEF, new_figure, plain_log_ticks

if TYPE_CHECKING:  # annotations only: the plots take a Trajectory, they do not simulate
    from ..sim.simulator import Trajectory

MODEL_STYLE = {
    "constant": dict(color="tab:blue", label="constant backlash"),
    "dynamic": dict(color="tab:red", label="dynamic backlash"),
}
LABEL_COLORS = {
    "stable": "#c8e6c9",
    "period-doubling": "#ffe0b2",
    "neimark-sacker": "#f8bbd0",
    "fold": "#d1c4e9",
    "unconverged": "#e0e0e0",
}


def _style(model: str) -> dict[str, Any]:
    return dict(MODEL_STYLE.get(model, dict(color="k", label=model)))


def plot_time_histories(
    trajectories: Mapping[str, Mapping[float, Trajectory]],
    channel: str = "bd",
    periods: int = 10,
) -> Figure:
    """Time histories of one channel at several omegas (paper Fig. 5: ``"bd"``, Fig. 6: ``"psi"``).

    Args:
        trajectories: model name -> {omega: Trajectory}; one row per omega, models overlaid.
        channel: ``"bd"`` (dynamic backlash B_d, b0), ``"psi"`` (meshing angle, plotted in degrees),
            ``"delta"`` or ``"U"``.
        periods: mesh periods shown (the last ones of each record).
    """
    omegas = sorted({w for d in trajectories.values() for w in d})
    if not omegas:
        raise ValueError("trajectories must hold at least one run")
    fig = new_figure(9, 2.3 * len(omegas) + 0.6)
    axs = np.atleast_1d(fig.subplots(len(omegas), 1, squeeze=False)[:, 0])
    for ax, w in zip(axs, omegas, strict=True):
        for model, runs in trajectories.items():
            if w not in runs:
                continue
            tr = runs[w]
            n = tr.steps_per_period
            k = min(len(tr.s), periods * n + 1)
            y = tr[channel][-k:]
            if channel == "psi":
                y = np.degrees(y)
            t = (tr.phase[-k:] - tr.phase[-k]) / (2 * np.pi)
            ax.plot(t, y, lw=1.0, **_style(model))
        ax.set_title(f"$\\omega$ = {w:g}", fontsize=10)
        unit = "deg" if channel == "psi" else B0
        ax.set_ylabel(f"{_chan_tex(channel)} [{unit}]")
        ax.ticklabel_format(axis="y", useOffset=False)
        _flat_at_round_off(ax, 1.0 if channel == "psi" else 0.05)
    axs[-1].set_xlabel("time [mesh periods]")
    # above the panels, so that it covers no curve
    fig.legend(*axs[0].get_legend_handles_labels(), loc="outside upper center", ncols=4, fontsize=8, frameon=False)
    return fig


def _flat_at_round_off(ax: Any, window: float) -> None:
    """An axis whose curves are constant to round-off shows +-window around them (not ticks such as
    20.00000000002) and says so."""
    ys = [np.asarray(line.get_ydata(), float) for line in ax.lines]
    if not ys:
        return
    lo, hi = min(float(y.min()) for y in ys), max(float(y.max()) for y in ys)
    mid = 0.5 * (lo + hi)
    if hi - lo <= 1e-9 * max(1.0, abs(mid)):
        ax.set_ylim(mid - window, mid + window)
        ax.text(0.01, 0.04, f"constant at {mid:.6g} to round-off", transform=ax.transAxes, fontsize=8)


def _sorted(sw: Any) -> tuple[np.ndarray, np.ndarray]:
    w = np.asarray(sw.omega, dtype=float)
    order = np.argsort(w, kind="stable")
    return w[order], order


def plot_amplitude_frequency(
    sweeps: Mapping[str, Any],
    channels: Sequence[str] = ("bd", "psi"),
) -> Figure:
    """Amplitude-frequency curves (half peak-to-peak vs omega) of several channels (paper Fig. 7).

    Args:
        sweeps: curve label (e.g. ``"forward"``, ``"reverse"``) -> sweep result.
        channels: amplitude names (``"U"``, ``"delta"``, ``"bd"``, ``"psi"``, ``"force"``).
    """
    fig = new_figure(9, 3.0 * len(channels) + 0.4)
    axs = fig.subplots(len(channels), 1, squeeze=False)[:, 0]
    styles = [dict(color="tab:red", lw=1.2), dict(color="tab:blue", lw=0.9, ls="--"), dict(color="tab:green", lw=0.9)]
    for ax, ch in zip(axs, channels, strict=True):
        for k, (lab, sw) in enumerate(sweeps.items()):
            w, o = _sorted(sw)
            a = np.asarray(sw.amplitude[ch])[o]
            if ch == "psi":
                a = np.degrees(a)
            ax.plot(w, a, marker=".", ms=2.5, label=lab, **styles[k % len(styles)])
        unit = "deg" if ch == "psi" else B0
        ax.set_ylabel(f"amplitude of {_chan_tex(ch)} [{unit}]")
        top = max(float(np.max(np.abs(np.asarray(sw.amplitude[ch])))) for sw in sweeps.values())
        if ch == "psi" and top < 1e-12:
            # eqs. (5)-(10) keep psi at alpha0 (MODEL.md sec. 6): show the round-off level as such
            ax.set_ylim(0, 1e-12)
            ax.text(
                0.5,
                0.5,
                "$\\psi - \\alpha_0$ stays at round-off level (< $10^{-13}$ deg):\nno force moves the centres "
                "off the line of action\n(see docs/RESULTS.md; GearParams.friction > 0 changes this)",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=9,
            )
        elif ch != "psi":
            ax.set_yscale("log")
            plain_log_ticks(ax)
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, title="sweep direction", title_fontsize=8)
    axs[-1].set_xlabel(OMEGA)
    return fig


def _chan_tex(ch: str) -> str:
    return {"bd": "$B_d$", "psi": "$\\psi$", "delta": "$\\Delta$", "U": "$U$", "force": "$F$"}.get(ch, ch)


def plot_phase_portraits(runs: Mapping[float, Trajectory], title: str = "") -> Figure:
    """Phase portraits (Delta, dDelta/ds) and Poincare maps at several omegas (paper Fig. 8).

    Delta and dDelta/ds in b0 (s = omega_n t, natural time); the Poincare map samples the motion
    once per mesh period (mesh phase 2 pi k). A dotted line marks the mean dynamic backlash B_d
    (the contact edge Delta = B_d). A Poincare map whose points coincide to round-off (a period-1
    orbit) is shown on a +-0.05 window rather than blown up to its round-off spread.

    Args:
        runs: {omega: Trajectory} (one column per omega).
        title: figure title (e.g. the model).
    """
    omegas = sorted(runs)
    if not omegas:
        raise ValueError("runs must hold at least one trajectory")
    fig = new_figure(3.3 * len(omegas), 6.0)
    axs = fig.subplots(2, len(omegas), squeeze=False)
    for j, w in enumerate(omegas):
        tr = runs[w]
        d, dd = tr["delta"], tr["ddelta"]
        axs[0, j].plot(d, dd, lw=0.3, color="tab:blue")
        axs[0, j].set_title(f"$\\omega$ = {w:g}", fontsize=10)
        n = tr.steps_per_period
        pd, pdd = d[n::n], dd[n::n]
        axs[1, j].plot(pd, pdd, ".", ms=2.0, color="tab:red")
        _zoom_round_off(axs[1, j], pd, pdd)
        for ax in axs[:, j]:
            ax.axvline(tr["bd"].mean(), color="k", lw=0.5, ls=":", label="mean $B_d$ (contact edge)")
            ax.set_xlabel(f"$\\Delta$ [{B0}]")
    axs[0, 0].set_ylabel(f"phase portrait\n$d\\Delta/ds$ [{B0}]")
    axs[1, 0].set_ylabel(f"Poincaré map (once per mesh period)\n$d\\Delta/ds$ [{B0}]")
    handles, labels = axs[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize=8, frameon=False)
    fig.suptitle((f"{title}; " if title else "") + f"velocity $d\\Delta/ds$ in natural time {S_DEF}")
    return fig


def _zoom_round_off(ax: Any, x: np.ndarray, y: np.ndarray, window: float = 0.05) -> None:
    """Keep a Poincare map whose points agree to round-off on a +-window range (not the spread)."""
    if x.size == 0:
        return
    for arr, setter in ((x, ax.set_xlim), (y, ax.set_ylim)):
        lo, hi = float(np.min(arr)), float(np.max(arr))
        if hi - lo < 1e-3:
            mid = 0.5 * (hi + lo)
            setter(mid - window, mid + window)
    ax.ticklabel_format(useOffset=False)


def plot_amplitude_vs_omega(sweeps: Mapping[str, Any], channel: str = "U") -> Figure:
    """Response amplitude vs omega for several models (paper Fig. 9).

    Args:
        sweeps: model name -> forward sweep result.
        channel: amplitude name (default ``"U"``, the paper's vibration displacement).
    """
    fig = new_figure(9, 4.0)
    ax = fig.subplots()
    for model, sw in sweeps.items():
        w, o = _sorted(sw)
        ax.plot(w, np.asarray(sw.amplitude[channel])[o], marker=".", ms=2.5, lw=1.0, **_style(model))
    ax.set_xlabel(OMEGA)
    ax.set_ylabel(f"amplitude of {_chan_tex(channel)} [{B0}]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def plot_waterfall(wf: Any, title: str = "") -> Figure:
    """3-D amplitude spectrum over omega (paper Fig. 10): one spectrum line per omega.

    Args:
        wf: :class:`gear_env.analysis.spectrum.Waterfall`.
    """
    fig = new_figure(8, 6)
    ax = fig.add_subplot(projection="3d")
    f = np.asarray(wf.frequency)
    amp = np.asarray(wf.amplitude)
    for i, w in enumerate(wf.omega):
        ax.plot(f, np.full_like(f, w), amp[i], lw=0.6, color="tab:blue")
    ax.set_xlabel("frequency / mesh frequency")
    ax.set_ylabel(OMEGA)
    ax.set_zlabel(f"amplitude of {_chan_tex(wf.channel)} [{B0}]")
    ax.view_init(elev=28, azim=-60)
    if title:
        ax.set_title(title)
    return fig


def plot_bifurcation(sweeps: Mapping[str, Any], column: int = K.PC_DELTA) -> Figure:
    """Bifurcation diagrams: Poincare samples of Delta (default) over omega, one panel per model
    (paper Fig. 11).

    Args:
        sweeps: panel title (e.g. model) -> sweep result.
        column: Poincare column (``kernels.PC_*`` layout; default PC_DELTA).
    """
    fig = new_figure(9, 3.3 * len(sweeps) + 0.3)
    axs = fig.subplots(len(sweeps), 1, squeeze=False)[:, 0]
    for ax, (name, sw) in zip(axs, sweeps.items(), strict=True):
        pc = np.asarray(sw.poincare)
        w = np.repeat(np.asarray(sw.omega, dtype=float), pc.shape[1])
        ax.plot(w, pc[:, :, column].ravel(), ",", color="k", alpha=0.6, rasterized=True)
        ax.set_title(name, fontsize=10)
        ylab = f"Poincaré samples of $\\Delta$ [{B0}]\n(mesh phase $2\\pi k$)"
        ax.set_ylabel(ylab if column == K.PC_DELTA else f"Poincaré column {column}")
    axs[-1].set_xlabel(OMEGA)
    return fig


LABEL_NAMES = {
    "stable": "stable",
    "period-doubling": "period doubling",
    "neimark-sacker": "Neimark–Sacker (torus)",
    "fold": "fold",
    "unconverged": "no orbit found",
}


def _shade_labels(ax: Any, smap: Any) -> None:
    seen = set()
    for lo, hi, lab in smap.intervals():
        name = LABEL_NAMES.get(lab, lab)
        ax.axvspan(lo, hi, color=LABEL_COLORS.get(lab, "#eeeeee"), lw=0, label=None if lab in seen else name)
        seen.add(lab)


def plot_stability_map(smap: Any, sweep: Any | None = None, title: str = "") -> Figure:
    """Floquet stability of the period-1 orbit over omega (a figure the paper lacks).

    Panels: max |multiplier| with the intervals shaded by label (stable / period doubling /
    Neimark-Sacker); the angle of the critical multiplier (0 fold, 180 deg period doubling, between:
    torus); and, if a sweep with Lyapunov exponents is given, its largest Lyapunov exponent.

    Args:
        smap: :class:`gear_env.analysis.stability.StabilityMap`.
        sweep: optional sweep result with ``lyapunov`` (same model).
    """
    has_ly = sweep is not None and getattr(sweep, "lyapunov", None) is not None
    rows = 3 if has_ly else 2
    fig = new_figure(9, 2.6 * rows + 0.4)
    axs = fig.subplots(rows, 1, sharex=True)
    w = smap.omega
    ok = np.asarray(smap.converged, dtype=bool)
    ax = axs[0]
    _shade_labels(ax, smap)
    ax.plot(w[ok], smap.max_multiplier[ok], "k.-", ms=2.5, lw=0.8)
    ax.axhline(1.0, color="k", lw=0.6, ls="--")
    ax.set_ylabel(r"max $|\mu|$ (Floquet multiplier)")
    ax.set_ylim(0, max(1.5, float(np.max(smap.max_multiplier[ok], initial=1.0)) * 1.05))
    # below the panels: the shading runs under every curve, a legend inside would cover one
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=5, fontsize=8, frameon=False)
    ax = axs[1]
    _shade_labels(ax, smap)
    mu0 = smap.multipliers[:, 0]
    ax.plot(w[ok], np.degrees(np.abs(np.angle(mu0[ok]))), "k.", ms=2.5)
    ax.set_ylabel(r"$|\arg \mu|$ of the largest" + "\n" + "multiplier [deg]")
    ax.set_ylim(-5, 185)
    if has_ly:
        ax = axs[2]
        _shade_labels(ax, smap)
        sw, o = _sorted(sweep)
        ly = np.asarray(sweep.lyapunov)[o]
        ax.plot(sw, ly, ".-", color="tab:purple", ms=2.5, lw=0.8)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel(LYAPUNOV)
    axs[-1].set_xlabel(OMEGA)
    fig.suptitle(title or f"Stability of the period-1 orbit, {smap.model} backlash")
    return fig


def plot_multipliers_complex(smap: Any, omegas: Sequence[float]) -> Figure:
    """Floquet multipliers in the complex plane at a few omegas, with the unit circle."""
    fig = new_figure(5, 5)
    ax = fig.subplots()
    t = np.linspace(0, 2 * math.pi, 200)
    ax.plot(np.cos(t), np.sin(t), "k-", lw=0.6)
    for w in omegas:
        i = int(np.argmin(np.abs(smap.omega - w)))
        mu = smap.multipliers[i]
        lab = LABEL_NAMES.get(str(smap.labels[i]), smap.labels[i])
        ax.plot(mu.real, mu.imag, "o", ms=4, label=f"$\\omega$ = {smap.omega[i]:.2f}: {lab}")
    ax.set_aspect("equal")
    ax.set_xlabel("Re $\\mu$")
    ax.set_ylabel("Im $\\mu$")
    ax.legend(fontsize=7)
    return fig


__all__ = [
    "plot_amplitude_frequency",
    "plot_amplitude_vs_omega",
    "plot_bifurcation",
    "plot_multipliers_complex",
    "plot_phase_portraits",
    "plot_stability_map",
    "plot_time_histories",
    "plot_waterfall",
]
