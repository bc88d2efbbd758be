"""numba plumbing of the kernels: the decorators and the helpers that keep one compiled copy of
each kernel (docs/SIMULATOR.md, "one compiled copy per kernel")."""

from __future__ import annotations

import numpy as np
from numba import njit

kernel = njit(cache=True, error_model="numpy")
"""Decorator of every kernel: compiled once, cached on disk, no Python exceptions inside."""
kernel_inline = njit(cache=True, error_model="numpy", inline="always")
"""Small helpers inlined into their callers at numba IR level."""


def readonly(a: np.ndarray) -> np.ndarray:
    """``a`` itself if it is read-only, else a read-only view of it (Python helper, not compiled).

    Kernels take their constants (``GearParams.consts``, one row per system for the batch
    kernels) as read-only arrays everywhere: numba compiles a separate copy of a kernel for a
    writable array argument, and a copy of the Newmark loop costs 25-50 s of first-call compile.
    """
    if not a.flags.writeable:
        return a
    v = a.view()
    v.flags.writeable = False
    return v


@njit(cache=True)
def runtime_int(v):
    """``v`` typed as a plain int64 inside a kernel (not a literal; see :func:`runtime_true`)."""
    return np.int64(v)


@njit(cache=True)
def runtime_true():
    """True typed as a plain boolean inside a kernel.

    A kernel that passes a literal (``1``, ``True``) to another kernel makes numba compile a
    copy of the callee specialised to that literal value; passing these instead reuses the
    copy that calls from Python compile.
    """
    return np.int64(0) == np.int64(0)
