"""The disk bound of the training caches: least recently used entries go first.

The entries of :class:`core.classify.keyed_store.KeyedStore` are files named
``<key><suffix>`` (a key is 64 lowercase hex digits, every suffix ends in
``.npz``); the sample and model caches may share one folder, and its bound
covers the entries of both. Recency is a file's modification time: a write
sets it, a hit refreshes it (:func:`touch`), and after a write
:func:`evict` removes the oldest entries until the rest fit the bound.
Nothing but entries is counted or removed (the hidden temporaries of atomic
writes, other files in the folder are left alone).

Several processes may share a folder: an entry another one removes between
listing and reading, touching or removing is skipped (a miss when read),
never an error.
"""

from __future__ import annotations

import contextlib
import os
import re
from pathlib import Path

from terratheme.core.errors import TerrathemeError

#: the default bound of a cache folder, in bytes (2 GiB)
DEFAULT_CACHE_BYTES = 2 << 30

_ENTRY = re.compile(r"[0-9a-f]{64}(\.[A-Za-z0-9_-]+)*\.npz")
_SIZE = re.compile(r"(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?", re.IGNORECASE)
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def parse_size(text: str, what: str = "a size") -> int:
    """Bytes of a size written as a number with an optional binary unit.

    ``"2G"`` is 2 GiB, ``"500M"`` 500 MiB, ``"1.5g"`` 1.5 GiB, ``"4096"``
    bytes; K, M, G, T (any case), optionally followed by ``B`` or ``iB``.

    Parameters
    ----------
    text : str
    what : str
        What the size is, for the error message.

    Returns
    -------
    int
        At least 1.

    Raises
    ------
    TerrathemeError
        Not such a number, or less than one byte.
    """
    match = _SIZE.fullmatch(text.strip())
    if match is None:
        raise TerrathemeError(f"{what} must be a number of bytes with an optional unit K, M, "
                              f"G or T (e.g. 2G, 500M), not {text!r}")
    size = int(float(match.group(1)) * _UNITS[match.group(2).lower()])
    if size < 1:
        raise TerrathemeError(f"{what} must be at least one byte, not {text!r}")
    return size


def is_entry(name: str) -> bool:
    """Whether a file name is a cache entry's (``<64 hex digits>[.<word>...].npz``)."""
    return _ENTRY.fullmatch(name) is not None


def touch(path: Path) -> None:
    """Mark the entry ``path`` as just used; nothing if it is gone or cannot be touched
    (a folder shared read-only, another process evicted it)."""
    with contextlib.suppress(OSError):
        os.utime(path)


def entries(folder: Path) -> list[tuple[int, str, int]]:
    """The entries of ``folder``, least recently used first.

    Returns
    -------
    list of (mtime_ns, name, bytes)
        Sorted by time, then name; entries that vanish while listed are left out;
        empty when the folder does not exist.
    """
    found = []
    try:
        with os.scandir(folder) as listing:
            for item in listing:
                if not is_entry(item.name):
                    continue
                try:
                    st = item.stat(follow_symlinks=False)
                except OSError:
                    continue
                if item.is_file(follow_symlinks=False):
                    found.append((st.st_mtime_ns, item.name, st.st_size))
    except FileNotFoundError:
        return []
    return sorted(found)


def evict(folder: Path, max_bytes: int) -> list[str]:
    """Remove the least recently used entries of ``folder`` until the rest fit ``max_bytes``.

    Parameters
    ----------
    folder : Path
    max_bytes : int
        The bound of the entries' total size.

    Returns
    -------
    list of str
        The names removed by this call. One another process removed first
        counts as gone; one that cannot be removed (not ours, in a shared
        folder) stays and the next goes instead.
    """
    listed = entries(folder)
    total = sum(size for _, _, size in listed)
    removed = []
    for _, name, size in listed:
        if total <= max_bytes:
            break
        try:
            (folder / name).unlink()
            removed.append(name)
        except FileNotFoundError:
            pass
        except OSError:
            continue          # not ours to remove (a shared folder): the next one goes
        total -= size
    return removed
