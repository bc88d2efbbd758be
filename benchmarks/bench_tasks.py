"""Speed of each registered task: env steps per second, single env and vector env (8 sub-envs).

Run:  taskset -c 0 python benchmarks/bench_tasks.py [--seconds 3] [--json FILE]

Same method as benchmarks/bench_env.py (whose helpers it uses): random actions (seeded), auto-reset
included, compile time excluded (a warm-up runs first), rates per second of this process's CPU time,
all tasks timed in this one run, interleaved (task A, B, C, then again), so the ratios between tasks
are taken under the same machine state. A GearSpeed-v1 / GearSpeedDemand-v0 step is 48 mesh
periods (v0: 24), so per mesh period they cost the same; the Demand task adds the per-episode draw
of the plant and the load changes of the duty cycle.
"""

from __future__ import annotations

import argparse
import os
import platform


def bench_task(env_id: str, seconds: float, vector: int = 0) -> float:
    """Env steps per CPU second of ``env_id`` (``vector`` sub-envs in the vector env, 0: single env)."""
    from bench_env import bench_single, bench_vector  # benchmarks/ is the script's folder

    from gear_env.envs.tasks import TASK_SETTINGS

    settings = TASK_SETTINGS[env_id]
    return bench_vector(vector, seconds, **settings) if vector else bench_single(seconds, **settings)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="CPU seconds per measurement")
    ap.add_argument("--rounds", type=int, default=2, help="interleaved rounds")
    ap.add_argument("--json", metavar="FILE", help="also write a JSON record (benchmarks/make_tables.py reads it)")
    args = ap.parse_args()
    from bench_record import Record, check_json_target

    check_json_target(args.json)
    rec = Record("bench_tasks")
    from gear_env.envs.env_config import task_config
    from gear_env.envs.tasks import TASK_SETTINGS

    print(f"{platform.processor() or platform.machine()}, load average {os.getloadavg()}")
    rates: dict[tuple[str, int], list[float]] = {}
    for _ in range(args.rounds):
        for env_id in TASK_SETTINGS:
            for vec in (0, 8):
                rates.setdefault((env_id, vec), []).append(bench_task(env_id, args.seconds, vec))
    print(
        "| task | periods/step | single env (steps/s) | vector env, 8 sub-envs (env-steps/s) | vector, mesh periods/s |"
    )
    print("|---|---:|---:|---:|---:|")
    for env_id in TASK_SETTINGS:
        pps = task_config(env_id).periods_per_step
        s, v = rates[(env_id, 0)], rates[(env_id, 8)]
        print(
            f"| {env_id} | {pps} | {min(s):,.0f}-{max(s):,.0f} | {min(v):,.0f}-{max(v):,.0f} | "
            f"{pps * min(v):,.0f}-{pps * max(v):,.0f} |"
        )
        rec.add(f"{env_id}, single env ({pps} periods/step)", "steps/s", s)
        rec.add(f"{env_id}, vector env, 8 sub-envs", "env-steps/s", v)
    print(f"load average after: {os.getloadavg()}")
    if args.json:
        rec.write(args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
