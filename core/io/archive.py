"""ZIP archives of JSON and numpy ``.npy`` members, read with work bounded by the file.

The project file (:mod:`core.model.project`) and the classifier file
(:mod:`core.classify.model_file`) are ZIP archives. A hostile archive can
declare members far larger than its bytes could hold, inflate a small file
to gigabytes, hide an ``.npy`` header claiming 2^62 bytes, nest JSON deeper
than the interpreter's stack, or use encryption and compression methods
terratheme never writes. Every member is therefore checked *before* it is
read:

* only stored and deflated members are read (no encryption, no bzip2/lzma);
* the declared size is below the caller's ceiling and consistent with the
  compressed bytes present (stored: equal; deflate: at most
  :data:`MAX_DEFLATE_RATIO` times, deflate's own limit, RFC 1951 / zlib
  technical details), and decompression stops at the declared size;
* an ``.npy`` member's header (``numpy.lib.format``) must name an allowed
  plain dtype, and shape x item size must equal the bytes that follow the
  header, before the array is allocated; the bytes then go straight into it;
* JSON rejects ``NaN``/``Infinity`` and nesting deeper than :data:`MAX_JSON_DEPTH`.

So reading costs at most about ``MAX_DEFLATE_RATIO`` bytes of memory per
byte of file (a 256 KiB file cannot cost more than 256 MiB) and never more
than the ceilings. Every failure is a :class:`~core.errors.CorruptFileError`
naming the file and the member; the CRC-32 of every member is checked.
"""

from __future__ import annotations

import io
import json
import math
import os
import zipfile
import zlib
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from typing import BinaryIO

import numpy as np
from terratheme.core.errors import CorruptFileError
from terratheme.core.io.inputs import check_input_file

#: deflate's largest possible expansion: 258 bytes from 2 bits (zlib's technical notes: 1032:1)
MAX_DEFLATE_RATIO = 1032
#: slack on top of the ratio for a member's headers and tiny members
DEFLATE_SLACK = 1024
#: deepest JSON nesting read (the manifests nest 3 levels; metadata may nest a few more)
MAX_JSON_DEPTH = 32
#: largest ``.npy`` header read (numpy's own default)
MAX_NPY_HEADER = 10_000
_READ_CHUNK = 1 << 20
_COMPRESSION_NAMES = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate",
                      zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "lzma"}
#: what can go wrong inside zipfile / zlib on damaged bytes
_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError,
               NotImplementedError, RuntimeError, OverflowError)


def open_archive(source: str | os.PathLike | bytes, label: str, *, kind: str,
                 max_members: int) -> zipfile.ZipFile:
    """Open a ZIP archive (a file, or bytes of one) after checking its directory.

    Parameters
    ----------
    source : path-like or bytes
    label : str
        How messages name the archive (its path, or ``"path: member"``).
    kind : str
        What the archive should be, for messages ("terratheme project").
    max_members : int
        Most entries a genuine archive has.

    Returns
    -------
    zipfile.ZipFile
        Close it (``with``) when done.

    Raises
    ------
    CorruptFileError
        Not a ZIP, a damaged directory, too many entries, duplicate names.
    """
    if not isinstance(source, bytes):
        check_input_file(source, f"a {kind}")
    try:
        zf = zipfile.ZipFile(io.BytesIO(source) if isinstance(source, bytes) else source)
    except _ZIP_ERRORS as exc:
        raise CorruptFileError(
            f"{label}: not a {kind} (damaged or not a ZIP: {_one_line(exc)})") from None
    infos = zf.infolist()
    names = [i.filename for i in infos]
    if len(infos) > max_members:
        zf.close()
        raise CorruptFileError(f"{label}: {len(infos)} entries, more than a {kind} has "
                               f"({max_members})")
    if len(set(names)) != len(names):
        zf.close()
        dup = next(n for n in names if names.count(n) > 1)
        raise CorruptFileError(f"{label}: the entry {dup!r} appears twice")
    return zf


def _printable(name: str) -> str:
    return name if name.isprintable() and len(name) <= 80 else repr(name[:80])


def _where(label: str, member: str) -> str:
    return f"{label}: {_printable(member)}"


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text[:120] or type(exc).__name__


def _checked_info(zf: zipfile.ZipFile, member: str, label: str, max_bytes: int
                  ) -> zipfile.ZipInfo:
    try:
        info = zf.getinfo(member)
    except KeyError:
        raise CorruptFileError(f"{label}: lacks {_printable(member)}") from None
    if info.flag_bits & 0x1:
        raise CorruptFileError(f"{_where(label, member)} is encrypted (terratheme never encrypts)")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        method = _COMPRESSION_NAMES.get(info.compress_type, f"method {info.compress_type}")
        raise CorruptFileError(f"{_where(label, member)} uses {method} compression "
                               "(only stored and deflate are read)")
    if info.file_size > max_bytes:
        raise CorruptFileError(f"{_where(label, member)} declares {info.file_size:,} bytes, "
                               f"over the {max_bytes:,}-byte limit for it")
    if info.compress_type == zipfile.ZIP_STORED:
        possible = info.compress_size
    else:
        possible = MAX_DEFLATE_RATIO * info.compress_size + DEFLATE_SLACK
    if info.file_size > possible:
        raise CorruptFileError(f"{_where(label, member)} declares {info.file_size:,} bytes from "
                               f"{info.compress_size:,} stored: more than the data can hold")
    return info


def _read_exactly(fh, buffer: memoryview, label: str, member: str) -> None:
    """Fill ``buffer`` from ``fh``, which must hold exactly that many bytes."""
    filled = 0
    while filled < len(buffer):
        chunk = fh.read(min(_READ_CHUNK, len(buffer) - filled))
        if not chunk:
            raise CorruptFileError(f"{_where(label, member)} is truncated "
                                   f"({filled:,} of {len(buffer):,} bytes)")
        buffer[filled:filled + len(chunk)] = chunk
        filled += len(chunk)
    if fh.read(1):
        raise CorruptFileError(f"{_where(label, member)} is longer than it declares")


@contextmanager
def _opened(zf: zipfile.ZipFile, info: zipfile.ZipInfo, label: str, member: str
            ) -> Iterator[BinaryIO]:
    """``zf.open(info)``; a ZIP or zlib error inside the block is a CorruptFileError."""
    try:
        with zf.open(info) as fh:
            yield fh
    except CorruptFileError:
        raise
    except _ZIP_ERRORS as exc:
        raise CorruptFileError(f"{_where(label, member)} is damaged ({_one_line(exc)})") from None


def read_member(zf: zipfile.ZipFile, member: str, label: str, *, max_bytes: int) -> bytes:
    """The bytes of one member, at most ``max_bytes`` of them, CRC checked.

    Raises
    ------
    CorruptFileError
        Missing, encrypted, unknown compression, over the ceiling, a declared
        size the compressed bytes cannot hold, truncated, CRC mismatch.
    """
    info = _checked_info(zf, member, label, max_bytes)
    out = bytearray(info.file_size)
    with _opened(zf, info, label, member) as fh:
        _read_exactly(fh, memoryview(out), label, member)
    return bytes(out)


def _npy_header(fh, label: str, member: str) -> tuple[tuple, bool, np.dtype]:
    """``(shape, fortran_order, dtype)`` from an ``.npy`` header (numpy's own parser)."""
    try:
        version = np.lib.format.read_magic(fh)
        read = {(1, 0): np.lib.format.read_array_header_1_0,
                (2, 0): np.lib.format.read_array_header_2_0}.get(version)
        if read is None:
            raise ValueError(f".npy version {version}, not 1.0 or 2.0")
        shape, fortran, dtype = read(fh, max_header_size=MAX_NPY_HEADER)
        return shape, bool(fortran), np.dtype(dtype)
    except Exception as exc:
        # numpy's header parser (tokenize, literal_eval) raises many types on hostile
        # text; all of them mean "not an array header".
        raise CorruptFileError(
            f"{_where(label, member)} is not a numpy array ({_one_line(exc)})") from None


def read_npy_member(zf: zipfile.ZipFile, member: str, label: str, *, max_bytes: int,
                    dtypes: Collection[np.dtype | type | str],
                    ndims: Collection[int]) -> np.ndarray:
    """One ``.npy`` member as an array, checked before anything is allocated.

    Parameters
    ----------
    zf, member, label
        As :func:`read_member`.
    max_bytes : int
        Ceiling on the array's bytes.
    dtypes : collection of dtypes
        Allowed element types (either byte order; the result is native).
    ndims : collection of int
        Allowed numbers of dimensions.

    Returns
    -------
    array : ndarray of one of ``dtypes``, native byte order, C-contiguous

    Raises
    ------
    CorruptFileError
        Everything :func:`read_member` raises, plus: not an ``.npy``, an
        unknown ``.npy`` version, a dtype or dimension count not allowed,
        a shape whose bytes differ from the bytes after the header.
    """
    info = _checked_info(zf, member, label, max_bytes + MAX_NPY_HEADER + 128)
    allowed = {np.dtype(d).newbyteorder("=") for d in dtypes}
    with _opened(zf, info, label, member) as fh:
        shape, fortran, dtype = _npy_header(fh, label, member)
        if dtype.newbyteorder("=") not in allowed or dtype.fields or dtype.subdtype:
            want = ", ".join(sorted(str(d) for d in allowed))
            raise CorruptFileError(f"{_where(label, member)} holds {dtype}, not {want}")
        if len(shape) not in ndims or not all(isinstance(s, int) and s >= 0
                                              for s in shape):
            raise CorruptFileError(f"{_where(label, member)} has shape {shape}; "
                                   f"expected {' or '.join(map(str, sorted(ndims)))} "
                                   "dimensions")
        nbytes = math.prod(shape) * dtype.itemsize
        body = info.file_size - fh.tell()
        if nbytes != body:
            raise CorruptFileError(f"{_where(label, member)} declares shape {shape} "
                                   f"({nbytes:,} bytes) but holds {body:,}")
        if nbytes > max_bytes:
            raise CorruptFileError(f"{_where(label, member)} of shape {shape} is {nbytes:,} "
                                   f"bytes, over the {max_bytes:,}-byte limit for it")
        arr = np.empty(shape[::-1] if fortran else shape, dtype)
        _read_exactly(fh, memoryview(arr.reshape(-1).view(np.uint8)), label, member)
    if fortran:
        arr = arr.T
    return np.ascontiguousarray(arr, dtype=dtype.newbyteorder("="))


def json_depth(value: object) -> int:
    """Nesting depth of parsed JSON (a scalar is 1), counted without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if isinstance(node, dict):
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, depth + 1) for v in node)
    return deepest


def _no_constant(name: str) -> None:
    raise ValueError(f"non-finite number {name}")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text[:20]} overflows")
    return value


def _unique_keys(pairs: list[tuple[str, object]]) -> dict:
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {key[:40]!r} appears twice in an object")
        out[key] = value
    return out


def read_bounded(path: str | os.PathLike, limit: int, label: str) -> bytes:
    """The bytes of a small file (a legend, an index, a metadata file), at most ``limit``.

    Reads ``limit + 1`` bytes at the most, so a huge file costs no more than a small one.

    Raises
    ------
    CorruptFileError
        ``"{label}: larger than {limit} bytes"``, or a file that cannot be read.
    """
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise CorruptFileError(f"{label}: cannot be read ({exc.strerror})") from None
    if len(data) > limit:
        raise CorruptFileError(f"{label}: larger than {limit} bytes")
    return data


def parse_json(data: bytes, label: str) -> object:
    """JSON bytes parsed as every reader wants them: UTF-8, finite numbers only, each
    key once per object (not silently the last), nesting at most :data:`MAX_JSON_DEPTH`.

    Parameters
    ----------
    data : bytes
        The JSON text (the caller bounds its size).
    label : str
        How the message names the file (``"path"`` or ``"path: member"``).

    Raises
    ------
    CorruptFileError
        Not UTF-8 JSON, ``NaN`` or ``Infinity``, a key twice in an object, too deep; one
        line naming ``label``.
    """
    try:
        value = json.loads(data.decode("utf-8"), parse_constant=_no_constant,
                           parse_float=_finite_float, object_pairs_hook=_unique_keys)
    except RecursionError:
        raise CorruptFileError(f"{label} nests deeper than {MAX_JSON_DEPTH} levels") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise CorruptFileError(f"{label} is not valid JSON ({_one_line(exc)})") from None
    if json_depth(value) > MAX_JSON_DEPTH:
        raise CorruptFileError(f"{label} nests deeper than {MAX_JSON_DEPTH} levels")
    return value


def read_json_member(zf: zipfile.ZipFile, member: str, label: str, *,
                     max_bytes: int) -> object:
    """One JSON member, parsed by :func:`parse_json`.

    Raises
    ------
    CorruptFileError
        Everything :func:`read_member` raises, plus: not UTF-8 JSON, ``NaN``
        or ``Infinity``, too deep.
    """
    data = read_member(zf, member, label, max_bytes=max_bytes)
    return parse_json(data, _where(label, member))
