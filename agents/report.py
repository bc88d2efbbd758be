"""Judge policies against the targets of the RL result: return vs the oracle, chaos once settled,
settled omega inside the stable window of the simulator's own stability map.

``python -m agents.report --policy RUN_DIR --policy oracle ... --episodes 20 --out DIR`` writes
``DIR/rl_report.md`` (the table for docs/RESULTS.md), ``DIR/rl_report.json`` and
``DIR/rl_omega.png`` (omega(t) of each policy over the stability bands). The general evaluation
table/figure of ``gear-env evaluate`` comes from ``gear_env.evaluation``; this module adds the
per-step bookkeeping the targets need (motion class of every step after the speed settled).

Definitions (per episode of ``max_steps`` steps):

* *settled phase*: the last quarter of the episode (steps >= 3/4 max_steps);
* *settled omega*: mean omega over the settled phase;
* *settled chaotic fraction*: fraction of settled-phase steps with non-periodic motion
  (``info["nonperiodic"]``: periodicity defect > half the defect scale);
* *return vs oracle*: mean return / mean return of the oracle on the same episode seeds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def rollout(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """One deterministic episode; per-step omega, reward, nonperiodic, contact loss, impacts."""
    obs, info = env.reset(seed=seed)
    state, start = None, np.ones((1,), bool)
    rec: dict[str, list] = {k: [] for k in ("omega", "reward", "nonperiodic", "contact_loss", "impacts")}
    w0 = info["omega"]
    done = False
    while not done:
        a, state = policy.predict(obs[None, :], state=state, episode_start=start, deterministic=True)
        start = np.zeros((1,), bool)
        obs, r, term, trunc, info = env.step(np.asarray(a, np.float32).reshape(1))
        rec["omega"].append(info["omega"])
        rec["reward"].append(r)
        rec["nonperiodic"].append(bool(info["nonperiodic"]))
        rec["contact_loss"].append(info["contact_loss"])
        rec["impacts"].append(info["drive_impacts"] + info["back_impacts"])
        done = term or trunc
    n = len(rec["omega"])
    q0 = n - max(1, n // 4)
    return {
        "seed": seed,
        "omega0": w0,
        "return": float(np.sum(rec["reward"])),
        "throughput": float(info["episode_throughput"]),
        "chaotic_fraction": float(np.mean(rec["nonperiodic"])),
        "settled_chaotic_fraction": float(np.mean(rec["nonperiodic"][q0:])),
        "contact_loss_fraction": float(info["episode_contact_loss"]),
        "settled_contact_loss": float(np.mean(rec["contact_loss"][q0:])),
        "impacts": int(np.sum(rec["impacts"])),
        "settled_omega": float(np.mean(rec["omega"][q0:])),
        "diverged": bool(info["diverged"]),
        "omega": [float(w) for w in rec["omega"]],
    }


def _ci(x: Sequence[float]) -> tuple[float, float]:
    a = np.asarray(x, float)
    if a.size < 2:
        return float(a.mean()), 0.0
    from scipy import stats

    return float(a.mean()), float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))


def stable_window(config: Any) -> list[tuple[float, float]]:
    """Stable intervals of the period-1 orbit from the simulator's own (shipped) stability map."""
    from gear_env.analysis.stability import default_stability_map, stability_map

    from .envs import GEAR_ENV_ID, make_config

    cfg = make_config(GEAR_ENV_ID, config)
    from gear_env.sim.params import GearParams

    smap = default_stability_map(cfg.model) if cfg.params == GearParams() else stability_map(cfg.model, cfg.params)
    return [(float(a), float(b)) for a, b in smap.stable_intervals()]


def compare(
    policies: Mapping[str, Any], config: Any = None, episodes: int = 20, seed: int = 0, oracle: str = "oracle"
) -> dict[str, Any]:
    """Roll out every policy on the same seeds and summarise against the targets."""
    from gear_env.envs.env import GearSpeedEnv

    from .envs import GEAR_ENV_ID, config_to_dict, make_config

    cfg = make_config(GEAR_ENV_ID, config)
    env = GearSpeedEnv(cfg)
    windows = stable_window(cfg)
    from .oracle import best_constant_omega

    best = best_constant_omega(cfg)
    # the operating window: the stable interval of the period-1 orbit that holds the best constant speed
    window = next(((a, b) for a, b in windows if a <= best <= b), None)
    res: dict[str, Any] = {
        "config": config_to_dict(cfg),
        "episodes": episodes,
        "seed": seed,
        "stable_intervals": windows,
        "best_constant_omega": best,
        "stable_window": window,
    }
    per: dict[str, list[dict[str, Any]]] = {}
    timing: dict[str, float] = {}
    for name, pol in policies.items():
        t0 = time.perf_counter()
        per[name] = [rollout(env, pol, seed + k) for k in range(episodes)]
        timing[name] = time.perf_counter() - t0
    ref = np.mean([e["return"] for e in per[oracle]]) if oracle in per else None
    summary = {}
    for name, eps in per.items():
        s: dict[str, Any] = {}
        for key in ("return", "throughput", "chaotic_fraction", "settled_chaotic_fraction", "contact_loss_fraction",
                    "impacts", "settled_omega"):  # fmt: skip
            s[key] = _ci([e[key] for e in eps])
        so = [e["settled_omega"] for e in eps]
        s["settled_in_stable_window"] = (
            float(np.mean([window[0] <= w <= window[1] for w in so])) if window is not None else None
        )
        s["return_vs_oracle"] = float(s["return"][0] / ref) if ref else None
        s["diverged"] = int(sum(e["diverged"] for e in eps))
        s["seconds"] = round(timing[name], 2)
        summary[name] = s
    res["summary"] = summary
    res["per_episode"] = per
    return res


def to_markdown(res: Mapping[str, Any]) -> str:
    """The comparison table (mean ± 95 % CI over episodes)."""
    lines = [
        "| policy | return | % of oracle | throughput (mean ω) | chaotic steps | chaotic steps, settled "
        "| contact loss | impacts | settled ω | settled ω in stable window |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, s in res["summary"].items():

        def f(key: str, fmt: str, scale: float = 1.0, s=s) -> str:
            m, h = s[key]
            return (fmt.format(m * scale)) + (" ± " + fmt.format(h * scale) if h > 0 else "")

        pct = f"{100 * s['return_vs_oracle']:.1f} %" if s["return_vs_oracle"] is not None else "–"
        lines.append(
            f"| {name} | {f('return', '{:.1f}')} | {pct} | {f('throughput', '{:.3f}')} | "
            f"{f('chaotic_fraction', '{:.1f}', 100)} % | {f('settled_chaotic_fraction', '{:.1f}', 100)} % | "
            f"{f('contact_loss_fraction', '{:.1f}', 100)} % | {f('impacts', '{:.0f}')} | "
            f"{f('settled_omega', '{:.3f}')} | "
            + (f"{100 * s['settled_in_stable_window']:.0f} % |" if s["settled_in_stable_window"] is not None else "- |")
        )
    win = ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in res["stable_intervals"])
    sw = res.get("stable_window")
    sw_text = f"[{sw[0]:.2f}, {sw[1]:.2f}]" if sw else "none"
    lines += [
        "",
        f"{res['episodes']} episodes per policy (seeds {res['seed']}..{res['seed'] + res['episodes'] - 1}, the same "
        f"initial ω for every policy); ± = 95 % t confidence interval. Settled = last quarter of the episode. "
        f"Stable intervals of the period-1 orbit (simulator's Floquet stability map): {win}; the stable window "
        f"is the one holding the best constant speed ω = {res['best_constant_omega']:.3f}: {sw_text}.",
    ]
    return "\n".join(lines)


def plot(res: Mapping[str, Any], path: str, episodes_shown: int = 4) -> None:
    """omega(t) of the first episodes of each policy over the stability bands (PNG, atomic).

    Background: the Floquet bands of the period-1 orbit (green stable, orange period doubling, red
    torus / Neimark-Sacker) and, hatched, where the steady reward map shows contact loss > 5 %."""
    from gear_env.plots.common import new_figure, save_figure

    names = list(res["per_episode"])
    ncol = 3 if len(names) > 4 else 2 if len(names) > 1 else 1
    nrow = -(-len(names) // ncol)
    fig = new_figure(4.2 * ncol, 2.4 * nrow + 0.7)
    axes = fig.subplots(nrow, ncol, sharex=True, sharey=True, squeeze=False).ravel()
    cfg = res["config"]
    try:
        from gear_env.evaluation import regime_bands

        bands = regime_bands(cfg).bands
    except Exception:  # plots still work without bands
        bands = {}
    colors = {
        "stable": "#d9f0d3",
        "periodic": "#d9f0d3",
        "period-doubling": "#fee0b6",
        "impacting": "#fee0b6",
        "neimark-sacker": "#f4a6a6",
        "nonperiodic": "#f4a6a6",
    }
    contact: list[tuple[float, float]] = []
    try:
        from gear_env.evaluation import steady_reward_map

        w = np.linspace(cfg["omega_min"], cfg["omega_max"], 117)
        smap = steady_reward_map({**cfg, "randomize_params": False, "demand": None}, w, 6, 4)
        bad = smap.terms["contact_loss"] > 0.05
        h = 0.5 * (w[1] - w[0])
        contact = [(float(a - h), float(a + h)) for a, b in zip(w, bad) if b]
    except Exception:
        pass
    for ax, name in zip(axes, names):
        for kind, ivs in bands.items():
            for lo, hi in ivs:
                ax.axhspan(lo, hi, color=colors.get(kind, "#eeeeee"), lw=0, zorder=0)
        for lo, hi in contact:
            ax.axhspan(lo, hi, facecolor="none", hatch="////", edgecolor="#999999", lw=0, zorder=0.5)
        for e in res["per_episode"][name][:episodes_shown]:
            ax.plot(np.arange(len(e["omega"]) + 1), [e["omega0"]] + e["omega"], lw=1.2)
        ax.set_title(f"{name}\nreturn {res['summary'][name]['return'][0]:.1f}", fontsize=8, loc="left")
        ax.set_ylim(cfg["omega_min"], cfg["omega_max"])
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    for ax in axes[::ncol]:
        ax.set_ylabel("ω = Ω/ω_n")
    for ax in axes[-ncol:]:
        ax.set_xlabel("step (24 mesh periods)")
    fig.suptitle(
        "ω(t), first episodes. Floquet bands of the period-1 orbit: green stable, orange period doubling, "
        "red torus; hatched: contact loss > 5 % (steady reward map)",
        fontsize=9,
    )
    save_figure(fig, path)
