"""Simulator layer: parameters, tooth geometry, the numba kernels and the simulator.

Imports flow parameters (:mod:`~gear_env.sim.params`, :mod:`~gear_env.sim.geometry`) -> kernels
(:mod:`~gear_env.sim.kernels`, :mod:`~gear_env.sim.batch_kernels`, :mod:`~gear_env.sim.integration`)
-> simulator (:mod:`~gear_env.sim.simulator`); :mod:`~gear_env.sim.reference` (SciPy, event-located)
and :mod:`~gear_env.sim.linear` are the independent, readable counterparts the tests compare with.
The public names are exported by :mod:`gear_env` itself (``from gear_env import simulate``). This
``__init__`` imports nothing, so that importing a kernel module does not load the simulator.
"""
