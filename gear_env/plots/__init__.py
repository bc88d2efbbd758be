"""matplotlib figures. Every function takes results and returns a ``Figure``; nothing is shown
unless the caller asks. ``save_figure`` writes a PNG atomically."""

from .common import save_figure
from .trajectory import plot_trajectory

__all__ = ["plot_trajectory", "save_figure"]
