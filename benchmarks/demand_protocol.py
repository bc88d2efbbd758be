"""The Demand tables of docs/RESULTS.md under the evaluation protocol (agents/protocol.py), with CIs.

Run:  python benchmarks/demand_protocol.py --set test [--policy SPEC ...] [--runs RUN_DIR ...]
                                          [--env GearSpeedDemandHard-v0] [--reference pretrained]
                                          [--cache DIR] [--markdown PATH] [--json PATH] [--config CONFIG.json]
      python benchmarks/demand_protocol.py --set validation --runs runs/demand_s0 runs/demand_s1 ... --select
      python benchmarks/demand_protocol.py --calibrate --set seeds:0-119   (the scripts' sensor map, training seeds)

Every policy runs the episodes of the named seed set (``validation``: 50 episodes, ``test``: 100; or
``seeds:A-B``) through ``gear_env.evaluation.run_episode`` (as ``gear-env evaluate`` does); per episode it
keeps the return, the demand delivered (the throughput term: mean of min(omega, demand) / omega_max summed over
the steps), the shortfall charge and the vibration cost (chaos + contact + impact + vibration + rate +
divergence terms). The table gives each policy's mean return with its 95 % bootstrap CI, the share of the
fixed-best -> oracle gap it closes (CI from resampling episodes), and the paired per-episode difference
against ``--reference`` (default: the shipped policy) with its CI. ``--runs`` adds training runs (each run's
``best_model.zip``, or a spec such as ``pretrained``: the shipped run): per run the same row, and over
the runs the IQM of the per-episode gap scores with its
95 % stratified-bootstrap CI (rliable). ``--select`` prints the run whose mean validation return is best
(the shipped run's rule). ``--cache DIR`` keeps each (policy, episode) result in DIR/<set>_<task>_config-<digest of
the task's settings>/<policy>.json, so baselines are rolled out once and a task whose settings change is rolled out
again (a changed policy needs a fresh cache file: delete it). ``--config`` changes the
task's settings (for instance the integration scheme); its results are cached apart from the task's, and
``--against-task`` adds the paired per-episode change of every policy against the task's own settings. On a
Fox-Goodwin task (``--env GearSpeedDemand-v1``, ...), ``--against-base`` adds the paired change against the older
id it integrates differently (``gear_env.envs.tasks.FOX_GOODWIN_TASKS``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

DEMAND_TASKS = (
    "GearSpeedDemand-v0",
    "GearSpeedDemandHard-v0",
    "GearSpeedDemandLimit-v0",
    "GearSpeedDemand-v1",
    "GearSpeedDemandHard-v1",
    "GearSpeedDemandLimit-v1",
)
"""The tasks of the tables (``--env``; the first is the default)."""
BASELINES = ("oracle", "fixed-best", "delayed-oracle:10", "identify-follow", "sensor-servo", "pretrained")
COST_TERMS = ("reward_chaos", "reward_contact", "reward_impact", "reward_vibration", "reward_rate", "reward_divergence")


def parse_seed_set(text: str) -> range:
    """A protocol set name (``validation``, ``test``, ...) or ``seeds:A-B`` (inclusive)."""
    from agents.protocol import seed_set

    m = re.fullmatch(r"seeds:(\d+)-(\d+)", text)
    if m:
        a, b = int(m.group(1)), int(m.group(2))
        if b < a + 1:
            raise ValueError(f"--set {text!r}: need B > A (at least 2 episodes)")
        return range(a, b + 1)
    return seed_set(text)


def episode_rows(policy, cfg, seeds: Sequence[int]) -> list[dict]:
    """Per episode: seed, return, delivered (throughput term), shortfall (demand term), cost (the rest)."""
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.evaluation import run_episode

    env = GearSpeedEnv(cfg)
    out = []
    for s in seeds:
        acc = dict.fromkeys(("reward_throughput", "reward_demand", *COST_TERMS), 0.0)

        def add(info, acc=acc):
            for k in acc:
                acc[k] += info[k]

        res = run_episode(env, policy, int(s), on_step=add)
        out.append(
            {
                "seed": int(s),
                "return": res.ret,
                "delivered": acc["reward_throughput"],
                "shortfall": acc["reward_demand"],
                "cost": sum(acc[k] for k in COST_TERMS),
                "settled_omega": res.settled_omega,
            }
        )
    return out


def calibrate(cfg, seeds: Sequence[int], env_id: str = DEMAND_TASKS[0]) -> str:
    """The sensor map of agents/demand_scripts.py from the oracle's rollouts on ``seeds`` (training seeds): on
    clean, steady steps where the demand is above the oracle's next speed, the log q sensed there per hold
    speed (0.05 grid), and the boundary between neighbouring holds (midway between the 95th percentile of the
    higher hold and the 5th of the lower one)."""
    from agents.demand_scripts import OBS_DOMEGA, log_q
    from agents.registry import resolve_policy
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.envs.env_terms import TROUBLE_CONTACT
    from gear_env.envs.force_level import TROUBLE_DEFECT

    env, oracle = GearSpeedEnv(cfg), resolve_policy("oracle", cfg, env_id=env_id)
    span = cfg.omega_max - cfg.omega_min
    x, hold = [], []
    for s in seeds:
        obs, _ = env.reset(seed=int(s))
        oracle.observe_episode(env.unwrapped.episode)
        state, start, t, done = None, np.ones(1, bool), 0, False
        while not done:
            a, state = oracle.predict(obs[None], state=state, episode_start=start, deterministic=True)
            start[:] = False
            w0 = cfg.omega_min + 0.5 * (obs[0] + 1.0) * span
            lq = float(log_q(np.array([w0]), obs[None], cfg.max_domega)[0])
            clean = obs[7] <= TROUBLE_CONTACT and obs[8] + obs[9] <= 0 and obs[5] <= TROUBLE_DEFECT
            nxt, _, term, trunc, info = env.step(np.asarray(a, np.float32).reshape(1))
            w1, d = info["omega"], env.unwrapped.episode.demand[t]
            if t > 8 and clean and abs(obs[OBS_DOMEGA]) < 0.3 and abs(w1 - w0) < 0.02 and d > w1 + 0.03:
                x.append(lq)
                hold.append(round(w1 / 0.05) * 0.05)
            obs, t, done = nxt, t + 1, term or trunc
    X, H = np.array(x), np.round(np.array(hold), 2)
    lines = [
        "| hold | steps | sensed log q: 5 % | median | 95 % | boundary to the next lower hold |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    hs = sorted(set(H.tolist()), reverse=True)
    for i, h in enumerate(hs):
        v = X[H == h]
        b = f"{0.5 * (np.percentile(v, 95) + np.percentile(X[H == hs[i + 1]], 5)):+.3f}" if i + 1 < len(hs) else "-"
        p5, p50, p95 = np.percentile(v, [5, 50, 95])
        lines.append(f"| {h:.2f} | {v.size} | {p5:+.2f} | {p50:+.2f} | {p95:+.2f} | {b} |")
    return "\n".join(lines)


def _safe(spec: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", spec).strip("_") or "policy"


def rollout(spec: str, cfg, seeds: range, cache: Path | None, label: str, env_id: str = DEMAND_TASKS[0]) -> list[dict]:
    """The episode rows of ``spec`` on ``seeds`` (read from / written to the cache when given)."""
    from agents.registry import resolve_policy
    from gear_env.io import atomic_write_text

    path = None if cache is None else cache / label / f"{_safe(spec)}.json"
    if path is not None:
        cached = read_cache(path, cache, spec, seeds)
        if cached is not None:
            return cached
    t0 = time.process_time()
    rows = episode_rows(resolve_policy(spec, cfg, env_id=env_id), cfg, seeds)
    print(f"  {spec}: {len(rows)} episodes, {time.process_time() - t0:.0f} s CPU", file=sys.stderr, flush=True)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_symlink() or (path.exists() and not path.is_file()):
            print(f"  not caching {spec}: {str(path)!r} is a link or not a regular file", file=sys.stderr)
        else:
            atomic_write_text(path, json.dumps({"spec": spec, "seeds": [seeds.start, seeds.stop], "episodes": rows}))
    return rows


ROW_KEYS = ("seed", "return", "delivered", "shortfall", "cost", "settled_omega")
"""The fields of one cached episode row (:func:`episode_rows`)."""
MAX_CACHE_BYTES = 8 * 2**20
"""Largest cache file read (bytes)."""


def read_cache(path: Path, cache: Path, spec: str, seeds: range) -> list[dict] | None:
    """The cached episode rows of ``spec`` on ``seeds``, or None (missing, of another policy or seeds, or refused).

    The file is read through the package's bounded reader (regular file inside ``cache``, size, JSON depth) and
    every row is checked: one per seed, in order, the known fields only, finite numbers. A refused file is
    named on stderr and recomputed (and replaced). A cache cannot be told from the user's own results beyond
    that: keep it in a folder only you write."""
    from gear_env.io import read_json
    from gear_env.untrusted import check_keys, inside, refuse, want_int, want_num

    if not (path.exists() or path.is_symlink()):
        return None
    try:
        inside(cache, path, "cache file")
        data = check_keys(read_json(path, "cache file", MAX_CACHE_BYTES), ("spec", "seeds", "episodes"), path, "",
                          required=("spec", "seeds", "episodes"))  # fmt: skip
        if data["spec"] != spec or data["seeds"] != [seeds.start, seeds.stop]:
            return None
        rows = data["episodes"]
        if not isinstance(rows, list) or len(rows) != len(seeds):
            raise refuse(path, "episodes", f"must be a list of {len(seeds)} episode rows")
        for i, (row, seed) in enumerate(zip(rows, seeds)):
            check_keys(row, ROW_KEYS, path, f"episodes[{i}]", required=ROW_KEYS)
            if want_int(row["seed"], 0, 2**32 - 1, path, f"episodes[{i}].seed") != seed:
                raise refuse(path, f"episodes[{i}].seed", f"must be {seed}, got {row['seed']}")
            for k in ROW_KEYS[1:]:
                want_num(row[k], -1e6, 1e6, path, f"episodes[{i}].{k}")
        return rows
    except ValueError as exc:
        print(f"  recomputing {spec}: the cache file is refused: {exc}", file=sys.stderr, flush=True)
        return None


def fmt(m: float, lo: float, hi: float, pct: bool = False) -> str:
    k = 100.0 if pct else 1.0
    u = " %" if pct else ""
    return f"{k * m:.2f}{u} [{k * lo:.2f}, {k * hi:.2f}]" if not pct else f"{k * m:.1f}{u} [{k * lo:.1f}, {k * hi:.1f}]"


def change_table(
    base: dict[str, list[dict]],
    changed: dict[str, list[dict]],
    names: tuple[str, str] = ("task's settings", "--config"),
) -> tuple[str, dict]:
    """Markdown table (and its numbers) of each policy's return and gap share under the task's settings
    (``base``) and under other settings (``changed``), with the paired per-episode change and its 95 % CI;
    ``names`` label the two columns."""
    from agents.protocol import gap_closed, paired_diff

    R0 = {k: np.array([e["return"] for e in v]) for k, v in base.items()}
    R1 = {k: np.array([e["return"] for e in v]) for k, v in changed.items()}
    a, b = names
    lines = [
        f"| policy | return, {a} | return, {b} | paired change [95 % CI] | gap closed, {a} | gap closed, {b} |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    nums = {}
    for name in changed:
        g0 = gap_closed(R0[name], R0["fixed-best"], R0["oracle"])[0]
        g1 = gap_closed(R1[name], R1["fixed-best"], R1["oracle"])[0]
        d = paired_diff(R1[name], R0[name])
        lines.append(
            f"| {name} | {np.mean(R0[name]):.2f} | {np.mean(R1[name]):.2f} | {fmt(*d)} | {100 * g0:.1f} % | "
            f"{100 * g1:.1f} % |"
        )
        nums[name] = {"return_task": float(np.mean(R0[name])), "return_config": float(np.mean(R1[name])),
                      "paired_change": d, "gap_closed_task": g0, "gap_closed_config": g1}  # fmt: skip
    return "\n".join(lines), nums


def table(results: dict[str, list[dict]], reference: str | None) -> tuple[str, dict]:
    """Markdown table (and its numbers) of every policy against fixed-best, the oracle and ``reference``."""
    from agents.protocol import gap_closed, mean_ci, paired_diff

    R = {k: np.array([e["return"] for e in v]) for k, v in results.items()}
    F, O = R["fixed-best"], R["oracle"]
    ref = R.get(reference) if reference else None
    head = "| policy | return [95 % CI] | gap closed [95 % CI] |"
    head += f" paired difference vs {reference} [95 % CI] |" if ref is not None else ""
    head += " delivered | shortfall | cost | settled omega |"
    lines = [head, "|" + "---|" + "---:|" * (head.count("|") - 2)]
    nums = {}
    for name, rows in results.items():
        x = R[name]
        m, g = mean_ci(x), gap_closed(x, F, O)
        line = f"| {name} | {fmt(*m)} | {fmt(*g, pct=True)} |"
        d = None
        if ref is not None:
            d = paired_diff(x, ref) if name != reference else None
            line += f" {fmt(*d)} |" if d else " - |"
        col = {k: float(np.mean([e[k] for e in rows])) for k in ("delivered", "shortfall", "cost", "settled_omega")}
        line += f" {col['delivered']:.2f} | {col['shortfall']:.2f} | {col['cost']:.2f} | {col['settled_omega']:.3f} |"
        lines.append(line)
        nums[name] = {"return": m, "gap_closed": g, "paired_vs_reference": d, **col}
    return "\n".join(lines), nums


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default=DEMAND_TASKS[0], choices=DEMAND_TASKS, help="the task (default v0)")
    ap.add_argument("--set", default="test", help="seed set: validation, test or seeds:A-B (default test)")
    ap.add_argument(
        "--policy",
        action="append",
        default=[],
        help="policy spec, repeatable (default: the baselines); oracle and fixed-best always run (the gap's ends)",
    )
    ap.add_argument(
        "--runs",
        nargs="*",
        default=[],
        help="training runs: folders (their best_model.zip) or policy specs (pretrained)",
    )
    ap.add_argument("--reference", default="pretrained", help="policy of the paired differences (default pretrained)")
    ap.add_argument("--select", action="store_true", help="print the run with the best mean return on this set")
    ap.add_argument("--cache", metavar="DIR", help="keep per-policy episode results here")
    ap.add_argument(
        "--calibrate", action="store_true", help="print the scripts' sensor map from the oracle on --set (train:0-119)"
    )
    ap.add_argument(
        "--config",
        metavar="CONFIG.json",
        help="JSON object of environment settings over the task's (as gear-env evaluate --config), e.g. "
        '{"scheme": "fox-goodwin-vc"} for the corrected Fox-Goodwin scheme (what the v1 demand ids set)',
    )
    ap.add_argument(
        "--against-task",
        action="store_true",
        help="with --config: also run every policy under the task's own settings and add a table of the paired "
        "per-episode change the settings make",
    )
    ap.add_argument(
        "--against-base",
        action="store_true",
        help="on a Fox-Goodwin task (GearSpeedDemand-v1, ...): also run every policy on the older task it integrates "
        "differently (GearSpeedDemand-v0, ...) and add a table of the paired per-episode change the scheme makes",
    )
    ap.add_argument("--markdown", metavar="PATH")
    ap.add_argument("--json", metavar="PATH")
    args = ap.parse_args(argv)
    if args.against_task and not args.config:
        ap.error("--against-task compares --config's settings with the task's: give --config")
    from gear_env.envs.tasks import base_task

    if args.against_base and (base_task(args.env) == args.env or args.config):
        ap.error("--against-base compares a Fox-Goodwin task (a v1 demand id) with its older id, without --config")
    from gear_env.io import hold_outputs

    with hold_outputs(
        {"--markdown": args.markdown, "--json": args.json}, inputs={"--config": args.config}
    ):  # aliases refused, outputs locked
        return _main(args)


def _main(args: argparse.Namespace) -> int:
    env_id = args.env

    from agents.protocol import gap_scores, iqm_ci
    from gear_env.envs.env_config import task_config
    from gear_env.io import atomic_write_text

    settings = None
    if args.config:
        from gear_env.io import read_json

        settings = read_json(args.config, "--config", max_bytes=1024 * 1024)
        if not isinstance(settings, dict):
            raise ValueError(f"--config {args.config!r} must hold a JSON object of settings")
    cfg = task_config(env_id, settings)  # validated before any work
    if args.calibrate:
        print(calibrate(cfg, parse_seed_set(args.set), env_id))
        return 0
    seeds = parse_seed_set(args.set)

    def set_label(task: str, task_cfg) -> str:
        """The cache folder of (seed set, task, settings): results under other settings, or of a task whose
        definition changed (a scheme, a setting), never mix with these."""
        fields = {k: v for k, v in task_cfg.to_dict().items() if k != "scheme"}  # params says what a scheme sets
        digest = hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:12]
        return args.set.replace(":", "_") + ("" if task == DEMAND_TASKS[0] else f"_{task}") + f"_config-{digest}"

    base_label = set_label(env_id, task_config(env_id))
    label = set_label(env_id, cfg)
    cache = Path(args.cache) if args.cache else None
    specs = list(dict.fromkeys(["oracle", "fixed-best", *(args.policy or BASELINES[2:])]))
    runs = [str(Path(r) / "best_model.zip") if Path(r).is_dir() else r for r in args.runs]
    if "pretrained" in specs + runs:  # refused before any rollout, not after the others
        from agents.registry import shipped_policy_dir

        try:
            shipped_policy_dir(env_id)  # the Demand tasks ship policy.json folders
        except ValueError as exc:
            raise ValueError(
                f"{exc}; name the policies with --policy (for example --policy identify-follow --policy "
                "sensor-servo --reference sensor-servo)"
            ) from None
    t0 = time.perf_counter()
    where = args.set if args.set.startswith("seeds:") else f"{args.set} seeds {seeds.start}-{seeds.stop - 1}"
    print(f"{env_id}: {len(specs)} policies + {len(runs)} runs on {where}")
    results = {s: rollout(s, cfg, seeds, cache, label, env_id) for s in dict.fromkeys(specs + runs)}
    ref = args.reference if args.reference in results else None
    md, nums = table(results, ref)
    out: dict = {"set": args.set, "seeds": [seeds.start, seeds.stop - 1], "policies": nums}
    if args.against_task:
        base = {s: rollout(s, task_config(env_id), seeds, cache, base_label, env_id) for s in results}
        md_c, out["change_vs_task"] = change_table(base, results)
        md += f"\n\nThe same episodes under the task's own settings, and the paired change --config makes:\n\n{md_c}"
    if args.against_base:
        from gear_env.envs.tasks import base_task

        older = base_task(env_id)
        base = {s: rollout(s, task_config(older), seeds, cache, set_label(older, task_config(older)), older)
                for s in results}  # fmt: skip
        md_c, out["change_vs_base"] = change_table(base, results, (older, env_id))
        md += f"\n\nThe same episodes on {older}, and the paired change the scheme makes:\n\n{md_c}"
    if runs:
        F = [e["return"] for e in results["fixed-best"]]
        O = [e["return"] for e in results["oracle"]]
        mat = np.array([[e["return"] for e in results[r]] for r in runs])
        m, lo, hi = iqm_ci(gap_scores(mat, F, O))
        # the same statistic of the reference policies, for its scale: it trims the quarter of episodes with the
        # largest gains (the precise pairs, where most of the gap lies), so even the oracle stays below 100 %
        refs = [k for k in ("oracle", "sensor-servo", "identify-follow") if k in results]
        ref_iqm = {k: iqm_ci(gap_scores(np.array([[e["return"] for e in results[k]]]), F, O))[0] for k in refs}
        shares = np.sort([nums[r]["gap_closed"][0] for r in runs])
        cut = len(shares) // 4
        iqm_runs = float(np.mean(shares[cut : len(shares) - cut]))
        md += (
            f"\n\n{len(runs)} runs x {len(seeds)} episodes: IQM of the per-episode gap scores {100 * m:.1f} %, "
            f"95 % stratified-bootstrap CI [{100 * lo:.1f}, {100 * hi:.1f}] (the same statistic of "
            + ", ".join(f"{k} {100 * v:.1f} %" for k, v in ref_iqm.items())
            + f"); IQM of the per-run gap shares {100 * iqm_runs:.1f} %; mean gap closed per run: "
            + ", ".join(f"{100 * nums[r]['gap_closed'][0]:.1f} %" for r in runs)
        )
        out["runs_iqm_gap"] = [m, lo, hi]
        out["reference_iqm_gap"] = ref_iqm
        out["runs_iqm_of_shares"] = iqm_runs
        if args.select:
            best = max(runs, key=lambda r: nums[r]["return"][0])
            md += f"\n\nselected (best mean return on {args.set}): {best}"
            out["selected"] = best
    md += f"\n\n{len(seeds)} episodes ({args.set}: seeds {seeds.start}-{seeds.stop - 1})"
    print(md)
    print(f"done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    if args.markdown:
        atomic_write_text(args.markdown, md + "\n")
    if args.json:
        atomic_write_text(args.json, json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except (ValueError, OSError) as exc:  # one line naming the option or file, as gear-env
        print(f"demand_protocol.py: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
