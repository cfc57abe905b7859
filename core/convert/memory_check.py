"""Whether a photo fits in memory on the whole-photo path, checked before any pixel is read.

``convert`` without ``--tile`` holds the photo and its per-pixel stages at
once: its peak grows by about 90 bytes per photo pixel (peak resident size
0.47 GB for the 1.2 Mpx sample, 1.44 GB for a 12 Mpx photo, 3.55 GB for the
sample tiled to 6000 x 6000). A photo that cannot fit would otherwise run for
minutes before running out of memory (a 874 KB PNG of 30000 x 30000 pixels:
77 s to the error under an 8 GB cap). :func:`check_fits` refuses it at once,
counting fewer bytes per pixel than measured, so it refuses only what cannot
fit.
"""

from __future__ import annotations

import resource
from pathlib import Path

from core.errors import TerrathemeError

#: bytes per photo pixel the check counts (measured: about 90; fewer, so no photo that fits
#: is refused)
BYTES_PER_PIXEL = 60
#: the tile size the refusal suggests
SUGGESTED_TILE = 2048


def meminfo_available(text: str) -> int | None:
    """Bytes free for a new process from ``/proc/meminfo`` text: MemAvailable + SwapFree."""
    fields = {}
    for line in text.splitlines():
        name, _, rest = line.partition(":")
        parts = rest.split()
        if parts and parts[0].isdigit():
            fields[name.strip()] = int(parts[0]) * 1024  # kB
    if "MemAvailable" not in fields:
        return None
    return fields["MemAvailable"] + fields.get("SwapFree", 0)


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
    soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    status = _read("/proc/self/status") or ""
    size = next((int(line.split()[1]) * 1024 for line in status.splitlines()
                 if line.startswith("VmSize:")), 0)
    return max(0, soft - size)


def available_memory() -> int | None:
    """Bytes this process can still allocate: the least of free memory (with swap), the
    cgroup's limit and the address-space limit; None where none can be read."""
    found = [v for v in (meminfo_available(_read("/proc/meminfo") or ""), _cgroup_free(),
                         _address_space_free()) if v is not None]
    return min(found) if found else None


def check_fits(name: str, width: int, height: int, available: int | None = None) -> None:
    """Refuse a ``width`` x ``height`` photo the whole-photo path cannot hold.

    Parameters
    ----------
    name : str
        The photo's path, for the message.
    width, height : int
        Photo pixels.
    available : int, optional
        Bytes free (default :func:`available_memory`; no check where it is unknown).

    Raises
    ------
    TerrathemeError
        ``BYTES_PER_PIXEL`` per pixel is more than is free; the message names
        ``--tile``.
    """
    free = available_memory() if available is None else available
    need = width * height * BYTES_PER_PIXEL
    if free is not None and need > free:
        raise TerrathemeError(
            f"{name}: {width} x {height} pixels need at least {need / 2**30:.1f} GiB in one "
            f"piece and {free / 2**30:.1f} GiB are free: convert it tile by tile "
            f"(--tile {SUGGESTED_TILE})")
