"""Index layers as palette PNGs: written row band by row band, and read back as indices.

A palette PNG stores the indices and shows them in colour (a grey one looks black).
OpenImageIO writes none, so the chunks are written here (ISO/IEC 15948), streamed through
one ``zlib`` compressor: memory is one band. Indices are read back through the file's
PLTE (:mod:`core.io.png`).
"""

from __future__ import annotations

import colorsys
import contextlib
import os
import struct
import zlib
from pathlib import Path

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.images import read_image
from terratheme.core.io.png import SIGNATURE, palette_indices, png_chunk, png_palette

#: Bytes of compressed data gathered before an IDAT chunk is written.
IDAT_BYTES = 1 << 16
#: Largest side a PNG states (the format's 2^31 - 1).
MAX_PNG_SIDE = (1 << 31) - 1


def display_colours(k: int) -> np.ndarray:
    """``(k, 3)`` uint8 distinct colours for an index layer that stores none: hues a golden
    angle apart, two alternating lightness levels, index 0 dark grey."""
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
    """Write an 8-bit palette PNG band by band (a context manager; the file appears on a
    clean exit only). ``colours``: (K <= 256, 3|4) uint8, a 4th column written as tRNS."""

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
        self._fh.write(png_chunk(b"IHDR", struct.pack(">IIBBBBB", self.width, self.height,
                                                   8, 3, 0, 0, 0)))
        self._fh.write(png_chunk(b"PLTE", self.colours[:, :3].tobytes()))
        if self.colours.shape[1] == 4:
            self._fh.write(png_chunk(b"tRNS", self.colours[:, 3].tobytes()))
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
            self._fh.write(png_chunk(b"IDAT", data))
        self._pending, self._pending_bytes = [], 0

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                if self.rows_written != self.height:
                    raise TerrathemeError(
                        f"{self.path}: {self.rows_written} of {self.height} rows written")
                self._pending.append(self._zip.flush())
                self._flush_idat()
                self._fh.write(png_chunk(b"IEND", b""))
            self._fh.close()  # its last flush fails on a full disk: named as the output's
        except BaseException as err:
            with contextlib.suppress(OSError):
                self._fh.close()
            self._ctx.__exit__(type(err), err, err.__traceback__)
            raise
        self._ctx.__exit__(exc_type, exc, tb)


def index_dtype(top: int, path: str | os.PathLike) -> np.dtype:
    """uint8 for a one-channel 32-bit index whose largest value ``top`` is under 256, else
    uint16; a value past 65535 does not fit an index layer (TerrathemeError)."""
    if top > np.iinfo(np.uint16).max:
        raise TerrathemeError(f"{path}: index value {top} does not fit an index layer's 16 bits")
    return np.dtype(np.uint8 if top <= np.iinfo(np.uint8).max else np.uint16)


def read_index_image(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """An image file to pack: a palette PNG as (H, W) uint8 indices and (K, 3|4) colours,
    any other as :func:`core.io.images.read_image` gives it, and None; a one-channel
    uint32 image (unpack's EXR: EXR has no 8- or 16-bit integers) in the narrowest of
    uint8 and uint16 its values fit (:func:`index_dtype`)."""
    image = read_image(path)
    colours = png_palette(path)
    if colours is None:
        if image.dtype == np.uint32 and image.shape[2] == 1:
            image = image.astype(index_dtype(int(image.max()), path))
        return image, None
    return palette_indices(image, colours, os.fspath(path)), colours
