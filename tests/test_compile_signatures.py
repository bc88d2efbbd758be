"""Each Newmark kernel is compiled once per process, whichever public path calls it first.

numba compiles a separate copy of a kernel for every distinct argument type signature: a
writable instead of a read-only constants array, or a literal ``1`` / ``True`` passed from one
kernel to another, each cost another 25-50 s of first-call compile. The simulator, the single
and the vector environments, the Lyapunov kernel and the scalar batch kernel must all share
one compiled copy (``kernels.readonly``, ``kernels.runtime_true``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

_CHILD = r"""
import json
import gymnasium as gym
import gear_env.envs.env
from gear_env import GearSimulator
from gear_env.sim import batch_kernels as BK
from gear_env.sim import kernels as K
from gear_env.analysis.lyapunov import largest_lyapunov
from gear_env.envs.vector_env import GearSpeedVectorEnv

GearSimulator(model="dynamic", omega=1.2, steps_per_period=32).advance(2)
e = gym.make("GearSpeed-v0")
e.reset(seed=0)
e.step(e.action_space.sample())
largest_lyapunov(1.2, "dynamic", periods=3, transient=1, steps_per_period=32)
v = GearSpeedVectorEnv(1)  # one sub-env: the scalar batch kernel
v.reset(seed=0)
v.step(v.action_space.sample())
v = GearSpeedVectorEnv(8)  # the SIMD lanes kernel (its start_step and split_step_t: the scalar kernels' copies)
v.reset(seed=0)
v.step(v.action_space.sample())
names = ("integrate_stats", "integrate_stats_tab", "stats_segment", "split_resume", "static_equilibrium")
counts = {n: len(getattr(K, n).overloads) for n in (*names, "start_step", "split_step_t")}
counts["_retire"] = len(BK._retire.overloads)
print(json.dumps(counts))
"""


@pytest.mark.slow
def test_one_compiled_signature_per_kernel(tmp_path):
    """From an empty cache (~40 s of compile): with a warm one, kernels called from other kernels
    come out of their callers' cached code and the dispatchers list no overloads to count."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts == {
        "integrate_stats": 1,
        "integrate_stats_tab": 1,
        "stats_segment": 1,  # called from Python (integrate_stats_lazy) and from integrate_stats_tab
        "split_resume": 1,
        "static_equilibrium": 1,
        "start_step": 1,  # also from the lanes kernel's _load_block (runtime_int, not the literal model code)
        "split_step_t": 1,  # compiled with split_resume (the Lyapunov kernel); the lanes kernel calls none
        "_retire": 1,  # lanes: one copy for both row offsets
    }
