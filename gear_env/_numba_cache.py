"""Where numba keeps the compiled kernels of gear-env.

numba's on-disk cache is keyed on each function's own source file, not on the files it calls or
the module constants it bakes in: a cached function in ``env_kernels.py`` would keep old code
after ``kernels/mesh.py`` changed. This module points numba's cache at a folder named after a hash of
every file that holds compiled code, so a changed package never meets a stale cache, and so the
cache works when the package folder is read-only:

* ``$NUMBA_CACHE_DIR`` set: ``$NUMBA_CACHE_DIR/gear-env-<hash>``;
* otherwise ``$GEAR_ENV_CACHE/numba-<hash>`` (default ``~/.cache/gear-env``), falling back to
  numba's own choice (``__pycache__`` beside the sources) if that folder cannot be created.

Several processes compiling into the same folder at once is safe: numba writes each cache file
to a temporary name and renames it (tested in tests/test_reliability.py).
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

# files (glob patterns) whose njit code is cached (their constants and callees included)
_SOURCES = (
    "sim/params.py",
    "sim/kernels/*.py",  # every module of the kernels package
    "sim/batch_kernels.py",
    "envs/env_kernels.py",
    "envs/env_terms.py",
    "analysis/lyapunov_kernel.py",
    "analysis/testsystems.py",
)


def source_hash() -> str:
    """Short SHA-256 of the package files that hold compiled code."""
    h = hashlib.sha256()
    here = Path(__file__).parent
    for pattern in _SOURCES:
        for p in sorted(here.glob(pattern)):
            h.update(p.relative_to(here).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def configure() -> str | None:
    """Point numba's cache at a folder versioned by :func:`source_hash`; return it (or None)."""
    from numba.core import config

    tag = source_hash()
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        target = Path(user) / f"gear-env-{tag}"
    else:
        base = Path(os.environ.get("GEAR_ENV_CACHE", Path.home() / ".cache" / "gear-env"))
        target = base / f"numba-{tag}"
    try:
        target.mkdir(parents=True, exist_ok=True)
        if not os.access(target, os.W_OK):
            return None
    except OSError:
        return None
    config.CACHE_DIR = str(target)  # type: ignore[attr-defined]  # numba sets its config attributes at runtime
    return str(target)


CACHE_DIR = configure()


_CHECKED: set[str] = set()


def cache_has(stem: str, cache_dir: str | None = None) -> bool:
    """True when the numba cache folder holds compiled code of the module file ``stem`` (e.g.
    ``"env_kernels"``; numba names its index files ``<stem>.<function>-<line>.py3XX.nbi``)."""
    folder = CACHE_DIR if cache_dir is None else cache_dir
    if folder is None:
        return False
    return next(Path(folder).rglob(f"{stem}.*.nbi"), None) is not None


def announce_compile(stem: str, what: str, duration: str, cache_dir: str | None = None) -> bool:
    """Say once per process, on stderr, that ``what`` is about to be compiled when the cache has none
    of ``stem``'s code (first use of this version of the package on this machine). Returns whether it
    spoke. ``GEAR_ENV_QUIET=1`` silences it."""
    if stem in _CHECKED:
        return False
    _CHECKED.add(stem)
    if os.environ.get("GEAR_ENV_QUIET") == "1" or cache_has(stem, cache_dir):
        return False
    print(
        f"gear-env: compiling {what} with numba (first use of this version on this machine: about {duration}; "
        "cached on disk afterwards; `gear-env compile` does it ahead of time)",
        file=sys.stderr,
        flush=True,
    )
    return True
