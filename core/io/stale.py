"""Temporaries that dead processes left behind: removed, and half-done file sets undone.

SIGKILL cannot be caught; what it leaves is recognised by name
(:data:`core.io.temporaries.TEMPORARY_NAME`) and cleaned by the next run that
writes into that folder, only when the name says this machine and a process
that no longer exists (:mod:`core.io.atomic`'s docstring).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
from pathlib import Path

from terratheme.core.io.temporaries import (
    HOST_TAG,
    TEMPORARY_NAME,
    critical_section,
    first_visit,
    undo_set,
)


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
        touched = undo_set(folder, entries, renamed)
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
    with critical_section():
        for match, path in sorted(found, key=lambda f: f[0]["kind"] != "set"):
            with contextlib.suppress(OSError):
                if match["kind"] == "set":
                    touched += _recover_journal(folder, path, match)
                elif path.exists():
                    path.unlink()
                    touched.append(path)
    return touched


def clean_once(folder: Path) -> None:
    """:func:`clean_stale_temporaries` the first time this process writes into ``folder``."""
    if first_visit(folder):
        clean_stale_temporaries(folder)
