"""The environment's renderer: :class:`gear_env.plots.env.EnvFrame` over the regime bands of the
environment's configuration (:func:`gear_env.envs.bands.regime_bands`, computed once and cached).

Kept out of :mod:`gear_env.plots` so that the plots take data and never run the environment or
the analysis (docs/ARCHITECTURE.md).
"""

from __future__ import annotations

from typing import Any

from ..plots.env import EnvFrame
from .bands import regime_bands


class EnvRenderer(EnvFrame):
    """The frame of ``env.render()``: omega history over the regime bands, Poincare window, contact.

    Args:
        config: the env's :class:`~gear_env.envs.env_config.GearSpeedConfig`.
        human: show the figure in a matplotlib window (pyplot) instead of off-screen.
    """

    def __init__(self, config: Any, human: bool = False):
        super().__init__(config, bands=regime_bands(config, points=30), human=human)


__all__ = ["EnvRenderer"]
