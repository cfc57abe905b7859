"""Whether a photo's whole-photo work fits in memory, checked before any pixel is read.

A command that holds a whole photo and its per-pixel stages at once would
otherwise run for seconds or minutes before running out of memory (a 874 KB
PNG of 30000 x 30000 pixels, legal at 1030:1: convert 77 s, classify 25 s to
the error under an 8 GB cap). :func:`check_fits` refuses it at once, counting
fewer bytes per pixel than measured (peak resident size, start-up taken
off), so it refuses only what cannot fit:

* ``convert`` without ``--tile``: about 88-90 bytes per pixel (0.47 GB for the
  1.2 Mpx sample, 1.44 GB for a 12 Mpx photo, 3.55 GB for the sample tiled to
  6000 x 6000);
* ``classify``: about 26 bytes per pixel unsupervised, 16 with ``--model
  aerial`` (the 6000 x 6000 photo: 1.18 / 0.86 GB, the sample 0.26 GB).
"""

from __future__ import annotations

from pathlib import Path

import psutil
from terratheme.core.errors import TerrathemeError

try:
    import resource  # Unix only: elsewhere there is no address-space limit to read
except ImportError:  # pragma: no cover - Windows
    resource = None

#: bytes per photo pixel counted for convert's whole-photo path (measured about 90)
CONVERT_BYTES_PER_PIXEL = 60
#: bytes per photo pixel counted for classify (measured 16-26)
CLASSIFY_BYTES_PER_PIXEL = 12


def system_available() -> int:
    """Bytes free for a new process: available memory plus free swap (psutil)."""
    return int(psutil.virtual_memory().available + psutil.swap_memory().free)


def _read(path: str) -> str | None:
    try:
        return Path(path).read_text()
    except (OSError, UnicodeDecodeError):
        return None


def _cgroup_free() -> int | None:
    """Bytes left under this cgroup's (v2) memory limit, or None without one."""
    limit, used = _read("/sys/fs/cgroup/memory.max"), _read("/sys/fs/cgroup/memory.current")
    if limit is None or used is None or not limit.strip().isdigit() or not used.strip().isdigit():
        return None
    return max(0, int(limit) - int(used))


def _address_space_free() -> int | None:
    """Bytes of address space left under ``ulimit -v``, or None without a limit."""
    if resource is None:  # pragma: no cover - Windows
        return None
    soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    return max(0, soft - psutil.Process().memory_info().vms)


def available_memory() -> int | None:
    """Bytes this process can still allocate: the least of free memory (with swap), the
    cgroup's limit and the address-space limit; None where none can be read."""
    found = [v for v in (system_available(), _cgroup_free(), _address_space_free())
             if v is not None]
    return min(found) if found else None


def check_fits(name: str, width: int, height: int, bytes_per_pixel: int, *,
               remedy: str = "", available: int | None = None) -> None:
    """Refuse a ``width`` x ``height`` photo whose work cannot fit in free memory.

    Parameters
    ----------
    name : str
        The photo's path, for the message.
    width, height : int
        Photo pixels.
    bytes_per_pixel : int
        What the work holds per photo pixel (``CONVERT_BYTES_PER_PIXEL``, ...).
    remedy : str
        Appended to the message after a colon (e.g. the bounded-memory option).
    available : int, optional
        Bytes free (default :func:`available_memory`; no check where it is unknown).

    Raises
    ------
    TerrathemeError
        ``bytes_per_pixel`` per pixel is more than is free.
    """
    free = available_memory() if available is None else available
    need = width * height * bytes_per_pixel
    if free is not None and need > free:
        raise TerrathemeError(
            f"{name}: {width} x {height} pixels need at least {need / 2**30:.1f} GiB in one "
            f"piece and {free / 2**30:.1f} GiB are free" + (f": {remedy}" if remedy else ""))
