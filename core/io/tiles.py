"""Images larger than memory: tile windows with overlap, bounded-memory tile jobs, Dask.

A tile job reads one window of a file (its core plus ``overlap`` pixels on
every side, clipped to the image) through :func:`core.io.images.read_region`,
computes on it, and keeps the core of the result. Peak memory is set by the
tile size and the number of tiles in flight, never by the image size
(``benchmarks/bench_convert.py`` measures it on a 16384 x 16384 TIFF).

The same jobs run serially (default, bounded by one tile) or on Dask
(:class:`Scheduler.DASK`: ``dask.delayed`` tasks computed in batches of
``batch`` tiles, so memory stays bounded there too); :func:`dask_image`
exposes a file as a lazy ``dask.array`` of ``read_region`` blocks for users
who want to write their own array pipeline.

Large outputs are written tile by tile with :class:`TiledImageWriter`
(OpenImageIO tiled TIFF/EXR, BigTIFF when asked).
"""

from __future__ import annotations

import enum
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from core.errors import TerrathemeError
from core.io.atomic import atomic_path
from core.io.images import OIIO_PIXEL_TYPES, Bands, image_info, read_region

ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class TileWindow:
    """One tile: its core (the pixels it owns) and the larger window read around it.

    All values are pixels of the full image: ``x, y, w, h`` the core,
    ``rx, ry, rw, rh`` the read window (core + overlap, clipped to the image).
    """

    x: int
    y: int
    w: int
    h: int
    rx: int
    ry: int
    rw: int
    rh: int

    @property
    def x1(self) -> int:
        """End column of the core (exclusive)."""
        return self.x + self.w

    @property
    def y1(self) -> int:
        """End row of the core (exclusive)."""
        return self.y + self.h

    @property
    def rx1(self) -> int:
        """End column of the read window (exclusive)."""
        return self.rx + self.rw

    @property
    def ry1(self) -> int:
        """End row of the read window (exclusive)."""
        return self.ry + self.rh

    @property
    def core_in_read(self) -> tuple[slice, slice]:
        """``(rows, cols)`` slices of the core inside the read window's array."""
        oy, ox = self.y - self.ry, self.x - self.rx
        return slice(oy, oy + self.h), slice(ox, ox + self.w)


def tile_windows(
    width: int, height: int, tile: int | tuple[int, int] = 1024, overlap: int = 0
) -> list[TileWindow]:
    """Cover a ``width x height`` image with tiles of ``tile`` pixels and ``overlap`` context.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    tile : int or (tw, th)
        Core size of a tile; the last column/row of tiles is smaller.
    overlap : int
        Extra pixels read on each side (clipped at the image border).

    Returns
    -------
    windows : list of TileWindow, row by row, left to right
    """
    tw, th = (tile, tile) if isinstance(tile, int | np.integer) else tile
    tw, th, overlap = int(tw), int(th), int(overlap)
    if width < 1 or height < 1:
        raise TerrathemeError(f"image {width} x {height} has no pixels to tile")
    if tw < 1 or th < 1:
        raise TerrathemeError(f"tile size must be at least 1 x 1, got {tw} x {th}")
    if overlap < 0:
        raise TerrathemeError(f"tile overlap must be >= 0, got {overlap}")
    out = []
    for y in range(0, height, th):
        for x in range(0, width, tw):
            w, h = min(tw, width - x), min(th, height - y)
            rx, ry = max(0, x - overlap), max(0, y - overlap)
            rx1, ry1 = min(width, x + w + overlap), min(height, y + h + overlap)
            out.append(TileWindow(x, y, w, h, rx, ry, rx1 - rx, ry1 - ry))
    return out


def iter_tiles(
    path: str | os.PathLike,
    tile: int | tuple[int, int] = 1024,
    overlap: int = 0,
    *,
    dtype: np.dtype | str | None = None,
) -> Iterator[tuple[TileWindow, np.ndarray]]:
    """Read a file tile by tile: yields ``(window, pixels)`` with ``pixels`` the read window.

    ``pixels`` is ``(rh, rw, C)``; ``pixels[window.core_in_read]`` is the core.
    Only one tile is in memory at a time.
    """
    info = image_info(path)
    for win in tile_windows(info.width, info.height, tile, overlap):
        yield win, read_region(path, win.rx, win.ry, win.rw, win.rh, dtype=dtype)


class Scheduler(enum.Enum):
    """Where tile jobs run."""

    #: one tile after the other in this process
    SERIAL = "serial"
    #: dask.delayed tasks on Dask's default (threaded) scheduler, or a distributed client
    DASK = "dask"


TileJob = Callable[[TileWindow, np.ndarray], object]
TileSink = Callable[[TileWindow, object], None]


def _run_one(path: str, win: TileWindow, job: TileJob, dtype, bands: Bands) -> object:
    return job(win, read_region(path, win.rx, win.ry, win.rw, win.rh, dtype=dtype, bands=bands))


def run_tiles(
    path: str | os.PathLike,
    job: TileJob,
    sink: TileSink,
    *,
    tile: int | tuple[int, int] = 1024,
    overlap: int = 0,
    dtype: np.dtype | str | None = None,
    scheduler: Scheduler = Scheduler.SERIAL,
    batch: int = 4,
    windows: list[TileWindow] | None = None,
    progress: ProgressFn | None = None,
    bands: Bands = Bands.ALL,
) -> int:
    """Run ``job(window, pixels)`` on every tile of a file and hand each result to ``sink``.

    Parameters
    ----------
    path : path-like
        Any image OpenImageIO reads; tiled TIFF/EXR read only the tiles a window touches.
    job : callable(TileWindow, (rh, rw, C) ndarray) -> result
        Pure function of one tile (it may run on a Dask worker).
    sink : callable(TileWindow, result)
        Called in this process, in tile order, with each result (stitch it
        into an array, write it with :class:`TiledImageWriter`, ...).
    tile, overlap : see :func:`tile_windows`
    scheduler : Scheduler
        ``SERIAL`` or ``DASK``.
    batch : int
        Tiles computed together on Dask (bounds the memory of results in flight).
    windows : list of TileWindow, optional
        Run these windows instead of the regular tiling.
    progress : callable(done, total), optional
    bands : Bands
        Which channels each tile holds (``Bands.PHOTO`` for photos).

    Returns
    -------
    n_tiles : int
    """
    info = image_info(path)
    wins = windows if windows is not None else tile_windows(info.width, info.height, tile, overlap)
    total = len(wins)
    path = str(path)
    if scheduler is Scheduler.SERIAL:
        for done, win in enumerate(wins, start=1):
            sink(win, _run_one(path, win, job, dtype, bands))
            if progress is not None:
                progress(done, total)
        return total
    import dask

    # Batches of delayed tasks keep at most ``batch`` results in memory.
    step = max(1, int(batch))
    for start in range(0, total, step):
        part = wins[start : start + step]
        results = dask.compute(*[dask.delayed(_run_one)(path, w, job, dtype, bands)
                                 for w in part])
        for win, res in zip(part, results, strict=True):
            sink(win, res)
        if progress is not None:
            progress(min(total, start + step), total)
    return total


def map_tiles(
    path: str | os.PathLike,
    func: Callable[[np.ndarray], np.ndarray],
    *,
    tile: int | tuple[int, int] = 1024,
    overlap: int = 0,
    dtype: np.dtype | str | None = None,
    out: np.ndarray | TiledImageWriter | None = None,
    scheduler: Scheduler = Scheduler.SERIAL,
    progress: ProgressFn | None = None,
) -> np.ndarray | TiledImageWriter:
    """Apply a per-pixel-window function tile by tile and stitch the tile cores.

    Parameters
    ----------
    func : callable((rh, rw, C) ndarray) -> (rh, rw) or (rh, rw, C') ndarray
        Sees each tile with its overlap; only the core of its result is kept,
        so a filter with a support up to ``overlap`` pixels gives the same
        result as on the whole image.
    out : (H, W[, C']) ndarray, np.memmap or TiledImageWriter, optional
        Where the cores go; default a new in-memory array.

    Returns
    -------
    out : the filled array or writer
    """
    info = image_info(path)
    state: dict = {"out": out}

    def job(win: TileWindow, pixels: np.ndarray) -> np.ndarray:
        res = np.asarray(func(pixels))
        if res.shape[:2] != pixels.shape[:2]:
            raise TerrathemeError(
                f"tile function returned shape {res.shape} for a {pixels.shape[:2]} tile"
            )
        return np.ascontiguousarray(res[win.core_in_read])

    def sink(win: TileWindow, core: np.ndarray) -> None:
        if state["out"] is None:
            state["out"] = np.empty((info.height, info.width, *core.shape[2:]), core.dtype)
        target = state["out"]
        if isinstance(target, TiledImageWriter):
            target.write(win.x, win.y, core)
        else:
            target[win.y : win.y + win.h, win.x : win.x + win.w] = core

    run_tiles(path, job, sink, tile=tile, overlap=overlap, dtype=dtype, scheduler=scheduler,
              progress=progress)
    return state["out"]


def dask_image(
    path: str | os.PathLike, chunk: int = 1024, *, dtype: np.dtype | str | None = None
):
    """The image as a lazy ``dask.array`` of ``(H, W, C)``, one ``read_region`` per chunk.

    Use ``.map_overlap`` / ``.map_blocks`` and compute as usual; nothing is
    read until then.
    """
    import dask
    import dask.array as da

    info = image_info(path)
    want = np.dtype(dtype) if dtype is not None else info.dtype
    rows = []
    for y in range(0, info.height, chunk):
        h = min(chunk, info.height - y)
        row = []
        for x in range(0, info.width, chunk):
            w = min(chunk, info.width - x)
            block = dask.delayed(read_region)(str(path), x, y, w, h, dtype=want)
            row.append(da.from_delayed(block, shape=(h, w, info.channels), dtype=want))
        rows.append(da.concatenate(row, axis=1))
    return da.concatenate(rows, axis=0)


class TiledImageWriter:
    """Write a large image tile by tile through OpenImageIO (bounded memory).

    Use as a context manager; the file appears (atomically renamed) on a
    clean exit only. Regions passed to :meth:`write` must start on tile
    boundaries; their width and height are multiples of the tile size except
    at the right and bottom edges.

    Parameters
    ----------
    path : path-like
        ``.tif`` / ``.tiff`` / ``.exr``.
    width, height, channels : int
    dtype : numpy dtype
    tile : int
        Square tile size of the file (a multiple of 16 for TIFF).
    compression : str, optional
        e.g. ``"zip"`` (default), ``"lzw"``, ``"none"``.
    bigtiff : bool
        Write BigTIFF (needed past 4 GiB).
    attributes : dict, optional
        Extra ImageSpec attributes.
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

    def __enter__(self) -> TiledImageWriter:
        self._ctx = atomic_path(self.path)
        tmp = self._ctx.__enter__()
        out = oiio.ImageOutput.create(str(self.path))
        if out is None or not out.supports("tiles"):
            self._ctx.__exit__(TerrathemeError, None, None)
            raise TerrathemeError(f"cannot write {self.path} tiled: format has no tiles")
        if not out.open(str(tmp), self.spec):
            err = out.geterror().strip()
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
        if arr.shape[2] != s.nchannels or x % s.tile_width or y % s.tile_height:
            raise TerrathemeError(
                f"{self.path}: region at ({x}, {y}) of shape {arr.shape} does not match "
                f"{s.nchannels} channels on a {s.tile_width}-pixel tile grid"
            )
        arr = np.ascontiguousarray(arr, dtype=self.dtype)
        if not self._out.write_tiles(x, x + w, y, y + h, 0, 1, arr):
            raise TerrathemeError(f"cannot write {self.path}: {self._out.geterror().strip()}")

    def __exit__(self, exc_type, exc, tb) -> None:
        ok = self._out.close()
        if exc_type is None and not ok:
            err = TerrathemeError(f"cannot finish {self.path}: {oiio.geterror().strip()}")
            self._ctx.__exit__(TerrathemeError, err, None)
            raise err
        # On success the temporary file is renamed; on an exception it is removed.
        self._ctx.__exit__(exc_type, exc, tb)
