"""Entries by content key: a bounded LRU in memory and one numbers-only file per key.

The storage under :class:`core.classify.sample_cache.SampleCache` (training
samples) and :class:`core.classify.model_cache.ModelCache` (fitted models).
A key is a hex SHA-256 of everything an entry depends on (the caches make
it); the entry's file, ``<key><suffix>`` in the folder, is an ``.npz`` of
arrays that also holds the key itself, read with ``allow_pickle=False`` (no
code runs) and written atomically (:mod:`core.io.atomic`). A file that does
not read back as arrays of its own key (damaged, truncated, renamed) reads as
None: the cache computes the entry again and replaces the file.

The folder is bounded (:mod:`core.classify.cache_bound`): a hit refreshes its
file's time, and after each miss the least recently used entries are removed
until the folder's entries fit ``max_bytes`` (an entry larger than that alone
is kept in memory only). A file another process removes meanwhile is a miss.
"""

from __future__ import annotations

import io
import os
import zipfile
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path

import numpy as np
from terratheme.core.classify.cache_bound import DEFAULT_CACHE_BYTES, evict, touch
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import write_bytes_atomic

#: what np.load raises on a file that is not a whole .npz of plain arrays
_UNREADABLE = (OSError, ValueError, KeyError, UnicodeDecodeError, zipfile.BadZipFile, EOFError)


class KeyedStore:
    """Values by key in memory (least recently used dropped first) and arrays on disk.

    Parameters
    ----------
    directory : path or None
        Folder of the files (made when the first one is written); None: memory only.
    suffix : str
        File name ending after the key (e.g. ``".npz"``).
    memory_entries : int
        Values kept in memory.
    what : str
        What the entries are, for the error message ("training samples").
    max_bytes : int
        Bound of the folder's entries (those of every store sharing it), in bytes.

    Raises
    ------
    TerrathemeError
        ``max_bytes`` below 1.
    """

    def __init__(self, directory: str | os.PathLike | None, suffix: str, memory_entries: int,
                 what: str, max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        if max_bytes < 1:
            raise TerrathemeError(f"the bound of a cache of {what} must be at least one byte, "
                                  f"not {max_bytes}")
        self.directory = None if directory is None else Path(directory)
        self.suffix = suffix
        self.memory_entries = memory_entries
        self.what = what
        self.max_bytes = int(max_bytes)
        self._memory: OrderedDict[str, object] = OrderedDict()
        #: lookups of :meth:`fetch` answered from the store / computed, since creation
        self.hits = 0
        self.misses = 0

    def fetch(self, key: str, names: tuple[str, ...],
              parse: Callable[[dict[str, np.ndarray]], object | None],
              compute: Callable[[], object],
              arrays_of: Callable[[object], dict[str, np.ndarray] | None]) -> object:
        """The value of ``key``: kept (:meth:`lookup`), or ``compute()`` then kept.

        A computed value is remembered, and written as ``arrays_of(value)``
        unless that is None (a value the files cannot hold stays in memory);
        then the folder is brought within its bound.
        """
        found = self.lookup(key, names, parse)
        if found is not None:
            self.hits += 1
            return found
        self.misses += 1
        value = compute()
        self.remember(key, value)
        if self.directory is not None:
            arrays = arrays_of(value)
            if arrays is not None:
                self.write_arrays(key, arrays)
            evict(self.directory, self.max_bytes)
        return value

    def recall(self, key: str) -> object | None:
        """The value kept in memory under ``key`` (now the most recent), or None."""
        found = self._memory.get(key)
        if found is not None:
            self._memory.move_to_end(key)
        return found

    def remember(self, key: str, value: object) -> None:
        """Keep ``value`` in memory under ``key``, dropping the least recent beyond the bound."""
        self._memory[key] = value
        self._memory.move_to_end(key)
        while len(self._memory) > self.memory_entries:
            self._memory.popitem(last=False)

    def lookup(self, key: str, names: tuple[str, ...],
               parse: Callable[[dict[str, np.ndarray]], object | None]) -> object | None:
        """The value of ``key``: from memory, else ``parse`` of its file's arrays ``names``
        (then kept in memory); None when neither has it (or ``parse`` refuses the file's).
        A value found refreshes its file's recency (if it has one)."""
        found = self.recall(key)
        if found is None:
            arrays = self.read_arrays(key, names)
            found = None if arrays is None else parse(arrays)
            if found is not None:
                self.remember(key, found)
        if found is not None and self.directory is not None:
            touch(self.path(key))
        return found

    def path(self, key: str) -> Path | None:
        """The file of ``key`` (None without a folder)."""
        return None if self.directory is None else self.directory / f"{key}{self.suffix}"

    def read_arrays(self, key: str, names: tuple[str, ...]) -> dict[str, np.ndarray] | None:
        """The arrays ``names`` of the file of ``key``, or None.

        None when there is no folder or file, the file does not read as an
        ``.npz`` of plain arrays holding ``names``, or it holds another key.
        """
        path = self.path(key)
        if path is None or not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as npz:
                stored = bytes(npz["key"]).decode("ascii")
                arrays = {name: npz[name] for name in names}
        except _UNREADABLE:
            return None
        return arrays if stored == key else None

    def write_arrays(self, key: str, arrays: dict[str, np.ndarray]) -> None:
        """Write ``arrays`` (and the key) as the file of ``key``, atomically; no-op without
        a folder or when the file would be larger than ``max_bytes``.

        Raises
        ------
        TerrathemeError
            The folder cannot be made or written.
        """
        path = self.path(key)
        if path is None:
            return
        buf = io.BytesIO()
        np.savez(buf, key=np.frombuffer(key.encode("ascii"), np.uint8), **arrays)
        data = buf.getvalue()
        if len(data) > self.max_bytes:
            return            # alone over the bound: memory only
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_bytes_atomic(path, data)
        except OSError as exc:
            raise TerrathemeError(f"{path.parent}: cannot keep {self.what} there "
                                  f"({exc.strerror or exc})") from None


class StoreFront:
    """What a cache over a :class:`KeyedStore` shares: its folder, bound and counters.

    Subclasses name their entries with the class attributes ``SUFFIX``
    (file name ending), ``MEMORY_ENTRIES`` and ``WHAT`` (for messages), and
    reach the store as ``self._store``.

    Parameters
    ----------
    directory : path, optional
        Folder of the entries (made when the first one is written). None: memory only.
    max_bytes : int
        Bound of the folder's entries (this cache's and any other's sharing the
        folder), least recently used removed first (:mod:`core.classify.cache_bound`).
    """

    SUFFIX = ".npz"
    MEMORY_ENTRIES = 1
    WHAT = "entries"

    def __init__(self, directory: str | os.PathLike | None = None,
                 max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self._store = KeyedStore(directory, self.SUFFIX, self.MEMORY_ENTRIES, self.WHAT,
                                 max_bytes)
        self.directory = self._store.directory
        self.max_bytes = self._store.max_bytes

    @property
    def hits(self) -> int:
        """Lookups answered from the cache since creation."""
        return self._store.hits

    @property
    def misses(self) -> int:
        """Lookups computed (not in the cache) since creation."""
        return self._store.misses
