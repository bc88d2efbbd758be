"""Small forced oscillators with known answers, for validating the classifier and the Lyapunov
estimate independently of the gear model.

The forced Duffing oscillator ``x'' + delta x' + alpha x + beta x^3 = gamma cos(omega t)``
is integrated with classical fixed-step RK4 (``n_steps`` per forcing period), an integrator
independent of the gear model's Newmark kernel. With ``alpha = -1, beta = 1, delta = 0.3,
omega = 1.2`` (the twin-well oscillator of Guckenheimer & Holmes, sec. 2.2) increasing ``gamma``
gives a period-doubling cascade into chaos; with ``beta = 0, alpha = 1, delta = 2 xi`` it is a
linear oscillator whose Lyapunov exponents are both ``-xi`` (per unit time) for ``xi < 1``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .lyapunov import lyapunov_map


@njit(cache=True)
def _rhs(t, x, v, delta, alpha, beta, gamma, omega):
    return v, gamma * math.cos(omega * t) - delta * v - alpha * x - beta * x * x * x


@njit(cache=True)
def duffing_advance(state, n_periods, n_steps, delta, alpha, beta, gamma, omega, out):
    """Advance ``state = [x, v]`` (in place) by ``n_periods`` forcing periods from t = 0 (mod T),
    writing the state at the end of each period into ``out`` (n_periods, 2) if it has rows."""
    h = 2.0 * math.pi / omega / n_steps
    x = state[0]
    v = state[1]
    for p in range(n_periods):
        t = 0.0
        for _ in range(n_steps):
            k1x, k1v = _rhs(t, x, v, delta, alpha, beta, gamma, omega)
            k2x, k2v = _rhs(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v, delta, alpha, beta, gamma, omega)
            k3x, k3v = _rhs(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v, delta, alpha, beta, gamma, omega)
            k4x, k4v = _rhs(t + h, x + h * k3x, v + h * k3v, delta, alpha, beta, gamma, omega)
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
            t += h
        if out.shape[0] > 0:
            out[p, 0] = x
            out[p, 1] = v
    state[0] = x
    state[1] = v


class Duffing:
    """The forced Duffing oscillator with fixed parameters (see the module docstring)."""

    def __init__(self, gamma: float, delta: float = 0.3, alpha: float = -1.0, beta: float = 1.0,
                 omega: float = 1.2, n_steps: int = 200):  # fmt: skip
        self.args = (float(delta), float(alpha), float(beta), float(gamma), float(omega))
        self.omega = float(omega)
        self.n_steps = int(n_steps)
        self._none = np.empty((0, 2))

    @property
    def period(self) -> float:
        """Forcing period 2 pi / omega (time units of the equation)."""
        return 2.0 * math.pi / self.omega

    def advance(self, x: np.ndarray, periods: int = 1) -> float:
        """Advance ``x`` in place by whole forcing periods; return the elapsed time."""
        duffing_advance(x, periods, self.n_steps, *self.args, self._none)
        return periods * self.period

    def poincare(self, x0=(0.1, 0.0), transient: int = 500, periods: int = 200) -> tuple[np.ndarray, np.ndarray]:
        """(Poincare points (periods, 2), final state) after a transient."""
        x = np.array(x0, float)
        self.advance(x, transient)
        out = np.empty((periods, 2))
        duffing_advance(x, periods, self.n_steps, *self.args, out)
        return out, x

    def lyapunov(self, x0, periods: int = 400, d0: float = 1e-8) -> float:
        """Largest Lyapunov exponent (per unit time) by two-trajectory renormalisation."""
        return lyapunov_map(lambda x: self.advance(x, 1), x0, periods, d0)


def linear_oscillator(xi: float, omega: float = 1.3, force: float = 1.0, n_steps: int = 200) -> Duffing:
    """``x'' + 2 xi x' + x = force cos(omega t)``: largest Lyapunov exponent exactly -xi (xi < 1)."""
    return Duffing(gamma=force, delta=2.0 * xi, alpha=1.0, beta=0.0, omega=omega, n_steps=n_steps)
