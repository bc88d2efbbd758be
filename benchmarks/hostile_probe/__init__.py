"""The second hostile probe of issue 25 as a rerunnable tool: 271 cases, each a real subprocess in its own folder.

    python -m benchmarks.hostile_probe                      # every case, a table, exit 1 if any did not hold
    python -m benchmarks.hostile_probe --select "A alias"   # the cases whose group or name contains a text
    python -m benchmarks.hostile_probe --list               # the case names
    python -m benchmarks.hostile_probe --out DIR --table T.md --jsonl R.jsonl

Run it from the repository root (``benchmarks`` is a folder of scripts, not an installed package). The
package under test is the one ``import gear_env`` finds in the current environment; nothing sets
``PYTHONPATH``. Each case builds its hostile input in a fresh sub-folder of the working folder (a
temporary folder, deleted at the end, unless ``--out`` keeps it), runs ``gear-env`` (the console script
beside this interpreter), ``python -m gear_env.evaluation``, ``benchmarks/demand_protocol.py`` or a
``python -c`` snippet as a subprocess, and records its exit code, the first error line of stderr, whether
a traceback appeared and its peak RSS (``wait4``). A case *holds* when the outcome is the expected one
(mostly: exit 2, one error line, no traceback, the named file or field; inputs and outside files
untouched; no pickle/YAML payload ran, which would create a marker in the working folder).

The cases are written from the issue's text, independently of ``benchmarks/crafted_cases.py`` (CI's
slow stage); ``tests/test_hostile_probe.py`` checks the case list only (no subprocess). The full run
takes about 20-30 min (the cases about 16 min, plus a numba compile and two small base runs).
"""
