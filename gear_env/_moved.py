"""Old module paths of gear-env <= 0.4 (flat ``gear_env/*.py``) as aliases of their new homes.

Release 0.5 grouped the flat modules into the layer packages :mod:`gear_env.sim`,
:mod:`gear_env.envs` and :mod:`gear_env.evaluation` (docs/ARCHITECTURE.md). ``import
gear_env.simulator`` (or ``from gear_env import env_terms``) still works: it returns the module at its
new path, the very same module object (so a ``monkeypatch`` of either name patches both), with a
``DeprecationWarning`` that names the new path. The aliases will be removed in a later release.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import os
import sys
import warnings
from types import FrameType

MOVED: dict[str, str] = {
    **{
        f"gear_env.{m}": f"gear_env.sim.{m}"
        for m in ("params", "geometry", "simulator", "integration", "batch_kernels", "linear", "reference", "kernels")
    },
    **{
        f"gear_env.{m}": f"gear_env.envs.{m}"
        for m in (
            "env_config",
            "env_terms",
            "env_kernels",
            "env_core",
            "env",
            "vector_env",
            "sb3_adapter",
            "tasks",
            "schedules",
            "warmup",
            "steady_map",
            "bands",
            "render",
        )
    },
    **{f"gear_env.{m}": f"gear_env.evaluation.{m}" for m in ("episodes", "report")},
}
"""Old module name -> new module name (sub-modules of a moved package follow it)."""


def new_name(old: str) -> str | None:
    """The new dotted name of an old module path, or None if ``old`` did not move."""
    parts = old.split(".")
    for k in range(len(parts), 1, -1):
        head = ".".join(parts[:k])
        if head in MOVED:
            return ".".join([MOVED[head], *parts[k:]])
    return None


class _AliasLoader(importlib.abc.Loader):
    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec):  # noqa: D102 - importlib protocol
        module = importlib.import_module(self.target)
        self._spec = module.__spec__  # importlib overwrites it with the alias spec before exec_module
        return module

    def exec_module(self, module) -> None:  # noqa: D102 - importlib protocol
        module.__spec__ = self._spec  # importlib set the alias spec; the module keeps its own


_STDLIB_IMPORTERS = (
    os.path.dirname(importlib.__file__) + os.sep,  # importlib.import_module, importlib.util.find_spec
    os.path.join(os.path.dirname(os.__file__), "pkgutil.py"),  # pkgutil.resolve_name (unittest.mock.patch)
    os.path.join(os.path.dirname(os.__file__), "unittest", "mock.py"),
)


def _importer_stacklevel() -> int:
    """The ``stacklevel`` (for ``warnings.warn`` in the finder) of the code that imported the old path.

    CPython's ``warnings`` skips its own import machinery when it counts levels (a frame whose file
    name contains both "importlib" and "_bootstrap"), so those frames are not counted here either;
    the standard library's importers above them (``importlib.import_module``, ``pkgutil.resolve_name``
    as ``unittest.mock.patch`` uses it) are counted and stepped over. The warning is then attributed
    to the user's line, and Python's default filters show it when that module is ``__main__``."""
    f: FrameType | None = sys._getframe(2)  # the finder's caller
    level = 1
    while f is not None:
        name = f.f_code.co_filename
        if not ("importlib" in name and "_bootstrap" in name):  # warnings' own test of an internal frame
            level += 1
            if not name.startswith(("<frozen importlib", *_STDLIB_IMPORTERS)):
                break
        f = f.f_back
    return level


class _AliasFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):  # noqa: D102 - importlib protocol
        new = new_name(fullname) if fullname.startswith("gear_env.") else None
        if new is None:
            return None
        warnings.warn(
            f"{fullname} moved to {new} in gear-env 0.5; import it from there (the old path is an alias "
            "and will be removed)",
            DeprecationWarning,
            stacklevel=_importer_stacklevel(),
        )
        return importlib.machinery.ModuleSpec(fullname, _AliasLoader(new))


def install() -> None:
    """Put the alias finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _AliasFinder())  # before the path finder: a moved package's sub-modules too
