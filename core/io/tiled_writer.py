"""Writing an image larger than memory tile by tile (OpenImageIO tiled TIFF/EXR, BigTIFF)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.image_format import error_line
from terratheme.core.io.images import OIIO_PIXEL_TYPES, check_written, open_failure


class TiledImageWriter:
    """Write a large image tile by tile through OpenImageIO (bounded memory).

    A context manager; the file appears (renamed) on a clean exit only. Regions given
    to :meth:`write` start on tile boundaries and span whole tiles except at the right
    and bottom edges; full-width bands written from the top are gathered into strips.
    ``path`` is ``.tif``/``.tiff``/``.exr``; ``tile`` a multiple of 16 for TIFF;
    ``bigtiff`` is needed past 4 GiB.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        width: int,
        height: int,
        channels: int,
        dtype: np.dtype | str = np.uint8,
        *,
        tile: int = 256,
        compression: str | None = "zip",
        bigtiff: bool = False,
        attributes: dict | None = None,
    ) -> None:
        self.path = Path(path)
        self.dtype = np.dtype(dtype)
        if self.dtype not in OIIO_PIXEL_TYPES:
            raise TerrathemeError(f"cannot write {path}: pixel type {self.dtype} not supported")
        if width < 1 or height < 1 or channels < 1:
            raise TerrathemeError(f"cannot write {path}: {width} x {height} x {channels} is empty")
        self.spec = oiio.ImageSpec(width, height, channels, OIIO_PIXEL_TYPES[self.dtype])
        self.spec.tile_width = self.spec.tile_height = int(tile)
        if compression:
            self.spec.attribute("compression", compression)
        if bigtiff:
            self.spec.attribute("tiff:bigtiff", 1)
        for key, value in (attributes or {}).items():
            self.spec.attribute(key, value)
        self._ctx = None
        self._out = None
        self._tmp: Path | None = None
        # rows of full-width bands not yet written: one strip of tile height
        self._strip: np.ndarray | None = None
        self._strip_y = 0
        self._strip_rows = 0

    def __enter__(self) -> TiledImageWriter:
        self._ctx = atomic_path(self.path)
        self._tmp = tmp = self._ctx.__enter__()
        out = oiio.ImageOutput.create(str(self.path))
        if out is None or not out.supports("tiles"):
            self._ctx.__exit__(TerrathemeError, None, None)
            raise TerrathemeError(f"cannot write {self.path} tiled: format has no tiles")
        if not out.open(str(tmp), self.spec):
            err = open_failure(self.path, tmp, out)
            self._ctx.__exit__(TerrathemeError, None, None)
            raise TerrathemeError(f"cannot write {self.path}: {err}")
        self._out = out
        return self

    def write(self, x: int, y: int, pixels: np.ndarray) -> None:
        """Write ``pixels`` ``(h, w[, C])`` with its top-left corner at column ``x``, row ``y``."""
        arr = np.asarray(pixels)
        if arr.ndim == 2:
            arr = arr[:, :, None]
        h, w = arr.shape[:2]
        s = self.spec
        if arr.shape[2] != s.nchannels:
            raise TerrathemeError(f"{self.path}: region of shape {arr.shape} does not have the "
                                  f"file's {s.nchannels} channels")
        arr = np.ascontiguousarray(arr, dtype=self.dtype)
        ragged = h % s.tile_height and y + h != s.height
        if x == 0 and w == s.width and (ragged or self._strip_rows or y % s.tile_height):
            self._gather_rows(y, arr)
            return
        if (x % s.tile_width or y % s.tile_height or ragged
                or (w % s.tile_width and x + w != s.width)):
            raise TerrathemeError(f"{self.path}: region at ({x}, {y}) of {w} x {h} pixels is "
                                  f"not on the {s.tile_width}-pixel tile grid")
        self._write_tiles(x, y, arr)

    def _write_tiles(self, x: int, y: int, arr: np.ndarray) -> None:
        h, w = arr.shape[:2]
        if not self._out.write_tiles(x, x + w, y, y + h, 0, 1, arr):
            why = error_line(self._out) or "OpenImageIO refused the tiles"
            raise TerrathemeError(f"cannot write {self.path}: {why}")

    def _gather_rows(self, y: int, arr: np.ndarray) -> None:
        """Add a full-width band to the strip; write each strip as it fills."""
        s = self.spec
        if self._strip is None:
            self._strip = np.empty((s.tile_height, s.width, s.nchannels), self.dtype)
        if not self._strip_rows and y % s.tile_height:
            raise TerrathemeError(f"{self.path}: a band starting at row {y} is not on the "
                                  f"{s.tile_height}-row tile grid")
        if not self._strip_rows:
            self._strip_y = y
        elif y != self._strip_y + self._strip_rows:
            raise TerrathemeError(f"{self.path}: bands must come in order from the top: row "
                                  f"{y} after row {self._strip_y + self._strip_rows - 1}")
        done = 0
        while done < arr.shape[0]:
            # Fill the strip, then write it once it is a whole tile row (or the last one).
            take = min(arr.shape[0] - done, s.tile_height - self._strip_rows)
            self._strip[self._strip_rows:self._strip_rows + take] = arr[done:done + take]
            self._strip_rows += take
            done += take
            if (self._strip_rows == s.tile_height
                    or self._strip_y + self._strip_rows == s.height):
                self._write_tiles(0, self._strip_y, self._strip[:self._strip_rows])
                self._strip_y += self._strip_rows
                self._strip_rows = 0

    def __exit__(self, exc_type, exc, tb) -> None:
        ok = self._out.close()
        if exc_type is None and (self._strip_rows or not ok):
            why = (f"rows from {self._strip_y} on were never written" if self._strip_rows
                   else error_line())
            err = TerrathemeError(f"cannot finish {self.path}: {why}")
            self._ctx.__exit__(TerrathemeError, err, None)
            raise err
        if exc_type is None:
            try:
                check_written(self.path, self._tmp)
            except TerrathemeError as err:
                self._ctx.__exit__(TerrathemeError, err, None)
                raise
        # On success the temporary file is renamed; on an exception it is removed.
        self._ctx.__exit__(exc_type, exc, tb)
