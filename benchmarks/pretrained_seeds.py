"""The shipped training configuration of a task, over several training seeds, scored against the oracle.

Run:  python benchmarks/pretrained_seeds.py --env GearSpeed-v1 --seeds 0 1 2 [--timesteps N] [--json out.json]
      (or one seed per process with --json each, then --combine a.json b.json c.json)

For each seed this trains exactly what ``gear-env train --env ID --hyperparams agents/hyperparams/ppo.yml
--seed S`` trains (the same command-line parser and ``agents.ppo.train``; ``--timesteps`` overrides the
entry's ``n_timesteps``) into a run folder (a temporary one unless ``--runs DIR``), then evaluates the run's
best evaluated model (what ``agents.shipped.export_run`` ships; ``--model final`` for the last one) on the
episodes of ``gear-env evaluate --env ID --episodes 20 --seed 9001`` (seeds never used in training), beside
``oracle``, ``fixed-best`` and ``random``. Printed: each run's mean return as % of the oracle's, its training
wall and CPU time with the load average, and the interquartile mean over runs x episodes of the
oracle-normalised return with its 95 % stratified-bootstrap interval (rliable's method: resample runs, then
episodes; ``stock_ppo.iqm_ci``).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ("oracle", "fixed-best", "random")


def train_shipped(env_id: str, seed: int, out: Path, hyperparams: Path, timesteps: int | None) -> dict:
    """Train the shipped configuration of ``env_id`` with ``seed`` into ``out``; wall/CPU seconds and load."""
    from agents.ppo import train
    from gear_env.cli.train import build_parser, options_from_args

    argv = ["--env", env_id, "--hyperparams", str(hyperparams), "--seed", str(seed), "--out", str(out)]
    argv += ["--no-progress", "--no-tensorboard", "--quiet"]
    if timesteps is not None:
        argv += ["--timesteps", str(timesteps)]
    opts = options_from_args(build_parser().parse_args(argv))
    load0 = os.getloadavg()
    t0, c0 = time.perf_counter(), time.process_time()
    train(opts)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "load_start": load0, "load_end": os.getloadavg(), "steps": opts.timesteps}


def combine(paths: Sequence[str], json_out: str | None, report_iqm) -> int:
    """Merge the JSON outputs of runs made in parallel (same task, episodes and baselines) and print the IQM."""
    parts = [json.loads(Path(p).read_text(encoding="utf-8")) for p in paths]
    keys = ("env", "eval_seed", "episodes", "model")
    for p, d in zip(paths, parts):
        if any(d[k] != parts[0][k] for k in keys) or d["baselines"] != parts[0]["baselines"]:
            raise SystemExit(f"{p}: not the same evaluation as {paths[0]} ({', '.join(keys)}, baselines)")
    out = {**parts[0], "runs": [r for d in parts for r in d["runs"]]}
    o = out["baselines"]["oracle"]["return_mean"]
    scores = np.array([np.asarray(r["returns"]) / o for r in out["runs"]])
    for r in out["runs"]:
        print(
            f"seed {r['seed']}: {r['pct_of_oracle']:.1f} % of the oracle, "
            f"{r['wall_s']:.0f} s wall, {r['cpu_s']:.0f} s CPU"
        )
    report_iqm(out, scores, len(scores), json_out)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="GearSpeed-v1")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--timesteps", type=int, default=None, help="total env steps (default: n_timesteps of the entry)")
    ap.add_argument("--hyperparams", type=Path, default=ROOT / "agents" / "hyperparams" / "ppo.yml")
    ap.add_argument("--runs", type=Path, default=None, help="keep the run folders under DIR (default: a temp dir)")
    ap.add_argument("--model", choices=("best", "final"), default="best")
    ap.add_argument("--reuse", action="store_true", help="evaluate finished runs found under --runs, train the rest")
    ap.add_argument("--eval-seed", type=int, default=9001)
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--json", metavar="PATH")
    ap.add_argument(
        "--combine", nargs="+", metavar="JSON", help="no training: merge the --json outputs of runs made in parallel"
    )
    args = ap.parse_args(argv)

    from stock_ppo import report_iqm  # benchmarks/ is the script's folder

    if args.combine:
        return combine(args.combine, args.json, report_iqm)

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    cfg = task_config(args.env)
    base = evaluate_policies(
        {b: resolve_policy(b, cfg, env_id=args.env) for b in BASELINES},
        cfg,
        episodes=args.episodes,
        seed=args.eval_seed,
    )
    ret = {b: np.array([e.ret for e in base.episodes[b]]) for b in BASELINES}
    o = ret["oracle"].mean()
    seeds_txt = f"seeds {args.eval_seed}-{args.eval_seed + args.episodes - 1}"
    print(
        f"{args.env}, {seeds_txt}: "
        + ", ".join(f"{b} {ret[b].mean():.2f} ({100 * ret[b].mean() / o:.1f} %)" for b in BASELINES)
    )
    out: dict = {"env": args.env, "eval_seed": args.eval_seed, "episodes": args.episodes, "model": args.model}
    out["baselines"] = {b: {"return_mean": float(ret[b].mean()), "returns": ret[b].tolist()} for b in BASELINES}
    out["runs"] = []
    scores = []
    with tempfile.TemporaryDirectory(prefix="pretrained_seeds_") as tmp:
        parent = args.runs if args.runs is not None else Path(tmp)
        for s in args.seeds:
            run_dir = parent / f"{args.env}_seed{s}"
            done = run_dir / "metrics.json"
            if args.reuse and done.is_file() and json.loads(done.read_text(encoding="utf-8"))["summary"]["finished"]:
                summ = json.loads(done.read_text(encoding="utf-8"))["summary"]  # a finished run: evaluate only
                t = {"wall_s": summ["wall_seconds"], "cpu_s": float("nan"), "load_start": [float("nan")] * 3}
                t.update(load_end=t["load_start"], steps=summ["timesteps"], reused=True)
            else:
                t = train_shipped(args.env, s, run_dir, args.hyperparams, args.timesteps)
            model = run_dir / ("best_model.zip" if args.model == "best" else "model.zip")
            pol = resolve_policy(str(model), cfg, env_id=args.env)
            rep = evaluate_policies({"run": pol}, cfg, episodes=args.episodes, seed=args.eval_seed)
            r = np.array([e.ret for e in rep.episodes["run"]])
            scores.append(r / o)
            settled = [e.settled_omega for e in rep.episodes["run"]]
            out["runs"].append({"seed": s, **t, "returns": r.tolist(), "pct_of_oracle": 100 * r.mean() / o,
                                "settled_omega": settled})  # fmt: skip
            print(
                f"seed {s}: {r.mean():.2f} = {100 * r.mean() / o:.1f} % of the oracle, settled omega "
                f"{min(settled):.3f}-{max(settled):.3f}; trained {t['steps']:,} steps in {t['wall_s']:.0f} s wall, "
                f"{t['cpu_s']:.0f} s CPU (load {t['load_start'][0]:.1f} -> {t['load_end'][0]:.1f})",
                flush=True,
            )
    report_iqm(out, scores, len(scores), args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
