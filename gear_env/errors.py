"""Exceptions raised by gear-env."""

from __future__ import annotations


class SimulationDivergedError(RuntimeError):
    """The integration blew up (non-finite or exploding state) or Newton failed.

    Attributes:
        period: index of the mesh period (counted from the start of the call) in which it happened.
        reason: short text, e.g. ``"state exceeded 1e6 b0"`` or ``"Newton did not converge"``.
        omega: meshing frequency at the start of the failing call.
    """

    def __init__(self, period: int, reason: str, omega: float | None = None):
        self.period = int(period)
        self.reason = reason
        self.omega = omega
        where = f" at omega={omega:.6g}" if omega is not None else ""
        super().__init__(f"simulation diverged in mesh period {self.period}{where}: {reason}")
