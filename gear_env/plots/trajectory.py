"""Figures of one simulated run: time history, phase portrait and Poincare map."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from .common import B0, OMEGA, S_DEF, new_figure

if TYPE_CHECKING:  # annotations only: the plots take a Trajectory, they do not simulate
    from ..sim.simulator import Trajectory


def plot_trajectory(traj: Trajectory, channel: str = "delta", last_periods: int = 20) -> Figure:
    """Time history (last periods), phase portrait and Poincare map of one run.

    Displacements in b0 (half the nominal backlash); velocities d/ds in b0 per unit natural time
    s = omega_n t; the Poincare map samples the motion once per mesh period. For Delta, the time
    history shows the contact edges +-B_d (drive side above, back side below).

    Args:
        traj: a recorded :class:`~gear_env.sim.simulator.Trajectory`.
        channel: ``"delta"`` (dynamic transmission error, b0 units) or ``"U"``.
        last_periods: mesh periods shown in the time history.
    """
    if channel not in ("delta", "U"):
        raise ValueError(f"channel must be 'delta' or 'U', got {channel!r}")
    n = traj.steps_per_period
    x = traj[channel]
    dx = traj["ddelta"] if channel == "delta" else traj["dU"]
    tau = traj.phase / (2 * np.pi)
    fig = new_figure(12, 4.2)
    axs = fig.subplots(1, 3)
    k = min(len(x), last_periods * n + 1)
    sym = "\\Delta" if channel == "delta" else "U"
    name = "transmission error $\\Delta$" if channel == "delta" else "$U$"
    axs[0].plot(tau[-k:], x[-k:], lw=0.8, label=name)
    if channel == "delta":  # contact edges: drive-side contact above +B_d, back-side below -B_d
        axs[0].plot(tau[-k:], traj["bd"][-k:], "k--", lw=0.6, label="contact edges $\\pm B_d$")
        axs[0].plot(tau[-k:], -traj["bd"][-k:], "k--", lw=0.6)
    axs[0].set_xlabel("time [mesh periods]")
    axs[0].set_ylabel(f"${sym}$ [{B0}]")
    axs[0].set_title("time history")
    # below the axes: inside, the legend covered the top of the curve
    axs[0].legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2, fontsize=8, frameon=False)
    axs[1].plot(x, dx, lw=0.4)
    axs[1].set_xlabel(f"${sym}$ [{B0}]")
    axs[1].set_ylabel(f"$d{sym}/ds$ [{B0}],  {S_DEF}")
    axs[1].set_title("phase portrait")
    px = x[n::n]
    pdx = dx[n::n]
    axs[2].plot(px, pdx, ".", ms=3)
    axs[2].set_xlabel(f"${sym}$ [{B0}]")
    axs[2].set_ylabel(f"$d{sym}/ds$ [{B0}]")
    axs[2].set_title(f"Poincaré map\n{len(px)} points, one per mesh period", fontsize=10)
    for arr, setter in ((px, axs[2].set_xlim), (pdx, axs[2].set_ylim)):
        lo, hi = float(np.min(arr)), float(np.max(arr))
        if hi - lo < 1e-3:  # a periodic orbit: do not blow round-off up to the full axis
            mid = 0.5 * (hi + lo)
            setter(mid - 0.05, mid + 0.05)
    axs[2].ticklabel_format(useOffset=False)
    w = traj.omega
    speed = f"{w[0]:.4g}" + ("" if np.all(w == w[0]) else f" → {w[-1]:.4g}")
    fig.suptitle(f"{traj.model} backlash, {OMEGA} = {speed}")
    return fig
