"""Amplitude spectra of a response and the waterfall over omega (the paper's Fig. 10).

The simulator samples uniformly in mesh phase (``steps_per_period`` samples per mesh period), so at
a constant omega a record is uniformly sampled in time and its FFT frequency axis is naturally in
multiples of the mesh frequency: bin k of a record of ``P`` whole mesh periods is the frequency
k / P times the mesh frequency (resolution 1/P, Nyquist ``steps_per_period / 2``).

Method: the mean is removed, the record is cut to an integer number of mesh periods, multiplied by a
Hann window and transformed; the one-sided amplitude is ``2 |X_k| / sum(w)`` (coherent-gain
correction). A harmonic of the mesh frequency, or of a sub-harmonic 1/N with N dividing P, falls
exactly on a bin and its peak reads its true amplitude; the window keeps the leakage of
quasi-periodic and chaotic components local (side lobes fall as 1/k^3) at the cost of spreading a
line over three bins.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..sim.params import GearParams
from ..sim.simulator import GearSimulator, Trajectory, check_count, check_omega


@dataclass(frozen=True)
class Spectrum:
    """One-sided amplitude spectrum.

    Attributes:
        frequency: (n,) frequencies in multiples of the mesh frequency (Omega).
        amplitude: (n,) amplitudes, same unit as the signal (b0 for displacements).
        periods: mesh periods analysed.
    """

    frequency: np.ndarray
    amplitude: np.ndarray
    periods: int

    def amplitude_at(self, multiple: float) -> float:
        """Largest amplitude within half a bin of ``multiple`` x the mesh frequency."""
        df = 1.0 / self.periods
        sel = np.abs(self.frequency - multiple) <= 0.5 * df + 1e-12
        if not np.any(sel):
            raise ValueError(f"multiple must be in [0, {self.frequency[-1]:g}], got {multiple!r}")
        return float(self.amplitude[sel].max())


def amplitude_spectrum(
    data: Trajectory | Sequence[float] | np.ndarray,
    channel: str = "delta",
    steps_per_period: int | None = None,
    max_multiple: float | None = None,
    window: str = "hann",
) -> Spectrum:
    """FFT amplitude spectrum with the frequency axis in multiples of the mesh frequency.

    Args:
        data: a :class:`Trajectory` (constant omega) or a 1-D signal sampled ``steps_per_period``
            times per mesh period, uniformly in mesh phase.
        channel: trajectory channel (``"delta"``, ``"U"``, ``"bd"``, ``"psi"``, ``"force"``...).
        steps_per_period: samples per mesh period (taken from the trajectory if omitted).
        max_multiple: keep frequencies up to this multiple of the mesh frequency (default: Nyquist).
        window: ``"hann"`` (default) or ``"rect"`` (no window).

    Returns:
        :class:`Spectrum`. Only whole mesh periods are used (the last sample of a trajectory, which
        repeats the phase of the first, is dropped).
    """
    if isinstance(data, Trajectory):
        x = np.asarray(data[channel], dtype=float)[:-1]
        n = data.steps_per_period if steps_per_period is None else steps_per_period
        w = data.omega
        if np.ptp(w) > 1e-12 * max(1.0, float(np.max(w))):
            raise ValueError("the trajectory's omega varies; a spectrum needs a constant omega")
    else:
        x = np.asarray(data, dtype=float)
        if x.ndim != 1:
            raise ValueError(f"data must be a Trajectory or a 1-D signal, got shape {x.shape}")
        if steps_per_period is None:
            raise ValueError("steps_per_period is required for a raw signal")
        n = steps_per_period
    n = check_count(n, "steps_per_period", 2)
    periods = len(x) // n
    if periods < 2:
        raise ValueError(f"need at least 2 whole mesh periods of data ({2 * n} samples), got {len(x)}")
    if not np.all(np.isfinite(x)):
        raise ValueError("data must be finite")
    x = x[: periods * n]
    x = x - x.mean()
    if window == "hann":
        win = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(len(x)) / len(x))  # periodic Hann
    elif window == "rect":
        win = np.ones(len(x))
    else:
        raise ValueError(f"window must be 'hann' or 'rect', got {window!r}")
    amp = 2.0 * np.abs(np.fft.rfft(x * win)) / win.sum()
    amp[0] = 0.0
    freq = np.arange(len(amp)) / periods
    if max_multiple is not None:
        if not (np.isfinite(max_multiple) and max_multiple > 0):
            raise ValueError(f"max_multiple must be a number > 0, got {max_multiple!r}")
        keep = freq <= max_multiple + 1e-12
        freq, amp = freq[keep], amp[keep]
    return Spectrum(frequency=freq, amplitude=amp, periods=periods)


@dataclass(frozen=True)
class Waterfall:
    """Spectra over a grid of omega (paper Fig. 10).

    Attributes:
        omega: (m,) meshing frequencies.
        frequency: (n,) frequency axis in multiples of the mesh frequency.
        amplitude: (m, n) amplitude spectra.
        channel, model: what was analysed.
    """

    omega: np.ndarray
    frequency: np.ndarray
    amplitude: np.ndarray
    channel: str
    model: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "omega": self.omega.tolist(),
            "frequency": self.frequency.tolist(),
            "amplitude": self.amplitude.tolist(),
            "channel": self.channel,
            "model": self.model,
        }


def waterfall(
    omegas: Sequence[float] | np.ndarray,
    model: str = "dynamic",
    channel: str = "delta",
    periods: int = 64,
    transient: int = 300,
    params: GearParams | None = None,
    steps_per_period: int | None = None,
    max_multiple: float = 4.0,
    progress: Callable[[int, int], None] | None = None,
) -> Waterfall:
    """Amplitude spectra of ``channel`` over a grid of omega, warm-started like a slow forward sweep.

    Args:
        omegas: meshing frequencies (in the order they are visited).
        model: backlash model.
        channel: trajectory channel analysed (default the dynamic transmission error Delta).
        periods: mesh periods per spectrum (frequency resolution 1/periods of the mesh frequency).
        transient: mesh periods discarded at each omega before recording.
        params: physical parameters (default Table 1).
        steps_per_period: Newmark steps per mesh period; None: ``default_steps_per_period(omega)``.
        max_multiple: highest frequency kept, in multiples of the mesh frequency.
        progress: optional callback ``progress(done, total)``.

    Returns:
        :class:`Waterfall`.
    """
    w = np.asarray(omegas, dtype=float)
    if w.ndim != 1 or len(w) == 0:
        raise ValueError("omegas must be a non-empty 1-D sequence")
    for v in w:
        check_omega(float(v), "omegas")
    check_count(periods, "periods", 2)
    check_count(transient, "transient", 0)
    sim = GearSimulator(params, model, steps_per_period, float(w[0]))
    rows = []
    freq = None
    for i, wi in enumerate(w):
        sim.omega = float(wi)
        if transient:
            sim.advance(transient)
        spec = amplitude_spectrum(sim.record(periods), channel, max_multiple=max_multiple)
        freq = spec.frequency
        rows.append(spec.amplitude)
        if progress is not None:
            progress(i + 1, len(w))
    return Waterfall(omega=w, frequency=np.asarray(freq), amplitude=np.array(rows), channel=channel, model=model)


__all__ = ["Spectrum", "Waterfall", "amplitude_spectrum", "waterfall"]
