"""The window the agent learned: delivered speed against demanded speed on plants of the family.

    python examples/learned_window.py [--policy pretrained] [--plot learned_window.png] [--json data.json]

For six gear pairs of ``GearSpeedDemand-v0``'s family (light/heavy load x precision/worn transmission error,
and the nominal pair), the policy follows a slow staircase of demands over the task's demand band
(1.2-1.8, each level held ``--hold`` steps, full load, no duty cycle); the delivered speed is omega at the
end of each hold. Each panel shades that plant's quiet window from its steady map (periodic motion,
contact loss < 5 %, no impacts), draws the oracle's steady choice for each demand (the plant's own map) and
fixed-best's (the family's robust map: the same for every plant), and the bars beside the panels show the
nominal pair's Floquet stable window and the paper's [0.4, 1.9].
"""

from __future__ import annotations

import argparse
import json

import numpy as np

PLANTS = (
    ("light load x0.45, worn TE x1.9", 0.45, 1.9),
    ("light load x0.45, precise TE x0.3", 0.45, 0.3),
    ("nominal", 1.0, 1.0),
    ("heavy load x1.45, worn TE x1.9", 1.45, 1.9),
    ("load x1.2, TE x0.6", 1.2, 0.6),
    ("heavy load x1.45, precise TE x0.3", 1.45, 0.3),
)


def quiet_intervals(omegas, terms) -> list[tuple[float, float]]:
    """Intervals of omega where the steady motion is periodic, keeps contact (< 5 %) and has no impacts."""
    from gear_env.envs.bands import mask_intervals

    imp = np.asarray(terms["drive_impacts"]) + np.asarray(terms["back_impacts"])
    ok = (np.asarray(terms["chaos"]) < 0.5) & (np.asarray(terms["contact_loss"]) < 0.05) & (imp < 1e-3)
    return mask_intervals(np.asarray(omegas), ok)


def learned_window(policy_spec: str = "pretrained", hold: int = 8, levels: np.ndarray | None = None) -> list[dict]:
    """One curve per plant of PLANTS (see :func:`gear_env.plots.tasks.plot_learned_window`)."""
    from agents.episode_oracle import cost_map, family_sample
    from agents.registry import resolve_policy
    from gear_env.envs.env import GearSpeedEnv
    from gear_env.envs.env_config import task_config
    from gear_env.evaluation import steady_reward_map

    base = task_config("GearSpeedDemand-v0")
    band = base.demand_range or (base.omega_min, base.omega_max)
    levels = np.round(np.linspace(band[0], band[1], 7), 3) if levels is None else np.asarray(levels, float)
    pts = []
    for k, d in enumerate(levels):
        pts += [(k * hold, float(d)), ((k + 1) * hold - 1e-6, float(d))]
    T = hold * len(levels)
    curves = []
    grid = np.round(np.arange(base.omega_min, base.omega_max + 1e-9, 0.05), 4)
    w_fam = None
    robust = []
    for f in family_sample(base):  # the family's robust (mean) cost map at full load: fixed-best's
        w_fam, c = cost_map(base, base.plant_family.plant(base.params, f))
        robust.append(c)
    assert w_fam is not None
    r_thr = np.minimum(w_fam[None, :], levels[:, None])
    r_short = np.maximum(0.0, levels[:, None] - w_fam[None, :])
    r_val = (base.w_throughput * r_thr - base.w_demand * r_short) / base.omega_max + np.mean(robust, axis=0)[None, :]
    fixed = w_fam[np.argmax(r_val, axis=1)].tolist()
    for label, lf, ef in PLANTS:
        cfg = base.replace(
            plant_family={"load": (lf, lf), "e_m1": (ef, ef)},
            duty_cycle=None,
            demand=pts,
            max_steps=T,
            initial_omega=float(levels[0]),
        )
        pol = resolve_policy(policy_spec, cfg, env_id="GearSpeedDemand-v0")
        env = GearSpeedEnv(cfg)
        obs, _ = env.reset(seed=0)
        state, start, om = None, np.ones(1, bool), []
        for _ in range(T):
            a, state = pol.predict(obs[None], state=state, episode_start=start, deterministic=True)
            start = np.zeros(1, bool)
            obs, _, term, trunc, info = env.step(np.asarray(a, np.float32).reshape(1))
            om.append(info["omega"])
            if term:
                break
        delivered = [om[min((k + 1) * hold - 1, len(om) - 1)] for k in range(len(levels))]
        plant = cfg.plant_family.plant(cfg.params, {"load": lf, "e_m1": ef})
        smap = steady_reward_map(cfg.replace(plant_family=None, demand=None, throughput="all", params=plant), grid)
        cost = smap.reward - smap.terms["reward_throughput"]
        thr = np.minimum(grid[None, :], levels[:, None])
        short = np.maximum(0.0, levels[:, None] - grid[None, :])
        val = (cfg.w_throughput * thr - cfg.w_demand * short) / cfg.omega_max + cost[None, :]
        curves.append(
            {
                "label": label,
                "demand": levels.tolist(),
                "delivered": delivered,
                "oracle": grid[np.argmax(val, axis=1)].tolist(),
                "fixed": fixed,
                "quiet": quiet_intervals(grid, smap.terms),
            }
        )
    return curves


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", default="pretrained")
    ap.add_argument("--hold", type=int, default=8)
    ap.add_argument("--plot", default="learned_window.png")
    ap.add_argument("--json")
    args = ap.parse_args()
    from gear_env.plots.common import save_figure
    from gear_env.plots.tasks import plot_learned_window

    curves = learned_window(args.policy, args.hold)
    floquet = None
    try:
        from gear_env.analysis.stability import default_stability_map

        for lo, hi in default_stability_map("dynamic").stable_intervals():
            if lo <= 1.2 <= hi:
                floquet = (float(lo), float(hi))
    except Exception:  # the bar is optional
        pass
    fig = plot_learned_window(
        curves, floquet, title=f"GearSpeedDemand-v0: the window the policy learned ({args.policy})"
    )
    save_figure(fig, args.plot)
    print(f"wrote {args.plot}")
    if args.json:
        from gear_env.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(curves, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
