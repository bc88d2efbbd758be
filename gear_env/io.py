"""Safe file input and output.

* Atomic writing: a result is either the old file or the complete new one, never partial, and only
  regular files are ever replaced (never a device such as ``/dev/null``, a pipe or a directory).
* :func:`check_outputs`: the command line's check, before any work, that no output is a device, a
  directory, an input or another output.
* :func:`read_json`: JSON input with its size, nesting depth and integer length bounded.
* :class:`OutputLock`: one writer per output path at a time.
"""

from __future__ import annotations

import json
import os
import stat
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any


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
    if _CONFINED:
        _check_confined(path, Path(os.path.realpath(target)))
    if target.is_symlink():  # write through a link to a regular file, keep the link
        target = Path(os.path.realpath(target))
    try:
        check_regular_target(target)
    except ValueError as exc:
        raise OSError(f"refusing to write {str(path)!r}: {exc}") from None
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
    except RuntimeError as exc:  # e.g. "NetCDF: HDF error" from a library writer on a full disk
        _unlink(tmp)
        raise OSError(f"could not write {str(target)!r}: {type(exc).__name__}: {exc}") from exc
    except BaseException:
        _unlink(tmp)
        raise


_CONFINED: list[str] = []
"""Output folders of the running command (:func:`hold_outputs`), as absolute paths: a file written inside
one of them must stay inside it after its symbolic links are resolved."""


def _check_confined(given: str | os.PathLike, resolved: Path) -> None:
    """OSError if ``given`` lies in an output folder of the running command but ``resolved`` (its link's
    target) does not: a link planted in an output folder never redirects a write outside it."""
    g = os.path.abspath(os.fspath(given))
    for folder in _CONFINED:
        if os.path.dirname(g) == folder or g.startswith(folder + os.sep):
            real = os.path.realpath(folder)
            r = os.fspath(resolved)
            if r != real and not r.startswith(real + os.sep):
                raise OSError(
                    f"refusing to write {os.fspath(given)!r}: a symbolic link leads it out of the output folder "
                    f"{folder!r} (to {r!r})"
                )


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


# --------------------------------------------------------------------------------------------------
# output and input checks (used by the command line before any work starts)
# --------------------------------------------------------------------------------------------------
def check_regular_target(path: str | os.PathLike, what: str = "output") -> None:
    """Raise ``ValueError`` unless ``path`` is absent or a regular file (after following symlinks).

    Devices (``/dev/null``, ``/dev/full``), directories, pipes and sockets are refused: an atomic
    write renames a new regular file over its target, which would replace the node itself."""
    p = os.fspath(path)
    if not p:
        raise ValueError(f"{what}: empty path")
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ValueError(f"{what} {p!r}: cannot inspect it ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{what} {p!r} is a directory; give a file name")
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(
            f"{what} {p!r} is not a regular file (a device, pipe or socket); gear-env writes only regular files"
        )


def _identity(path: str) -> tuple[Any, ...]:
    """What makes two paths the same file: (device, inode) if it exists, else the resolved path."""
    try:
        st = os.stat(path)
        return ("inode", st.st_dev, st.st_ino)
    except OSError:
        return ("path", os.path.realpath(path))


FOLDER_INPUT_FILES = (
    "config.json", "env_config.json", "metrics.json", "metrics.csv", "model.zip", "best_model.zip",
    "vecnormalize.npz", "best_vecnormalize.npz", "vecnormalize.pkl", "best_vecnormalize.pkl", "policy.json",
    "policy.pt", ".gear-env-run",
)  # fmt: skip
"""Files of a run or policy folder given as an input (``--policy RUN``) that its loaders read: an output
may not be one of them (nor any file of its ``checkpoints/``)."""


def _input_paths(value: Any) -> list[str]:
    """The existing paths among an input option's values (one, a list, or ``NAME=PATH`` policy specs)."""
    out = []
    for one in value if isinstance(value, (list, tuple)) else [value]:
        if one is None:
            continue
        s = os.fspath(one)
        for cand in (s, s.split("=", 1)[1] if "=" in s else ""):
            if cand and os.path.lexists(cand):
                out.append(cand)
                break
    return out


def check_outputs(outputs: Mapping[str, Any], inputs: Mapping[str, Any] | None = None) -> None:
    """Check the output paths of a command before it starts (``ValueError`` naming the option).

    ``outputs`` and ``inputs`` map an option name (``"--json"``) to a path or None (unused).
    Refused: an output that is not a regular file (see :func:`check_regular_target`), whose folder
    does not exist, that is also an input, or that is another output."""
    seen: dict[tuple[Any, ...], str] = {}
    for name, path in (inputs or {}).items():
        for one in _input_paths(path):
            if not os.path.isdir(one):
                seen.setdefault(_identity(one), f"the input {name} {one!r}")
                continue
            # a run or policy folder given as input (--policy RUN): the files its loaders read are inputs too
            for f in FOLDER_INPUT_FILES:
                q = os.path.join(one, f)
                if os.path.exists(q):
                    seen.setdefault(_identity(q), f"the file {f} of the input {name} {one!r}")
            ck = os.path.join(one, "checkpoints")
            if os.path.isdir(ck):
                for f in os.listdir(ck):
                    q = os.path.join(ck, f)
                    seen.setdefault(_identity(q), f"the checkpoint file {f} of the input {name} {one!r}")
    for name, path in outputs.items():
        if path is None:
            continue
        p = os.fspath(path)
        check_regular_target(p, name)
        d = os.path.dirname(os.path.abspath(p))
        if not os.path.isdir(d):
            raise ValueError(f"{name} {p!r}: output folder {d!r} does not exist")
        key = _identity(p)
        if key in seen:
            raise ValueError(f"{name} {p!r} is the same file as {seen[key]}; choose another path")
        seen[key] = f"the output {name} {p!r}"


# --------------------------------------------------------------------------------------------------
# bounded JSON input
# --------------------------------------------------------------------------------------------------
MAX_JSON_BYTES = 16 * 1024 * 1024
"""Largest JSON (or schedule) input file read, in bytes (16 MiB)."""
MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays/objects accepted in a JSON input."""
MAX_INT_DIGITS = 40
"""Longest integer literal accepted in a JSON input (digits)."""
MAX_NUMBER_CHARS = 64
"""Longest non-integer number literal accepted in a JSON input (characters)."""


def read_limited(path: str | os.PathLike, what: str, max_bytes: int = MAX_JSON_BYTES) -> bytes:
    """The bytes of a regular file of at most ``max_bytes`` (checked before reading); ``ValueError`` otherwise.

    A FIFO, directory, device or unreadable file (``/proc/self/mem``) is refused by name without
    blocking (:func:`gear_env.untrusted.read_regular`)."""
    from .untrusted import read_regular

    return read_regular(path, what, max_bytes)


def _json_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text (brackets inside strings ignored)."""
    depth = best = 0
    in_str = esc = False
    for ch in text:
        if in_str:
            if esc:
                esc = False
            elif ch == "\\":
                esc = True
            elif ch == '"':
                in_str = False
        elif ch == '"':
            in_str = True
        elif ch in "[{":
            depth += 1
            if depth > best:
                best = depth
        elif ch in "]}":
            depth -= 1
    return best


def parse_json_text(text: str, where: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """``json.loads`` with the size, nesting depth and number length bounded; ``ValueError`` naming ``where``.

    The one JSON parser of the package for anything read from a file (configs, schedules, run
    folders, policies, checkpoints' fingerprints, results files' attributes)."""
    if len(text) > MAX_JSON_BYTES:
        raise ValueError(f"{where}: {len(text):,} characters of JSON; the limit is {MAX_JSON_BYTES:,}")
    if _json_depth(text) > max_depth:
        raise ValueError(f"{where} is nested deeper than {max_depth} levels")

    def _int(s: str) -> int:
        if len(s.lstrip("-")) > MAX_INT_DIGITS:
            raise ValueError(f"{where}: an integer of {len(s)} digits (the limit is {MAX_INT_DIGITS})")
        return int(s)

    def _float(s: str) -> float:
        if len(s) > MAX_NUMBER_CHARS:
            raise ValueError(f"{where}: a number of {len(s)} characters (the limit is {MAX_NUMBER_CHARS})")
        return float(s)

    try:
        return json.loads(text, parse_int=_int, parse_float=_float)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where} is not valid JSON: {exc}") from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise ValueError(f"{where} is nested too deeply") from None


def read_json(path: str | os.PathLike, what: str, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """Read a JSON file with its size, nesting depth and integer length bounded (``ValueError``)."""
    raw = read_limited(path, what, max_bytes)
    try:
        text = raw.decode("utf-8-sig")  # -sig: tolerate a byte-order mark
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} {os.fspath(path)!r} is not UTF-8 text: {exc}") from None
    return parse_json_text(text, f"{what} {os.fspath(path)!r}")


# --------------------------------------------------------------------------------------------------
# one writer at a time
# --------------------------------------------------------------------------------------------------
class OutputLock:
    """An exclusive, non-blocking lock on an output file or folder, held for a command's life.

    Two locks are taken: ``fcntl.flock`` on ``.<name>.lock`` beside the *resolved* path (a symbolic
    link and its target share it), and, when the output exists, on the output itself (a hard link,
    or a folder reached by another path, shares its inode). A second process that asks for the same
    output, by any name, gets a ``ValueError`` at once. The locks die with their process (also on
    kill -9), so a crashed run never leaves a stale lock behind; the lock file is removed on
    :meth:`release`.
    """

    def __init__(self, path: str | os.PathLike, what: str = "output"):
        p = Path(os.path.realpath(os.path.abspath(os.fspath(path))))
        self.given = os.fspath(path)
        self.target = p
        self.path = p.with_name(f".{p.name}.lock")
        self.what = what
        self._fd: int | None = None
        self._node_fd: int | None = None

    def _busy(self, holder: str) -> ValueError:
        return ValueError(
            f"{self.what} {self.given!r} is being written by another process (pid {holder}); "
            "wait for it to finish or choose another path"
        )

    def acquire(self) -> OutputLock:
        import fcntl

        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
            except OSError as exc:
                raise OSError(f"could not create the lock file {str(self.path)!r} of {self.given!r}: {exc}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                try:
                    holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
                finally:
                    os.close(fd)
                raise self._busy(holder) from None
            # the file may have been removed by a releasing holder between open and flock: retry
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        except OSError as exc:
            os.close(fd)
            raise OSError(f"could not write the lock file {str(self.path)!r} of {self.given!r}: {exc}") from None
        self._fd = fd
        try:
            self._lock_node()
        except BaseException:
            self.release()
            raise
        return self

    def _lock_node(self) -> None:
        """Lock the existing output itself (its inode), so that a hard link to it is refused too."""
        import fcntl

        try:
            st = os.stat(self.target)
        except OSError:
            return
        if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
            return
        try:
            nfd = os.open(self.target, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        except OSError:  # unreadable: the beside lock alone guards it
            return
        try:
            fcntl.flock(nfd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(nfd)
            raise self._busy("?") from None
        self._node_fd = nfd

    def release(self) -> None:
        if self._node_fd is not None:
            os.close(self._node_fd)
            self._node_fd = None
        if self._fd is None:
            return
        try:
            os.unlink(self.path)
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> OutputLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()


def hold_outputs(
    outputs: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, folders: Mapping[str, Any] | None = None
) -> Any:
    """The writing rule of every command: check, then lock, every output for the life of the ``with`` block.

    ``outputs`` map an option name to an output file path (or None), ``folders`` to an output
    folder (created if missing), ``inputs`` to input paths. Refused before any work (ValueError
    naming the option): an output that is a device or directory, that is an input or another
    output by any name (symbolic links and hard links: device and inode), or that another process
    is writing (:class:`OutputLock`). Returns an ``ExitStack`` holding the locks."""
    from contextlib import ExitStack

    check_outputs(outputs, inputs)
    seen: dict[tuple[Any, ...], str] = {}
    created: list[str] = []  # folders made here: removed again if the command fails and left them empty
    for name, path in (folders or {}).items():
        if path is None:
            continue
        p = os.fspath(path)
        if os.path.exists(p) and not os.path.isdir(p):
            raise ValueError(f"{name} {p!r} exists and is not a folder")
        if not os.path.exists(p):
            created.append(p)
        os.makedirs(p, exist_ok=True)
        key = _identity(p)
        if key in seen:
            raise ValueError(f"{name} {p!r} is the same folder as {seen[key]}; choose another path")
        seen[key] = f"{name} {p!r}"
    stack = ExitStack()

    def _drop_empty_created(exc_type: Any, exc: Any, tb: Any) -> bool:
        if exc_type is not None:
            for folder in reversed(created):
                try:
                    os.rmdir(folder)  # only an empty folder: never anything the command or the user wrote
                except OSError:
                    pass
        return False

    stack.push(_drop_empty_created)  # runs last, after the locks are released
    for path in (folders or {}).values():
        if path is not None:
            folder = os.path.abspath(os.fspath(path))
            _CONFINED.append(folder)
            stack.callback(_CONFINED.remove, folder)
    try:
        for name, path in {**(folders or {}), **outputs}.items():
            if path is not None:
                stack.enter_context(OutputLock(path, name))
    except BaseException:
        stack.close()
        raise
    return stack
