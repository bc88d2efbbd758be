"""Command line of the hostile probe: ``python -m benchmarks.hostile_probe --help`` (run from the repository root)."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

from . import lib
from .cases import CASES, Skip

HEADER = (
    "| # | group | case | expected | exit code | first stderr line | peak RSS MiB | held |\n"
    "|---:|---|---|---|---|---|---:|---|\n"
)


def _cell(x: object, n: int = 140) -> str:
    return str(x if x is not None else "").replace("|", "/").replace("\n", " ")[:n]


def table(rows: list[dict]) -> str:
    """The Markdown table of the rows (one per case run)."""
    out = [
        f"| {r['i']} | {_cell(r['group'])} | {_cell(r['name'])} | {_cell(r['expected'])} | {_cell(r['rc'])} | "
        f"{_cell(r['err'])} | {_cell(r['rss'])} | {'skipped: ' + _cell(r['note']) if r['skipped'] else r['held']} |"
        for r in rows
    ]
    return HEADER + "\n".join(out) + "\n"


def run_case(i: int, root: Path) -> dict:
    """Run case ``i`` in a fresh folder under ``root``; the row of the table."""
    name, expected, group, fn = CASES[i]
    w = root / f"{i:03d}"
    shutil.rmtree(w, ignore_errors=True)
    w.mkdir(parents=True)
    t0 = time.time()
    skipped = False
    try:
        r, held, note = fn(w)
    except Skip as e:
        r, held, note, skipped = {"rc": "-", "err": "", "tb": False, "rss": 0}, False, str(e), True
    except Exception as e:  # a defect of the probe itself, reported as a failed case
        r = {"rc": "HARNESS", "err": f"{type(e).__name__}: {e}", "tb": False, "rss": 0}
        held, note = False, traceback.format_exc()[-300:]
    return {
        "i": i,
        "group": group,
        "name": name,
        "expected": expected,
        "rc": r.get("rc"),
        "err": r.get("err") or "",
        "tb": bool(r.get("tb")),
        "rss": r.get("rss"),
        "held": bool(held) and not skipped,
        "skipped": skipped,
        "note": note,
        "secs": round(time.time() - t0, 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.hostile_probe",
        description="The 271 cases of the second hostile probe (issue 25), each a real subprocess; a table; "
        "exit 1 if any case did not hold.",
    )
    ap.add_argument("--out", type=Path, help="working folder to keep (default: a temporary folder, deleted)")
    ap.add_argument(
        "--select",
        nargs="+",
        default=[],
        metavar="SUBSTR",
        help="run only the cases whose group or name contains one of these texts",
    )
    ap.add_argument("--table", type=Path, help="also write the Markdown table to this file")
    ap.add_argument("--jsonl", type=Path, help="also write one JSON row per case to this file")
    ap.add_argument("--list", action="store_true", help="print the case numbers, groups and names, run nothing")
    a = ap.parse_args(argv)
    chosen = [
        i
        for i, (name, _, group, _) in enumerate(CASES)
        if not a.select or any(s in group or s in name for s in a.select)
    ]
    if a.list:
        for i in chosen:
            print(f"{i:3d}  [{CASES[i][2]}] {CASES[i][0]}")
        return 0
    if not chosen:
        print(f"error: --select {a.select!r} matches no case (see --list)", file=sys.stderr)
        return 2
    for opt, p in (("--table", a.table), ("--jsonl", a.jsonl)):
        if p is not None and p.exists() and not p.is_file():
            print(f"error: {opt} {str(p)!r} is not a regular file", file=sys.stderr)
            return 2
    if a.out is not None:
        a.out.mkdir(parents=True, exist_ok=True)
        out, tmp = a.out, None
    else:
        tmp = tempfile.mkdtemp(prefix="hostile_probe_")
        out = Path(tmp)
    try:
        lib.configure(out)
        print(f"gear_env under test: {lib.package_dir()}; working folder: {out.resolve()}", flush=True)
        print("compiling the numba kernels into the working folder's cache (gear-env compile --jobs 1)", flush=True)
        lib.warm_cache()
        rows = []
        for i in chosen:
            row = run_case(i, out / "cases")
            rows.append(row)
            if a.jsonl is not None:
                with open(a.jsonl, "a") as f:
                    f.write(json.dumps(row) + "\n")
            state = "SKIP" if row["skipped"] else ("HELD" if row["held"] else "FAIL")
            print(
                f"{state} {i:03d} [{row['group']}] {row['name']} | rc={row['rc']} rss={row['rss']} "
                f"{row['secs']} s | {row['err'][:150]} | {row['note'][:150]}",
                flush=True,
            )
        text = table(rows)
        if a.table is not None:
            tmp_table = a.table.with_name(f".{a.table.name}.{os.getpid()}.tmp")
            tmp_table.write_text(text)
            os.replace(tmp_table, a.table)
        print(text)
        held = sum(r["held"] for r in rows)
        skipped = [r for r in rows if r["skipped"]]
        failed = [r for r in rows if not r["held"] and not r["skipped"]]
        print(f"{held} held, {len(failed)} failed, {len(skipped)} skipped of {len(rows)} cases")
        for r in skipped:
            print(f"skipped {r['i']} {r['name']}: {r['note']}")
        for r in failed:
            print(f"FAILED {r['i']} {r['name']}: rc={r['rc']} {r['err'][:150]} {r['note'][:150]}")
        return 1 if failed else 0
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
