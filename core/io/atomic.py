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
import json
import os
import secrets
import shutil
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from terratheme.core.errors import TerrathemeError
from terratheme.core.io.stale import clean_once
from terratheme.core.io.temporaries import (
    critical_section,
    drop,
    forget,
    install_signal_handlers,
    register,
    temporary_name,
    undo_set,
)


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
    clean_once(folder)
    install_signal_handlers()
    while True:
        tmp = temporary_name(folder, final.name, "tmp",
                        final.suffix if suffix is None else suffix, secrets.token_hex(6))
        # Known before it exists: a Ctrl-C or SIGTERM at any point still finds it.
        register(tmp)
        try:
            _create(tmp)
            return tmp
        except FileExistsError:
            forget(tmp)
        except BaseException:
            drop(tmp)
            raise


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
            drop(tmp)


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
            drop(tmp)
        raise
    _commit(finals, temps)


def write_files(writers: Sequence[tuple[str | os.PathLike, Callable[[Path], None]]]) -> None:
    """Write files by their writers: as one set when they share a folder, else one by one.

    Parameters
    ----------
    writers : sequence of (path, writer)
        Each final path and the function that writes the file to the path it is
        given: a temporary of :func:`atomic_file_set` when every path is in one
        folder (all replaced, or none), else the final path itself (each writer
        then writes atomically on its own), in order.
    """
    finals = [Path(p) for p, _ in writers]
    if len(finals) > 1 and len({_folder_of(p).resolve() for p in finals}) == 1:
        with atomic_file_set(finals) as temps:
            for (_, write), tmp in zip(writers, temps, strict=True):
                write(tmp)
        return
    for final, (_, write) in zip(finals, writers, strict=True):
        write(final)


def _commit(finals: list[Path], temps: list[Path]) -> None:
    folder = _folder_of(finals[-1])
    token = secrets.token_hex(6)
    journal = temporary_name(folder, finals[-1].name, "set", "", token)
    entries = []
    for final, tmp in zip(finals, temps, strict=True):
        backup = temporary_name(folder, final.name, "bak", "", token) if final.exists() else None
        entries.append({"final": final.name, "temp": tmp.name,
                        "backup": None if backup is None else backup.name,
                        "inode": os.stat(tmp).st_ino})
    done: list[dict] = []
    with critical_section():
        try:
            # Journal first, then backups of the old files, then the renames in order.
            with open(journal, "x", encoding="utf-8") as fh:
                json.dump({"entries": entries}, fh)
            for e in entries:
                if e["backup"] is not None:
                    _link_or_copy(folder / e["final"], folder / e["backup"])
            for e in entries:
                os.replace(folder / e["temp"], folder / e["final"])
                forget(folder / e["temp"])
                done.append(e)
        except BaseException:
            undo_set(folder, entries, renamed=done)
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


