"""Accuracy and cost of the environments' integration settings: fixed steps per mesh period against ``tol``.

For each episode seed, every setting runs the same episode (reset + a fixed sequence of set-point actions) on
``GearSpeedDemand-v0``; the error is the largest difference of the physical features (force RMS, force peak,
bearing deflection: observation entries 2-4, log1p-scaled) from the same episode at 1024 steps per period (per
episode: the largest over its steps, then the median and max over episodes; per step: the median and 75th
percentile over all steps of all episodes, which non-periodic steps do not dominate), and
the cost the CPU time of the steps (the settings interleaved per seed, so drift of the machine hits all alike).

    python benchmarks/env_tol.py                 # 10 seeds x 20 steps, about a minute
    python benchmarks/env_tol.py --seeds 20 --steps 40 --json env_tol.json
    python benchmarks/env_tol.py --vector 16 --rounds 5   # also the vector env's env-steps/s, Fox-Goodwin vs 64 steps

The Fox-Goodwin settings are ``params={"newmark_beta": 1/12}`` (``GearParams.newmark_beta``), at 64 and 96 steps,
with the velocity correction (``"velocity_correction": True``, scheme ``"fox-goodwin-vc"``) at 64 and 68, at 64
with the contact changes located (``locate_contacts=True``) or their kinks corrected (``correct_kinks=True``), and
with ``steps_per_period="auto"`` (48, 64 or 80 steps by the contact loss of the step before; opt-in, the Fox-Goodwin
ids keep 64).

    python benchmarks/env_tol.py --task-cost 20 --policy pretrained   # the cost on the task as a policy runs it

``--task-cost N`` runs N episodes of ``--policy`` on the task, on its Fox-Goodwin id (``GearSpeedDemand-v1`` for
``GearSpeedDemand-v0``; the corrected scheme since 2026-12-07, plain Fox-Goodwin before), on that id with
``steps_per_period="auto"``, on it with ``locate_contacts=True`` and with ``correct_kinks=True``, interleaved per
episode, and prints the CPU ratios and the auto run's mean steps per mesh period (the counts chosen for steps 2 to the
last of each episode).

``--task-vector N`` drives ``GearSpeedVectorEnv(N)`` with ``--policy`` (batched, deterministic) on the task, its
Fox-Goodwin id, and that id with ``locate_contacts=True`` and with ``correct_kinks=True``: ``--rounds`` interleaved
rounds of 150 vector steps, the CPU time of ``step`` only; prints the env-steps/s ratios to the task.

    python benchmarks/env_tol.py --seeds 1 --steps 2 --settings "Fox-Goodwin-vc 64 steps" --task-vector 16 --rounds 6

``--json FILE`` writes the run's record (benchmarks/bench_record.py; benchmarks/make_tables.py reads it).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

FOX_GOODWIN = {"newmark_beta": 1.0 / 12.0}  # GearParams(newmark_beta=1/12) as the env's params setting
FOX_GOODWIN_VC = {"newmark_beta": 1.0 / 12.0, "velocity_correction": True}  # scheme "fox-goodwin-vc"
SETTINGS = {
    "64 steps (default)": {},
    "128 steps": {"steps_per_period": 128},
    "192 steps": {"steps_per_period": 192},
    "tol 1e-3": {"tol": 1e-3},
    "tol 1e-4": {"tol": 1e-4},
    "tol 1e-5": {"tol": 1e-5},
    "Fox-Goodwin 64 steps": {"params": FOX_GOODWIN},
    "Fox-Goodwin 96 steps": {"params": FOX_GOODWIN, "steps_per_period": 96},
    "Fox-Goodwin-vc 64 steps": {"params": FOX_GOODWIN_VC},
    "Fox-Goodwin-vc 68 steps": {"params": FOX_GOODWIN_VC, "steps_per_period": 68},
    "Fox-Goodwin auto": {"params": FOX_GOODWIN, "steps_per_period": "auto"},
    "Fox-Goodwin-vc 64 located": {"params": FOX_GOODWIN_VC, "locate_contacts": True},
    "Fox-Goodwin-vc 64 corrected": {"params": FOX_GOODWIN_VC, "correct_kinks": True},
    "Fox-Goodwin-vc auto corrected": {"params": FOX_GOODWIN_VC, "correct_kinks": True, "steps_per_period": "auto"},
}


def episode(env_id: str, seed: int, actions: np.ndarray, **kw) -> tuple[np.ndarray, float]:
    """(observations (steps + 1, obs_dim), CPU seconds of the steps) of one episode."""
    import gymnasium as gym

    env = gym.make(env_id, **kw)
    o, _ = env.reset(seed=seed)
    obs = [o]
    t0 = time.process_time()
    for a in actions:
        o, *_ = env.step(np.array([a], np.float32))
        obs.append(o)
    return np.array(obs), time.process_time() - t0


def vector_rates(env_id: str, n: int, rounds: int, seconds: float) -> dict[str, list[float]]:
    """Env-steps/s of ``GearSpeedVectorEnv(n)`` (random set-points, auto-reset), the paper's 64 steps, Fox-Goodwin's
    64 (plain and with the velocity correction) and the contact rule alternately, ``rounds`` times: CPU time of this
    process."""
    from gear_env.envs.env_config import task_config
    from gear_env.envs.vector_env import GearSpeedVectorEnv

    envs = {
        "64 steps (default)": GearSpeedVectorEnv(n, task_config(env_id, {})),
        "Fox-Goodwin 64 steps": GearSpeedVectorEnv(n, task_config(env_id, {"params": FOX_GOODWIN})),
        "Fox-Goodwin auto": GearSpeedVectorEnv(n, task_config(env_id, SETTINGS["Fox-Goodwin auto"])),
        "Fox-Goodwin-vc 64 steps": GearSpeedVectorEnv(n, task_config(env_id, {"params": FOX_GOODWIN_VC})),
        "Fox-Goodwin-vc 64 located": GearSpeedVectorEnv(n, task_config(env_id, SETTINGS["Fox-Goodwin-vc 64 located"])),
        "Fox-Goodwin-vc 64 corrected": GearSpeedVectorEnv(
            n, task_config(env_id, SETTINGS["Fox-Goodwin-vc 64 corrected"])
        ),
    }
    rng = np.random.default_rng(1)
    for e in envs.values():
        e.reset(seed=list(range(n)))
        e.step(rng.uniform(-1, 1, (n, 1)).astype(np.float32))
    out: dict[str, list[float]] = {k: [] for k in envs}
    for _ in range(rounds):
        for name, e in envs.items():
            steps, t0 = 0, time.process_time()
            while time.process_time() - t0 < seconds:
                e.step(rng.uniform(-1, 1, (n, 1)).astype(np.float32))
                steps += n
            out[name].append(steps / (time.process_time() - t0))
    return out


def task_runs(env_id: str, auto: bool) -> dict[str, tuple[str, dict]]:
    """The runs that --task-cost and --task-vector compare, name -> (id, settings): ``env_id``, its Fox-Goodwin id (main
    checked that it has one), with ``steps_per_period="auto"`` if ``auto``, with ``locate_contacts`` and with
    ``correct_kinks``."""
    from gear_env.envs.tasks import FOX_GOODWIN_TASKS

    fg_id = {old: new for new, old in FOX_GOODWIN_TASKS.items()}[env_id]
    runs = {env_id: (env_id, {}), fg_id: (fg_id, {})}
    if auto:
        runs[f"{fg_id}, auto steps"] = (fg_id, {"steps_per_period": "auto"})
    runs[f"{fg_id}, contacts located"] = (fg_id, {"locate_contacts": True})
    runs[f"{fg_id}, kinks corrected"] = (fg_id, {"correct_kinks": True})
    return runs


def task_cost(env_id: str, spec: str, episodes: int, rec) -> None:
    """CPU of ``episodes`` episodes of policy ``spec`` on ``env_id``, on its Fox-Goodwin id, on that id with
    ``steps_per_period="auto"``, with ``locate_contacts=True`` and with ``correct_kinks=True``, interleaved per
    episode."""
    import gymnasium as gym

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation.episodes import run_episode

    runs = task_runs(env_id, auto=True)
    cpu = dict.fromkeys(runs, 0.0)
    counts: list[int] = []
    for tid, kw in runs.values():  # warm up (maps, compilation)
        run_episode(gym.make(tid, **kw), resolve_policy(spec, task_config(tid, kw), env_id=tid), 799999)
    for ep in range(episodes):
        for name, (tid, kw) in runs.items():
            env = gym.make(tid, **kw)
            pol = resolve_policy(spec, task_config(tid, kw), env_id=tid)
            core = env.unwrapped._core
            mine: list[int] = []
            auto = kw.get("steps_per_period") == "auto"
            count = (lambda info, core=core, mine=mine: mine.append(int(core.n_steps[0]))) if auto else None
            t0 = time.process_time()
            run_episode(env, pol, 800000 + ep, count)
            cpu[name] += time.process_time() - t0
            counts += mine[:-1]  # the last is the count of a step that is not taken
    print(f"\n{spec} on {episodes} episodes (seeds 800000-), CPU against {env_id}:")
    for name in runs:
        print(f"  {name}: {cpu[name] / cpu[env_id]:.2f}x")
        rec.add(f"{spec} on {name} vs {env_id}: CPU per episode", "ratio", [cpu[name] / cpu[env_id]])
    c = np.array(counts)
    print(f"  auto steps per mesh period: mean {c.mean():.1f} (48/64/80: "
          + " / ".join(f"{np.mean(c == k):.2f}" for k in (48, 64, 80)) + ")")  # fmt: skip


def task_vector_cost(env_id: str, spec: str, n: int, rounds: int, steps: int, rec) -> None:
    """Env-steps/s of ``GearSpeedVectorEnv(n)`` driven by policy ``spec`` (deterministic, batched) on ``env_id``, on its
    Fox-Goodwin id, with ``locate_contacts=True`` and with ``correct_kinks=True``: ``rounds`` interleaved rounds of
    ``steps`` vector steps each, CPU time of ``step`` only (the policy's time is left out), episodes auto-reset."""
    import os

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.envs.vector_env import GearSpeedVectorEnv

    runs = task_runs(env_id, auto=False)
    state = {}
    for name, (tid, kw) in runs.items():
        venv = GearSpeedVectorEnv(n, task_config(tid, kw))
        pol = resolve_policy(spec, task_config(tid, kw), env_id=tid)
        obs, _ = venv.reset(seed=[800000 + i for i in range(n)])
        for _ in range(3):  # warm up
            obs = venv.step(pol.predict(obs, deterministic=True)[0])[0]
        state[name] = [venv, pol, obs]
    cpu: dict[str, list[float]] = {name: [] for name in runs}
    for r in range(rounds):
        for name in runs if r % 2 == 0 else list(runs)[::-1]:
            venv, pol, obs = state[name]
            t = 0.0
            for _ in range(steps):
                act = pol.predict(obs, deterministic=True)[0]
                t0 = time.process_time()
                obs = venv.step(act)[0]
                t += time.process_time() - t0
            state[name][2] = obs
            cpu[name].append(t)
    base = np.array(cpu[env_id])
    print(f"\n{spec} driving GearSpeedVectorEnv({n}), {rounds} interleaved rounds of {steps} steps (load average "
          f"{os.getloadavg()[0]:.1f}), env-steps/s against {env_id}: median [min, max]")  # fmt: skip
    for name in runs:
        ratio = base / np.array(cpu[name])
        print(f"  {name}: {np.median(ratio):.2f} [{ratio.min():.2f}, {ratio.max():.2f}]")
        rec.add(f"{spec} driving GearSpeedVectorEnv({n}) on {name} vs {env_id}: env-steps/s", "ratio",
                [float(np.median(ratio))], note=f"range {ratio.min():.2f}-{ratio.max():.2f}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    import gear_env  # noqa: F401

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="GearSpeedDemand-v0")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--vector", type=int, default=0, metavar="N",
                    help="also time GearSpeedVectorEnv(N), the Fox-Goodwin settings against 64 steps")  # fmt: skip
    ap.add_argument("--rounds", type=int, default=5, help="rounds of the vector timing (5)")
    ap.add_argument("--task-cost", type=int, default=0, metavar="N",
                    help="also: N episodes of --policy on the task and its Fox-Goodwin id, interleaved "
                         "(CPU ratio)")  # fmt: skip
    ap.add_argument("--policy", default="pretrained", help="policy spec of --task-cost (default pretrained)")
    ap.add_argument("--task-vector", type=int, default=0, metavar="N",
                    help="also: GearSpeedVectorEnv(N) driven by --policy on the task and its Fox-Goodwin id "
                         "(env-steps/s ratio; --rounds rounds of 150 steps)")  # fmt: skip
    ap.add_argument("--json", metavar="FILE", help="also write a JSON record (benchmarks/make_tables.py reads it)")
    ap.add_argument("--settings", nargs="+", metavar="NAME", choices=list(SETTINGS), default=list(SETTINGS),
                    help="only these settings (the 64-step default always runs: ratios are against it)")  # fmt: skip
    args = ap.parse_args(argv)
    from gear_env.envs.tasks import FOX_GOODWIN_TASKS

    if (args.task_cost or args.task_vector) and args.env not in FOX_GOODWIN_TASKS.values():
        ap.error(
            "--task-cost and --task-vector compare a task with its Fox-Goodwin id: --env one of "
            f"{sorted(FOX_GOODWIN_TASKS.values())}"
        )
    settings = {k: v for k, v in SETTINGS.items() if k in args.settings or k == "64 steps (default)"}
    from bench_record import Record, check_json_target

    check_json_target(args.json)
    rec = Record("env_tol", argv)
    rng = np.random.default_rng(0)
    actions = np.clip(np.cumsum(rng.normal(0, 0.15, args.steps)) * 0.5 + 0.2, -1, 1)
    for kw in settings.values():  # compile and warm every path first
        episode(args.env, 0, actions[:2], **kw)
    err: dict[str, list[float]] = {k: [] for k in settings}
    per_step: dict[str, list[np.ndarray]] = {k: [] for k in settings}  # every step's largest feature error
    cpu: dict[str, float] = dict.fromkeys(settings, 0.0)
    for seed in range(args.seeds):
        ref, _ = episode(args.env, 1000 + seed, actions, steps_per_period=1024)
        for name, kw in settings.items():
            o, t = episode(args.env, 1000 + seed, actions, **kw)
            err[name].append(float(np.max(np.abs(o[:, 2:5] - ref[:, 2:5]))))
            per_step[name].append(np.max(np.abs(o[1:, 2:5] - ref[1:, 2:5]), axis=1))
            cpu[name] += t
    base = cpu["64 steps (default)"]
    print(f"{args.env}: {args.seeds} episodes x {args.steps} steps; error = max |feature - 1024-step feature|")
    print("| setting | median error | max error | per step: median | per step: p75 | CPU per step [ms] | vs 64 steps |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name in settings:
        e = np.array(err[name])
        ms = 1e3 * cpu[name] / (args.seeds * args.steps)
        ps = np.concatenate(per_step[name])
        print(
            f"| {name} | {np.median(e):.1e} | {e.max():.1e} | {np.median(ps):.1e} | {np.percentile(ps, 75):.1e} | "
            f"{ms:.2f} | {cpu[name] / base:.2f}x |"
        )
        rec.add(
            f"{args.env}, {name}: feature error vs 1024 steps, median over {args.seeds} episodes",
            "log1p units",
            [float(np.median(e))],
            note=f"max {e.max():.1e}",
        )
        rec.add(
            f"{args.env}, {name}: CPU per env step", "ms", [ms], note=f"{cpu[name] / base:.2f}x the 64-step default"
        )
    if args.vector:
        import os

        rates = vector_rates(args.env, args.vector, args.rounds, 1.0)
        a = np.array(rates["64 steps (default)"])
        print(f"\nGearSpeedVectorEnv({args.vector}), {args.rounds} interleaved rounds (load average "
              f"{os.getloadavg()[0]:.1f}): 64 steps {np.median(a):.0f} env-steps/s")  # fmt: skip
        for name in [k for k in rates if k != "64 steps (default)"]:
            ratio = np.array(rates[name]) / a
            print(f"  {name}: {np.median(rates[name]):.0f} env-steps/s; ratio {np.median(ratio):.2f} "
                  f"[{ratio.min():.2f}, {ratio.max():.2f}]")  # fmt: skip
            rec.add(f"{args.env}, GearSpeedVectorEnv({args.vector}): {name} vs 64 steps, env-steps/s",
                    "ratio", [float(np.median(ratio))], note=f"range {ratio.min():.2f}-{ratio.max():.2f}")  # fmt: skip
    if args.task_cost:
        task_cost(args.env, args.policy, args.task_cost, rec)
    if args.task_vector:
        task_vector_cost(args.env, args.policy, args.task_vector, args.rounds, 150, rec)
    if args.json:
        rec.write(args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
