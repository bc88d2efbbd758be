"""``gear-env compile``: fill the numba cache ahead of time, several processes at once."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    from ..envs.warmup import GROUPS

    p = sub.add_parser(
        "compile",
        help="compile every numba kernel ahead of time (in parallel) into the disk cache",
        description=(
            "Compile the numba kernels of gear-env into the on-disk cache, one process per group of "
            "kernels, so that later processes (a demo, a training run, many SubprocVecEnv workers) "
            "load them in well under a second. Groups: " + "; ".join(f"{k}: {v}" for k, v in GROUPS.items())
        ),
    )
    p.add_argument("--jobs", type=int, default=None, help="worker processes at once (default: CPUs available)")
    p.add_argument("--only", nargs="+", metavar="GROUP", default=None, help="compile only these groups")
    p.add_argument("--list", action="store_true", help="list the groups and exit")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import time

    from .. import _numba_cache
    from ..envs.warmup import GROUPS, check_groups, compile_kernels, default_jobs

    if args.list:
        for k, v in GROUPS.items():
            print(f"{k:14s} {v}")
        return 0
    groups = check_groups(args.only)
    jobs = default_jobs() if args.jobs is None else args.jobs
    if jobs < 1:
        raise ValueError(f"--jobs must be >= 1, got {jobs}")
    where = _numba_cache.CACHE_DIR or "numba's default (__pycache__ beside the sources)"
    print(f"compiling {len(groups)} kernel group(s) with {min(jobs, len(groups))} process(es) into {where}", flush=True)
    t0 = time.perf_counter()

    def progress(group: str, seconds: float, done: int, total: int) -> None:
        print(f"  [{done}/{total}] {group:14s} {seconds:6.1f} s", flush=True)

    try:
        compile_kernels(groups, jobs, progress)
    except RuntimeError as exc:
        print(f"gear-env compile: {exc}")
        return 1
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0
