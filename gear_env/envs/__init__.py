"""Environment layer: the Gymnasium tasks and what they are made of.

:mod:`~gear_env.envs.env_terms` (every observation, reward and cost term, once) ->
:mod:`~gear_env.envs.env_kernels` (their numba step) -> :mod:`~gear_env.envs.env_core` (the physics,
features and reward shared by) :mod:`~gear_env.envs.env` (``GearSpeedEnv``) and
:mod:`~gear_env.envs.vector_env` (``GearSpeedVectorEnv``; :mod:`~gear_env.envs.sb3_adapter` for SB3);
settings in :mod:`~gear_env.envs.env_config` and :mod:`~gear_env.envs.tasks` (the registered ids);
scripted speed schedules in :mod:`~gear_env.envs.schedules`; the steady reward map, the regime bands
and the render frame (:mod:`~gear_env.envs.steady_map`, :mod:`~gear_env.envs.bands`,
:mod:`~gear_env.envs.render`); :mod:`~gear_env.envs.warmup` compiles the kernels ahead of use.
The ids are registered by ``import gear_env``. This ``__init__`` imports nothing.
"""
