"""This process's temporary files: their names, the live ones, the signals that remove them.

The machinery under :mod:`core.io.atomic` (whose docstring tells the whole
story): a temporary is registered before it exists, so SIGTERM or SIGHUP at
any point finds it; renames run in a critical section that defers those
signals (and Ctrl-C in the main thread); a file set's renames are undone
from its journal entries.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import signal
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

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


def install_signal_handlers() -> None:
    """SIGTERM/SIGHUP remove this process's temporaries (once, from the main thread)."""
    if _STATE.installed or threading.current_thread() is not threading.main_thread():
        return
    _STATE.installed = True
    for signum in _TERMINATING:
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, _on_terminate)


@contextlib.contextmanager
def critical_section() -> Iterator[None]:
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


def register(tmp: Path) -> None:
    """Count ``tmp`` among this process's live temporaries (before it exists)."""
    _STATE.live.add(tmp)


def forget(tmp: Path) -> None:
    """``tmp`` is no longer a temporary (renamed onto its final file)."""
    _STATE.live.discard(tmp)


def first_visit(folder: Path) -> bool:
    """True the first time this process asks about ``folder`` (resolved)."""
    key = folder.resolve()
    with _STATE.lock:
        if key in _STATE.cleaned:
            return False
        _STATE.cleaned.add(key)
    return True


def temporary_name(folder: Path, final_name: str, kind: str, suffix: str, token: str) -> Path:
    """The name of a temporary (``kind`` tmp), backup (bak) or journal (set) for ``final_name``."""
    suffix = suffix if _SUFFIX.match(suffix or "") else ""
    return folder / f".{final_name[:100]}~tt{HOST_TAG}-{os.getpid()}-{token}.{kind}{suffix}"


def drop(tmp: Path) -> None:
    """Remove a temporary and forget it."""
    _STATE.live.discard(tmp)
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()


def undo_set(folder: Path, entries: list[dict], renamed: list[dict]) -> list[Path]:
    """Put a set's old files back: renamed entries from backups, the rest untouched."""
    touched = []
    for e in entries:
        final, tmp = folder / e["final"], folder / e["temp"]
        backup = None if e["backup"] is None else folder / e["backup"]
        if e in renamed:
            if backup is not None and backup.exists():
                os.replace(backup, final)
                touched.append(final)
            elif backup is None and inode_of(final) == e["inode"]:
                final.unlink()
                touched.append(final)
        for leftover in (tmp, backup):
            if leftover is not None and leftover.exists():
                leftover.unlink()
                _STATE.live.discard(leftover)
                touched.append(leftover)
    return touched


def inode_of(path: Path) -> int | None:
    """The inode number of ``path`` (not following a link), None if it is gone."""
    with contextlib.suppress(OSError):
        return os.lstat(path).st_ino
    return None
