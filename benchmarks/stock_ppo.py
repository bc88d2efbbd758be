"""Stock stable-baselines3 PPO, as a new user would run it, on a GearSpeed task; scored against the oracle.

Run:  python benchmarks/stock_ppo.py --env GearSpeed-v1 --seeds 0 1 [--timesteps 200000] [--json out.json]
      [--set reference_filter=0.1] [--diagnose]

What "stock" means here: ``PPO("MlpPolicy", venv)`` with every hyper-parameter at SB3's default,
``venv = VecNormalize(make_vec_env(ENV_ID, n_envs=8, seed=seed))``, 200k steps, one torch thread,
no project helper. After training, the deterministic policy (VecNormalize statistics frozen) runs the
evaluation episodes (seeds 100-119 by default, never used in training: training seeds the sub-envs
with seed, seed + 1, ...), and so do the oracle and the fixed-best schedule, through
``gear_env.evaluation.evaluate_policies``. Printed: each run's return as % of the oracle, the
interquartile mean over runs x episodes of the oracle-normalised return and its 95 % bootstrap
confidence interval (rliable's method: resample runs, then episodes), and the wall time. ``--set KEY=JSON``
changes a setting of the task (an ablation; the registered task otherwise); ``--diagnose`` prints, after each
rollout, the policy's std (in action units) and the quantiles of omega in the settled phase (steps > 30).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence

import numpy as np

from agents.protocol import iqm, iqm_ci  # noqa: F401  (re-exported: demand_gap and pretrained_seeds use them)


def parse_settings(items: Sequence[str]) -> dict:
    """``--set KEY=JSON`` items as a dict of task settings (JSON values)."""
    out = {}
    for item in items:
        k, _, v = item.partition("=")
        out[k.strip()] = json.loads(v)
    return out


def report_iqm(out: dict, scores: Sequence, n_runs: int, json_path: str | None) -> None:
    """Add the IQM of the (runs, episodes) oracle-normalised ``scores`` and its 95 % bootstrap CI to
    ``out`` (in %), print them, and write ``out`` atomically to ``json_path`` if given."""
    m, lo, hi = iqm_ci(np.array(scores))
    out["iqm_pct"], out["iqm_ci95_pct"] = 100 * m, [100 * lo, 100 * hi]
    print(f"IQM {100 * m:.1f} % of the oracle, 95 % bootstrap CI [{100 * lo:.1f}, {100 * hi:.1f}] over {n_runs} runs")
    if json_path:
        from gear_env.io import atomic_write_text

        atomic_write_text(json_path, json.dumps(out, indent=1))


class _Frozen:
    """A trained SB3 model + frozen VecNormalize as a policy with the common ``predict``."""

    def __init__(self, model, venv, name="stock-ppo"):
        self.model, self.venv, self.name = model, venv, name

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = self.venv.normalize_obs(np.asarray(observation, np.float32))
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)


def _diagnosis_callback(log: list, after_step: int = 30):
    """SB3 callback: after each rollout, append the policy's std (action units) and the 5/25/50/75/95 %
    quantiles of omega over the rollout's steps past ``after_step`` of their episode (the settled phase)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    class Diagnose(BaseCallback):
        def _on_training_start(self) -> None:
            self.omegas: list[float] = []

        def _on_step(self) -> bool:
            self.omegas += [i["omega"] for i in self.locals["infos"] if i.get("step", 0) > after_step]
            return True

        def _on_rollout_end(self) -> None:
            w = np.asarray(self.omegas)
            self.omegas = []
            row = {"steps": self.num_timesteps, "std": float(torch.exp(self.model.policy.log_std.detach()).mean())}
            row["omega_q"] = np.percentile(w, [5, 25, 50, 75, 95]).round(3).tolist() if len(w) else []
            log.append(row)
            print(f"  {row['steps']:>7,} steps: std {row['std']:.3f}, settled omega quantiles {row['omega_q']}")

    return Diagnose()


def train_stock(env_id: str, seed: int, timesteps: int, env_kwargs: dict | None = None, log: list | None = None):
    """Train stock PPO (SB3 defaults, 8 envs via make_vec_env, VecNormalize); returns (policy, wall s).

    ``env_kwargs``: settings passed to ``gym.make`` (default none: the registered task); ``log``: if a
    list, the per-rollout diagnosis (policy std, settled omega quantiles) is appended to it."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    import gear_env  # noqa: F401  (registers the tasks)

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    venv = VecNormalize(make_vec_env(env_id, n_envs=8, seed=seed, env_kwargs=env_kwargs))
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu")
    model.learn(timesteps, callback=None if log is None else _diagnosis_callback(log))
    venv.training = False
    venv.norm_reward = False
    return _Frozen(model, venv), time.perf_counter() - t0


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="GearSpeed-v1")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--timesteps", type=int, default=200_000)
    ap.add_argument("--eval-seed", type=int, default=100)
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="environment setting (repeatable)")
    ap.add_argument("--diagnose", action="store_true", help="print the policy std and settled omega per rollout")
    ap.add_argument("--json", metavar="PATH")
    args = ap.parse_args(argv)
    settings = parse_settings(args.set)

    from agents.registry import resolve_policy
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import evaluate_policies

    cfg = task_config(args.env, settings)
    base = evaluate_policies(
        {"oracle": resolve_policy("oracle", cfg), "fixed-best": resolve_policy("fixed-best", cfg)},
        cfg,
        episodes=args.episodes,
        seed=args.eval_seed,
    )
    oracle = np.array([e.ret for e in base.episodes["oracle"]])
    fixed = np.array([e.ret for e in base.episodes["fixed-best"]])
    out = {
        "env": args.env,
        "timesteps": args.timesteps,
        "settings": settings,
        "oracle_mean": float(oracle.mean()),
        "fixed_best_mean": float(fixed.mean()),
        "runs": [],
    }
    print(
        f"{args.env}: oracle {oracle.mean():.2f}, fixed-best {fixed.mean():.2f} "
        f"({100 * fixed.mean() / oracle.mean():.1f} %) on seeds {args.eval_seed}-{args.eval_seed + args.episodes - 1}"
    )
    scores = []
    for s in args.seeds:
        log: list | None = [] if args.diagnose else None
        pol, wall = train_stock(args.env, s, args.timesteps, settings, log)
        rep = evaluate_policies({"stock": pol}, cfg, episodes=args.episodes, seed=args.eval_seed)
        r = np.array([e.ret for e in rep.episodes["stock"]])
        scores.append(r / oracle.mean())
        out["runs"].append(
            {
                "seed": s,
                "wall_s": wall,
                "returns": r.tolist(),
                "pct_of_oracle": 100 * r.mean() / oracle.mean(),
                "settled_omega": [e.settled_omega for e in rep.episodes["stock"]],
                "diagnosis": log,
            }
        )
        print(f"seed {s}: {r.mean():.2f} = {100 * r.mean() / oracle.mean():.1f} % of the oracle, {wall:.0f} s wall")
    report_iqm(out, scores, len(args.seeds), args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
