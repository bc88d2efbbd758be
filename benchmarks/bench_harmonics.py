"""Cost of a Fourier-series excitation: 16 stiffness harmonics (+ a 3-harmonic TE) against one cosine.

The same gear pair (the paper's, its stiffness from the teeth: ``GearParams.from_pair`` with
Table 1's masses and inertias) once with the geometry's 16 harmonics and once with only the
first (the single-cosine path of the kernels), in mesh periods per second, interleaved A/B
rounds in one process on one core (the ratio is what counts; the VMs drift 1.5-2x over minutes):

The pure cost of the series is the "same motion" variant (16 stiffness and 3 TE terms, the higher
ones zero); the geometry's harmonics also change the motion (contact loss, Newton iterations,
step splitting), which costs or saves more than the series itself.

* ``simulator``: ``GearSimulator.advance`` over 200 mesh periods (one excitation table per call);
* ``env``: ``GearSpeedVectorEnv`` (16 sub-envs) steps, where the table is rebuilt at every
  step for every sub-env (the shortest intervals, the worst case for the series).

    python benchmarks/bench_harmonics.py [--rounds 7]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gear_env import GearParams, GearSimulator
from gear_env.envs.vector_env import GearSpeedVectorEnv
from gear_env.sim.geometry import SpurPair

PAIR = SpurPair(module=2e-3, teeth=(55, 75), face_width=0.03785, bore=(0.04, 0.05))
TABLE1 = dict(J_p=0.041, J_g=0.079, m_p=1.53, m_g=3.01)


def variants() -> dict[str, GearParams]:
    """The single cosine; the same excitation as a 16-term stiffness series and a 3-term TE series
    with zero higher terms (the series path of the kernels, the same motion: the pure cost of
    evaluating the series); the geometry's 16 harmonics (a different motion) and with a 3-harmonic TE."""
    many = GearParams.from_pair(PAIR, 16, **TABLE1)
    one = many.replace(stiffness_harmonics=many.stiffness_harmonics[:1])
    padded = one.replace(
        stiffness_harmonics=many.stiffness_harmonics[:1] + ((0.0, 0.0),) * 15,
        te_harmonics=((one.e_m1, one.phi_e), (0.0, 0.0), (0.0, 0.0)),
    )
    te3 = ((1e-5, 0.0), (3e-6, 0.5), (1e-6, -1.0))
    return {"1 cosine": one, "series 16+3, same motion": padded, "16 harmonics": many,
            "16 + TE 3": many.replace(te_harmonics=te3)}  # fmt: skip


def sim_rate(p: GearParams, omega: float, periods: int = 200) -> float:
    sim = GearSimulator(p, "dynamic", None, omega)
    sim.advance(50)
    t = time.process_time()
    sim.advance(periods)
    return periods / (time.process_time() - t)


def env_rate(p: GearParams, steps: int = 100) -> float:
    env = GearSpeedVectorEnv(16, params=p)
    env.reset(seed=0)
    act = np.zeros((16,) + env.single_action_space.shape, np.float32)
    env.step(act)
    t = time.process_time()
    for _ in range(steps):
        env.step(act)
    dt = time.process_time() - t
    env.close()
    return steps * 16 / dt  # sub-env steps per second


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    vs = variants()
    for p in vs.values():  # compile and warm
        sim_rate(p, 1.2, 5)
        env_rate(p, 2)
    print(f"load {os.getloadavg()}")
    for what, fn in (("simulator, omega 1.2 [periods/s]", lambda p: sim_rate(p, 1.2)),
                     ("simulator, omega 0.45 [periods/s]", lambda p: sim_rate(p, 0.45)),
                     ("vector env, 16 sub-envs [env steps/s]", env_rate)):  # fmt: skip
        rates: dict[str, list[float]] = {k: [] for k in vs}
        for _ in range(args.rounds):
            for k, p in vs.items():
                rates[k].append(fn(p))
        base = np.array(rates["1 cosine"])
        line = [f"{what}: 1 cosine {np.median(base):.0f}"]
        for k in list(vs)[1:]:
            r = base / np.array(rates[k])  # time ratio per round (series / single cosine)
            line.append(f"{k} {np.median(rates[k]):.0f} (time x{np.median(r):.3f}, rounds {r.min():.3f}-{r.max():.3f})")
        print("; ".join(line))
    print(f"load {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
