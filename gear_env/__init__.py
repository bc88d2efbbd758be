"""gear-env: nonlinear dynamics of a spur gear-bearing pair and a Gymnasium speed-scheduling env."""

from . import _numba_cache  # noqa: F401  (must run before any kernel module is imported)
from .errors import SimulationDivergedError
from .params import GearParams
from .simulator import (
    DEFAULT_STEPS_PER_PERIOD,
    GearSimulator,
    IntervalStats,
    Trajectory,
    default_initial_state,
    default_steps_per_period,
    simulate,
    simulate_batch,
)

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_STEPS_PER_PERIOD",
    "GearParams",
    "GearSimulator",
    "IntervalStats",
    "SimulationDivergedError",
    "Trajectory",
    "default_initial_state",
    "default_steps_per_period",
    "simulate",
    "simulate_batch",
    "__version__",
]


def _register() -> None:
    """Register ``GearSpeed-v0`` with Gymnasium (the modules load only on ``gym.make``)."""
    import gymnasium as gym

    if "GearSpeed-v0" not in gym.registry:
        gym.register(
            id="GearSpeed-v0",
            entry_point="gear_env.env:GearSpeedEnv",
            vector_entry_point="gear_env.vector_env:GearSpeedVectorEnv",
            max_episode_steps=None,
        )


_register()
