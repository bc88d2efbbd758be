"""Nonlinear analysis of the gear model: sweeps, motion classification, Lyapunov exponents.

Public API::

    from gear_env.analysis import sweep, SweepResult, classify_motion, Classification, largest_lyapunov

See docs/ANALYSIS.md.
"""

from .classify import Classification, classify_motion
from .lyapunov import largest_lyapunov
from .results import ResultsFileError, SweepResult
from .sweep import steps_for, sweep, sweep_many

__all__ = [
    "Classification",
    "ResultsFileError",
    "SweepResult",
    "classify_motion",
    "largest_lyapunov",
    "steps_for",
    "sweep",
    "sweep_many",
]
