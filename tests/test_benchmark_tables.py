"""docs/BENCHMARKS.md's tables are generated from the benchmark scripts' JSON records (issue #26, item 2):
``python benchmarks/make_tables.py docs/BENCHMARKS.md`` regenerates them from docs/benchmarks/*.json, the
output depends only on the records, a malformed record is refused with a one-line error naming the file and
the field, and a record written by a benchmark script (benchmarks/bench_record.py) is one the generator reads."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "BENCHMARKS.md"
RECORDS = ROOT / "docs" / "benchmarks"

sys.path.insert(0, str(ROOT / "benchmarks"))
try:
    import bench_record as BR
    import make_tables as MT
finally:
    sys.path.pop(0)


def test_benchmarks_page_is_up_to_date_with_the_records():
    text = DOC.read_text(encoding="utf-8")
    assert text.count(MT.BEGIN) == 1 and text.count(MT.END) == 1
    assert MT.update(text, MT.read_records(RECORDS)) == text, "run: python benchmarks/make_tables.py docs/BENCHMARKS.md"
    # one table per release, newest first, each with the machine and load columns
    releases = sorted({r["release"] for r in MT.read_records(RECORDS)}, key=MT._version_key, reverse=True)
    heads = [line[len("### Release ") :] for line in text.splitlines() if line.startswith("### Release ")]
    assert heads == releases and len(releases) >= 2
    assert text.count("| benchmark | measured | result | machine | load | date | commit |") == len(releases)


def test_generator_is_deterministic_and_follows_the_records(tmp_path):
    records = MT.read_records(RECORDS)
    once = MT.render(records)
    assert MT.render(list(reversed(records))) == once == MT.render(MT.read_records(RECORDS))
    # a record in another folder under another name order gives the same text
    for i, p in enumerate(sorted(RECORDS.glob("*.json"), reverse=True)):
        shutil.copy(p, tmp_path / f"{i:02d}-{p.name}")
    assert MT.render(MT.read_records(tmp_path)) == once
    # and a changed value changes it
    first = sorted(tmp_path.glob("*.json"))[0]
    data = json.loads(first.read_text())
    data["results"][0]["values"] = [123456.0]
    first.write_text(json.dumps(data))
    changed = MT.render(MT.read_records(tmp_path))
    assert changed != once and "123,456" in changed


def test_check_mode_reports_and_does_not_write(tmp_path, capsys):
    doc = tmp_path / "B.md"
    doc.write_text(f"# B\n\n{MT.BEGIN}\nold\n{MT.END}\n", encoding="utf-8")
    args = [str(doc), "--records", str(RECORDS)]
    assert MT.main([*args, "--check"]) == 1 and "old" in doc.read_text()
    assert "out of date" in capsys.readouterr().out
    assert MT.main(args) == 0 and "### Release" in doc.read_text()
    assert MT.main([*args, "--check"]) == 0


def _good() -> dict:
    return json.loads(sorted(RECORDS.glob("*.json"))[0].read_text(encoding="utf-8"))


BAD = [
    (lambda d: d.pop("machine"), "'machine'"),
    (lambda d: d.update(release="latest"), "'release'"),
    (lambda d: d.update(date="yesterday"), "'date'"),
    (lambda d: d["results"][0].update(values=[]), "results[0]: field 'values'"),
    (lambda d: d["results"][0].update(values=["1"]), "results[0]: field 'values'"),
    (lambda d: d.update(results=[]), "'results'"),
    (lambda d: d["machine"].update(cores=0), "'machine.cores'"),
    (lambda d: d.update(load={"before": [1.0], "after": None}), "'load.before'"),
    (lambda d: d.update(load={"before": None, "after": None}), "'load'"),
    (lambda d: d["results"][1].update(name="a | b"), "results[1]: field 'name'"),
    (lambda d: d.update(schema="other/2"), "'schema'"),
]


@pytest.mark.parametrize("spoil,field", BAD, ids=[b[1] for b in BAD])
def test_malformed_record_is_refused_in_one_line(spoil, field, tmp_path, capsys):
    d = _good()
    spoil(d)
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "bad.json").write_text(json.dumps(d), encoding="utf-8")
    doc = tmp_path / "B.md"
    doc.write_text(f"{MT.BEGIN}\nold\n{MT.END}\n", encoding="utf-8")
    assert MT.main([str(doc), "--records", str(tmp_path / "rec")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("make_tables: ") and "bad.json" in err and field in err
    assert doc.read_text() == f"{MT.BEGIN}\nold\n{MT.END}\n"  # nothing written


@pytest.mark.parametrize(
    "text,why",
    [
        ('{"schema": "gear-env-benchmark/1", "results": [NaN]', "not valid JSON"),
        ("[" * 100 + "]" * 100, "nested deeper"),
        ('{"results": [{"values": [NaN]}]}', "'schema'"),
    ],
)
def test_unparseable_or_hostile_json_is_refused(text, why, tmp_path):
    (tmp_path / "x.json").write_text(text, encoding="utf-8")
    with pytest.raises(MT.RecordError, match=why):
        MT.read_records(tmp_path)


def test_non_finite_values_are_refused(tmp_path):
    d = _good()
    (tmp_path / "nan.json").write_text(json.dumps(d).replace('"values": [', '"values": [NaN, ', 1), encoding="utf-8")
    with pytest.raises(MT.RecordError, match=r"nan.json: results\[0\]: field 'values'"):
        MT.read_records(tmp_path)


def test_a_script_record_is_read_by_the_generator(tmp_path):
    rec = BR.Record("bench_tasks", ["--seconds", "1", "--json", "x.json"])
    rec.add("GearSpeed-v1, single env (48 periods/step)", "steps/s", [1780.4, 1795.0])
    rec.add("ratio", "x", [2.19])
    with pytest.raises(ValueError, match="finite"):
        rec.add("bad", "x", [float("nan")])
    (tmp_path / "rec").mkdir()
    path = tmp_path / "rec" / "r.json"
    rec.write(path)
    (got,) = MT.read_records(tmp_path / "rec")
    assert got["command"] == "python benchmarks/bench_tasks.py --seconds 1"  # --json FILE dropped
    assert got["release"] == __import__("gear_env").__version__ and got["machine"]["cores"] >= 1
    assert got["load"]["before"] is None or len(got["load"]["before"]) == 3
    table = MT.render([got])
    assert "| 1,780-1,795 steps/s |" in table and "| 2.19 x |" in table
    with pytest.raises(SystemExit, match="directory"):
        BR.check_json_target(str(tmp_path))  # a folder is not a record file


def test_number_format():
    assert [MT.fmt(v) for v in (123456.0, 17.0, 2.19, 0.45, 6.6e-4, 0.0)] == [
        "123,456",
        "17.0",
        "2.19",
        "0.450",
        "6.6e-04",
        "0.00",
    ]
