"""Index layers as palette PNGs: written row band by row band, and read back as indices.

An index layer unpacked to a plain grey PNG looks black (its values are
0..K). A palette PNG (colour type 3) stores the same values, the indices,
and shows them in colour in any viewer or GIS. OpenImageIO writes no palette
PNG and expands one to RGB on reading, so this module writes the format's
chunks itself (signature, IHDR, PLTE, tRNS, IDAT through ``zlib``, IEND;
PNG specification, ISO/IEC 15948) and reads indices back by mapping the
decoded colours through the file's PLTE chunk (:mod:`core.io.png`, the one
palette reader).

Writing streams: rows go through one ``zlib`` compressor into IDAT chunks as
they come, so a 65536 x 65536 layer needs one band in memory, not 4 GiB.
"""

from __future__ import annotations

import colorsys
import os
import struct
import zlib
from pathlib import Path

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.images import read_image
from terratheme.core.io.png import palette_indices, png_palette

SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Bytes of compressed data gathered before an IDAT chunk is written.
IDAT_BYTES = 1 << 16
#: Largest side a PNG states (the format's 2^31 - 1).
MAX_PNG_SIDE = (1 << 31) - 1


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def display_colours(k: int) -> np.ndarray:
    """``k`` distinct colours for an index layer that stores none.

    Hues step by the golden angle (so neighbouring indices differ strongly),
    with two alternating lightness levels; index 0 is a dark grey.

    Returns
    -------
    colours : (k, 3) uint8 ndarray
    """
    out = np.empty((k, 3), np.uint8)
    for i in range(k):
        if i == 0:
            out[i] = (40, 40, 40)
            continue
        hue = (i * 0.618033988749895) % 1.0
        value = 0.95 if i % 2 else 0.7
        out[i] = np.round(np.array(colorsys.hsv_to_rgb(hue, 0.75, value)) * 255)
    return out


class PalettePngWriter:
    """Write an 8-bit palette PNG band by band (use as a context manager).

    The file appears (atomically renamed) on a clean exit only.

    Parameters
    ----------
    path : path-like
    width, height : int
    colours : (K, 3) or (K, 4) uint8 ndarray, K <= 256
        Colour of each index; a 4th column is written as the tRNS chunk.
    level : int
        zlib compression level.
    """

    def __init__(self, path: str | os.PathLike, width: int, height: int, colours: np.ndarray,
                 *, level: int = 6) -> None:
        colours = np.asarray(colours)
        if colours.ndim != 2 or colours.shape[1] not in (3, 4) or not 1 <= len(colours) <= 256:
            raise TerrathemeError(f"palette of shape {colours.shape}: (K <= 256, 3 or 4) expected")
        if not (1 <= width <= MAX_PNG_SIDE and 1 <= height <= MAX_PNG_SIDE):
            raise TerrathemeError(f"cannot write {path}: {width} x {height} is not a PNG size")
        self.path = Path(path)
        self.width, self.height = int(width), int(height)
        self.colours = colours.astype(np.uint8)
        self.rows_written = 0
        self._zip = zlib.compressobj(level)
        self._pending: list[bytes] = []
        self._pending_bytes = 0
        self._ctx = None
        self._fh = None

    def __enter__(self) -> PalettePngWriter:
        self._ctx = atomic_path(self.path)
        tmp = self._ctx.__enter__()
        self._fh = open(tmp, "wb")
        # Signature, header (8-bit indices, colour type 3), palette and transparency.
        self._fh.write(SIGNATURE)
        self._fh.write(_chunk(b"IHDR", struct.pack(">IIBBBBB", self.width, self.height,
                                                   8, 3, 0, 0, 0)))
        self._fh.write(_chunk(b"PLTE", self.colours[:, :3].tobytes()))
        if self.colours.shape[1] == 4:
            self._fh.write(_chunk(b"tRNS", self.colours[:, 3].tobytes()))
        return self

    def write_rows(self, rows: np.ndarray) -> None:
        """Append the next ``(h, width)`` band of indices (top to bottom)."""
        rows = np.asarray(rows)
        if rows.ndim != 2 or rows.shape[1] != self.width or rows.dtype != np.uint8:
            raise TerrathemeError(f"{self.path}: band of shape {rows.shape} and {rows.dtype}, "
                                  f"(h, {self.width}) uint8 expected")
        if self.rows_written + rows.shape[0] > self.height:
            raise TerrathemeError(f"{self.path}: more than {self.height} rows written")
        if rows.size and int(rows.max()) >= len(self.colours):
            raise TerrathemeError(f"{self.path}: index {int(rows.max())} has no palette colour")
        # Each scanline is filter byte 0 (none) then its indices.
        lines = np.zeros((rows.shape[0], self.width + 1), np.uint8)
        lines[:, 1:] = rows
        self._pending.append(self._zip.compress(lines.tobytes()))
        self._pending_bytes += len(self._pending[-1])
        self.rows_written += rows.shape[0]
        if self._pending_bytes >= IDAT_BYTES:
            self._flush_idat()

    def _flush_idat(self) -> None:
        data = b"".join(self._pending)
        if data:
            self._fh.write(_chunk(b"IDAT", data))
        self._pending, self._pending_bytes = [], 0

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                if self.rows_written != self.height:
                    raise TerrathemeError(
                        f"{self.path}: {self.rows_written} of {self.height} rows written")
                self._pending.append(self._zip.flush())
                self._flush_idat()
                self._fh.write(_chunk(b"IEND", b""))
        except BaseException as err:
            self._fh.close()
            self._ctx.__exit__(type(err), err, err.__traceback__)
            raise
        self._fh.close()
        self._ctx.__exit__(exc_type, exc, tb)


def read_index_image(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """An image file to pack: a palette PNG as its indices and colours, any other as it is.

    Returns
    -------
    image : (H, W) uint8 (palette PNG) or (H, W, C) ndarray (:func:`core.io.images.read_image`)
    colours : (K, 3) or (K, 4) uint8 ndarray, or None for a file without a palette
    """
    image = read_image(path)
    colours = png_palette(path)
    if colours is None:
        return image, None
    return palette_indices(image, colours, os.fspath(path)), colours
