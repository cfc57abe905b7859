"""Tiled GeoTIFFs with overviews in the Cloud Optimized GeoTIFF layout, with bounded memory.

GDAL's COG layout: the full image and its halving overviews are tiled IFDs, all IFDs
first, then the tiles, smallest overview first. tifffile writes each IFD before its own
data, so :func:`write_cog` writes every level to a temporary TIFF (each from the last,
band by band: memory is a band of ``2 * tile`` rows), then the output's IFDs without
data, then the compressed tiles copied after them with ``TileOffsets`` set in place.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import cv2
import numpy as np
import tifffile
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.images import read_region

#: ``band(y0, y1)``: rows ``y0..y1`` of the full-resolution image, ``(y1 - y0, W[, C])``
BandSource = Callable[[int, int], np.ndarray]
#: a band of a level (even row count except the last) -> the band of the next level
Downsample = Callable[[np.ndarray], np.ndarray]

#: raw bytes of the largest level :func:`write_cog` can hold (classic TIFF, 32 MiB of headroom);
#: the output is a BigTIFF when its compressed tiles pass it
MAX_LEVEL_BYTES = (1 << 32) - (1 << 25)


def box_half(band: np.ndarray) -> np.ndarray:
    """Half-size band: 2 x 2 means (odd sizes: the last row/column repeated first), for pictures."""
    h, w = band.shape[:2]
    padded = cv2.copyMakeBorder(band, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
    half = cv2.resize(padded, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
    return half.reshape(((h + 1) // 2, (w + 1) // 2) + band.shape[2:])


def nearest_half(band: np.ndarray) -> np.ndarray:
    """Half-size band: every other pixel (for class maps, whose values are not averaged)."""
    return np.ascontiguousarray(band[::2, ::2])


def overview_sizes(width: int, height: int, tile: int) -> list[tuple[int, int]]:
    """``(w, h)`` of the full image and of every overview, halving until one tile holds it."""
    sizes = [(width, height)]
    while max(sizes[-1]) > tile:
        w, h = sizes[-1]
        sizes.append(((w + 1) // 2, (h + 1) // 2))
    return sizes


def _tiles(band_of: BandSource, size: tuple[int, int], tile: int, channels: int,
           dtype: np.dtype) -> Iterator[np.ndarray]:
    """Tiles of an image row by row, padded to full tiles, from bands of ``tile`` rows."""
    w, h = size
    for y0 in range(0, h, tile):
        band = band_of(y0, min(h, y0 + tile)).reshape(-1, w, channels)
        for x0 in range(0, w, tile):
            block = np.zeros((tile, tile, channels), dtype=dtype)
            part = band[:, x0 : x0 + tile]
            block[: part.shape[0], : part.shape[1]] = part
            yield block[:, :, 0] if channels == 1 else block


def write_cog(
    path: str | os.PathLike,
    band_of: BandSource,
    size: tuple[int, int],
    *,
    channels: int,
    dtype: np.dtype | type = np.uint8,
    tile: int = 512,
    photometric: str = "rgb",
    colormap: np.ndarray | None = None,
    downsample: Downsample = box_half,
    extratags: Sequence[tuple] = (),
) -> int:
    """Write an image made band by band as a COG-layout tiled TIFF; returns the overview count.

    ``band_of(y0, y1)`` gives rows ``(y1 - y0, W[, C])`` of the full image in ``tile``-row
    bands (``tile`` a multiple of 16), top first. ``colormap`` (3, 2**bits) uint16 makes a
    palette image on every level; ``downsample`` is :func:`box_half` for pictures,
    :func:`nearest_half` for class maps; ``extratags`` (the GeoTIFF tags) go on the
    full-resolution IFD only.
    """
    if tile < 16 or tile % 16:
        raise TerrathemeError(f"TIFF tile size must be a multiple of 16, got {tile}")
    w, h = size
    if w < 1 or h < 1:
        raise TerrathemeError(f"cannot write {path}: image of {w} x {h} pixels is empty")
    final = Path(path)
    dtype = np.dtype(dtype)
    levels = overview_sizes(w, h, tile)
    shapes = [(lh, lw) + ((channels,) if channels > 1 else ()) for lw, lh in levels]
    common = {"dtype": dtype, "tile": (tile, tile), "compression": "zlib",
              "predictor": colormap is None, "software": "terratheme", "metadata": None}
    with contextlib.ExitStack() as stack:
        # The levels go to temporaries beside the output, cleaned as its own (SIGTERM too).
        parts = [stack.enter_context(atomic_path(final, suffix=".tif", rename=False))
                 for _ in levels]
        source = band_of
        for k, (lw, lh) in enumerate(levels):
            # Each level from the bands of the level before it (the first from the caller).
            with tifffile.TiffWriter(parts[k], byteorder="<") as tw:
                tw.write(_tiles(source, (lw, lh), tile, channels, dtype), shape=shapes[k],
                         photometric=photometric, **common)
            source = _halving(parts[k], (lw, lh), downsample)
        pages = [stack.enter_context(tifffile.TiffFile(p)).pages.first for p in parts]
        big = sum(sum(p.databytecounts) for p in pages) > MAX_LEVEL_BYTES
        with atomic_path(final) as out:
            # The IFDs: tifffile counts each tile's bytes from (b"", count) and writes none.
            with tifffile.TiffWriter(out, bigtiff=big, byteorder="<") as tw:
                for k, page in enumerate(pages):
                    tw.write(((b"", n) for n in page.databytecounts), shape=shapes[k],
                             photometric=photometric if colormap is None else "palette",
                             colormap=colormap, subfiletype=1 if k else 0,
                             extratags=() if k else extratags, **common)
            offsets = _append_tiles(pages, out)
            with tifffile.TiffFile(out, mode="r+b") as tif:
                for page, new in zip(tif.pages, offsets, strict=True):
                    page.tags["TileOffsets"].overwrite(new)
    return len(levels) - 1


def _halving(level_path: Path, size: tuple[int, int], downsample: Downsample) -> BandSource:
    """Band source of the next level: rows of ``level_path`` read back in pairs and halved."""
    w, h = size

    def band(y0: int, y1: int) -> np.ndarray:
        top, bottom = 2 * y0, min(h, 2 * y1)
        rows = read_region(level_path, 0, top, w, bottom - top)
        return downsample(rows[:, :, 0] if rows.shape[2] == 1 else rows)

    return band


def _append_tiles(pages: list[tifffile.TiffPage], out: Path) -> list[list[int]]:
    """Append the levels' compressed tiles to ``out``, smallest level first; their new offsets."""
    offsets: list[list[int]] = [[] for _ in pages]
    with open(out, "r+b") as fh:
        pos = fh.seek(0, os.SEEK_END)
        for k in reversed(range(len(pages))):
            page = pages[k]
            # One tile a read (buffersize 0): memory stays one tile whatever the level's size.
            for chunk, _ in page.parent.filehandle.read_segments(
                    page.dataoffsets, page.databytecounts, sort=False, buffersize=0):
                offsets[k].append(pos)
                pos += fh.write(chunk)
    return offsets
