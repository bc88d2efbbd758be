"""One version: ``gear_env.__version__`` is what pyproject.toml builds and the newest release of CHANGELOG.md."""

from __future__ import annotations

import re
from pathlib import Path

import tomllib

import gear_env

ROOT = Path(__file__).resolve().parents[1]
RELEASE = re.compile(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$", re.M)


def test_version_is_pep440_release():
    assert re.fullmatch(r"\d+\.\d+\.\d+", gear_env.__version__)


def test_pyproject_reads_the_version_from_the_package():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert "version" not in meta["project"], "a literal version in pyproject.toml would be a second source"
    assert "version" in meta["project"]["dynamic"]
    assert meta["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "gear_env.__version__"}


def test_changelog_newest_release_is_the_package_version():
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    releases = RELEASE.findall(text)
    assert releases, "CHANGELOG.md has no '## [X.Y.Z] - YYYY-MM-DD' release"
    assert releases[0][0] == gear_env.__version__
    assert text.index("## [Unreleased]") < text.index(f"## [{releases[0][0]}]")
    versions = [tuple(map(int, v.split("."))) for v, _ in releases]
    assert versions == sorted(versions, reverse=True) and len(set(versions)) == len(versions)
    dates = [d for _, d in releases]
    assert dates == sorted(dates, reverse=True)


def test_changelog_links_each_environment_ids_version_history():
    from gear_env.envs.tasks import TASK_SETTINGS

    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    for env_id in TASK_SETTINGS:
        link = f"docs/tasks/{env_id}.md"
        assert f"]({link})" in text, f"CHANGELOG.md does not link {link}"
        assert (ROOT / link).is_file()
        assert "## Version history" in (ROOT / link).read_text(encoding="utf-8")
