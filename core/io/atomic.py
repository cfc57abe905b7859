"""Output files: each written to a temporary beside it, flushed to disk, then renamed onto it.

A reader never sees half a file, and a failed run changes no file. :func:`file_set`
writes files that belong together, the last one (a project, a manifest) naming the
others: under a lock on each folder the old last file is removed, the others are
renamed and the last one last, so a reader trusts a set only when its last file is
there. Only temporaries this process made are ever removed; nothing here reads,
repairs or removes what it finds in a folder.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

from terratheme.core.errors import TerrathemeError

try:
    import fcntl
except ImportError:  # not POSIX: concurrent commits are not serialised
    fcntl = None

_LOCK = threading.RLock()  # re-entrant: a signal handler may run while it is held
#: temporaries this process made and has not yet renamed or removed
_LIVE: set[Path] = set()
#: open file sets by the final paths they hold
_OPEN: dict[Path, FileSet] = {}
#: set by :func:`refuse_commits`: no output is renamed into place after it
_REFUSED = threading.Event()


def _key(path: Path) -> Path:
    """``path`` with its folder resolved (the file itself may be a link we replace)."""
    try:
        return Path(os.path.realpath(path.parent)) / path.name
    except (OSError, RuntimeError):
        return Path(os.path.abspath(path))


def special_file(path: str | os.PathLike) -> str | None:
    """What ``path`` is when it is neither a regular file, a link nor absent (a pipe, a
    device, a socket): the rename would replace it, so no output goes there."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode) or stat.S_ISDIR(mode):
        return None
    return ("a pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a device")


def missing_folders(paths: Iterable[str | os.PathLike]) -> list[Path]:
    """The folders that writing ``paths`` would have to make (absent now), deepest first."""
    missing = {d for p in paths for d in Path(p).parents if not os.path.lexists(d)}
    return sorted(missing, key=lambda d: len(d.parts), reverse=True)


def remove_empty_folders(folders: Iterable[Path]) -> None:
    """Remove each of ``folders`` (give them deepest first) that nothing has been put in."""
    for folder in folders:
        with contextlib.suppress(OSError):
            folder.rmdir()


def _new_temporary(final: Path, suffix: str | None) -> Path:
    folder = final.parent
    if not folder.is_dir():
        raise TerrathemeError(f"cannot write {final}: folder {folder} does not exist")
    kind = special_file(final)
    if kind is not None:
        raise TerrathemeError(f"{final}: is {kind}, not a file to write")
    suffix = final.suffix if suffix is None else suffix
    suffix = suffix if suffix[1:].isalnum() and len(suffix) <= 17 else ""
    while True:
        tmp = folder / f".{final.name[:100]}.tt-{secrets.token_hex(6)}.tmp{suffix}"
        with _LOCK:
            _LIVE.add(tmp)  # known before it exists: a signal handler always finds it
        try:
            # The umask applies, as for a plain open().
            fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            _forget(tmp)
            continue
        except BaseException:
            _forget(tmp)
            raise
        try:
            os.close(fd)
        except BaseException:  # Ctrl-C just after it was made
            _drop(tmp)
            raise
        return tmp


def refuse_commits() -> None:
    """Make every later commit raise KeyboardInterrupt, its temporaries removed.

    For a Ctrl-C handler: a library may swallow the KeyboardInterrupt the handler raises
    (imagecodecs' input check under tifffile's zlib tiles does), and the run would then
    finish and replace the outputs the user meant to keep.
    """
    _REFUSED.set()


def _check_refused() -> None:
    if _REFUSED.is_set():
        raise KeyboardInterrupt


def _forget(tmp: Path) -> None:
    with _LOCK:
        _LIVE.discard(tmp)


def _drop(tmp: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    _forget(tmp)


def remove_temporaries() -> None:
    """Remove every temporary this process made and still holds (for a SIGTERM handler)."""
    with _LOCK:
        live = list(_LIVE)
        _LIVE.clear()
    for tmp in live:
        with contextlib.suppress(OSError):
            tmp.unlink()


def _fsync(path: Path, final: Path) -> None:
    """Flush a written temporary to disk; a late write error (full disk) is raised here."""
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        raise TerrathemeError(f"cannot write {final}: {exc.strerror or exc}") from None


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None,
                rename: bool = True) -> Iterator[Path]:
    """Yield a new temporary path beside ``path``; flush and rename it onto ``path`` on success.

    ``suffix`` is the temporary's (default ``path``'s own, for writers that pick a
    format by extension); ``rename=False`` makes a scratch file, always removed. On
    any exception the temporary is removed. Inside a :func:`file_set` holding
    ``path``, the set's temporary is yielded and renamed when the set commits.
    """
    final = Path(path)
    owner = _OPEN.get(_key(final)) if rename else None
    if owner is not None:
        yield owner.temporary(final)
        return
    tmp = _new_temporary(final, suffix)
    try:
        with _naming(lambda: {"": final, str(tmp): final}):
            yield tmp
        if rename:
            _fsync(tmp, final)
            _check_refused()
            os.replace(tmp, final)
            _forget(tmp)
            _fsync_folder(final.parent)
    finally:
        if tmp in _LIVE:
            _drop(tmp)


#: what only a write raises: such an error naming no file is the output's
_WRITE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


@contextlib.contextmanager
def _naming(finals: Callable[[], dict[str, Path]]) -> Iterator[None]:
    """An OSError naming a temporary, or a full disk naming no file (zipfile's), names the
    output: ``finals()`` maps temporaries (as str; "" for no name) to their final paths."""
    try:
        yield
    except OSError as exc:
        if exc.filename is None and exc.errno not in _WRITE_ERRORS:
            raise
        final = finals().get("" if exc.filename is None else str(exc.filename))
        if exc.errno is None or final is None:
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(final)) from exc


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


class FileSet:
    """The temporaries of an open :func:`file_set`, made when first asked for."""

    def __init__(self, finals: list[Path]) -> None:
        self.finals = finals
        self._temps: dict[Path, Path] = {}

    def temporary(self, final: str | os.PathLike) -> Path:
        """The temporary that becomes ``final`` (one of the set's paths) on commit."""
        named = [f for f in self.finals if _key(f) == _key(Path(final))]
        if not named:
            raise TerrathemeError(f"{final}: not one of the files of this set")
        final = named[0]
        if final not in self._temps:
            self._temps[final] = _new_temporary(final, None)
        return self._temps[final]

    def discard(self) -> None:
        """Remove the temporaries not renamed yet."""
        for tmp in self._temps.values():
            if tmp in _LIVE:
                _drop(tmp)

    def commit(self, remove: Sequence[Path] = ()) -> None:
        """Rename the written members in order and the last file last (module docstring).

        ``remove``: files of the old set the new one has not, removed with the old last file.
        """
        last = self.finals[-1]
        if last not in self._temps:
            raise TerrathemeError(f"{last}: not written, so the files of its set are left as "
                                  "they were")
        for final, tmp in self._temps.items():
            _fsync(tmp, final)
        _check_refused()
        members = [f for f in self.finals[:-1] if f in self._temps]
        folders = sorted({os.path.realpath(f.parent) for f in self.finals})
        with contextlib.ExitStack() as locks:
            for folder in folders:
                locks.enter_context(_folder_lock(folder))
            if members or remove:
                # From here until the last rename, no set is there for a reader to trust.
                for old in (last, *remove):
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(old)
            for final in members:
                os.replace(self._temps[final], final)
                _forget(self._temps[final])
            for folder in folders:
                _fsync_folder(Path(folder))
            os.replace(self._temps[last], last)
            _forget(self._temps[last])
            _fsync_folder(last.parent)


@contextlib.contextmanager
def _folder_lock(folder: str) -> Iterator[None]:
    """An advisory lock on a folder, so concurrent runs commit one set after the other."""
    fd = None
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)


@contextlib.contextmanager
def file_set(paths: Sequence[str | os.PathLike], *,
             remove: Sequence[str | os.PathLike] = ()) -> Iterator[FileSet]:
    """Write several files as a set: all replaced, or none as a reader sees it.

    ``paths`` are in rename order, the one naming the others last (it must be
    written; a member never written keeps its old file). ``remove``: files of the
    old set the new one lacks, removed on commit with the old last file. Write each
    file to ``.temporary(path)`` of the yielded :class:`FileSet`, or through
    :func:`atomic_path` on its path. On an exception no file has changed.
    """
    finals = [Path(p) for p in paths]
    keys = [_key(p) for p in finals]
    if not finals:
        raise TerrathemeError("a file set needs at least one file")
    if len(set(keys)) != len(keys):
        raise TerrathemeError("a file set names the same file twice")
    files = FileSet(finals)
    with _LOCK:
        if any(k in _OPEN for k in keys):
            raise TerrathemeError("a file is already being written by another set")
        _OPEN.update(dict.fromkeys(keys, files))
    try:
        # A full disk naming no file is the file being written: the newest temporary's.
        with _naming(lambda: {str(t): f for f, t in files._temps.items()}
                     | ({"": next(reversed(files._temps))} if files._temps else {})):
            yield files
        files.commit([Path(p) for p in remove])
    finally:
        with _LOCK:
            for k in keys:
                _OPEN.pop(k, None)
        files.discard()
