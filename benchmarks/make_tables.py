"""Regenerate the benchmark tables of docs/BENCHMARKS.md from the JSON records in docs/benchmarks/.

    python benchmarks/make_tables.py docs/BENCHMARKS.md              # rewrite the generated block
    python benchmarks/make_tables.py docs/BENCHMARKS.md --check      # exit 1 if it is out of date
    python benchmarks/make_tables.py docs/BENCHMARKS.md --records DIR

The records are what the benchmark scripts write with ``--json FILE`` (benchmarks/bench_record.py):
benchmark, release, commit, date, machine, load averages before and after, results. The block between
``<!-- benchmarks:generated -->`` and ``<!-- /benchmarks:generated -->`` becomes one table per release
(newest first), a row per result with the machine and the load in columns. The output depends only on
the records (sorted by release, benchmark, date and file name), so the same records give the same text.
A malformed record is refused with a one-line error naming the file and the field; nothing is written.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

SCHEMA = "gear-env-benchmark/1"
BEGIN = "<!-- benchmarks:generated -->"
END = "<!-- /benchmarks:generated -->"
_BLOCK = re.compile(re.escape(BEGIN) + r"\n.*?" + re.escape(END), re.S)
_RELEASE = re.compile(r"\d+\.\d+\.\d+")
_DATE = re.compile(r"\d{4}-\d\d-\d\d(T\d\d:\d\dZ)?")


class RecordError(ValueError):
    """A record that does not follow the schema (the message names the file and the field)."""


def _str(obj: dict, key: str, where: str, optional: bool = False) -> str | None:
    v = obj.get(key)
    if v is None and optional:
        return None
    if not isinstance(v, str) or not v.strip() or "\n" in v or "|" in v:
        raise RecordError(f"{where}: field {key!r} must be a one-line string without '|', got {v!r}")
    return v


def _load(v: Any, where: str) -> list[float] | None:
    if v is None:
        return None
    if (
        not isinstance(v, list)
        or len(v) != 3
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x >= 0 for x in v)
    ):
        raise RecordError(f"{where}: must be null or three finite load averages >= 0, got {v!r}")
    return [float(x) for x in v]


def validate(obj: Any, where: str) -> dict[str, Any]:
    """The record ``obj`` (parsed JSON) checked against the schema; ``RecordError`` naming ``where`` otherwise."""
    if not isinstance(obj, dict):
        raise RecordError(f"{where}: a record must be a JSON object, got {type(obj).__name__}")
    if obj.get("schema") != SCHEMA:
        raise RecordError(f"{where}: field 'schema' must be {SCHEMA!r}, got {obj.get('schema')!r}")
    for key in ("benchmark", "command", "date", "release"):
        _str(obj, key, where)
    _str(obj, "commit", where, optional=True)
    _str(obj, "source", where, optional=True)
    if not _RELEASE.fullmatch(obj["release"]):
        raise RecordError(f"{where}: field 'release' must be a version X.Y.Z, got {obj['release']!r}")
    if not _DATE.fullmatch(obj["date"]):
        raise RecordError(f"{where}: field 'date' must be YYYY-MM-DD or YYYY-MM-DDTHH:MMZ, got {obj['date']!r}")
    m = obj.get("machine")
    if not isinstance(m, dict):
        raise RecordError(f"{where}: field 'machine' must be an object")
    _str(m, "cpu", f"{where}: machine")
    if not isinstance(m.get("cores"), int) or isinstance(m.get("cores"), bool) or not 1 <= m["cores"] <= 4096:
        raise RecordError(f"{where}: field 'machine.cores' must be an integer in [1, 4096], got {m.get('cores')!r}")
    load = obj.get("load")
    if not isinstance(load, dict):
        raise RecordError(f"{where}: field 'load' must be an object with 'before' and 'after'")
    _load(load.get("before"), f"{where}: field 'load.before'")
    _load(load.get("after"), f"{where}: field 'load.after'")
    _str(load, "note", f"{where}: load", optional=True)
    if load.get("before") is None and load.get("after") is None and not load.get("note"):
        raise RecordError(f"{where}: field 'load' has neither averages nor a note saying why")
    results = obj.get("results")
    if not isinstance(results, list) or not results:
        raise RecordError(f"{where}: field 'results' must be a non-empty list")
    for i, r in enumerate(results):
        w = f"{where}: results[{i}]"
        if not isinstance(r, dict):
            raise RecordError(f"{w} must be an object")
        _str(r, "name", w)
        _str(r, "unit", w)
        _str(r, "note", w, optional=True)
        vals = r.get("values")
        if (
            not isinstance(vals, list)
            or not vals
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in vals)
        ):
            raise RecordError(f"{w}: field 'values' must be a non-empty list of finite numbers, got {vals!r}")
    return obj


def read_records(folder: str | Path) -> list[dict[str, Any]]:
    """Every ``*.json`` record of ``folder``, validated (read through gear_env.io's bounded JSON parser)."""
    from gear_env.io import read_json

    folder = Path(folder)
    if not folder.is_dir():
        raise RecordError(f"{folder}: no such folder of benchmark records")
    out = []
    for path in sorted(folder.glob("*.json")):
        try:
            obj = read_json(path, "benchmark record")
        except ValueError as exc:
            raise RecordError(" ".join(str(exc).split())) from None
        rec = validate(obj, str(path.as_posix()))
        rec["_file"] = path.name
        out.append(rec)
    if not out:
        raise RecordError(f"{folder}: no *.json benchmark records")
    return out


def fmt(v: float) -> str:
    """A measured number for a table: thousands separated above 1,000, three significant digits below."""
    a = abs(v)
    if a >= 100:
        return f"{v:,.0f}"
    if a >= 0.01 or a == 0:
        return f"{v:#.3g}".rstrip(".")  # 17.0, 2.19, 0.450: three significant digits shown
    return f"{v:.1e}"


def _range(vals: Sequence[float]) -> str:
    lo, hi = min(vals), max(vals)
    return fmt(lo) if fmt(lo) == fmt(hi) else f"{fmt(lo)}-{fmt(hi)}"


def _load_cell(load: dict[str, Any]) -> str:
    b, a = load.get("before"), load.get("after")
    cells = []
    if b is not None or a is not None:
        cells.append(f"{b[0]:.2f}" if b else "?")
        cells.append(f"{a[0]:.2f}" if a else "?")
    text = " → ".join(cells)
    if load.get("note"):
        text = f"{text}; {load['note']}" if text else load["note"]
    return text


def _machine_cell(m: dict[str, Any]) -> str:
    text = f"{m['cpu']}, {m['cores']} cores"
    if m.get("usable_cores") and m["usable_cores"] != m["cores"]:
        text += f" ({m['usable_cores']} used)"
    return text


def _version_key(release: str) -> tuple[int, ...]:
    return tuple(int(x) for x in release.split("."))


def render(records: Sequence[dict[str, Any]]) -> str:
    """The generated Markdown: one table per release, newest first (deterministic in the records)."""
    releases = sorted({r["release"] for r in records}, key=_version_key, reverse=True)
    parts = [
        "_Generated by `python benchmarks/make_tables.py docs/BENCHMARKS.md` from the records in "
        "`docs/benchmarks/*.json`; do not edit by hand. Load: the 1-minute load average before → after the run "
        "(2 cores: above 2 the benchmark shared its core). A release's table also holds records of the "
        "development commits after it (commit column)._"
    ]
    for rel in releases:
        rows = sorted(
            (r for r in records if r["release"] == rel), key=lambda r: (r["benchmark"], r["date"], r["_file"])
        )
        parts.append(f"### Release {rel}")
        lines = [
            "| benchmark | measured | result | machine | load | date | commit |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in rows:
            common = (
                f"{_machine_cell(r['machine'])} | {_load_cell(r['load'])} | {r['date'][:10]} | "
                f"{r.get('commit') or '-'} |"
            )
            for res in r["results"]:
                what = res["name"] + (f"; {res['note']}" if res.get("note") else "")
                lines.append(f"| `{r['benchmark']}` | {what} | {_range(res['values'])} {res['unit']} | {common}")
        parts.append("\n".join(lines))
        cmds = sorted({f"`{r['command']}`" + (f" ({r['source']})" if r.get("source") else "") for r in rows})
        parts.append("Commands: " + "; ".join(cmds) + ".")
    return "\n\n".join(parts)


def update(text: str, records: Sequence[dict[str, Any]]) -> str:
    """``text`` with its generated block replaced by :func:`render` of ``records``."""
    if len(_BLOCK.findall(text)) != 1:
        raise RecordError(f"the Markdown file must hold exactly one block {BEGIN} ... {END}")
    body = render(records)
    return _BLOCK.sub(lambda _m: f"{BEGIN}\n{body}\n{END}", text)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("markdown", help="the Markdown file holding the generated block (docs/BENCHMARKS.md)")
    ap.add_argument("--records", help="folder of JSON records (default: benchmarks/ beside the Markdown file)")
    ap.add_argument("--check", action="store_true", help="only check: exit 1 if the block is out of date")
    args = ap.parse_args(argv)
    path = Path(args.markdown)
    folder = Path(args.records) if args.records else path.parent / "benchmarks"
    try:
        from gear_env.io import read_limited

        old = read_limited(path, "Markdown file").decode("utf-8")
        new = update(old, read_records(folder))
    except (RecordError, ValueError, OSError) as exc:
        print(f"make_tables: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    if args.check:
        state = "up to date" if new == old else f"out of date; run python benchmarks/make_tables.py {path}"
        print(f"{path}: {state}")
        return 0 if new == old else 1
    if new != old:
        from gear_env.io import atomic_write_text

        atomic_write_text(path, new)
    print(f"{path}: {'updated' if new != old else 'up to date'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
