"""A TIFF's strip or tile table checked against its declared size, before OpenImageIO reads it.

libtiff reads a TIFF whose header declares more rows than its strip table covers
without an error (the missing strips come back as zeros or stray bytes), so such a
file is refused here, its tags read with tifffile (warnings silenced).
"""

from __future__ import annotations

import functools
import logging
import math
from pathlib import Path

from terratheme.core.errors import CorruptFileError


def _expected_chunks(page) -> int:
    separate = page.planarconfig == 2 and page.samplesperpixel > 1
    planes = page.samplesperpixel if separate else 1
    if page.is_tiled:
        tw, tl, td = page.tilewidth, page.tilelength, max(1, page.tiledepth or 1)
        return (math.ceil(page.imagewidth / tw) * math.ceil(page.imagelength / tl)
                * math.ceil(max(1, page.imagedepth) / td) * planes)
    rows = page.rowsperstrip if 0 < page.rowsperstrip < page.imagelength else page.imagelength
    return math.ceil(page.imagelength / max(1, rows)) * max(1, page.imagedepth) * planes


def check_tiff_chunks(path: Path) -> None:
    """CorruptFileError if a TIFF's first image lists fewer strips or tiles than its size
    needs (one tifffile cannot parse is left to OpenImageIO); cached by size and mtime."""
    stat = path.stat()
    problem = _chunk_problem(str(path), stat.st_size, stat.st_mtime_ns)
    if problem:
        raise CorruptFileError(f"{path}: {problem}")


@functools.lru_cache(maxsize=64)
def _chunk_problem(path: str, size: int, mtime_ns: int) -> str:
    """What is wrong with the chunk table of the TIFF at ``path`` ("" if nothing)."""
    import tifffile

    log = logging.getLogger("tifffile")
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages.first
            if page.imagewidth <= 0 or page.imagelength <= 0:
                return ""
            want = _expected_chunks(page)
            have = min(len(page.dataoffsets), len(page.databytecounts))
            kind = "tiles" if page.is_tiled else "strips"
            size = (page.imagewidth, page.imagelength)
    except Exception:
        return ""
    finally:
        log.setLevel(level)
    if have < want:
        return (f"TIFF header declares {size[0]} x {size[1]} pixels in {want:,} {kind} but "
                f"lists {have:,}: damaged or forged")
    return ""
