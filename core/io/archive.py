"""ZIP archives of JSON and ``.npy`` members (projects, classifiers), read with work
bounded by the file: each member is checked before it is read.

* stored and deflated members only (no encryption, bzip2, lzma);
* members do not overlap: each one's data ends before the next local header (so one
  small deflate stream cannot be read once per member: an "overlapping" ZIP bomb);
* the declared size is under the caller's ceiling and one the compressed bytes can
  hold (deflate expands at most :data:`MAX_DEFLATE_RATIO` times, RFC 1951);
  decompression stops there and the CRC-32 is checked;
* an ``.npy`` header names an allowed plain dtype whose shape x item size equals the
  bytes after it, before the array is allocated;
* JSON: no ``NaN``/``Infinity``, no key twice, nesting at most :data:`MAX_JSON_DEPTH`.

Every failure is one :class:`~core.errors.CorruptFileError` naming file and member.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
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

    ``label`` names the archive in messages, ``kind`` says what it should be ("terratheme
    project"), ``max_members`` is the most entries a genuine one has. The caller closes
    the ZipFile. Raises CorruptFileError for a damaged directory, too many entries or a
    name twice.
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
    seen: set[str] = set()
    dup = next((n for n in names if n in seen or seen.add(n)), None)  # linear, not n^2
    if dup is not None:
        zf.close()
        raise CorruptFileError(f"{label}: the entry {dup[:80]!r} appears twice")
    try:
        _check_disjoint(zf, infos, label)
    except BaseException:
        zf.close()
        raise
    return zf


_LOCAL_HEADER = struct.Struct("<4s22xHH")


def _check_disjoint(zf: zipfile.ZipFile, infos: list[zipfile.ZipInfo], label: str) -> None:
    """Refuse members whose data overlaps another member's or the central directory.

    Each local header is read (30 bytes) for its name and extra lengths, which place
    the data; the data must end before the next header by offset. One read a member.
    """
    ordered = sorted(infos, key=lambda i: i.header_offset)
    ends = [i.header_offset for i in ordered[1:]] + [zf.start_dir]
    for info, end in zip(ordered, ends, strict=True):
        try:
            zf.fp.seek(info.header_offset)
            head = zf.fp.read(_LOCAL_HEADER.size)
        except (OSError, ValueError) as exc:
            raise CorruptFileError(f"{_where(label, info.filename)} cannot be read "
                                   f"({_one_line(exc)})") from None
        if len(head) < _LOCAL_HEADER.size or head[:4] != b"PK\x03\x04":
            raise CorruptFileError(f"{_where(label, info.filename)} has no local header "
                                   "where the directory says")
        _, name_length, extra_length = _LOCAL_HEADER.unpack(head)
        data_end = (info.header_offset + _LOCAL_HEADER.size + name_length + extra_length
                    + info.compress_size)
        if data_end > end:
            raise CorruptFileError(f"{_where(label, info.filename)} overlaps the next entry "
                                   "(a ZIP bomb or a damaged archive)")


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
    """The bytes of one member, at most ``max_bytes``, checked as the module says."""
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

    ``max_bytes`` bounds the array's bytes; ``dtypes`` (either byte order) and ``ndims``
    are the allowed element types and dimension counts. Returns a native-order,
    C-contiguous array; raises CorruptFileError as :func:`read_member`, or for a bad
    ``.npy`` header, dtype, dimension count or byte count.
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
    """The bytes of a small file (legend, index, metadata), reading ``limit + 1`` at most.

    Raises CorruptFileError if it is larger than ``limit`` or cannot be read.
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
    """UTF-8 JSON ``data`` (size bounded by the caller) parsed with finite numbers only,
    each key once per object and nesting at most :data:`MAX_JSON_DEPTH`; anything else
    is a CorruptFileError naming ``label`` (``"path"`` or ``"path: member"``).
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
    """One member (:func:`read_member`) parsed by :func:`parse_json`."""
    data = read_member(zf, member, label, max_bytes=max_bytes)
    return parse_json(data, _where(label, member))
