"""Is the plant-specific part of GearSpeedDemand-v0 worth learning? The fixed-best -> oracle gap, measured.

Run:  python benchmarks/demand_gap.py [--maps] [--env-episodes 20 --seed 9001] [--policy pretrained]
                                       [--seeds-json runs.json] [--set KEY=JSON ...]

* ``--maps`` (quasi-static, cheap): for the task's family (``agents.episode_oracle.family_sample``, 24 plants)
  under each duty level and for demands on a grid over the demand band, the per-step value
  ``w_throughput min(w, d) - w_demand max(0, d - w)`` / omega_max + the plant's steady cost at ``w``, at the
  plant's own best ``w`` (the oracle's steady choice) and at the family's robust choice (argmax of the
  family-mean value: what fixed-best holds). Cached maps (``GEAR_ENV_CACHE``).
* the environment (default): ``oracle``, ``fixed-best``, ``hill-climber``, ``random`` (and ``--policy`` specs)
  on the episodes of ``gear-env evaluate --env GearSpeedDemand-v0 --episodes N --seed S``; printed: each
  return, the gap fixed-best -> oracle as % of the oracle's return and as % of the oracle-minus-random
  span, and for every other policy the fraction of that gap it closes.
* ``edge-seeker`` (in the environment runs): a scripted policy that reads only its sensors and the demand
  (:class:`EdgeSeeker`): it climbs towards the demand by 0.02 per step while the motion is clean and backs
  off by 0.1 when contact loss (> 2 %), impacts or a periodicity defect appear, remembering where (the
  ceiling creeps up again by 0.005 per clean step, so it re-probes after a load change); not below 1.15,
  the family's robust speed. It shows what the sensors allow: how much of the gap a policy that never
  sees the plant can close.
* ``--seeds-json`` (the output of ``benchmarks/pretrained_seeds.py --env GearSpeedDemand-v0 --json``): each
  run's episode returns normalised two ways, r / O (% of the oracle) and (r - F) / (O - F) (the fraction of
  the fixed-best -> oracle gap closed; F, O the mean returns of fixed-best and the oracle on the same
  episodes), and the interquartile mean over runs x episodes with its 95 % stratified-bootstrap interval
  (rliable's method, ``stock_ppo.iqm_ci``).

``--terms``: each policy's episode return split into its reward terms (``info["reward_*"]`` summed over the
episode, mean over the episodes), e.g. the rate charge of a jittering speed reference.

``--set`` overrides task settings (JSON values), e.g. ``--set w_demand=0`` or
``--set 'demand_range=[0.1, 3.0]'``, to reproduce the design comparison of docs/ENVIRONMENT.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ENV_ID = "GearSpeedDemand-v0"


def edge_seeker(cfg, floor: float = 1.15, up: float = 0.02, back: float = 0.1, contact: float | None = None):
    """The sensor-only edge seeker described in the module docstring (``predict`` of the baselines);
    ``contact``: the contact-loss fraction that counts as trouble (default ``env_terms.TROUBLE_CONTACT``,
    the threshold of the environment's memory features)."""
    from gear_env.envs.env_terms import TROUBLE_CONTACT

    contact = TROUBLE_CONTACT if contact is None else contact
    from agents.baselines import (
        OBS_BACK_IMPACTS,
        OBS_CONTACT,
        OBS_DEFECT,
        OBS_DEMAND,
        OBS_DRIVE_IMPACTS,
        ScriptedPolicy,
    )

    class EdgeSeeker(ScriptedPolicy):
        name = "edge-seeker"

        def initial_state(self, n):
            return {"t": np.zeros(n, np.int64), "ceil": np.full(n, np.inf)}

        def _targets(self, omega, obs, state):
            d = self.omega_min + 0.5 * (obs[:, OBS_DEMAND] + 1.0) * (self.omega_max - self.omega_min)
            impacts = obs[:, OBS_DRIVE_IMPACTS] + obs[:, OBS_BACK_IMPACTS]
            trouble = (obs[:, OBS_CONTACT] > contact) | (impacts > 0) | (obs[:, OBS_DEFECT] > np.log1p(0.5))
            ceil = np.where(trouble & (omega < 2.0), np.minimum(state["ceil"], omega - 0.05), state["ceil"] + 0.005)
            target = np.where(trouble, omega - back, np.minimum(np.minimum(d, ceil), omega + up))
            target = np.where(omega > 1.9, np.minimum(d, 1.2), target)  # from a start above: down to the band
            state["ceil"] = np.maximum(ceil, floor)
            state["t"] = state["t"] + 1
            return np.maximum(target, floor), state

    return EdgeSeeker(cfg)


def term_sums(policy, cfg, episodes: int, seed: int) -> dict[str, float]:
    """Mean over episodes ``seed``.. of each reward term summed over the episode (the rollout of
    ``gear_env.evaluation.run_episode``, same seeds and calls)."""
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.evaluation import run_episode

    env = GearSpeedEnv(cfg)
    keys = env._core.terms.reward_keys
    tot = dict.fromkeys(keys, 0.0)

    def add(info):
        for key in keys:
            tot[key] += info[key] / episodes

    for k in range(episodes):
        run_episode(env, policy, seed + k, on_step=add)
    return tot


def quasi_static(cfg, n_demands: int = 25) -> dict:
    """Per-step oracle and fixed (robust) values over the family sample, duty levels and demand grid."""
    from agents.episode_oracle import cost_map, family_sample

    lo, hi = cfg.demand_range or (cfg.omega_min, cfg.omega_max)
    ds = np.linspace(lo, hi, n_demands)
    levels = cfg.duty_cycle.levels if cfg.duty_cycle is not None else (1.0,)
    orc, fix, nom = [], [], []
    for lv in levels:
        maps = [cost_map(cfg, cfg.plant_family.plant(cfg.params, f, lv)) for f in family_sample(cfg)]
        w = maps[0][0]
        C = np.array([m[1] for m in maps])  # (plants, omegas)
        thr = np.minimum(w[None], ds[:, None])
        short = np.maximum(0.0, ds[:, None] - w[None])
        base = (cfg.w_throughput * thr - cfg.w_demand * short) / cfg.omega_max  # (demands, omegas)
        V = base[None] + C[:, None, :]  # (plants, demands, omegas)
        robust = np.argmax(base + C.mean(axis=0)[None], axis=1)
        nominal = cost_map(cfg, cfg.plant_family.plant(cfg.params, {"load": 1.0, "e_m1": 1.0}, lv))[1]
        k_nom = np.argmax(base + nominal[None], axis=1)
        orc.append(V.max(axis=2).mean())
        fix.append(V[:, np.arange(len(ds)), robust].mean())
        nom.append(V[:, np.arange(len(ds)), k_nom].mean())
    o, f, n = float(np.mean(orc)), float(np.mean(fix)), float(np.mean(nom))
    return {
        "oracle_per_step": o,
        "robust_per_step": f,
        "nominal_per_step": n,
        "gap_pct_of_oracle": 100 * (o - f) / abs(o),
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", action="store_true", help="the quasi-static estimate only (no episodes)")
    ap.add_argument("--env-episodes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=9001)
    ap.add_argument("--policy", action="append", default=[], help="extra policy spec (e.g. pretrained, RUN_DIR)")
    ap.add_argument("--seeds-json", help="output of benchmarks/pretrained_seeds.py for this task")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="override a task setting")
    ap.add_argument("--terms", action="store_true", help="also split each return into its reward terms")
    ap.add_argument("--json", metavar="PATH")
    args = ap.parse_args(argv)

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from stock_ppo import parse_settings

    over = parse_settings(args.set)
    cfg = task_config(ENV_ID, over)
    out: dict = {"settings": over}
    if args.maps:
        qs = quasi_static(cfg)
        out["quasi_static"] = qs
        print(
            f"quasi-static ({ENV_ID}, {over or 'shipped settings'}): oracle {qs['oracle_per_step']:.4f}/step, "
            f"robust (fixed) {qs['robust_per_step']:.4f}, nominal map {qs['nominal_per_step']:.4f}; "
            f"gap {qs['gap_pct_of_oracle']:.1f} % of the oracle"
        )
    else:
        t0 = time.perf_counter()
        specs = ["oracle", "fixed-best", "hill-climber", "random", *args.policy]
        pols = {s: resolve_policy(s, cfg, env_id=ENV_ID) for s in specs}
        specs.insert(2, "edge-seeker")
        pols["edge-seeker"] = edge_seeker(cfg)
        rep = evaluate_policies(pols, cfg, episodes=args.env_episodes, seed=args.seed)
        R = {s: np.array([e.ret for e in rep.episodes[s]]) for s in specs}
        o, f, r = R["oracle"].mean(), R["fixed-best"].mean(), R["random"].mean()
        seeds = f"seeds {args.seed}-{args.seed + args.env_episodes - 1}"
        print(f"{ENV_ID} ({over or 'shipped settings'}), {seeds}, {time.perf_counter() - t0:.0f} s:")
        for s in specs:
            x = R[s]
            settled = np.mean([e.settled_omega for e in rep.episodes[s]])
            print(
                f"  {s:14s} {x.mean():8.2f} +- {1.96 * x.std(ddof=1) / np.sqrt(len(x)):5.2f}  "
                f"{100 * x.mean() / o:6.1f} % of oracle  {100 * (x.mean() - r) / (o - r):6.1f} % of oracle-random  "
                f"gap closed {100 * (x.mean() - f) / (o - f):7.1f} %  settled omega {settled:.3f}"
            )
        wins = int((R["oracle"] > R["fixed-best"]).sum())
        print(
            f"gap fixed-best -> oracle: {o - f:.2f} per episode = {100 * (o - f) / abs(o):.1f} % of the oracle's "
            f"return, {100 * (o - f) / (o - r):.1f} % of the oracle-minus-random span; oracle ahead in {wins}/"
            f"{len(R['oracle'])} episodes"
        )
        out["env"] = {s: R[s].tolist() for s in specs}
        if args.terms:
            sums = {s: term_sums(pols[s], cfg, args.env_episodes, args.seed) for s in specs if s != "random"}
            keys = list(next(iter(sums.values())))
            print("reward terms per episode (mean): " + ", ".join(k.removeprefix("reward_") for k in keys))
            for s, t in sums.items():
                print(f"  {s:14s} " + " ".join(f"{t[k]:7.2f}" for k in keys))
            out["terms"] = sums
    if args.seeds_json:
        from stock_ppo import iqm_ci

        data = json.loads(Path(args.seeds_json).read_text(encoding="utf-8"))
        O = np.mean(data["baselines"]["oracle"]["returns"])
        F = np.mean(data["baselines"]["fixed-best"]["returns"])
        runs = np.array([run["returns"] for run in data["runs"]])
        for name, scores in (("% of the oracle", runs / O), ("gap closed", (runs - F) / (O - F))):
            m, lo, hi = iqm_ci(scores)
            print(f"{len(runs)} runs: IQM {name} {100 * m:.1f} %, 95 % CI [{100 * lo:.1f}, {100 * hi:.1f}]")
            out.setdefault("iqm", {})[name] = [100 * m, 100 * lo, 100 * hi]
    if args.json:
        from gear_env.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
