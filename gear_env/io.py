"""Atomic file writing: a result is either the old file or the complete new one, never partial."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def _check_dir(path: Path) -> None:
    d = path.parent if str(path.parent) else Path(".")
    if not d.exists():
        raise OSError(f"output folder {str(d)!r} does not exist")
    if not os.access(d, os.W_OK):
        raise PermissionError(f"output folder {str(d)!r} is not writable")


def atomic_write(path: str | os.PathLike, writer: Callable[[str], None]) -> None:
    """Call ``writer(tmp_path)`` on a temporary file beside ``path``, then rename it into place.

    The rename is atomic on POSIX file systems, so a crash or a full disk leaves any previous
    ``path`` intact. Errors are re-raised with the target path in the message.
    """
    target = Path(path)
    _check_dir(target)
    try:  # a read-only mount (EROFS, even for root) or a full inode table fails here
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or ".")
    except OSError as exc:
        raise OSError(f"could not write {str(target)!r}: {exc}") from exc
    os.close(fd)
    try:
        os.chmod(tmp, _file_mode(target))
        writer(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except OSError as exc:
        _unlink(tmp)
        raise OSError(f"could not write {str(target)!r}: {exc}") from exc
    except BaseException:
        _unlink(tmp)
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""

    def _w(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write(path, _w)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""

    def _w(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    atomic_write(path, _w)


def _file_mode(target: Path) -> int:
    """Mode of a new file as open() would give it (0o666 less the umask), or the old file's mode."""
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def _unlink(p: str) -> None:
    try:
        os.unlink(p)
    except OSError:
        pass
