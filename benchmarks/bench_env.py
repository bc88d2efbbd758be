"""Speed of GearSpeed-v0: single env, vector env at 1/8/64 sub-envs, and CartPole-v1 for scale.

Run:  taskset -c 0 python benchmarks/bench_env.py [--seconds 3] [--rounds 1] [--trade] [--json FILE]

"physics alone" times the two batch kernels on the same 64 initial states: the SIMD lanes kernel
the vector env uses and the scalar one (one system after the other) it replaced.

Every number is measured in this one run on one core, as steps per second of this process's CPU
time (robust against other jobs sharing the machine; compile time excluded: a warm-up runs
first). Actions are uniform random in [-1, 1] (seeded); episodes auto-reset, so the warm-up of
each new episode is included in the cost. ``--trade`` also times other control intervals and step
sizes (periods_per_step x steps_per_period).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def _timed(step_fn, seconds: float) -> tuple[int, float]:
    """Run ``step_fn`` in batches of 10 for ~``seconds`` of CPU time; return (calls, CPU seconds).

    CPU time of this process (``time.process_time``) rather than wall time: on a machine shared
    with other jobs the wall-clock rate depends on the load, the CPU-time rate is the speed of
    one core given to this process.
    """
    n = 0
    c0 = time.process_time()
    c = c0
    while c - c0 < seconds:
        for _ in range(10):
            step_fn()
        n += 10
        c = time.process_time()
    return n, c - c0


def bench_single(seconds: float, env_id: str | None = None, actions: np.ndarray | None = None, **cfg) -> float:
    """Env steps per second of one GearSpeedEnv (random actions, auto-reset); with ``env_id``, of
    ``gym.make(env_id, **cfg)`` (its wrappers included); with ``actions`` (T, 1), those replayed in turn instead
    of random ones (:func:`record_policy_actions`)."""
    if env_id is None:
        from gear_env.envs.env import GearSpeedEnv

        env = GearSpeedEnv(**cfg)
    else:
        import gymnasium as gym

        import gear_env  # noqa: F401  (registers the ids)

        env = gym.make(env_id, **cfg)
    env.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-1, 1, (4096, 1)).astype(np.float32) if actions is None else actions
    k = [0]

    def step():
        _, _, te, tr, _ = env.step(acts[k[0] % len(acts)])
        k[0] += 1
        if te or tr:
            env.reset()

    for _ in range(5):
        step()
    n, dt = _timed(step, seconds)
    return n / dt


def bench_vector(
    num_envs: int, seconds: float, env_id: str | None = None, actions: np.ndarray | None = None, **cfg
) -> float:
    """Environment steps per second (num_envs x vector steps) of GearSpeedVectorEnv; with ``env_id``,
    of ``gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **cfg)``; with ``actions``
    (T, num_envs, 1), those replayed in turn instead of random ones (:func:`record_policy_actions`)."""
    if env_id is None:
        from gear_env.envs.vector_env import GearSpeedVectorEnv

        venv = GearSpeedVectorEnv(num_envs, **cfg)
    else:
        import gymnasium as gym

        import gear_env  # noqa: F401  (registers the ids)

        venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **cfg)
    venv.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-1, 1, (64, num_envs, 1)).astype(np.float32) if actions is None else actions
    k = [0]

    def step():
        venv.step(acts[k[0] % len(acts)])
        k[0] += 1

    for _ in range(3):
        step()
    n, dt = _timed(step, seconds)
    return n * num_envs / dt


def record_policy_actions(spec: str, env_id: str, num_envs: int, steps: int, **cfg) -> np.ndarray:
    """The actions that policy ``spec`` (``agents.registry.resolve_policy``: ``pretrained``, a script name, a policy
    file; deterministic) takes on ``env_id`` with settings ``cfg`` over ``steps`` steps from the start that
    :func:`bench_single` (``num_envs`` 0: one env, actions (steps, 1)) or :func:`bench_vector` (``num_envs`` sub-envs,
    actions (steps, num_envs, 1)) makes (``reset(seed=0)``, auto-reset). Replayed there, they time the environment
    under the set-points a policy chooses (quiet speeds, few contact changes) rather than random ones; the replay is
    open loop, so another tree's environment sees the same set-points whatever its small numerical differences."""
    import gymnasium as gym

    import gear_env  # noqa: F401  (registers the ids)
    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config

    pol = resolve_policy(spec, task_config(env_id, cfg), env_id=env_id)
    told = hasattr(pol, "observe_episode")  # a privileged baseline: told each episode's scenario
    out = []
    if num_envs == 0:
        env = gym.make(env_id, **cfg)
        obs, _ = env.reset(seed=0)
        if told:
            pol.observe_episode(env.unwrapped.episode)
        for _ in range(steps):
            act = np.asarray(pol.predict(obs, deterministic=True)[0], np.float32).reshape(1)
            out.append(act)
            obs, _, te, tr, _ = env.step(act)
            if te or tr:
                obs, _ = env.reset()
                if told:
                    pol.observe_episode(env.unwrapped.episode)
        return np.array(out, np.float32)
    if told:
        raise ValueError(
            f"policy {spec!r} is told each episode's scenario, which a vector env's rows do not give it: record it "
            "with num_envs=0 (env-single), or use a policy that acts on observations (pretrained, a policy file, a "
            "sensor script such as sensor-servo)"
        )
    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **cfg)
    obs, _ = venv.reset(seed=0)
    for _ in range(steps):
        act = np.asarray(pol.predict(obs, deterministic=True)[0], np.float32).reshape(num_envs, 1)
        out.append(act)
        obs = venv.step(act)[0]
    return np.array(out, np.float32)


def bench_kernel(num_envs: int, seconds: float, lanes: bool, ramp: float = 0.0) -> float:
    """Physics alone over the default control step, env-steps per second: the SIMD lanes kernel
    (``batch_kernels.integrate_stats_lanes``, what the vector env uses) or the scalar batch kernel
    (``kernels.integrate_stats_batch``, one system after the other); omega ramps by ``ramp`` per
    step (alternating up and down) or stays constant."""
    from gear_env.envs.env_config import GearSpeedConfig
    from gear_env.envs.env_core import GearSpeedCore
    from gear_env.sim import batch_kernels as BK
    from gear_env.sim import kernels as K

    cfg = GearSpeedConfig()
    core = GearSpeedCore(cfg, num_envs)
    rng = np.random.default_rng(0)
    core.reset_rows(np.arange(num_envs), [rng] * num_envs)
    X, A, C, codes = core.X.copy(), core.A.copy(), core.C, core.codes
    w = [core.omega.copy(), core.omega + ramp]
    pc = np.zeros((num_envs, cfg.periods_per_step, K.N_PC))
    st = np.zeros((num_envs, K.N_STATS))
    status = np.zeros(num_envs, np.int64)
    el = np.zeros(num_envs)
    k = [0]

    def step():
        w0, w1 = w[k[0] % 2], w[(k[0] + 1) % 2]
        k[0] += 1
        if lanes:
            BK.integrate_stats_lanes(
                X, A, w0, w1, cfg.periods_per_step, cfg.steps_per_period, C, core.code, pc, st, status, el, 12, 1e-10
            )
        else:
            K.integrate_stats_batch(
                X, A, w0, w1, cfg.periods_per_step, cfg.steps_per_period, C, codes, pc, st, status, el, 12, 1e-10
            )

    step()
    n, dt = _timed(step, seconds)
    return n * num_envs / dt


def bench_cartpole(seconds: float) -> float:
    import gymnasium as gym

    env = gym.make("CartPole-v1")
    env.reset(seed=0)
    space = env.action_space
    space.seed(0)

    def step():
        _, _, te, tr, _ = env.step(space.sample())
        if te or tr:
            env.reset()

    n, dt = _timed(step, seconds)
    return n / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="time per measurement (default 3 s)")
    ap.add_argument("--rounds", type=int, default=1, help="interleaved rounds of every measurement (default 1)")
    ap.add_argument("--trade", action="store_true", help="also time other control intervals / step sizes")
    ap.add_argument("--json", metavar="FILE", help="also write a JSON record (benchmarks/make_tables.py reads it)")
    args = ap.parse_args()
    from bench_record import Record, check_json_target

    check_json_target(args.json)
    rec = Record("bench_env")
    s = args.seconds
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover
        cores = os.cpu_count()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"machine: {platform.machine()}, {cores} usable core(s), Python {platform.python_version()}, "
        f"load average {load:.2f}; rates are per second of this process's CPU time"
    )
    print("default control step: 24 mesh periods x 64 Newmark steps, dynamic backlash")
    rates: dict[str, list[float]] = {}
    for r in range(args.rounds):
        if args.rounds > 1:
            print(f"-- round {r + 1}")
        single = bench_single(s)
        rates.setdefault("single", []).append(single)
        print(f"single env                : {single:9.0f} steps/s")
        for n in (1, 8, 64):
            v = bench_vector(n, s)
            rates.setdefault(f"vector{n}", []).append(v)
            print(f"vector env, {n:2d} sub-envs   : {v:9.0f} env-steps/s")
        for ramp, what in ((0.0, "omega held   "), (0.02, "omega ramping")):
            kern = bench_kernel(64, s, lanes=True, ramp=ramp)
            scal = bench_kernel(64, s, lanes=False, ramp=ramp)
            rates.setdefault(what.strip(), []).append(kern / scal)
            print(
                f"physics alone, 64, {what}: SIMD lanes {kern:6.0f}, scalar {scal:6.0f} env-steps/s "
                f"(SIMD / scalar = {kern / scal:.2f}x)"
            )
        cp = bench_cartpole(s)
        rates.setdefault("cartpole", []).append(cp)
        rates.setdefault("ratio", []).append(single / cp)
        print(f"CartPole-v1 (gym.make)    : {cp:9.0f} steps/s   (GearSpeed single / CartPole = {single / cp:.3f})")
    rec.add("GearSpeed-v0, single env (24 periods x 64 steps per step)", "steps/s", rates["single"])
    for n in (1, 8, 64):
        rec.add(f"GearSpeed-v0, vector env, {n} sub-env{'s' if n > 1 else ''}", "env-steps/s", rates[f"vector{n}"])
    for what in ("omega held", "omega ramping"):
        rec.add(f"physics alone, 64 sub-envs, {what}: SIMD lanes / scalar", "x", rates[what])
    rec.add("Gymnasium CartPole-v1, same loop", "steps/s", rates["cartpole"])
    rec.add("GearSpeed-v0 single env / CartPole-v1", "x", rates["ratio"])
    if args.trade:
        print("\ntrade-off (vector env, 8 sub-envs, env-steps/s; single env steps/s):")
        for pps, nsp, model in ((24, 64, "dynamic"), (16, 64, "dynamic"), (8, 64, "dynamic"), (24, 32, "dynamic"),
                                (24, 64, "constant"), (24, 128, "dynamic")):  # fmt: skip
            cfg = dict(periods_per_step=pps, steps_per_period=nsp, model=model)
            v = bench_vector(8, s, **cfg)
            one = bench_single(s, **cfg)
            print(
                f"  periods_per_step={pps:2d} steps_per_period={nsp:3d} {model:8s}: vector {v:7.0f}  single {one:7.0f}"
            )
    if args.json:
        rec.write(args.json)


if __name__ == "__main__":
    main()
