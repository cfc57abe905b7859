"""Input paths checked with ``stat`` (which never blocks) before they are opened.

Opening a FIFO blocks until some process writes to it, and a device may never end.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from terratheme.core.errors import TerrathemeError

_KINDS = {stat.S_ISFIFO: "a named pipe (FIFO)", stat.S_ISCHR: "a character device",
          stat.S_ISBLK: "a block device", stat.S_ISSOCK: "a socket"}


def check_input_file(path: str | os.PathLike, what: str = "a file") -> Path:
    """``path`` as a Path, if it names a regular file (symlinks followed); nothing is opened.

    ``what`` says what the file should be, for the message ("an image").
    """
    p = Path(path)
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        raise TerrathemeError(f"{p}: no such file") from None
    except OSError as exc:
        why = "a symlink loop" if exc.errno == errno.ELOOP else exc.strerror or str(exc)
        raise TerrathemeError(f"{p}: cannot be read ({why})") from None
    if stat.S_ISDIR(mode):
        raise TerrathemeError(f"{p}: is a folder, not {what}")
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in _KINDS.items() if test(mode)), "not a regular file")
        raise TerrathemeError(f"{p}: is {kind}, not {what}")
    return p
