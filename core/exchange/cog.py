"""Tiled GeoTIFFs with overviews in the Cloud Optimized GeoTIFF layout, with bounded memory.

The layout (GDAL's COG definition, checked by its
``validate_cloud_optimized_geotiff.py``): the full-resolution image and its
overviews (each half the size of the one before, ``NewSubfileType = 1``,
down to one tile) are tiled IFDs of one TIFF file; **all IFDs come first**
(the full-resolution one at byte 8, or 16 for BigTIFF), then the tile data,
**smallest overview first** and the full resolution last, so a reader that
fetches the first bytes knows every tile's place and an overview reads from
one contiguous run.

No dependency writes this layout without GDAL: OpenImageIO writes neither
palettes nor overview IFDs before their data, and tifffile writes each
IFD just before its own data. So every level is written by tifffile (its
deflate compression and horizontal predictor, tiles streamed from an
iterator) to a temporary single-image TIFF, and :func:`write_cog` then lays
the levels out: it re-encodes the directories with the new tile offsets and
copies the compressed tiles verbatim (never decoding them). Level ``k + 1``
is made from level ``k`` read back band by band, so memory is bounded by a
band of ``2 * tile`` rows whatever the image size.
"""

from __future__ import annotations

import contextlib
import os
import struct
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

_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8,
              13: 4, 16: 8, 17: 8, 18: 8}
_TILE_OFFSETS, _TILE_BYTE_COUNTS = 324, 325
_LONG, _LONG8 = 4, 16
_PHOTOMETRIC, _COLOR_MAP = 262, 320


#: raw bytes of the largest level :func:`write_cog` can hold (classic TIFF, 32 MiB of headroom)
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

    Parameters
    ----------
    path : path-like
        ``.tif`` output, written atomically.
    band_of : callable(y0, y1) -> (y1 - y0, W[, C]) ndarray
        Rows of the full-resolution image, asked for in ``tile``-row bands, top first.
    size : (W, H)
    channels : int
    dtype : numpy dtype
    tile : int
        Tile side, a multiple of 16.
    photometric : str
        ``"rgb"`` or ``"minisblack"``.
    colormap : (3, 2**bits) uint16 ndarray, optional
        Make a palette image with this colour table (on every level; the
        levels are kept grey while they are made, so their values read back
        unchanged).
    downsample : callable
        :func:`box_half` for pictures, :func:`nearest_half` for class maps.
    extratags : sequence of tifffile extratags
        Written on the full-resolution IFD only (the GeoTIFF tags).
    """
    if tile < 16 or tile % 16:
        raise TerrathemeError(f"TIFF tile size must be a multiple of 16, got {tile}")
    w, h = size
    if w < 1 or h < 1:
        raise TerrathemeError(f"cannot write {path}: image of {w} x {h} pixels is empty")
    final = Path(path)
    dtype = np.dtype(dtype)
    levels = overview_sizes(w, h, tile)
    with contextlib.ExitStack() as stack:
        # The levels go to temporaries beside the output, cleaned as its own (SIGTERM too).
        parts = [stack.enter_context(atomic_path(final, suffix=".tif", rename=False))
                 for _ in levels]
        source = band_of
        for k, (lw, lh) in enumerate(levels):
            # Each level from the bands of the level before it (the first from the caller).
            with tifffile.TiffWriter(parts[k], byteorder="<") as tw:
                shape = (lh, lw) if channels == 1 else (lh, lw, channels)
                tw.write(_tiles(source, (lw, lh), tile, channels, dtype), shape=shape,
                         dtype=dtype, tile=(tile, tile), compression="zlib",
                         predictor=colormap is None, photometric=photometric,
                         subfiletype=1 if k else 0, software="terratheme",
                         extratags=() if k else extratags, metadata=None)
            source = _halving(parts[k], (lw, lh), downsample)
        with atomic_path(final) as out:
            _lay_out(parts, out, _palette_entries(colormap))
    return len(levels) - 1


def _halving(level_path: Path, size: tuple[int, int], downsample: Downsample) -> BandSource:
    """Band source of the next level: rows of ``level_path`` read back in pairs and halved."""
    w, h = size

    def band(y0: int, y1: int) -> np.ndarray:
        top, bottom = 2 * y0, min(h, 2 * y1)
        rows = read_region(level_path, 0, top, w, bottom - top)
        return downsample(rows[:, :, 0] if rows.shape[2] == 1 else rows)

    return band


def _palette_entries(colormap: np.ndarray | None) -> dict[int, tuple[int, int, bytes]]:
    """TIFF entries that make a grey level a palette one: PhotometricInterpretation 3, ColorMap."""
    if colormap is None:
        return {}
    table = np.ascontiguousarray(colormap, dtype="<u2")
    return {_PHOTOMETRIC: (3, 1, struct.pack("<H", 3)),
            _COLOR_MAP: (3, table.size, table.tobytes())}


def _page_entries(path: Path) -> tuple[dict[int, tuple[int, int, bytes]], list[int], list[int]]:
    """``{code: (type, count, raw value)}``, tile offsets and byte counts of a one-image TIFF."""
    with tifffile.TiffFile(path) as tif, open(path, "rb") as fh:
        page = tif.pages.first
        entries = {}
        for tag in page.tags.values():
            if tag.code in (_TILE_OFFSETS, _TILE_BYTE_COUNTS):
                continue
            fh.seek(tag.valueoffset)
            raw = fh.read(_TYPE_SIZE[int(tag.dtype)] * tag.count)
            entries[tag.code] = (int(tag.dtype), tag.count, raw)
        return entries, list(page.dataoffsets), list(page.databytecounts)


def _lay_out(parts: list[Path], out: Path, extra: dict[int, tuple[int, int, bytes]]) -> None:
    """Write the levels of ``parts`` into ``out``: header, all IFDs, then tiles, smallest first.

    ``extra`` entries are added to (or replace those of) every level.
    """
    pages = [_page_entries(p) for p in parts]
    data_bytes = sum(sum(counts) for _, _, counts in pages)
    big = data_bytes + (1 << 24) > (1 << 32) - 1
    head, count_fmt, ptr_fmt, entry, inline = (16, "Q", "Q", 20, 8) if big else (8, "H", "I", 12, 4)
    offset_type = _LONG8 if big else _LONG
    # Each level's entries, with placeholder tile offsets of the right length.
    tables = []
    for entries, offsets, counts in pages:
        table = {**entries, **extra}
        placeholder = bytes(_TYPE_SIZE[offset_type] * len(offsets))
        table[_TILE_OFFSETS] = (offset_type, len(offsets), placeholder)
        table[_TILE_BYTE_COUNTS] = (_LONG, len(counts), struct.pack(f"<{len(counts)}I", *counts))
        tables.append(table)

    def ifd_size(table: dict) -> int:
        spill = sum(len(raw) + len(raw) % 2 for _, _, raw in table.values() if len(raw) > inline)
        return struct.calcsize(count_fmt) + entry * len(table) + struct.calcsize(ptr_fmt) + spill

    ifd_at = [head]
    for table in tables[:-1]:
        ifd_at.append(ifd_at[-1] + ifd_size(table))
    pos = ifd_at[-1] + ifd_size(tables[-1])
    # Tile data positions: the smallest overview first, the full resolution last.
    new_offsets: list[list[int]] = [[] for _ in pages]
    for k in reversed(range(len(pages))):
        for n in pages[k][2]:
            new_offsets[k].append(pos)
            pos += n
    with open(out, "wb") as fh:
        magic = struct.pack("<HHHQ", 43, 8, 0, head) if big else struct.pack("<HI", 42, head)
        fh.write(b"II" + magic)
        for k, table in enumerate(tables):
            fmt = "<Q" if big else "<I"
            table[_TILE_OFFSETS] = (offset_type, len(new_offsets[k]),
                                    b"".join(struct.pack(fmt, o) for o in new_offsets[k]))
            nxt = ifd_at[k + 1] if k + 1 < len(tables) else 0
            fh.write(_encode_ifd(table, ifd_at[k], nxt, count_fmt, ptr_fmt, inline))
        for k in reversed(range(len(pages))):
            _copy_tiles(parts[k], pages[k][1], pages[k][2], fh)


def _encode_ifd(table: dict, at: int, next_ifd: int, count_fmt: str, ptr_fmt: str,
                inline: int) -> bytes:
    """One directory at file offset ``at``: entry table sorted by tag, then its long values."""
    n = len(table)
    spill_at = at + struct.calcsize(count_fmt) + n * (4 + struct.calcsize(ptr_fmt) + inline) \
        + struct.calcsize(ptr_fmt)
    head, spill = bytearray(struct.pack("<" + count_fmt, n)), bytearray()
    for code in sorted(table):
        ttype, count, raw = table[code]
        if len(raw) <= inline:
            value = raw.ljust(inline, b"\0")
        else:
            value = struct.pack("<" + ptr_fmt, spill_at + len(spill))
            spill += raw + b"\0" * (len(raw) % 2)
        head += struct.pack("<HH" + ptr_fmt, code, ttype, count) + value
    head += struct.pack("<" + ptr_fmt, next_ifd)
    return bytes(head + spill)


def _copy_tiles(src: Path, offsets: list[int], counts: list[int], fh) -> None:
    """Append the compressed tiles of ``src`` to ``fh`` in tile order, verbatim."""
    with open(src, "rb") as inp:
        for off, n in zip(offsets, counts, strict=True):
            inp.seek(off)
            chunk = inp.read(n)
            if len(chunk) != n:
                raise TerrathemeError(f"{src}: tile at {off} is truncated")
            fh.write(chunk)
