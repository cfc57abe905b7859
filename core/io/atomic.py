"""Atomic file output: write to a temporary file beside the target, then rename.

A failed or interrupted write never leaves a half-written output file, and
never a stray temporary one:

* :func:`atomic_path` yields a hidden temporary path beside one target and
  renames it onto the target on success; on an exception (KeyboardInterrupt
  included) it is removed (``rename=False``: a scratch file, always removed).
* :func:`atomic_file_set` does the same for several files that belong
  together (``convert``'s project, preview and packed layer): all are written
  to temporaries, then renamed in the given order, the manifest/project
  last; if a rename fails, the ones done are undone from hard-linked
  backups, so the old set stays whole. A journal written before the first
  rename lets the next run undo a set whose process was killed mid-commit.
* SIGTERM and SIGHUP (installed when the first temporary is made in the main
  thread, if those signals still have their default action) remove this
  process's temporaries and then terminate as the signal would have.
* SIGKILL cannot be caught: the temporaries it leaves are recognised by
  their names, ``.<name>~tt<host>-<pid>-<token>.<tmp|bak|set>[<suffix>]``,
  and removed (a journal: undone) by the next run that writes into that
  folder -- only when ``<host>`` is this machine and process ``<pid>`` no
  longer exists. Nothing else is ever removed.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import secrets
import shutil
import signal
import socket
import stat
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path

from core.errors import TerrathemeError

#: this machine, as temporaries' names carry it
HOST_TAG = hashlib.sha1(socket.gethostname().encode()).hexdigest()[:8]
#: what a temporary, backup or journal of ours is called
TEMPORARY_NAME = re.compile(
    r"^\.(?P<name>.{1,100})~tt(?P<host>[0-9a-f]{8})-(?P<pid>[1-9][0-9]{0,9})-"
    r"(?P<token>[0-9a-f]{12})\.(?P<kind>tmp|bak|set)(?P<suffix>\.[A-Za-z0-9_-]{1,16})?$")
_SUFFIX = re.compile(r"^\.[A-Za-z0-9_-]{1,16}$")
_TERMINATING = (signal.SIGTERM, signal.SIGHUP)


class _State:
    """Temporaries alive in this process, and signals deferred during a commit."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.live: set[Path] = set()
        self.installed = False
        self.critical = 0
        self.pending: list[int] = []
        self.cleaned: set[Path] = set()


_STATE = _State()


def _remove_live() -> None:
    for tmp in list(_STATE.live):
        with contextlib.suppress(OSError):
            tmp.unlink()
    _STATE.live.clear()


def _on_terminate(signum: int, frame: object) -> None:
    if _STATE.critical:
        _STATE.pending.append(signum)
        return
    # Remove our temporaries, then die of the signal as its default action would.
    _remove_live()
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _install_handlers() -> None:
    if _STATE.installed or threading.current_thread() is not threading.main_thread():
        return
    _STATE.installed = True
    for signum in _TERMINATING:
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, _on_terminate)


@contextlib.contextmanager
def _critical() -> Iterator[None]:
    """Renames and their undoing run whole: SIGTERM/SIGHUP (and, in the main thread,
    Ctrl-C) wait until the section ends."""
    main = threading.current_thread() is threading.main_thread()
    interrupts: list[int] = []
    old_int = signal.getsignal(signal.SIGINT) if main else None
    if main and old_int is signal.default_int_handler:
        signal.signal(signal.SIGINT, lambda s, f: interrupts.append(s))
    _STATE.critical += 1
    try:
        yield
    finally:
        _STATE.critical -= 1
        if main and old_int is signal.default_int_handler:
            signal.signal(signal.SIGINT, old_int)
        if not _STATE.critical and _STATE.pending:
            _on_terminate(_STATE.pending.pop(0), None)
        if interrupts:
            raise KeyboardInterrupt


def _new_name(folder: Path, final_name: str, kind: str, suffix: str, token: str) -> Path:
    suffix = suffix if _SUFFIX.match(suffix or "") else ""
    return folder / f".{final_name[:100]}~tt{HOST_TAG}-{os.getpid()}-{token}.{kind}{suffix}"


def _create(path: Path) -> None:
    fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
    os.close(fd)
    # Give the output the permissions a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def _folder_of(path: Path) -> Path:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise TerrathemeError(f"cannot write {path}: folder {folder} does not exist")
    return folder


def _new_temporary(final: Path, suffix: str | None) -> Path:
    folder = _folder_of(final)
    _clean_once(folder)
    _install_handlers()
    while True:
        tmp = _new_name(folder, final.name, "tmp",
                        final.suffix if suffix is None else suffix, secrets.token_hex(6))
        # Known before it exists: a Ctrl-C or SIGTERM at any point still finds it.
        _STATE.live.add(tmp)
        try:
            _create(tmp)
            return tmp
        except FileExistsError:
            _STATE.live.discard(tmp)
        except BaseException:
            _drop(tmp)
            raise


def _drop(tmp: Path) -> None:
    _STATE.live.discard(tmp)
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None,
                rename: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    Parameters
    ----------
    path : path-like
        The final output file.
    suffix : str, optional
        Suffix of the temporary file (defaults to ``path``'s own suffix, so
        writers that pick a format by extension, like OpenImageIO, still work).
    rename : bool
        False: a scratch file for intermediate data beside ``path``, always
        removed (named and cleaned as every temporary, SIGTERM and SIGKILL included).

    On any exception the temporary file is removed and ``path`` is untouched;
    SIGTERM removes it too (module docstring).
    """
    tmp = None
    try:
        tmp = _new_temporary(Path(path), suffix)
        yield tmp
        if rename:
            os.replace(tmp, path)
    finally:
        if tmp is not None:
            _drop(tmp)


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


@contextlib.contextmanager
def atomic_file_set(paths: Sequence[str | os.PathLike]) -> Iterator[list[Path]]:
    """Write several files of one folder as a set: all replaced, or none.

    Parameters
    ----------
    paths : sequence of path-like
        The final files, in rename order: put the file that names the others
        (the manifest, the project) last, so it never points at a set that
        is not there yet.

    Yields
    ------
    temporaries : list of Path
        One temporary path per final path (same suffix), to write each file to.

    On success every temporary is renamed onto its path, in order. On an
    exception while writing, the temporaries are removed and no path has
    changed. If a rename fails, the renames done are undone (old files back
    from hard-linked backups, new ones removed). A process killed during the
    renames leaves a journal that the next run in the folder uses to undo them.

    Raises
    ------
    TerrathemeError
        No paths, a path given twice, paths in different folders, a missing folder.
    """
    finals = [Path(p) for p in paths]
    if not finals:
        raise TerrathemeError("a file set needs at least one file")
    if len({p.resolve() for p in finals}) != len(finals):
        raise TerrathemeError("a file set names the same file twice")
    folders = {_folder_of(p).resolve() for p in finals}
    if len(folders) != 1:
        raise TerrathemeError("the files of a set must share one folder: "
                              + ", ".join(str(p) for p in finals))
    temps: list[Path] = []
    try:
        for final in finals:
            temps.append(_new_temporary(final, None))
        yield list(temps)
    except BaseException:
        for tmp in temps:
            _drop(tmp)
        raise
    _commit(finals, temps)


def _commit(finals: list[Path], temps: list[Path]) -> None:
    folder = _folder_of(finals[-1])
    token = secrets.token_hex(6)
    journal = _new_name(folder, finals[-1].name, "set", "", token)
    entries = []
    for final, tmp in zip(finals, temps, strict=True):
        backup = _new_name(folder, final.name, "bak", "", token) if final.exists() else None
        entries.append({"final": final.name, "temp": tmp.name,
                        "backup": None if backup is None else backup.name,
                        "inode": os.stat(tmp).st_ino})
    done: list[dict] = []
    with _critical():
        try:
            # Journal first, then backups of the old files, then the renames in order.
            with open(journal, "x", encoding="utf-8") as fh:
                json.dump({"entries": entries}, fh)
            for e in entries:
                if e["backup"] is not None:
                    _link_or_copy(folder / e["final"], folder / e["backup"])
            for e in entries:
                os.replace(folder / e["temp"], folder / e["final"])
                _STATE.live.discard(folder / e["temp"])
                done.append(e)
        except BaseException:
            _undo(folder, entries, renamed=done)
            with contextlib.suppress(FileNotFoundError):
                journal.unlink()
            raise
        journal.unlink()
        for e in entries:
            if e["backup"] is not None:
                with contextlib.suppress(FileNotFoundError):
                    (folder / e["backup"]).unlink()


def _link_or_copy(src: Path, dst: Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _undo(folder: Path, entries: list[dict], renamed: list[dict]) -> list[Path]:
    """Put a set's old files back: renamed entries from backups, the rest untouched."""
    touched = []
    for e in entries:
        final, tmp = folder / e["final"], folder / e["temp"]
        backup = None if e["backup"] is None else folder / e["backup"]
        if e in renamed:
            if backup is not None and backup.exists():
                os.replace(backup, final)
                touched.append(final)
            elif backup is None and _inode(final) == e["inode"]:
                final.unlink()
                touched.append(final)
        for leftover in (tmp, backup):
            if leftover is not None and leftover.exists():
                leftover.unlink()
                _STATE.live.discard(leftover)
                touched.append(leftover)
    return touched


def _inode(path: Path) -> int | None:
    with contextlib.suppress(OSError):
        return os.lstat(path).st_ino
    return None


def _owner_gone(match: re.Match) -> bool:
    if match["host"] != HOST_TAG:
        return False
    pid = int(match["pid"])
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)  # raises ProcessLookupError when no such process
    except ProcessLookupError:
        return True
    except OSError:
        pass
    return False


def _same_owner(name: object, kind: str, journal: re.Match) -> bool:
    match = TEMPORARY_NAME.match(name) if isinstance(name, str) else None
    return bool(match and match["kind"] == kind and match["pid"] == journal["pid"]
                and match["host"] == journal["host"])


def _journal_entries(journal: Path, match: re.Match) -> list[dict] | None:
    """A journal's entries if every name in it is a plain name of the same dead process."""
    try:
        entries = json.loads(journal.read_text(encoding="utf-8"))["entries"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    for e in entries if isinstance(entries, list) else [None]:
        if not (isinstance(e, dict) and isinstance(e.get("final"), str)
                and "/" not in e["final"] and e["final"] not in ("", ".", "..")
                and _same_owner(e.get("temp"), "tmp", match)
                and (e.get("backup") is None or _same_owner(e["backup"], "bak", match))
                and isinstance(e.get("inode"), int)):
            return None
    return entries


def _recover_journal(folder: Path, journal: Path, match: re.Match) -> list[Path]:
    """Undo the renames of a set whose process died mid-commit (module docstring)."""
    entries = _journal_entries(journal, match)
    touched = []
    if entries:
        # A temporary that is gone was renamed onto its final file (all of them
        # existed when the journal was written).
        renamed = [e for e in entries if not (folder / e["temp"]).exists()]
        touched = _undo(folder, entries, renamed)
    journal.unlink()
    return [*touched, journal]


def clean_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporaries dead processes of this machine left in ``folder``.

    Journals of interrupted file sets are undone first (the old files come
    back), then orphaned temporaries and backups are removed. Only regular
    files named as :data:`TEMPORARY_NAME` describes, made on this host by a
    process that no longer exists, are touched.

    Returns
    -------
    touched : list of Path, the files removed or restored
    """
    folder = Path(folder)
    found = []
    with contextlib.suppress(OSError), os.scandir(folder) as it:
        for entry in it:
            match = TEMPORARY_NAME.match(entry.name)
            if match and entry.is_file(follow_symlinks=False) and stat.S_ISREG(
                    entry.stat(follow_symlinks=False).st_mode) and _owner_gone(match):
                found.append((match, folder / entry.name))
    touched: list[Path] = []
    with _critical():
        for match, path in sorted(found, key=lambda f: f[0]["kind"] != "set"):
            with contextlib.suppress(OSError):
                if match["kind"] == "set":
                    touched += _recover_journal(folder, path, match)
                elif path.exists():
                    path.unlink()
                    touched.append(path)
    return touched


def _clean_once(folder: Path) -> None:
    key = folder.resolve()
    with _STATE.lock:
        if key in _STATE.cleaned:
            return
        _STATE.cleaned.add(key)
    clean_stale_temporaries(folder)
