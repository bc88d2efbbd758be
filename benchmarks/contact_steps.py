"""How well ``steps_per_period="auto"`` (the contact rule, ``gear_env.sim.integration.contact_steps``) bounds the
error of Fox-Goodwin's Newmark steps, against fixed 64 steps, on period-1 orbits and an event-located reference.

    python benchmarks/contact_steps.py             # the three sets below, about 4 minutes on 2 cores
    python benchmarks/contact_steps.py --sets fresh family
    python benchmarks/contact_steps.py --by-class  # per class of contact loss: where the correction buys accuracy

Sets (both backlash models, period-1 orbits only: the reference's last two Poincare points agree to 1e-5):

* ``tuning``: the Table 1 pair at omega 0.30 + 0.01 k (``bench_tolerance.py --omega-step 0.01``), the orbits the
  rule's classes were chosen on;
* ``fresh``: the Table 1 pair at omega 0.305 + 0.01 k, never used for a choice;
* ``family``: five pairs of GearSpeedDemand's plant family (load x0.4-1.5, transmission error x0.25-2, the
  corners and one inside) at omega 0.307 + 0.04 k, never used for a choice.

Per orbit: the largest difference of 10 Poincare points from ``gear_env.sim.reference.reference_poincare`` after
starting on the orbit, at 64 fixed steps, at the rule's count (from the orbit's contact loss at 64 steps), at 64
steps of ``"fox-goodwin-vc"`` (``GearParams.velocity_correction``, the Fox-Goodwin ids' scheme) and at the rule's
count under that scheme (from its own contact loss at 64 steps: what ``steps_per_period="auto"`` does on those ids),
at 64 steps of that scheme with the contact changes located inside the steps (the environments'
``locate_contacts=True``), with the contact changes located per mesh period, and at 64 steps of that scheme with the
kinks of the contact changes corrected (``correct_kinks=True``), and so at the count of the rule's classes for corrected
steps (``contact_steps(..., corrected=True)``: 48 or 64, from the separation at 64 steps; what
``steps_per_period="auto"`` with ``correct_kinks=True`` takes).
The rule's cost is its mean count over the orbits (the environments' cost is measured by ``env_tol.py``).
"""

from __future__ import annotations

import argparse

import numpy as np

SETS = ("tuning", "fresh", "family")
FAMILY = ((0.4, 0.25), (0.4, 2.0), (1.5, 0.25), (1.5, 2.0), (0.6, 1.0))  # (load x duty, e_m1 factor)


def orbits(params, omegas) -> list[tuple[str, float, np.ndarray, np.ndarray]]:
    """(model, omega, start state, reference Poincare points) of the period-1 orbits of ``params``."""
    from gear_env import GearSimulator
    from gear_env.sim.reference import reference_poincare

    out = []
    for model in ("constant", "dynamic"):
        for w in omegas:
            sim = GearSimulator(params, model, 512, float(w))
            sim.advance(300)
            ref = reference_poincare(float(w), model, params, 0, 10, initial_state=sim.state).states
            if np.max(np.abs(ref[-1] - ref[-2])) <= 1e-5 * (1 + np.max(np.abs(ref[-1]))):
                out.append((model, float(w), sim.state, ref))
    return out


def errors(params, cases) -> tuple[np.ndarray, ...]:
    """Per orbit: error at 64 fixed Fox-Goodwin steps, error at the rule's count, the rule's count; error at 64
    steps of Fox-Goodwin with the velocity correction (scheme ``"fox-goodwin-vc"``), error at the rule's count under
    that scheme and that count."""
    from gear_env import GearSimulator
    from gear_env.sim.integration import contact_steps

    fg = params.replace(newmark_beta=1.0 / 12.0)
    vc = fg.replace(velocity_correction=True)
    e64, er, ns, evc, erv, nsv, sepv = [], [], [], [], [], [], []
    for model, w, x0, ref in cases:
        for p, e_fixed, e_rule, counts in ((fg, e64, er, ns), (vc, evc, erv, nsv)):
            iv = GearSimulator(p, model, 64, w, x0).advance(10)
            if p is vc:
                sepv.append(iv.separation_fraction)
            e_fixed.append(float(np.max(np.abs(iv.poincare[:, :10] - ref))))
            n = contact_steps(iv.separation_fraction)
            counts.append(n)
            iv_n = iv if n == 64 else GearSimulator(p, model, n, w, x0).advance(10)
            e_rule.append(float(np.max(np.abs(iv_n.poincare[:, :10] - ref))))
    eloc, nloc, ecor, ecr, ncr = [], [], [], [], []
    for (model, w, x0, ref), sep in zip(cases, sepv):
        e, n = located(vc, model, w, x0, ref)
        eloc.append(e)
        nloc.append(n)
        ecor.append(located(vc, model, w, x0, ref, corrected=True)[0])
        ncr.append(contact_steps(sep, corrected=True))
        ecr.append(ecor[-1] if ncr[-1] == 64 else located(vc, model, w, x0, ref, ncr[-1], corrected=True)[0])
    return tuple(np.array(v) for v in (e64, er, ns, evc, erv, nsv, eloc, nloc, ecor, ecr, ncr))


def located(
    params, model: str, w: float, x0, ref, steps: int = 64, periods: int = 10, corrected: bool = False
) -> tuple[float, float]:
    """Error over ``periods`` Poincare points (``ref``) of ``steps`` fixed steps of ``params`` with the contact changes
    located (the kernels' ``C_LOC`` flag, the environments' ``locate_contacts``; not a ``GearSimulator`` option) or,
    with ``corrected``, their kinks corrected (``correct_kinks``), and the contact changes located per mesh period."""
    from gear_env.sim import kernels as K
    from gear_env.sim.integration import integrate
    from gear_env.sim.params import C_LOC, CONTACTS_CORRECTED, CONTACTS_LOCATED, model_code

    c = params.consts.copy()
    c[C_LOC] = CONTACTS_CORRECTED if corrected else CONTACTS_LOCATED
    x, a = np.array(x0, float), np.zeros(5)
    run = integrate(x, a, K.readonly(c), model_code(model), w, w, periods, steps)
    return float(np.max(np.abs(run.poincare[:, :10] - ref))), float(run.stats[K.ST_SPLITS]) / periods


def line(name: str, e64, er, ns, evc, erv, nsv, eloc, nloc, ecor, ecr, ncr) -> str:
    def s(e: np.ndarray) -> str:
        return f"{np.percentile(e, 95):.1e} / {e.max():.1e} | {(e > 1e-3).sum()}"

    return (
        f"| {name} | {len(e64)} | {s(e64)} | {s(er)} | {ns.mean():.1f} | {s(evc)} | {s(erv)} | {nsv.mean():.1f} "
        f"| {s(eloc)} | {nloc.mean():.2f} | {s(ecor)} | {s(ecr)} | {ncr.mean():.1f} |"
    )


CLASS_COLUMNS = (
    ("fox-goodwin-vc", 64),
    ("fox-goodwin-vc", 72),
    ("corrected", 32),
    ("corrected", 48),
    ("corrected", 64),
)
"""``--by-class``: the schemes and step counts measured on every orbit (kinks as they fall, or corrected)."""
CLASSES = ((-1.0, 0.2), (0.2, 0.5), (0.5, 1.0))
"""``--by-class``: the classes of contact loss (time out of drive-side contact at 64 steps of ``fox-goodwin-vc``)."""


def orbit_sets(name: str) -> list[tuple[str, object, np.ndarray]]:
    """(label, pair, omegas) of orbit set ``name`` (:data:`SETS`): one pair for the Table 1 sets, five for the
    family."""
    from gear_env import GearParams
    from gear_env.envs.tasks import PlantFamily

    base = GearParams()
    if name in ("tuning", "fresh"):
        start = 0.30 if name == "tuning" else 0.305
        return [(f"Table 1 pair, {name}", base, np.round(np.arange(start, 3.0 + 1e-9, 0.01), 6))]
    omegas = np.round(np.arange(0.307, 2.4, 0.04), 6)
    return [
        (f"family: load x{load:g}, e_m1 x{te:g}", PlantFamily.plant(base, {"load": load, "e_m1": te}, 1.0), omegas)
        for load, te in FAMILY
    ]


def class_errors(params, cases) -> tuple[np.ndarray, np.ndarray]:
    """Per orbit: its contact loss at 64 steps of ``fox-goodwin-vc`` and its error at each of :data:`CLASS_COLUMNS`
    (orbits x columns)."""
    from gear_env import GearSimulator

    vc = params.replace(newmark_beta=1.0 / 12.0, velocity_correction=True)
    sep, err = [], []
    for model, w, x0, ref in cases:
        iv64 = GearSimulator(vc, model, 64, w, x0).advance(10)
        sep.append(iv64.separation_fraction)
        row = []
        for scheme, n in CLASS_COLUMNS:
            if scheme == "corrected":
                row.append(located(vc, model, w, x0, ref, n, corrected=True)[0])
            else:
                iv = iv64 if n == 64 else GearSimulator(vc, model, n, w, x0).advance(10)
                row.append(float(np.max(np.abs(iv.poincare[:, :10] - ref))))
        err.append(row)
    return np.array(sep), np.array(err).reshape(-1, len(CLASS_COLUMNS))


def class_lines(name: str, sep: np.ndarray, err: np.ndarray) -> list[str]:
    """Rows of the ``--by-class`` table: per class of contact loss, p95 / max [b0] and the orbits above 1e-3."""
    out = []
    for lo, hi in CLASSES:
        m = (sep > lo) & (sep <= hi)
        if not m.any():
            continue
        cells = " | ".join(
            f"{np.percentile(err[m, i], 95):.1e} / {err[m, i].max():.1e}, {(err[m, i] > 1e-3).sum()}"
            for i in range(len(CLASS_COLUMNS))
        )
        out.append(f"| {name} | {max(lo, 0.0):g}-{hi:g} | {m.sum()} | {cells} |")
    return out


def by_class(sets: list[str]) -> int:
    """``--by-class``: the error of each scheme and count of :data:`CLASS_COLUMNS` per class of contact loss: where
    the kink correction and the step count buy accuracy, and where they do not."""
    head = " | ".join(f"{s}, {n}: p95 / max, > 1e-3" for s, n in CLASS_COLUMNS)
    print(f"| orbit set | contact loss | orbits | {head} |")
    print("|---|---|---:|" + "---:|" * len(CLASS_COLUMNS))
    for name in sets:
        sets_ = orbit_sets(name)
        parts = [class_errors(p, orbits(p, omegas)) for _, p, omegas in sets_]
        sep = np.concatenate([a for a, _ in parts])
        err = np.concatenate([b for _, b in parts])
        label = "family, all five" if name == "family" else sets_[0][0]
        print("\n".join(class_lines(label, sep, err)), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="+", choices=SETS, default=list(SETS), help="orbit sets (default: all three)")
    ap.add_argument(
        "--by-class",
        action="store_true",
        help="per class of contact loss (up to 0.2, 0.2-0.5, above): p95 / max of fox-goodwin-vc at 64 and 72 steps "
        "and of corrected steps at 32, 48 and 64 (about 4 minutes on 2 cores)",
    )
    args = ap.parse_args(argv)
    if args.by_class:
        return by_class(args.sets)
    print(
        "| orbit set | orbits | 64 steps: p95 / max [b0] | > 1e-3 | rule: p95 / max [b0] | > 1e-3 | rule: mean steps "
        "| fox-goodwin-vc, 64 steps: p95 / max [b0] | > 1e-3 | fox-goodwin-vc, rule: p95 / max [b0] | > 1e-3 "
        "| its mean steps | fox-goodwin-vc, 64 located: p95 / max [b0] | > 1e-3 | contact changes per period "
        "| fox-goodwin-vc, 64 kinks corrected: p95 / max [b0] | > 1e-3 "
        "| fox-goodwin-vc, kinks corrected, corrected rule: p95 / max [b0] | > 1e-3 | its mean steps |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in args.sets:
        total = [np.zeros(0)] * 11
        for label, p, omegas in orbit_sets(name):
            res = errors(p, orbits(p, omegas))
            print(line(label, *res), flush=True)
            total = [np.concatenate([a, b]) for a, b in zip(total, res)]
        if name == "family":
            print(line("family, all five", *total), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
