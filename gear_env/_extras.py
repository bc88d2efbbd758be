"""Optional dependencies: a clear error naming the extra to install when one is missing.

The core install (``pip install gear-env``) has no torch, stable-baselines3 or pandas; the library imports
them only inside the functions that need them, through :func:`require`.
"""

from __future__ import annotations

import importlib
from types import ModuleType

EXTRA_OF = {"torch": "rl", "stable_baselines3": "rl", "pandas": "analysis", "xarray": "analysis"}
"""The pip extra that installs each optional top-level module."""


def require(module: str, what: str) -> ModuleType:
    """Import ``module`` or raise ``ImportError`` saying that ``what`` needs it and which extra installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        extra = EXTRA_OF.get(top)
        hint = f"pip install 'gear-env[{extra}]'" if extra else f"pip install {top}"
        raise ImportError(f"{what} needs {top}, which is not installed: {hint} ({exc})", name=top) from exc


__all__ = ["EXTRA_OF", "require"]
