"""One bounded disk cache: arrays by key, every entry checked as hostile input.

One file ``<key>.<kind>`` per entry (layout and rules: docs/formats.md, "Disk caches"):
no pickles; an entry is read only if it is a regular file of this user whose size,
key, kind and SHA-256 match, else it is a miss (a damaged one is removed). Writes are
renamed into place, then least recently used entries go until the folder fits
``max_bytes``. Processes may share a folder.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import secrets
import stat
import struct
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.archive import parse_json

#: the default bound of a cache folder, in bytes (2 GiB)
DEFAULT_CACHE_BYTES = 2 << 30
MAGIC = b"TTCACHE1"
_LENGTH = struct.Struct("<I")
_DIGEST = 32
_MAX_HEADER = 4096
#: the array types an entry may hold, by the name its header gives
DTYPES = {"uint8": np.dtype("u1"), "uint16": np.dtype("<u2"), "float32": np.dtype("<f4")}
_KEY = re.compile(r"[0-9a-f]{64}")
_KIND = re.compile(r"[a-z]{1,16}")
_NAME = re.compile(r"[a-z_]{1,32}")
_ENTRY = re.compile(r"[0-9a-f]{64}\.[a-z]{1,16}")
_TEMPORARY = re.compile(r"\.[0-9a-f]{64}\.[a-z]{1,16}\.[0-9a-f]{16}\.tmp")
#: a temporary older than this was left by a killed run
_STALE_SECONDS = 3600

T = TypeVar("T")
Arrays = dict[str, np.ndarray]


class DiskCache:
    """Entries of arrays by key in ``folder`` (made on the first write), least recently
    used removed first to keep them within ``max_bytes``; ``hits`` and ``misses`` count
    lookups by kind."""

    def __init__(self, folder: str | os.PathLike, max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        if max_bytes < 1:
            raise TerrathemeError(f"a cache's bound must be at least one byte, not {max_bytes}")
        self.folder = Path(folder)
        self.max_bytes = int(max_bytes)
        self.hits: Counter[str] = Counter()
        self.misses: Counter[str] = Counter()

    def unusable(self) -> str | None:
        """Make the folder; why it cannot be used (e.g. "not writable"), or None."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            return exc.strerror or str(exc)
        return None if os.access(self.folder, os.W_OK | os.X_OK) else "not writable"

    def path(self, key: str, kind: str) -> Path:
        """The entry's file; ValueError for a key that is not 64 hex digits or a bad kind."""
        if not (_KEY.fullmatch(key) and _KIND.fullmatch(kind)):
            raise ValueError(f"not a cache key and kind: {key!r}, {kind!r}")
        return self.folder / f"{key}.{kind}"

    def load(self, key: str, kind: str, parse: Callable[[Arrays], T | None]) -> T | None:
        """``parse`` of the entry's arrays, or None (no usable entry, or ``parse`` refused
        it: then removed). A hit makes the entry the most recently used."""
        path = self.path(key, kind)
        try:
            arrays = _read(path, key, kind, self.max_bytes)
        except _Damaged:
            arrays = None
            _remove(path)
        value = None if arrays is None else parse(arrays)
        if value is None:
            if arrays is not None:
                _remove(path)
            self.misses[kind] += 1
            return None
        self.hits[kind] += 1
        with contextlib.suppress(OSError):
            os.utime(path, follow_symlinks=False)
        return value

    def store(self, key: str, kind: str, arrays: Arrays) -> bool:
        """Write ``arrays`` (types of :data:`DTYPES`) as the entry, then bound the folder.

        Returns whether it was written: a folder that cannot be made or written, a
        full disk or an entry over the bound alone costs the caching, never the result.
        """
        path = self.path(key, kind)
        parts = [np.ascontiguousarray(a, _dtype_of(a)) for a in arrays.values()]
        specs = {name: [a.dtype.name, list(a.shape)] for name, a in zip(arrays, parts, strict=True)}
        header = json.dumps({"key": key, "kind": kind, "arrays": specs}).encode()
        size = len(MAGIC) + _LENGTH.size + len(header) + sum(a.nbytes for a in parts) + _DIGEST
        if size > self.max_bytes or len(header) > _MAX_HEADER:
            return False
        tmp = self.folder / f".{path.name}.{secrets.token_hex(8)}.tmp"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            digest = hashlib.sha256()
            with open(tmp, "xb") as f:
                for part in (MAGIC, _LENGTH.pack(len(header)), header, *parts):
                    data = part.reshape(-1).view(np.uint8) if isinstance(part, np.ndarray) else part
                    f.write(data)
                    digest.update(data)
                f.write(digest.digest())
            os.replace(tmp, path)
        except OSError:
            _remove(tmp)
            return False
        self.evict(keep=path.name)
        return True

    def fetch(self, key: str, kind: str, parse: Callable[[Arrays], T | None],
              compute: Callable[[], T], arrays_of: Callable[[T], Arrays | None]) -> T:
        """The entry's value (:meth:`load`), else ``compute()``, stored as ``arrays_of`` of it
        (unless that is None: a value no entry can hold)."""
        value = self.load(key, kind, parse)
        if value is None:
            value = compute()
            arrays = arrays_of(value)
            if arrays is not None:
                self.store(key, kind, arrays)
        return value

    def evict(self, keep: str | None = None) -> list[str]:
        """Remove the least recently used entries until the rest fit ``max_bytes``.

        ``keep`` (an entry's name) is never removed. Returns the names removed; one
        another process removed first counts as gone, one that cannot be removed (not
        ours, in a shared folder) stays and the next goes instead.
        """
        listed, removed = entries(self.folder), []
        total = sum(size for _, _, size in listed)
        for _, name, size in listed:
            if total <= self.max_bytes:
                break
            if name == keep:
                continue
            try:
                (self.folder / name).unlink()
                removed.append(name)
            except FileNotFoundError:
                pass
            except OSError:
                continue
            total -= size
        return removed


def entries(folder: Path) -> list[tuple[int, str, int]]:
    """``(mtime_ns, name, bytes)`` of the regular entries of ``folder``, least recently used
    first (empty without the folder); temporaries of killed runs are removed."""
    found = []
    try:
        with os.scandir(folder) as listing:
            for item in listing:
                with contextlib.suppress(OSError):
                    st = item.stat(follow_symlinks=False)
                    if not stat.S_ISREG(st.st_mode):
                        continue
                    if _ENTRY.fullmatch(item.name):
                        found.append((st.st_mtime_ns, item.name, st.st_size))
                    elif (_TEMPORARY.fullmatch(item.name)
                          and st.st_mtime < time.time() - _STALE_SECONDS):
                        os.unlink(item.path)
    except OSError:
        return []
    return sorted(found)


class _Damaged(Exception):
    """A regular entry that is not a whole entry of its key: to be removed."""


def _dtype_of(a: np.ndarray) -> np.dtype:
    for dtype in DTYPES.values():
        if a.dtype == dtype:
            return dtype
    raise TypeError(f"a cache entry holds {', '.join(DTYPES)} arrays, not {a.dtype}")


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        path.unlink()


def _read(path: Path, key: str, kind: str, max_bytes: int) -> Arrays | None:
    """The arrays of a regular entry of this user; None if absent or not such a file
    (left alone), :class:`_Damaged` if it is not a whole entry of ``key`` and ``kind``."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None                 # absent, a symlink, unreadable
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid():
        os.close(fd)
        return None                 # a FIFO, a device, a folder; another user's file
    with os.fdopen(fd, "rb") as f:
        if st.st_size > max_bytes:
            raise _Damaged
        try:
            return _parse(f, st.st_size, key, kind)
        except (OSError, ValueError, struct.error) as exc:
            raise _Damaged from exc


def _parse(f, size: int, key: str, kind: str) -> Arrays:
    """Read and check an entry of ``size`` bytes; ValueError on any damage."""
    head = f.read(len(MAGIC) + _LENGTH.size)
    if len(head) != len(MAGIC) + _LENGTH.size or head[: len(MAGIC)] != MAGIC:
        raise ValueError("not a cache entry")
    (n_header,) = _LENGTH.unpack(head[len(MAGIC):])
    if n_header > _MAX_HEADER:
        raise ValueError("header too long")
    raw = f.read(n_header)
    meta = parse_json(raw, "cache entry")
    if (not isinstance(meta, dict) or set(meta) != {"key", "kind", "arrays"}
            or meta["key"] != key or meta["kind"] != kind or not isinstance(meta["arrays"], dict)):
        raise ValueError("not an entry of this key")
    layout = [(name, *_array_spec(name, spec)) for name, spec in meta["arrays"].items()]
    payload = sum(dtype.itemsize * math.prod(shape) for _, dtype, shape in layout)
    if len(head) + n_header + payload + _DIGEST != size:
        raise ValueError("size does not match the header")
    data = bytearray(payload)
    if f.readinto(data) != payload:
        raise ValueError("truncated")
    digest = hashlib.sha256(head)
    digest.update(raw)
    digest.update(data)
    if f.read(_DIGEST + 1) != digest.digest():
        raise ValueError("digest mismatch")
    arrays, offset = {}, 0
    for name, dtype, shape in layout:
        count = math.prod(shape)
        arrays[name] = np.frombuffer(data, dtype, count, offset).reshape(shape)
        offset += count * dtype.itemsize
    return arrays


def _array_spec(name: object, spec: object) -> tuple[np.dtype, tuple[int, ...]]:
    """``(dtype, shape)`` of a header's ``name: [dtype, shape]``; ValueError if malformed."""
    if not (isinstance(name, str) and _NAME.fullmatch(name) and isinstance(spec, list)
            and len(spec) == 2 and isinstance(spec[0], str) and spec[0] in DTYPES
            and isinstance(spec[1], list) and len(spec[1]) <= 4
            and all(type(n) is int and 0 <= n <= 1 << 40 for n in spec[1])):
        raise ValueError("bad array in the header")
    return DTYPES[spec[0]], tuple(spec[1])
