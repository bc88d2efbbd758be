"""The reading layer for files from outside: every loader of the package reads through it.

A file gear-env reads may come from someone else (a shared run folder, a downloaded policy, a results
file): it is read as if it were hostile. This module holds the checks every loader uses, so the same
rule holds for SB3 model zips, ``.npz`` statistics and sweep checkpoints, ``policy.json`` + state
dicts, ``.nc`` results, run folders, schedules and configs:

* **Regular files only**, opened without blocking (a FIFO, a directory, a device or ``/proc/self/mem``
  is refused by name, never waited on) and with the size read from ``stat`` before anything is read
  (:func:`open_regular`).
* **Archives** (zip: SB3 models, ``.npz``, torch state dicts): the number of members, each member's
  declared uncompressed size and their total are checked *before* anything is inflated
  (:func:`check_zip`); a member is then read with its declared size as the ceiling (Python's
  ``zipfile`` never returns more than the declared size), so a decompression bomb costs nothing.
* **Arrays** (``.npz`` members): the ``.npy`` header is parsed first; dtype (never an object),
  number of dimensions and element count are checked against a schema, and the declared shape must
  fit in the member's declared size, before one element is allocated (:func:`read_npz`).
* **JSON**: size, nesting depth and number length bounded by one helper (:func:`gear_env.io.parse_json_text`).
* **Fields**: known keys only, types and ranges (:func:`check_keys`, :func:`want_int`, ...).
* **Paths** named by a file or found in a run folder must stay inside it after resolving symbolic
  links (:func:`inside`).

Every refusal is a :class:`gear_env.errors.FileFormatError` (a ``ValueError``) whose one-line
message names the file and the field; the CLI prints it and exits with code 2. The limits are the
module constants below (docs/RELIABILITY.md lists them).
"""

from __future__ import annotations

import math
import os
import re
import stat
import zipfile
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .errors import FileFormatError

MAX_ARCHIVE_MEMBERS = 1024
"""Most members of a zip archive (an SB3 model has 6, a torch state dict about 20, an ``.npz`` one per array)."""
MAX_MEMBER_BYTES = 256 * 2**20
"""Largest declared uncompressed size of one archive member (256 MiB) unless a loader sets less."""
MAX_ARCHIVE_BYTES = 1024 * 2**20
"""Largest declared uncompressed total of one archive (1 GiB) unless a loader sets less."""
MAX_NPY_HEADER = 10_000
"""Largest ``.npy`` header read (bytes)."""


def refuse(path: str | os.PathLike | None, field: str | None, problem: str) -> FileFormatError:
    """The one-line error for a refused file: ``<path>: <field>: <problem>``."""
    p = os.fspath(path) if path is not None else None
    head = f"{p!r}" if p is not None else "input"
    msg = f"{head}: {field}: {problem}" if field else f"{head}: {problem}"
    return FileFormatError(msg, p, field)


# --------------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------------
def open_regular(path: str | os.PathLike, what: str) -> tuple[int, os.stat_result]:
    """Open a regular file for reading without ever blocking; (fd, stat). The caller closes fd.

    A FIFO would block ``open`` until a writer came (``O_NONBLOCK`` prevents that), a directory or
    device is refused by type, and a missing file by name; every refusal is a FileFormatError
    naming ``what`` and the path."""
    p = os.fspath(path)
    if not p:
        raise refuse(None, None, f"{what}: empty path")
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise refuse(p, None, f"{what} does not exist") from None
    except IsADirectoryError:
        raise refuse(p, None, f"{what} is a directory, expected a file") from None
    except OSError as exc:
        raise refuse(p, None, f"{what}: cannot open it ({exc.strerror or exc})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file (a FIFO, device or socket)"
        raise refuse(p, None, f"{what} is {kind}; expected a file")
    os.set_blocking(fd, True)
    return fd, st


def read_regular(path: str | os.PathLike, what: str, max_bytes: int) -> bytes:
    """The bytes of a regular file of at most ``max_bytes`` (size checked from ``stat`` before reading).

    Files of the ``/proc`` kind that claim size 0 are read up to the limit only."""
    fd, st = open_regular(path, what)
    p = os.fspath(path)
    try:
        if st.st_size > max_bytes:
            raise refuse(p, None, f"{what} is {st.st_size:,} bytes; the limit is {max_bytes:,} bytes")
        chunks: list[bytes] = []
        n = 0
        while n <= max_bytes:
            b = os.read(fd, min(1 << 20, max_bytes + 1 - n))
            if not b:
                break
            chunks.append(b)
            n += len(b)
    except OSError as exc:
        raise refuse(p, None, f"{what}: cannot read it ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if n > max_bytes:
        raise refuse(p, None, f"{what} is larger than the limit of {max_bytes:,} bytes")
    return b"".join(chunks)


def inside(root: str | os.PathLike, path: str | os.PathLike, what: str) -> Path:
    """``path`` resolved (symbolic links followed); FileFormatError if it is not inside ``root`` (resolved).

    Used for every path of a run folder (checkpoints/, the files latest.json names, logs) before it
    is read or written."""
    r = Path(os.path.realpath(os.fspath(root)))
    q = Path(os.path.realpath(os.fspath(path)))
    if q != r and r not in q.parents:
        raise refuse(path, what, f"leaves the folder {str(root)!r} (resolves to {str(q)!r}); refused")
    return q


# --------------------------------------------------------------------------------------------------
# archives
# --------------------------------------------------------------------------------------------------
def _src_name(source: Any) -> str:
    return os.fspath(source) if isinstance(source, (str, os.PathLike)) else "<archive>"


def open_zip(
    source: str | os.PathLike | bytes,
    what: str,
    *,
    allowed: Collection[str] | Callable[[str], bool] | None = None,
    required: Collection[str] = (),
    max_member: int = MAX_MEMBER_BYTES,
    max_total: int = MAX_ARCHIVE_BYTES,
    max_members: int = MAX_ARCHIVE_MEMBERS,
    stored_only: bool = False,
    path: str | os.PathLike | None = None,
) -> zipfile.ZipFile:
    """An open ``ZipFile`` whose members were checked before anything was inflated.

    Checked: at most ``max_members`` members, each declared uncompressed size at most ``max_member``
    and their sum at most ``max_total``; names in ``allowed`` (a set or a predicate) and every name
    of ``required`` present; with ``stored_only``, no compressed member (torch writes none). ``path``
    names the file in messages when ``source`` is bytes (a nested archive)."""
    import io

    name = os.fspath(path) if path is not None else _src_name(source)
    if isinstance(source, (bytes, bytearray)):
        fh: Any = io.BytesIO(source)
    else:
        fd, st = open_regular(source, what)
        os.close(fd)
        if st.st_size > max_total + (1 << 20):  # headers aside, an archive is no larger than its content
            raise refuse(name, None, f"{what} is {st.st_size:,} bytes on disk; the limit is {max_total:,}")
        fh = os.fspath(source)
    try:
        z = zipfile.ZipFile(fh)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError, NotImplementedError) as exc:
        raise refuse(name, None, f"{what} is not a valid zip archive ({type(exc).__name__}: {exc})") from None
    try:
        infos = z.infolist()
        if len(infos) > max_members:
            raise refuse(name, None, f"{what} has {len(infos)} members; the limit is {max_members}")
        total = 0
        seen = set()
        for info in infos:
            if info.filename in seen:
                raise refuse(name, info.filename, f"{what}: member stored twice")
            seen.add(info.filename)
            if allowed is not None:
                ok = allowed(info.filename) if callable(allowed) else info.filename in allowed
                if not ok:
                    raise refuse(name, info.filename, f"unknown member of {what}; refused")
            if info.file_size > max_member:
                raise refuse(
                    name, info.filename, f"declares {info.file_size:,} bytes uncompressed; the limit is {max_member:,}"
                )
            if stored_only and info.compress_type != zipfile.ZIP_STORED:
                raise refuse(name, info.filename, "is compressed; this archive kind stores its members uncompressed")
            if info.flag_bits & 0x1:
                raise refuse(name, info.filename, "is encrypted")
            total += info.file_size
        if total > max_total:
            raise refuse(name, None, f"{what} declares {total:,} bytes uncompressed in all; the limit is {max_total:,}")
        missing = [r for r in required if r not in seen]
        if missing:
            raise refuse(name, missing[0], f"{what} lacks this member")
    except BaseException:
        z.close()
        raise
    return z


def read_member(z: zipfile.ZipFile, member: str, path: str | os.PathLike) -> bytes:
    """The bytes of an archive member (its declared size, checked by :func:`open_zip`, is the ceiling)."""
    try:
        info = z.getinfo(member)
        with z.open(info) as fh:
            data = fh.read(info.file_size + 1)
    except KeyError:
        raise refuse(path, member, "member missing") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError, RuntimeError) as exc:
        raise refuse(path, member, f"corrupt member ({type(exc).__name__}: {exc})") from None
    except Exception as exc:  # zlib.error and the like from a damaged stream
        raise refuse(path, member, f"corrupt member ({type(exc).__name__}: {exc})") from None
    if len(data) != info.file_size:
        raise refuse(path, member, f"holds {len(data):,} bytes, declares {info.file_size:,}")
    return data


class ArraySpec(NamedTuple):
    """What an ``.npz`` member may hold: dtype kinds (``"f"``, ``"i"``, ``"b"``, ``"U"``, ...),
    number of dimensions (None: any up to 8), most elements and most bytes (None: the archive's limit)."""

    kinds: str
    ndim: int | None
    max_elems: int
    max_bytes: int | None = None


def _npy(z: zipfile.ZipFile, info: zipfile.ZipInfo, spec: ArraySpec, path: str, field: str) -> np.ndarray:
    """One ``.npy`` member: header parsed and checked against ``spec`` before the data is allocated."""
    from numpy.lib import format as npf

    try:
        with z.open(info) as fh:
            version = npf.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = npf.read_array_header_1_0(fh, max_header_size=MAX_NPY_HEADER)
            elif version in ((2, 0), (3, 0)):
                shape, fortran, dtype = npf.read_array_header_2_0(fh, max_header_size=MAX_NPY_HEADER)
            else:
                raise ValueError(f"unsupported .npy version {version}")
            header = fh.tell()
            if dtype.hasobject or dtype.kind not in spec.kinds or dtype.fields is not None or dtype.subdtype:
                raise refuse(path, field, f"dtype {dtype} not allowed (expected kind {spec.kinds!r})")
            if (spec.ndim is not None and len(shape) != spec.ndim) or len(shape) > 8:
                raise refuse(path, field, f"shape {shape} has {len(shape)} dimensions, expected {spec.ndim}")
            count = math.prod(shape)
            if count > spec.max_elems:
                raise refuse(path, field, f"shape {shape} has {count:,} elements; the limit is {spec.max_elems:,}")
            nbytes = count * dtype.itemsize
            if spec.max_bytes is not None and nbytes > spec.max_bytes:
                raise refuse(path, field, f"{nbytes:,} bytes of {dtype}; the limit is {spec.max_bytes:,}")
            if header + nbytes != info.file_size:
                raise refuse(
                    path, field, f"shape {shape} of {dtype} needs {nbytes:,} bytes, the member holds "
                    f"{info.file_size - header:,}"
                )  # fmt: skip
            raw = fh.read(nbytes)
    except FileFormatError:
        raise
    except Exception as exc:  # ValueError from the header parser, zlib/zip errors from a damaged stream
        raise refuse(path, field, f"corrupt array ({type(exc).__name__}: {exc})") from None
    if len(raw) != nbytes:
        raise refuse(path, field, "truncated array")
    if dtype.kind == "U":  # UTF-32 code units: one beyond U+10FFFF would crash numpy's str()
        units = np.frombuffer(raw, dtype=np.dtype("u4").newbyteorder(dtype.byteorder))
        if units.size and int(units.max()) > 0x10FFFF:
            raise refuse(path, field, "text holds an invalid code point")
    arr = np.frombuffer(raw, dtype=dtype)
    return arr.reshape(shape, order="F" if fortran else "C").copy()


def read_npz(
    path: str | os.PathLike,
    what: str,
    spec: Mapping[str, ArraySpec],
    optional: Collection[str] = (),
    max_total: int = MAX_ARCHIVE_BYTES,
    only: Collection[str] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` written by the package, every member checked against ``spec``.

    Members not in ``spec`` are refused (an unused 800 MB member too), members of ``spec`` not in
    ``optional`` are required, nothing is unpickled and nothing is allocated before its header was
    checked. ``only`` reads just those members (the archive is checked whole)."""
    p = os.fspath(path)
    names = {f"{k}.npy": k for k in spec}
    req = [f"{k}.npy" for k in spec if k not in optional]
    z = open_zip(p, what, allowed=names, required=req, max_member=max_total, max_total=max_total)
    try:
        return {
            names[i.filename]: _npy(z, i, spec[names[i.filename]], p, names[i.filename])
            for i in z.infolist()
            if only is None or names[i.filename] in only
        }
    finally:
        z.close()


# --------------------------------------------------------------------------------------------------
# fields
# --------------------------------------------------------------------------------------------------
def check_keys(
    obj: Any, allowed: Collection[str], path: str | os.PathLike, where: str, required: Collection[str] = ()
) -> dict[str, Any]:
    """``obj`` as a dict whose keys are all in ``allowed`` and include ``required`` (FileFormatError otherwise)."""
    if not isinstance(obj, dict):
        raise refuse(path, where, f"must be a JSON object, got {type(obj).__name__}")
    unknown = sorted(str(k) for k in obj if k not in allowed)
    if unknown:
        raise refuse(path, f"{where}.{unknown[0]}" if where else unknown[0], f"unknown key; known: {sorted(allowed)}")
    for k in required:
        if k not in obj:
            raise refuse(path, f"{where}.{k}" if where else k, "missing")
    return obj


def want_int(v: Any, lo: int, hi: int, path: str | os.PathLike, field: str) -> int:
    """``v`` if it is an integer (not a bool; numpy integers accepted) in [lo, hi]."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not lo <= int(v) <= hi:
        raise refuse(path, field, f"must be an integer in [{lo}, {hi}], got {_short(v)}")
    return int(v)


def want_num(v: Any, lo: float, hi: float, path: str | os.PathLike, field: str, lo_open: bool = False) -> float:
    """``v`` as a float if it is a finite number in [lo, hi] (``(lo, hi]`` with ``lo_open``)."""
    ok = not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer, np.floating))
    if ok:
        f = float(v)
        ok = math.isfinite(f) and (f > lo if lo_open else f >= lo) and f <= hi
    if not ok:
        left = "(" if lo_open else "["
        raise refuse(path, field, f"must be a finite number in {left}{lo:g}, {hi:g}], got {_short(v)}")
    return float(v)


def want_str(
    v: Any, path: str | os.PathLike, field: str, choices: Collection[str] | None = None, max_len: int = 256,
    pattern: str | None = None,
) -> str:  # fmt: skip
    """``v`` if it is a string of at most ``max_len`` characters (one of ``choices``, matching ``pattern``)."""
    if not isinstance(v, str) or len(v) > max_len:
        raise refuse(path, field, f"must be a string of at most {max_len} characters, got {_short(v)}")
    if choices is not None and v not in choices:
        raise refuse(path, field, f"must be one of {sorted(choices)}, got {_short(v)}")
    if pattern is not None and not re.fullmatch(pattern, v):
        raise refuse(path, field, f"must match {pattern!r}, got {_short(v)}")
    return v


def want_bool(v: Any, path: str | os.PathLike, field: str) -> bool:
    """``v`` if it is true or false."""
    if not isinstance(v, (bool, np.bool_)):
        raise refuse(path, field, f"must be true or false, got {_short(v)}")
    return bool(v)


def want_numbers(
    v: Any, path: str | os.PathLike, field: str, length: int | None = None, max_len: int = 4096,
    lo: float = -math.inf, hi: float = math.inf,
) -> np.ndarray:  # fmt: skip
    """``v`` as a float64 array if it is a flat list of finite numbers in [lo, hi] (of ``length`` entries)."""
    if not isinstance(v, (list, tuple, np.ndarray)) or len(v) > max_len or (length is not None and len(v) != length):
        n = f"{length}" if length is not None else f"at most {max_len}"
        raise refuse(path, field, f"must be a list of {n} numbers, got {_short(v)}")
    if any(isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)) for x in v):
        raise refuse(path, field, "must hold numbers only")
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(a)) or np.any(a < lo) or np.any(a > hi):
        raise refuse(path, field, f"must hold finite numbers in [{lo:g}, {hi:g}]")
    return a


def layer_sizes(v: Any, path: str | os.PathLike, field: str, max_layers: int = 16, max_width: int = 4096) -> list[int]:
    """A ``net_arch`` list of layer widths, bounded before any network is built."""
    if not isinstance(v, (list, tuple)) or not 0 <= len(v) <= max_layers:
        raise refuse(path, field, f"must be a list of at most {max_layers} layer sizes, got {_short(v)}")
    return [want_int(n, 1, max_width, path, f"{field}[{i}]") for i, n in enumerate(v)]


def mlp_parameters(n_in: int, layers: Sequence[int], n_out: int) -> int:
    """Weights and biases of a fully connected net n_in -> layers -> n_out."""
    total, prev = 0, n_in
    for w in [*layers, n_out]:
        total += prev * w + w
        prev = w
    return total


def _short(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


__all__ = [
    "MAX_ARCHIVE_BYTES",
    "MAX_ARCHIVE_MEMBERS",
    "MAX_MEMBER_BYTES",
    "ArraySpec",
    "check_keys",
    "inside",
    "layer_sizes",
    "mlp_parameters",
    "open_regular",
    "open_zip",
    "read_member",
    "read_npz",
    "read_regular",
    "refuse",
    "want_bool",
    "want_int",
    "want_num",
    "want_numbers",
    "want_str",
]
