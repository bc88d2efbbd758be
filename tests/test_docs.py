"""The docs name only things that exist: every ``gear_env.x.y`` / ``agents.x.y`` import path and every
repository file path in backticks resolves, and the site's nav lists every page (``mkdocs build --strict``
itself runs in CI: .ci/run)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", ROOT / "CHANGELOG.md", *(ROOT / "docs").rglob("*.md")])
DOTTED = re.compile(r"(?<![\w./-])((?:gear_env|agents)(?:\.[A-Za-z_]\w*)+)")
FILE = re.compile(r"(?<![\w./-])((?:gear_env|agents|examples|benchmarks|tests|docs)/[\w./*{},<>-]*[\w*}>])")
CODE = re.compile(r"`([^`\n]+)`")


def dotted_names(text: str) -> set[str]:
    """``gear_env.a.b`` / ``agents.a.b`` names inside inline code or code blocks of Markdown ``text``."""
    spans = CODE.findall(text) + re.findall(r"^```\w*\n(.*?)^```", text, re.S | re.M)
    return {m.rstrip(".") for span in spans for m in DOTTED.findall(span)}


def resolves(name: str) -> bool:
    """True if ``name`` is a module, or an attribute chain on the longest importable module prefix."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def _as_glob(name: str) -> str:
    """A documented path as a glob: ``{a,b}`` and ``<placeholder>`` match anything."""
    return re.sub(r"\{[^}]*\}|<[^>]*>", "*", name)


def test_the_checkers_find_and_judge_names():
    text = (
        "use `gear_env.envs.env_config.task_config(ID)` and\n```python\nimport agents.registry\n```\n`gear_env/io.py`"
    )
    assert dotted_names(text) == {"gear_env.envs.env_config.task_config", "agents.registry"}
    assert resolves("gear_env.envs.env_config.task_config") and resolves("agents.registry.resolve_policy")
    assert not resolves("gear_env.envs.tasks.task_config")  # issue #26: ENVIRONMENT.md named it
    assert not resolves("gear_env.nope")
    assert any(ROOT.glob(_as_glob("gear_env/data/stability_{constant,dynamic}.json")))
    assert not any(ROOT.glob(_as_glob("gear_env/data/nope_{a,b}.json")))


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_import_path_the_docs_name_exists(page):
    text = page.read_text(encoding="utf-8")
    missing = sorted(n for n in dotted_names(text) if not resolves(n))
    assert not missing, f"{page.relative_to(ROOT)} names import paths that do not exist: {missing}"


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_repository_file_the_docs_name_exists(page):
    text = page.read_text(encoding="utf-8")
    names = {m for span in CODE.findall(text) for m in FILE.findall(span)}
    missing = sorted(n for n in names if not any(ROOT.glob(_as_glob(n))))
    assert not missing, f"{page.relative_to(ROOT)} names files that do not exist: {missing}"


def test_the_site_nav_lists_every_page():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    listed = set(re.findall(r":\s*([\w/.-]+\.md)\s*$", nav, re.M))
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert pages <= listed, f"pages missing from mkdocs.yml's nav: {sorted(pages - listed)}"
    assert listed - {"changelog.md"} <= pages, f"nav entries without a page: {sorted(listed - pages)}"
