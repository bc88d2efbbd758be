"""mkdocs hooks of the documentation site (``mkdocs.yml``: ``hooks``).

The docs are written to read well on a repository host as plain Markdown, so they link files outside
``docs/`` (``../examples/basins.py``, ``../../CHANGELOG.md``). The site has no such pages; these hooks

* add ``changelog.md``, generated from the repository's ``CHANGELOG.md`` (its ``docs/...`` links made
  relative to the site);
* rewrite every link to a file outside ``docs/`` into that file's repository path in code font (the
  changelog's and the README's into their site pages), and fail the build if the file does not exist, so a
  broken link to an example or a script fails ``mkdocs build --strict`` as a broken page link does.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"(?<!!)\[([^\]\n]*)\]\(([^)\s]+)\)")
SITE_PAGES = {"CHANGELOG.md": "changelog.md", "README.md": "index.md"}


def on_files(files, config):
    """Add the changelog page, generated from CHANGELOG.md."""
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/", "](", text)
    files.append(File.generated(config, "changelog.md", content=text))
    return files


def _rewrite(page_src: str, text: str) -> str:
    """Links of the page ``page_src`` (path under docs/) that leave docs/: code text or a site page."""
    page_dir = posixpath.dirname(page_src)
    out = []
    pos = 0
    for m in LINK.finditer(text):
        label, target = m.group(1), m.group(2)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue
        path, _, anchor = target.partition("#")
        rel = posixpath.normpath(posixpath.join("docs", page_dir, path))
        if rel.startswith("docs/") or rel == "docs":
            continue  # a page of the site: mkdocs validates it
        if rel.startswith("../") or not (ROOT / rel).exists():
            raise PluginError(f"docs/{page_src}: the link {target!r} points at {rel!r}, which does not exist")
        out.append(text[pos : m.start()])
        if rel in SITE_PAGES:
            site = posixpath.relpath(SITE_PAGES[rel], page_dir or ".")
            out.append(f"[{label}]({site}{'#' + anchor if anchor else ''})")
        elif label.strip("`") in (rel, posixpath.basename(rel), ""):
            out.append(f"`{rel}`")
        else:
            out.append(f"{label} (`{rel}`)")
        pos = m.end()
    out.append(text[pos:])
    return "".join(out)


def on_page_markdown(markdown, page, config, files):
    """Rewrite the links that leave docs/ (see the module docstring)."""
    if page.file.src_uri == "changelog.md":
        return _rewrite_changelog(markdown)
    return _rewrite(page.file.src_uri, markdown)


def _rewrite_changelog(text: str) -> str:
    """The changelog's links are relative to the repository root; those into docs/ were made relative above."""

    def sub(m: re.Match) -> str:
        label, target = m.group(1), m.group(2)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            return m.group(0)
        path = target.partition("#")[0]
        if (ROOT / "docs" / path).exists():
            return m.group(0)
        if (ROOT / path).exists():
            return f"{label} (`{path}`)"
        raise PluginError(f"CHANGELOG.md: the link {target!r} does not exist")

    return LINK.sub(sub, text)
