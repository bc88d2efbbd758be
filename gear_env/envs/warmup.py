"""Compile every numba kernel of gear-env ahead of time, several processes at once.

numba compiles a kernel on its first call and keeps it in an on-disk cache
(:mod:`gear_env._numba_cache`); the first process to need the simulator, the environment or
the SIMD batch kernels pays 30-60 s for each of them. :func:`compile_kernels` (command line:
``gear-env compile``) fills the cache beforehand, one subprocess per group of kernels that share
no compiled code, up to ``jobs`` at a time: in a container image, before launching many
``SubprocVecEnv`` workers on a cluster node, or in CI. Processes started afterwards load the
kernels from the cache in well under a second each.

    python -m gear_env.envs.warmup GROUP      # exercise one group in this process (what the workers run)
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed

GROUPS: dict[str, str] = {
    "tangent": "the tangent map of continuation (gear-env continuation, continue_orbits)",
    "simulator": "GearSimulator, simulate, sweeps, Lyapunov, Floquet, GearSpeed-v0 (single env, 1 sub-env)",
    "simd-dynamic": "SIMD batch kernel, dynamic backlash (simulate_batch, vector env of >= 2 sub-envs)",
    "simd-constant": "SIMD batch kernel, constant backlash",
}
"""Groups of kernels compiled by one worker each, slowest first. They share little compiled
code (the split-step fallback), so running them at once duplicates little work."""


def _exercise(group: str) -> None:
    """Call every kernel of ``group`` once on a tiny problem (compiles or loads it)."""
    if group == "simulator":
        import gymnasium as gym

        from ..analysis.lyapunov import largest_lyapunov
        from ..sim.simulator import GearSimulator
        from . import env as _env  # noqa: F401  (registers GearSpeed-v0)
        from .vector_env import GearSpeedVectorEnv

        for model in ("dynamic", "constant"):
            sim = GearSimulator(model=model, omega=1.2, steps_per_period=16)
            sim.advance(1)
            sim.record(1)
        largest_lyapunov(1.2, "dynamic", periods=2, steps_per_period=16)
        e = gym.make("GearSpeed-v0")
        e.reset(seed=0)
        e.step(e.action_space.sample())
        v = GearSpeedVectorEnv(1)
        v.reset(seed=0)
        v.step(v.action_space.sample())
    elif group == "tangent":
        import numpy as np

        from ..analysis import tangent as TG
        from ..sim import kernels as K
        from ..sim.params import GearParams, model_code
        from ..sim.simulator import NEWTON_MAX_ITER, NEWTON_TOL

        x = np.zeros(K.NSTATE)
        jac, pc, info = np.empty((K.NSTATE, K.NSTATE)), np.empty((1, K.NSTATE)), np.empty(TG.N_INFO)
        c = GearParams().consts
        TG.tangent_map(x, 1.2, 1, 16, c, model_code("dynamic"), NEWTON_MAX_ITER, NEWTON_TOL, jac, pc, info, 0)
    elif group in ("simd-dynamic", "simd-constant"):
        from ..sim.simulator import simulate_batch

        simulate_batch([1.0, 1.2], model=group.split("-")[1], periods=1, transient=0, steps_per_period=16)
    else:
        raise ValueError(f"unknown kernel group {group!r}; groups: {', '.join(GROUPS)}")


def check_groups(groups: Sequence[str] | None) -> list[str]:
    """The groups to compile (all if None), validated; ValueError names an unknown one."""
    if groups is None:
        return list(GROUPS)
    out = []
    for g in groups:
        if g not in GROUPS:
            raise ValueError(f"unknown kernel group {g!r}; groups: {', '.join(GROUPS)}")
        if g not in out:
            out.append(g)
    if not out:
        raise ValueError(f"no kernel group given; groups: {', '.join(GROUPS)}")
    return out


def default_jobs() -> int:
    """CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def compile_kernels(
    groups: Sequence[str] | None = None,
    jobs: int | None = None,
    progress: Callable[[str, float, int, int], None] | None = None,
) -> dict[str, float]:
    """Compile (or load from the disk cache) the kernels of ``groups`` (default: all), up to
    ``jobs`` worker processes at once (default: the CPUs available).

    Each group runs in a fresh ``python -m gear_env.envs.warmup GROUP`` process with this process's
    environment (so the same ``NUMBA_CACHE_DIR``). ``progress(group, seconds, done, total)`` is
    called as each finishes. Returns the wall-clock seconds per group. Raises RuntimeError
    naming the groups that failed, with the end of their error output; ValueError for an unknown
    group or a ``jobs`` below 1.
    """
    names = check_groups(groups)
    n_jobs = default_jobs() if jobs is None else jobs
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")

    def run(group: str) -> tuple[str, float, subprocess.CompletedProcess]:
        t = time.perf_counter()
        cp = subprocess.run(
            [sys.executable, "-m", "gear_env.envs.warmup", group], capture_output=True, text=True, env=dict(os.environ)
        )
        return group, time.perf_counter() - t, cp

    times: dict[str, float] = {}
    failed: list[str] = []
    with ThreadPoolExecutor(max_workers=min(n_jobs, len(names))) as pool:
        futures = [pool.submit(run, g) for g in names]
        for fut in as_completed(futures):
            group, dt, cp = fut.result()
            times[group] = dt
            if cp.returncode != 0:
                failed.append(f"{group} (exit {cp.returncode}): {cp.stderr.strip()[-2000:]}")
            if progress is not None:
                progress(group, dt, len(times), len(names))
    if failed:
        raise RuntimeError("kernel compilation failed for " + "; ".join(failed))
    return {g: times[g] for g in names}


if __name__ == "__main__":
    _exercise(sys.argv[1] if len(sys.argv) > 1 else "")
