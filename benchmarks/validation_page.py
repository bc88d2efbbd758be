"""Regenerate docs/VALIDATION.md: every row a quantity, its source, inputs, reference, ours, tolerance, pass/fail.

    python benchmarks/validation_page.py                 # writes docs/VALIDATION.md (~1 min, 1 core)
    python benchmarks/validation_page.py --out page.md   # elsewhere

Sources of the reference values:

* ROSS (petrobras/ross, ``ross/multi_rotor``): its own test values for the 62/62 pair
  (``tests/test_gear_element.py``) and, for five more pairs, values computed once with ROSS by
  ``python benchmarks/geometry_vs_ross.py --ross-python <python with ross> --json out.json``
  (commit 631a249a, 2026-12-03) and pinned here and in ``tests/test_geometry.py``. ROSS is
  not needed to regenerate the page; ``benchmarks/geometry_vs_ross.py`` reruns it side by side.
* ROSS's ``tests/test_multi_rotor.py::test_mesh_with_backlash``: the six means it asserts, pinned in
  ``benchmarks/ross_backlash.py`` (which rebuilds the case and reruns ROSS with ``--ross-python``).
* ISO 6336-1 method B (c' and c_gamma_alpha), a coarser estimate of the same stiffness.
* The paper (Table 1 k_m0 and its claims, /work/shared/seed; the claims table of docs/RESULTS.md).
* The model's independent statements: the linear eigenproblem (MODEL.md sec. 5) and the SciPy
  ``solve_ivp`` integrator of ``gear_env/sim/reference.py``.
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from gear_env import GearParams, GearSimulator
from gear_env.analysis.stability import stability_map
from gear_env.io import atomic_write_text
from gear_env.sim.geometry import SpurPair
from gear_env.sim.linear import natural_frequencies
from gear_env.sim.reference import reference_poincare

sys.path.insert(0, str(Path(__file__).resolve().parent))
from geometry_vs_ross import PAIRS, PHASES  # noqa: E402  (the pairs and phases of the ROSS benchmark)
from ross_backlash import TOL as ROSS_TOL  # noqa: E402  (ROSS's test_mesh_with_backlash rebuilt)
from ross_backlash import comparison as ross_backlash_comparison  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

ROSS_PAIR = PAIRS[0][1]  # ROSS tests/test_gear_element.py (20 deg, 206 GPa, nu 0.3, h_a* 1, c* 0.25: the defaults)
ROSS_FIRST5 = [396622921.3581085, 396738680.0375346, 396854147.2919756, 396969323.136738, 397084207.5865779]
# ROSS's contact ratio, max, min, mean of the 1000-point waveform [N/m] of PAIRS[1:] (the pairs of
# benchmarks/geometry_vs_ross.py after ROSS's own test pair), in that order
ROSS_VALUES = [
    (1.7939883590132288, 886563610.3350345, 488006619.07114655, 791347304.0805657),
    (1.6351859635714614, 564445694.4634221, 314239923.63292164, 469071588.6597274),
    (1.5039976948757665, 1059044180.9121268, 592820871.9653096, 828303566.5898292),
    (1.727959352645959, 90817600.58296451, 49876838.67771769, 78638012.49521632),
    (1.7135336237677612, 1087961453.5890226, 601176201.1313995, 935323038.937726),
]
ROSS_PAIRS = [(name, kw, *vals) for (name, kw), vals in zip(PAIRS[1:], ROSS_VALUES, strict=True)]
PAPER_KM0 = 7.74e8  # [N/m], Table 1


class Page:
    """Rows of the validation table."""

    def __init__(self) -> None:
        self.sections: list[tuple[str, str, list[list[str]]]] = []

    def section(self, title: str, text: str) -> None:
        self.sections.append((title, text, []))

    def row(
        self, quantity: str, source: str, inputs: str, ref: str, ours: str, tol: str, ok: bool | None, note: str = ""
    ) -> None:
        verdict = "pass" if ok else ("fail" if ok is not None else "see note")
        self.sections[-1][2].append([quantity, source, inputs, ref, ours, tol, verdict + (f": {note}" if note else "")])

    def counts(self) -> tuple[int, int, int]:
        v = [r[6].split(":")[0] for _, _, rows in self.sections for r in rows]
        return v.count("pass"), v.count("fail"), v.count("see note")

    def markdown(self, header: str) -> str:
        out = [header]
        for title, text, rows in self.sections:
            out += [f"## {title}", "", text, ""] if text else [f"## {title}", ""]
            out.append("| quantity | source | inputs | reference | ours | tolerance | verdict |")
            out.append("|---|---|---|---|---|---|---|")
            out += ["| " + " | ".join(r) + " |" for r in rows]
            out.append("")
        return "\n".join(out)


def rel(a: float, b: float) -> float:
    return abs(a / b - 1.0)


def geometry_rows(page: Page) -> None:
    page.section(
        "Mesh stiffness from the teeth against ROSS",
        "`gear_env.sim.geometry.SpurPair` against ROSS's `Mesh(GearElementTVMS, GearElementTVMS)`. Waveform: "
        "1000 phases `linspace(0, one mesh period, 1000)`, ROSS's last sample being the end of the period. "
        "Steel E 206 GPa, nu 0.3, rho 7810 kg/m^3, h_a* 1, c* 0.25, 20 deg unless stated.",
    )
    p = SpurPair(**ROSS_PAIR)
    inp = "62/62, m 2 mm, b 20 mm, bore 35 mm"
    src = "ROSS tests/test_gear_element.py"
    page.row(
        "contact ratio",
        src,
        inp,
        "1.7897798668",
        f"{p.contact_ratio:.10f}",
        "1e-4 abs",
        abs(p.contact_ratio - 1.7897798668330458) < 1e-4,
    )
    page.row(
        "Hertzian stiffness [N/m]",
        src,
        inp,
        "3.5559e9",
        f"{p.hertzian_stiffness:.5e}",
        "1e-4 rel",
        rel(p.hertzian_stiffness, 3555868607.9093266) < 1e-4,
    )
    k = p.mesh_stiffness(PHASES)
    for i, r in enumerate(ROSS_FIRST5):
        page.row(f"k at phase {i}/999 [N/m]", src, inp, f"{r:.6e}", f"{k[i]:.6e}", "1e-6 rel", rel(k[i], r) < 1e-6)
    page.row(
        "gear mass [kg] / polar inertia [kg m^2]",
        src,
        inp,
        "1.736033 / 3.602486e-3",
        f"{p.pinion.mass:.6f} / {p.pinion.polar_inertia:.6e}",
        "1e-9 rel",
        max(rel(p.pinion.mass, 1.7360332618790646), rel(p.pinion.polar_inertia, 0.0036024860225567935)) < 1e-9,
    )
    for _label, kw, cr, kmax, kmin, kmean in ROSS_PAIRS:
        q = SpurPair(**kw)
        kq = q.mesh_stiffness(PHASES)
        inp = _describe(kw)
        page.row(
            "contact ratio",
            "ROSS (computed, pinned)",
            inp,
            f"{cr:.10f}",
            f"{q.contact_ratio:.10f}",
            "1e-4 abs",
            abs(q.contact_ratio - cr) < 1e-4,
        )
        ours = (kq.max(), kq.min(), kq.mean())
        worst = max(rel(ours[0], kmax), rel(ours[1], kmin), rel(ours[2], kmean))
        page.row(
            "k max / min / mean [N/m]",
            "ROSS (computed, pinned)",
            inp,
            f"{kmax:.4e} / {kmin:.4e} / {kmean:.4e}",
            " / ".join(f"{v:.4e}" for v in ours),
            "3 % each",
            worst < 0.03,
            f"largest difference {worst:.1e}",
        )
    t0 = time.perf_counter()
    for _ in range(5):
        SpurPair(**ROSS_PAIR).mesh_stiffness(PHASES)
    dt = (time.perf_counter() - t0) / 5
    page.row(
        "time of one 1000-point waveform [s]",
        "issue #28 (ROSS ~8 s; 2.8-5.4 s measured by benchmarks/geometry_vs_ross.py)",
        "62/62 pair",
        "well under 1 s",
        f"{dt:.3f}",
        "< 1 s",
        dt < 1.0,
    )


def _describe(kw: dict) -> str:
    z = kw["teeth"]
    b = kw["bore"]
    s = f"{z[0]}/{z[1]}, m {kw['module'] * 1e3:g} mm, b {kw['face_width'] * 1e3:g} mm"
    s += f", bores {b[0] * 1e3:g}/{b[1] * 1e3:g} mm"
    if "pressure_angle_deg" in kw:
        s += f", {kw['pressure_angle_deg']:g} deg"
    if "youngs_modulus" in kw:
        s += f", E {kw['youngs_modulus'] / 1e9:g} GPa, nu {kw['poisson']}"
    if "tip_clearance_coeff" in kw:
        s += f", c* {kw['tip_clearance_coeff']}"
    return s


def iso_rows(page: Page) -> None:
    page.section(
        "ISO 6336-1 mesh stiffness",
        "ISO 6336-1 method B: c_gamma_alpha = c' (0.75 eps_alpha + 0.25), c' = c'_th C_M C_R C_B (E/206 GPa), "
        "C_M 0.8, C_R 1, times the face width; against the mean of the potential-energy waveform. The standard's "
        "formula is an empirical fit for the mean stiffness of steel pairs under load; the two methods are "
        "different models, so the tolerance is the spread reported between them in the literature (25 %).",
    )
    for _label, kw, *_ in [("ROSS 62/62", ROSS_PAIR), *ROSS_PAIRS]:
        q = SpurPair(**kw)
        iso, mean = q.iso_mesh_stiffness(), q.mean_mesh_stiffness
        page.row(
            "mean mesh stiffness [N/m]",
            "ISO 6336-1 c_gamma_alpha b",
            _describe(kw),
            f"{iso:.4e}",
            f"{mean:.4e} (ratio {mean / iso:.3f})",
            "25 %",
            rel(mean, iso) < 0.25,
        )


def paper_km0_rows(page: Page) -> None:
    page.section(
        "The paper's pair",
        "The paper gives k_m0 = 7.74e8 N/m for 55/75 teeth, module 2 mm, 20 deg, but no face width. Every "
        "compliance scales as 1/b, so the face width giving that mean is b = k_m0 / (mean k per metre).",
    )
    kw = dict(module=2e-3, teeth=(55, 75), face_width=0.0387, bore=(0.04, 0.05))
    q = SpurPair(**kw)
    b = PAPER_KM0 / (q.mean_mesh_stiffness / q.face_width)
    check = SpurPair(**{**kw, "face_width": b}).mean_mesh_stiffness
    page.row(
        "face width giving k_m0 = 7.74e8 N/m [mm]",
        "issue #28 (ROSS at 38.7 mm: mean 8.18e8, bores not reported)",
        "55/75, m 2 mm, bores 40/50 mm",
        "~37 (36.6 scaled)",
        f"{b * 1e3:.2f} (mean at it {check:.4e})",
        "5 %",
        rel(b * 1e3, 36.6) < 0.05,
        "the bores move it: ROSS at 38.7 mm with bores 40/50 mm gives 7.913e8, i.e. 37.85 mm",
    )
    exact = SpurPair(**{**kw, "face_width": b}, kinematics="line_of_action").mean_mesh_stiffness
    page.row("mean stiffness, exact path of contact / ROSS's kinematics - 1", "gear_env.sim.geometry (kinematics="
             "'line_of_action')", "as above", "-", f"{exact / check - 1:+.2%}", "-", None,
             "information: ROSS moves the contact linearly in pressure angle from the form circle")  # fmt: skip
    k0, kap, _ = SpurPair(**{**kw, "face_width": b}).stiffness_harmonics(4)
    page.row(
        "first stiffness harmonic kappa_1 [-]",
        "MODEL.md (kappa = 0.2 assumed; the paper gives none)",
        "as above",
        "0.2 (assumption)",
        f"{kap[0]:.3f} (kappa_2..4 = {', '.join(f'{v:.3f}' for v in kap[1:])})",
        "-",
        None,
        "information: the geometry's first harmonic beside the assumed one",
    )


def reference_row(page: Page, p: GearParams, model: str, omega: float, transient: int, periods: int, source: str,
                  extra: str) -> None:  # fmt: skip
    """A row: the Newmark kernels against the solve_ivp reference from the same state on the attractor."""
    sim = GearSimulator(p, model, None, omega)
    sim.advance(transient)
    start = sim.state
    st = sim.advance(periods)
    ref = reference_poincare(omega, model, p, transient=0, periods=periods, initial_state=start)
    e = float(np.max(np.abs(st.poincare[:, :10] - ref.states)))
    page.row(f"Poincare states over {periods} mesh periods [b0]", source, f"{model}, omega {omega}{extra}",
             "DOP853 states", f"max difference {e:.1e}", "1e-3", e < 1e-3)  # fmt: skip


def harmonic_rows(page: Page) -> None:
    page.section(
        "Any periodic excitation (Fourier series in the kernels)",
        "The geometry's 16 stiffness harmonics (paper's pair, Table 1 masses and inertias) plus a 3-harmonic "
        "TE ((10, 3, 1) um at phases (0, 0.5, -1) rad) in the Newmark kernels against the series stated "
        "independently in gear_env/sim/reference.py (SciPy DOP853); the single cosine against the code before "
        "the series existed.",
    )
    root = str(ROOT)
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
         "tests/test_harmonics.py::test_single_cosine_trajectories_are_bit_identical_to_before"],
        cwd=root, capture_output=True, text=True,
    )  # fmt: skip
    tail = res.stdout.strip().splitlines()[-1] if res.stdout.strip() else res.stderr.strip()[-200:]
    skipped = "skipped" in tail
    page.row(
        "trajectory digest, single cosines (simulate x 6, batch x 8)",
        "sha256 pinned at commit 8ced8e4 (before the series)",
        "tests/test_harmonics.py",
        "8d43bcb2...",
        tail,
        "bit-identical",
        None if skipped else res.returncode == 0,
        "skipped off numba 0.68.1/x86_64" if skipped else "",
    )
    pair = SpurPair(module=2e-3, teeth=(55, 75), face_width=0.03785, bore=(0.04, 0.05))
    p = GearParams.from_pair(pair, 16, J_p=0.041, J_g=0.079, m_p=1.53, m_g=3.01)
    p = p.replace(te_harmonics=((1e-5, 0.0), (3e-6, 0.5), (1e-6, -1.0)))
    for model, omega in (("dynamic", 1.2), ("constant", 2.8), ("dynamic", 0.25)):
        reference_row(page, p, model, omega, 200, 10, "gear_env/sim/reference.py with the series", ", 16 + 3 harmonics")
    page.row(
        "cost of 16 + 3 harmonics vs one cosine",
        "issue #28 (<= 1.3x)",
        "python benchmarks/bench_harmonics.py",
        "<= 1.3x time per mesh period",
        "see docs/GEOMETRY.md (same motion: 0.99-1.02x)",
        "1.3x",
        None,
        "timings are not made on this page (the VMs drift)",
    )


def ross_dynamics_rows(page: Page) -> None:
    page.section(
        "Cross-code dynamics: ROSS's test_mesh_with_backlash",
        "ROSS's two 20-tooth gears (module 10 mm, 30 mm wide, 6.57 kg, on bearings 1e8 N/m, 512.64 N s/m), "
        "square-wave stiffness (ratio 0.275), half backlash 5e-5 m, TE 2e-5 sin(z theta) m, torques "
        "300 + 100 sin(shaft angle) N m on both, 1000 rpm, from rest, 5 revolutions at ROSS's step, rebuilt "
        "with `simulate` by `python benchmarks/ross_backlash.py` (which prints the same table and reruns ROSS "
        "with `--ross-python`): the torque fluctuation `T_p1`, `T_g1`, ROSS's backlash law "
        "`backlash_law='involute'` and ROSS's force direction `mesh_force_direction='gradient'` (the mesh force "
        "along -d(Delta - b(q))/dq, the gradient of its potential; MODEL.md, extension). Each mean is over all "
        "time steps, as ROSS's. With the line of action of eq. (10) instead, the bearings carry half ROSS's "
        "separating force (ROSS's bearing x: -2.187e-5 m = 2 F sin alpha0 / k; the line of action's -1.092e-5 m "
        "= F sin alpha0 / k) and the mean TE and backlash are 10-12 % low (rows 'line of action'). The paper's "
        "backlash law instead of ROSS's, with ROSS's force (rows 'gradient, paper's law'), raises the backlash's "
        "rise by 10 % (its slope tan alpha0 is 1/cos alpha0 = 6.4 % steeper and, through the gradient, pushes "
        "the centres 3.3 % further apart) and the mean TE and backlash by 2.1 % and 2.3 %, just outside the "
        "2 %; along the line of action the law moves them by under 1 %. The mean "
        "stiffness is 0.13 % high because ROSS reads its square wave at the instantaneous contact ratio "
        "(mean 1.5525), ours at the nominal one (1.5568).",
    )
    res = ross_backlash_comparison()
    src = "ROSS test_multi_rotor.py (asserted)"
    for r in res["rows"]:
        page.row(
            f"mean {r['quantity']}",
            src,
            "ROSS's case, law and force direction",
            f"{r['ref']:.6g}",
            f"{r['ross']:.6g} ({100 * r['rel_ross']:+.2f} %)",
            "2 %",
            abs(r["rel_ross"]) <= ROSS_TOL,
        )
    for r in res["shifts"]:
        ratio = r["ross"] / r["ref"]
        page.row(
            r["quantity"],
            "ROSS run (the test's run; y in ROSS's axes)" if "bearing" in r["quantity"] else src,
            "ROSS's case, law and force direction",
            f"{r['ref']:.4g}",
            f"{r['ross']:.4g} (x {ratio:.4f})",
            "2 %",
            abs(ratio - 1.0) <= ROSS_TOL,
        )
    variants = (
        ("paper_law", "gradient", "paper", "gradient, paper's law"),
        ("involute", "line_of_action", "involute", "line of action, ROSS's law"),
        ("paper", "line_of_action", "paper", "line of action, paper's law"),
    )
    for variant, direction, law, label in variants:
        for r in res["rows"][:2] + res["shifts"][:1] + res["shifts"][3:4]:
            ref = r["ref"]
            page.row(
                f"{r['quantity']}, {label}",
                src if "bearing" not in r["quantity"] else "ROSS run",
                f"ROSS's case, mesh_force_direction='{direction}', backlash_law='{law}'",
                f"{ref:.4g}",
                f"{r[variant]:.4g} ({100 * (r[variant] / ref - 1):+.2f} %)",
                "-",
                None,
                "what the force direction and the law move",
            )
    st = res["static"]
    page.row(
        "static backlash at F = 3192 N, gradient force",
        src,
        "balance of the bearings: d - a0 = 4 F sin(alpha0) / k",
        f"{res['rows'][1]['ref']:.6g}",
        f"{st['ROSS gradient']['backlash [m]']:.6g} (line of action: {st['line of action']['backlash [m]']:.6g})",
        "1 %",
        rel(st["ROSS gradient"]["backlash [m]"], res["rows"][1]["ref"]) < 0.01,
        "the force direction explains the line of action's gap",
    )


def existing_rows(page: Page) -> None:
    page.section(
        "Existing checks of the dynamic model",
        "From tests/test_verification.py and the claims table of docs/RESULTS.md, recomputed here (Table 1 "
        "parameters).",
    )
    w = natural_frequencies(GearParams(), "constant")
    expected = [0.32004, 0.81887, 0.94374, 1.14856, 3.11400]
    err = float(np.max(np.abs(w - expected)))
    page.row(
        "linear natural frequencies w/omega_n",
        "MODEL.md sec. 5 (eigenproblem)",
        "constant model",
        ", ".join(f"{v:.5f}" for v in expected),
        ", ".join(f"{v:.5f}" for v in w),
        "6e-6 abs",
        err < 6e-6,
    )
    for model, omega in (("dynamic", 1.2), ("dynamic", 2.8), ("constant", 0.45)):
        src = "gear_env/sim/reference.py (SciPy DOP853, rtol 1e-11, contact events)"
        reference_row(page, GearParams(), model, omega, 300, 15, src, "")
    maps = {m: stability_map(m, cache=False) for m in ("constant", "dynamic")}
    iv = {m: max(maps[m].stable_intervals(), key=lambda t: t[1] - t[0]) for m in maps}
    lo, hi = iv["dynamic"]
    page.row(
        "stable period-1 window (dynamic backlash)",
        "paper, claim 1",
        "Table 1",
        "[0.4, 1.9]",
        f"[{lo:.3f}, {hi:.3f}]",
        "-",
        False,
        "documented disagreement (RESULTS.md claim 1): below 0.59 the orbit period-doubles",
    )
    page.row(
        "loss of period-1 stability (constant backlash)",
        "paper, claim 3",
        "Table 1",
        "1.6",
        f"{iv['constant'][1]:.3f}",
        "5 %",
        rel(iv["constant"][1], 1.6) < 0.05,
        "a Neimark-Sacker (torus), not the paper's chaos",
    )
    page.row(
        "dynamic backlash defers that onset",
        "paper, claim 9",
        "Table 1",
        "1.6 -> 1.9 (+0.3)",
        f"{iv['constant'][1]:.3f} -> {hi:.3f} ({hi - iv['constant'][1]:+.3f})",
        "same sign",
        hi > iv["constant"][1],
        "direction agrees, size does not (RESULTS.md claim 9)",
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Regenerate docs/VALIDATION.md")
    ap.add_argument("--out", default=str(ROOT / "docs" / "VALIDATION.md"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    page = Page()
    geometry_rows(page)
    iso_rows(page)
    paper_km0_rows(page)
    harmonic_rows(page)
    ross_dynamics_rows(page)
    existing_rows(page)
    try:
        commit = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    n_pass, n_fail, n_note = page.counts()
    header = (
        "# Validation\n\n"
        "Each row: a quantity, where its reference comes from, the inputs, the reference value, ours, the "
        "tolerance and the verdict. Regenerate the whole page with\n\n"
        "    python benchmarks/validation_page.py\n\n"
        f"Last generated {datetime.date.today().isoformat()} at commit {commit} in "
        f"{time.perf_counter() - t0:.0f} s (load {os.getloadavg()[0]:.1f}): "
        f"{n_pass} pass, {n_fail} fail (each with its reason), {n_note} for information.\n\n"
        "ROSS is not needed to regenerate it (its values are pinned; see the script's docstring); "
        "`python benchmarks/geometry_vs_ross.py --ross-python <python with ross>` reruns ROSS side by side.\n"
    )
    text = page.markdown(header)
    atomic_write_text(args.out, text)
    print(f"wrote {args.out}: {n_pass} pass, {n_fail} fail, {n_note} information")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
