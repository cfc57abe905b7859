"""A cache of prefiltered families on disk, so a second preview starts at once.

Families live in one cache folder (the CLI uses ``$XDG_CACHE_HOME/terratheme/
families``), not beside the texture: the texture's folder may be read-only or
shared, a project's texture is rendered (it has no file of its own), and one
folder is easy to bound. Each file is named by a key of the texture's content
(its texels, shape and type) and the options that shape the family, so an
edited texture or other options miss, never read a stale family.

A file: magic ``TTFAMILY``, a format version, a JSON header (the cells' type
and shape, the grid and options), the cells, then the CRC-32 of everything
before it. The tables are recomputed from the grid and options
(``family_layout``) and must account for exactly the cells stored; sizes are
checked against the file's size before anything is allocated; a file that
fails any check is removed and reported as a miss, so a damaged cache costs a
rebuild, never a wrong frame. Writes are atomic; after each write the least
recently used files are removed until the folder is within ``max_bytes``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import struct
import zlib
from pathlib import Path

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.archive import parse_json
from terratheme.core.io.atomic import atomic_path
from terratheme.core.perspective.family import ParallelogramFamily, family_layout

MAGIC = b"TTFAMILY"
#: bump when the family's construction changes (old files then miss)
FORMAT_VERSION = 2
SUFFIX = ".ttfamily"
#: default bound on the cache folder
DEFAULT_MAX_BYTES = 2 << 30
_HEADER = struct.Struct("<8sII")  # magic, version, JSON length
_TYPES = {"uint8": np.uint8, "uint16": np.uint16, "float32": np.float32}


def family_key(texels: np.ndarray, max_lambda_log2: int, skew_oversampling: int) -> str:
    """The cache key of the family of ``texels`` ``(h, w, C)`` for these options."""
    digest = hashlib.sha1(usedforsecurity=False)
    digest.update(json.dumps([FORMAT_VERSION, list(texels.shape), str(texels.dtype),
                              int(max_lambda_log2), int(skew_oversampling)]).encode())
    digest.update(np.ascontiguousarray(texels).data)
    return digest.hexdigest()


class FamilyCache:
    """Families stored in ``folder`` under their :func:`family_key`.

    Parameters
    ----------
    folder : path-like
        Made on the first store.
    max_bytes : int
        Bound on the folder's ``*.ttfamily`` files (least recently used go first);
        a family larger than this is not stored.
    """

    def __init__(self, folder: str | os.PathLike, max_bytes: int = DEFAULT_MAX_BYTES) -> None:
        self.folder = Path(folder)
        self.max_bytes = int(max_bytes)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}{SUFFIX}"

    def load(self, key: str) -> ParallelogramFamily | None:
        """The family stored under ``key``, or None (missing or damaged: removed)."""
        path = self.path(key)
        try:
            family = _read(path)
        except FileNotFoundError:
            return None
        except (OSError, ValueError, struct.error, TerrathemeError):
            with contextlib.suppress(OSError):
                path.unlink()
            return None
        # most recently used
        with contextlib.suppress(OSError):
            os.utime(path)
        return family

    def store(self, key: str, family: ParallelogramFamily) -> bool:
        """Write ``family`` under ``key`` (atomically), then bound the folder.

        Returns whether it was stored: a folder that cannot be made or written
        (or a full disk) costs the caching, never the frame.
        """
        size = family.buf.nbytes + 4096
        if size > self.max_bytes:
            return False
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.path(key)) as tmp:
                _write(tmp, family)
        except (OSError, TerrathemeError):
            return False
        self.trim(keep=self.path(key))
        return True

    def trim(self, keep: Path | None = None) -> None:
        """Remove the least recently used files until the folder fits ``max_bytes``."""
        files = []
        for p in self.folder.glob(f"*{SUFFIX}"):
            with contextlib.suppress(OSError):
                st = p.stat()
                files.append((st.st_mtime, st.st_size, p))
        total = sum(f[1] for f in files)
        for _, size, p in sorted(files, key=lambda f: f[0]):
            if total <= self.max_bytes:
                break
            if p == keep:
                continue
            with contextlib.suppress(OSError):
                p.unlink()
                total -= size


def _write(path: Path, family: ParallelogramFamily) -> None:
    header = json.dumps({
        "dtype": str(family.buf.dtype), "cells": list(family.buf.shape),
        "grid": list(family.grid_size), "k": family.max_lambda_log2,
        "so": family.skew_oversampling,
    }).encode()
    parts = [_HEADER.pack(MAGIC, FORMAT_VERSION, len(header)), header,
             np.ascontiguousarray(family.buf).data]
    crc = 0
    with open(path, "wb") as f:
        for part in parts:
            f.write(part)
            crc = zlib.crc32(part, crc)
        f.write(struct.pack("<I", crc))


def _whole_numbers(value: object, n: int) -> list[int]:
    """``value`` as a list of ``n`` whole numbers (JSON ints, not bools); ValueError if not."""
    if (not isinstance(value, list) or len(value) != n
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise ValueError(f"not {n} whole numbers")
    return value


def _read(path: Path) -> ParallelogramFamily:
    """Read and check a family file; ValueError (or CorruptFileError) on any damage."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(_HEADER.size)
        magic, version, hlen = _HEADER.unpack(head)
        if magic != MAGIC or version != FORMAT_VERSION or hlen > 4096:
            raise ValueError("not a family file of this version")
        raw = f.read(hlen)
        meta = parse_json(raw, str(path))
        if (not isinstance(meta, dict) or not isinstance(meta.get("dtype"), str)
                or meta["dtype"] not in _TYPES):
            raise ValueError("bad header")
        dtype = np.dtype(_TYPES[meta["dtype"]])
        rows, channels = _whole_numbers(meta.get("cells"), 2)
        w, h = _whole_numbers(meta.get("grid"), 2)
        k, so = _whole_numbers([meta.get("k"), meta.get("so")], 2)
        if not (1 <= channels <= 4 and 0 <= k <= 64 and so in (1, 2) and 1 <= w <= 1 << 20
                and 1 <= h <= 1 << 20 and not w & (w - 1) and not h & (h - 1)):
            raise ValueError("bad header values")
        # the tables follow from the grid and options; they must hold exactly these cells
        start, count, total = family_layout((w, h), k, so)
        n_buf = rows * channels * dtype.itemsize
        if rows != total or _HEADER.size + hlen + n_buf + 4 != size:
            raise ValueError("size does not match the header")
        buf = np.empty((rows, channels), dtype)
        if f.readinto(memoryview(buf).cast("B")) != n_buf:
            raise ValueError("truncated")
        (crc,) = struct.unpack("<I", f.read(4))
    check = zlib.crc32(buf.data, zlib.crc32(raw, zlib.crc32(head)))
    if check != crc:
        raise ValueError("checksum mismatch")
    return ParallelogramFamily(buf, start, count, (w, h), k, so)
