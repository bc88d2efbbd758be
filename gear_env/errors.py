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


class FileFormatError(ValueError):
    """A file the package was asked to read was refused: missing, too large, corrupt or holding a bad field.

    The message is one line naming the file and, where there is one, the field. Attributes:
        path: the file (as given).
        field: the refused field or archive member, or None.
    """

    def __init__(self, message: str, path: str | None = None, field: str | None = None):
        self.path = path
        self.field = field
        super().__init__(" ".join(str(message).split()))  # one line, whatever the problem text held
