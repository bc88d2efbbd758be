"""Imports flow one way (docs/ARCHITECTURE.md): the import graph of ``gear_env`` and ``agents``,
read from the source with :mod:`ast`, has no cycle, the library never reaches up into ``agents``,
and the plotting modules take data without calling the simulator, the analysis or the environment.

Every ``import`` counts, also those inside functions (a lazy import still runs, only later);
imports under ``if TYPE_CHECKING:`` do not (they never run). Importing ``a.b.c`` also runs the
``__init__`` of the package ``a.b``, so that package is an edge too (unless the importer sits
inside it). Dynamic imports (``importlib.import_module``, Gymnasium's ``entry_point`` strings) are
not seen; the only ones are the sub-command loader of ``gear_env/cli`` and the environment
registration in ``gear_env/__init__.py``, both of which point downwards.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("gear_env", "agents")

PLOTS_MAY_IMPORT = ("gear_env.plots", "gear_env.io", "gear_env.sim.kernels")
"""What ``gear_env/plots`` may import inside the package: itself, the atomic writer and the column
layout constants of the recorded arrays (``kernels.PC_*``). Nothing that computes: no simulator,
analysis, environment or evaluation module; callers hand the plots their results."""


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST):
    """(node, names) of every import statement, skipping ``if TYPE_CHECKING:`` bodies."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def import_graph(root: Path = ROOT, packages: tuple[str, ...] = PACKAGES) -> dict[str, set[str]]:
    """module -> the modules of ``packages`` it imports (anywhere in its code)."""
    files = {_module_name(p, root): p for pkg in packages for p in sorted((root / pkg).rglob("*.py"))}
    is_package = {m: files[m].name == "__init__.py" for m in files}
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        here = mod if is_package[mod] else mod.rpartition(".")[0]
        targets: set[str] = set()
        for node in _imports(tree):
            if isinstance(node, ast.Import):
                found = [a.name for a in node.names]
            else:
                if node.level:
                    base_parts = here.split(".")
                    base_parts = base_parts[: len(base_parts) - (node.level - 1)]
                    base = ".".join(base_parts + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                found = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            for name in found:
                while name and name not in files:  # ``import a.b.func``-like tails, outside modules
                    name = name.rpartition(".")[0]
                if not name:
                    continue
                # the target and every package on its way whose __init__ runs for it
                parts = name.split(".")
                for k in range(1, len(parts) + 1):
                    t = ".".join(parts[:k])
                    if t != mod and not (mod + ".").startswith(t + ".") and t in files:
                        targets.add(t)
        graph[mod] = targets
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (or a self-import), each
    given as one closed path through it (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on: set[str] = set()
    stack: list[str] = []
    comps: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1 or v in graph[v]:
                        comps.append(_closed_path(graph, set(comp)))
    return comps


def _closed_path(graph: dict[str, set[str]], comp: set[str]) -> list[str]:
    """A shortest cycle through the smallest module of a strongly connected component (BFS)."""
    start = min(comp)
    prev: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & comp):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(prev[path[-1]])
                    return path[::-1] + [start]
                if w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    return sorted(comp)  # pragma: no cover - a component always has a cycle


@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_graph_reader_sees_lazy_relative_and_package_imports(tmp_path):
    """The reader itself: a lazy relative import closes a cycle, a package's __init__ counts,
    TYPE_CHECKING imports do not (so a checker that cannot fail would fail here)."""
    pkg = tmp_path / "p"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .c import X\n")
    (pkg / "a.py").write_text("def f():\n    from .b import g\n    return g\n")
    (pkg / "b.py").write_text("import p.sub.c\n")
    lazy = "def h():\n    from .. import a\n"
    (pkg / "sub" / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..b import g\n" + lazy
    )
    (pkg / "d.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import f\n")
    g = import_graph(tmp_path, ("p",))
    assert g["p.a"] == {"p.b"}
    assert g["p.b"] == {"p.sub", "p.sub.c"}
    assert g["p.sub.c"] == {"p.a"}
    assert g["p.d"] == set()
    cycles = find_cycles(g)
    assert cycles == [["p.a", "p.b", "p.sub.c", "p.a"]]


def test_no_import_cycles(graph):
    assert len(graph) > 40, "the graph reader found too few modules"
    cycles = find_cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_library_never_imports_agents(graph):
    bad = sorted(
        f"{m} -> {t}"
        for m, ts in graph.items()
        if m.startswith("gear_env") and not (m + ".").startswith("gear_env.cli.")
        for t in ts
        if t.split(".")[0] == "agents"
    )
    assert not bad, "gear_env (outside gear_env.cli) imports agents:\n" + "\n".join(bad)


def test_plots_take_data(graph):
    plots = [m for m in graph if (m + ".").startswith("gear_env.plots.")]
    assert "gear_env.plots.env" in plots
    bad = sorted(
        f"{m} -> {t}"
        for m in plots
        for t in graph[m]
        # gear_env.sim: the package's __init__ runs on the way to sim.kernels (it imports nothing)
        if t != "gear_env.sim" and not any(t == a or t.startswith(a + ".") for a in PLOTS_MAY_IMPORT)
    )
    assert not bad, "plots import modules that compute (pass them the results instead):\n" + "\n".join(bad)


def test_evaluation_keeps_its_public_names_and_command(capsys, monkeypatch):
    """The split of ``gear_env.evaluation`` by concern kept every name it exported, and
    ``python -m gear_env.evaluation`` is the command-line layer's steady-map command."""
    import runpy

    import gear_env.evaluation as ev
    from gear_env.cli import steady
    from gear_env.envs import bands, steady_map
    from gear_env.evaluation import episodes, report

    old = {"INFO_KEYS", "EpisodeResult", "EvaluationReport", "RegimeBands", "SteadyRewardMap", "METRICS"}
    old |= {"evaluate_policies", "regime_bands", "run_episode", "steady_reward_map"}
    assert old <= set(dir(ev)) and set(ev.__all__) <= old
    assert ev.steady_reward_map is steady_map.steady_reward_map and ev.regime_bands is bands.regime_bands
    assert ev.evaluate_policies is episodes.evaluate_policies and ev.EvaluationReport is report.EvaluationReport
    monkeypatch.setattr("sys.argv", ["python -m gear_env.evaluation", "--help"])
    with pytest.raises(SystemExit) as exc:
        runpy.run_module("gear_env.evaluation", run_name="__main__")
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "python -m gear_env.evaluation" in out and "--steps-per-period" in out
    assert steady.build_parser().parse_args(["--models", "constant"]).models == "constant"


LAYERS = {
    "util": 0,  # gear_env/*.py: errors, io, untrusted, _numba_cache, _extras, _moved
    "sim": 1,
    "plots": 1.5,  # results in, figures out: only io and the column constants of sim.kernels
    "analysis": 2,
    "envs": 3,
    "evaluation": 4,
    "agents": 5,
    "cli": 6,
}
"""The layer folders in import order (docs/ARCHITECTURE.md): a module imports only from its own layer
or from layers below it. The root ``gear_env/__init__.py`` (the public face: it re-exports the
simulator and registers the environments) and ``__main__`` modules (entry points) sit outside."""


def layer_of(mod: str) -> str | None:
    """The layer folder of a module name (None for the root package and ``__main__`` modules)."""
    parts = mod.split(".")
    if parts[0] == "agents":
        return "agents"
    if len(parts) == 1 or parts[-1] == "__main__":
        return None
    return parts[1] if parts[1] in LAYERS else "util"


def layer_violations(graph: dict[str, set[str]]) -> tuple[list[str], list[str]]:
    """(imports reaching up a layer, imports of the root package from inside the library) of ``graph``."""
    up, root = [], []
    for m, ts in graph.items():
        lm = layer_of(m)
        if lm is None:
            continue
        for t in ts:
            lt = layer_of(t)
            if lt is None and t == "gear_env" and lm not in ("cli", "agents"):
                root.append(f"{m} -> gear_env")
            elif lt is not None and LAYERS[lt] > LAYERS[lm]:
                up.append(f"{m} ({lm}) -> {t} ({lt})")
    return sorted(up), sorted(root)


def test_layer_folders_import_only_downwards(graph):
    """The folders show the architecture: every import goes to the importer's layer or below, and
    only the command line, the agents and entry points import the root package (which loads
    everything)."""
    assert {layer_of(m) for m in graph} >= set(LAYERS), "a layer folder is missing or empty"
    up, root = layer_violations(graph)
    assert not up, "imports reaching up a layer:\n" + "\n".join(up)
    assert not root, "the root package imported from inside the library:\n" + "\n".join(root)


def test_the_layer_check_can_fail():
    """The checker itself: an upward import and a root import from inside are caught, a downward one is not."""
    g = {
        "gear_env.sim.kernels": {"gear_env.envs.env_terms"},
        "gear_env.envs.env": {"gear_env.sim.params"},
        "gear_env.analysis.sweep": {"gear_env"},
    }
    assert layer_violations(g) == (
        ["gear_env.sim.kernels (sim) -> gear_env.envs.env_terms (envs)"],
        ["gear_env.analysis.sweep -> gear_env"],
    )


def test_old_module_paths_are_deprecated_aliases_of_the_new_ones():
    """``gear_env.simulator`` and the other paths of 0.4 still import, as the same module objects,
    with a DeprecationWarning naming the new path; the flat folder holds no such file any more."""
    import importlib
    import sys

    from gear_env import _moved

    for old, new in _moved.MOVED.items():
        assert not (ROOT / (old.replace(".", "/") + ".py")).exists(), old
        sys.modules.pop(old, None)
        with pytest.warns(DeprecationWarning, match=new.replace(".", r"\.")):
            mod = importlib.import_module(old)
        assert mod is importlib.import_module(new) and mod.__name__ == new and mod.__spec__.name == new
        sys.modules.pop(old, None)
    sys.modules.pop("gear_env.kernels.mesh", None)
    with pytest.warns(DeprecationWarning, match=r"gear_env\.sim\.kernels\.mesh"):
        mesh = importlib.import_module("gear_env.kernels.mesh")
    assert mesh is importlib.import_module("gear_env.sim.kernels.mesh")
    for k in [k for k in sys.modules if k == "gear_env.kernels" or k.startswith("gear_env.kernels.")]:
        sys.modules.pop(k)
    assert _moved.new_name("gear_env.io") is None and _moved.new_name("gear_env.analysis.sweep") is None


def test_the_deprecation_names_the_users_line_so_a_plain_script_shows_it(tmp_path):
    """Python shows a DeprecationWarning by default only when it is attributed to ``__main__``: the alias
    warning must point at the user's line for every way of importing (a plain ``import`` inside a function,
    ``from ... import``, ``importlib.import_module``, ``pkgutil.resolve_name``, ``unittest.mock.patch`` and
    ``importlib.util.find_spec``), not into the standard library, or scripts never see it. Run with the
    import machinery frozen (the default) and not frozen (its frames then have real file names)."""
    import subprocess
    import sys

    script = tmp_path / "old_paths.py"
    script.write_text(
        "import importlib, importlib.util, pkgutil\n"
        "from unittest import mock\n"
        "def f():\n"
        "    import gear_env.simulator\n"
        "f()\n"
        "from gear_env import env_terms\n"
        "importlib.import_module('gear_env.episodes')\n"
        "pkgutil.resolve_name('gear_env.tasks')\n"
        "with mock.patch('gear_env.report.__doc__', 'x'):\n"
        "    pass\n"
        "importlib.util.find_spec('gear_env.bands')\n"
    )
    expected = {4: "sim.simulator", 6: "envs.env_terms", 7: "evaluation.episodes", 8: "envs.tasks",
                9: "evaluation.report", 11: "envs.bands"}  # fmt: skip
    for frozen in ("on", "off"):
        run = subprocess.run(
            [sys.executable, "-X", f"frozen_modules={frozen}", str(script)],
            capture_output=True, text=True, timeout=300, cwd=tmp_path,
        )  # fmt: skip
        assert run.returncode == 0, run.stderr
        for line, new in expected.items():
            assert f"{script}:{line}: DeprecationWarning: " in run.stderr, (frozen, line, run.stderr)
            assert f"moved to gear_env.{new} " in run.stderr, (frozen, new, run.stderr)


def test_sb3_adapter_is_not_reexported_from_vector_env():
    """The lazy re-export closed a cycle; the old import now says where the class lives."""
    import gear_env.envs.vector_env as ve

    with pytest.raises(ImportError, match="gear_env.envs.sb3_adapter"):
        ve.SB3VecEnvAdapter  # noqa: B018
    with pytest.raises(AttributeError):
        ve.no_such_name  # noqa: B018
