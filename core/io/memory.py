"""Whether a photo's whole-photo work fits in memory, checked before any pixel is read.

A whole-photo command on a huge but legal photo would otherwise run for minutes
before running out of memory; :func:`check_fits` refuses it at once, counting
fewer bytes per pixel than measured so it refuses only what cannot fit.
"""

from __future__ import annotations

from pathlib import Path

import psutil
from terratheme.core.errors import TerrathemeError

try:
    import resource  # Unix only: elsewhere there is no address-space limit to read
except ImportError:  # pragma: no cover - Windows
    resource = None

#: bytes per photo pixel counted for convert's whole-photo path
CONVERT_BYTES_PER_PIXEL = 60
#: bytes per photo pixel counted for classify: unsupervised, with a forest (scribbles,
#: training pairs or a saved model), with the shipped network
CLASSIFY_BYTES_PER_PIXEL = 24
CLASSIFY_FOREST_BYTES_PER_PIXEL = 13
CLASSIFY_NETWORK_BYTES_PER_PIXEL = 10
#: bytes per output pixel counted for render's whole-image (not streamed) path
RENDER_BYTES_PER_PIXEL = 8
#: bytes per frame pixel counted for perspective's CPU filters
PERSPECTIVE_BYTES_PER_PIXEL = 128


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

    ``bytes_per_pixel`` is what the work holds per photo pixel
    (``CONVERT_BYTES_PER_PIXEL``, ...); ``remedy`` is appended to the message;
    ``available`` defaults to :func:`available_memory` (no check where unknown).
    """
    free = available_memory() if available is None else available
    need = width * height * bytes_per_pixel
    if free is not None and need > free:
        raise TerrathemeError(
            f"{name}: {width} x {height} pixels need at least {need / 2**30:.1f} GiB in one "
            f"piece and {free / 2**30:.1f} GiB are free" + (f": {remedy}" if remedy else ""))
