"""gear-env: nonlinear dynamics of a spur gear-bearing pair and a Gymnasium speed-scheduling env."""

from . import (
    _moved,
    _numba_cache,  # noqa: F401  (must run before any kernel module is imported)
)
from .errors import FileFormatError, SimulationDivergedError
from .sim.params import GearParams
from .sim.simulator import (
    DEFAULT_STEPS_PER_PERIOD,
    GearSimulator,
    IntervalStats,
    Trajectory,
    default_initial_state,
    default_steps_per_period,
    simulate,
    simulate_batch,
)

__version__ = "0.4.0"
"""The package version: the newest release of CHANGELOG.md; pyproject.toml reads it from here."""

__all__ = [
    "DEFAULT_STEPS_PER_PERIOD",
    "GearParams",
    "GearSimulator",
    "IntervalStats",
    "FileFormatError",
    "SimulationDivergedError",
    "Trajectory",
    "default_initial_state",
    "default_steps_per_period",
    "simulate",
    "simulate_batch",
    "__version__",
]


def _register() -> None:
    """Register the tasks of :data:`gear_env.envs.tasks.TASK_SETTINGS` with Gymnasium (``GearSpeed-v0``,
    ``GearSpeed-v1``, ``GearSpeedDemand-v0``; the env modules load only on ``gym.make``), each with
    ``max_episode_steps`` = its episode length."""
    import gymnasium as gym

    from .envs.tasks import TASK_SETTINGS

    for env_id, settings in TASK_SETTINGS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point="gear_env.envs.env:GearSpeedEnv",
                vector_entry_point="gear_env.envs.vector_env:GearSpeedVectorEnv",
                kwargs=dict(settings),
                max_episode_steps=int(settings.get("max_steps", 200)),
            )


_register()
_moved.install()  # the module paths of 0.4 (gear_env.simulator, ...) as deprecated aliases
