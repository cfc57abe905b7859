"""Images larger than memory: tile windows with overlap, bounded-memory tile jobs.

A job reads one window (core plus ``overlap``, clipped) and keeps its core's result, so
memory follows the tile size, not the image. Jobs run serially or on a dask cluster
(:mod:`core.io.cluster`), with the serial run's result bit for bit.
"""

from __future__ import annotations

import contextlib
import enum
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import Bands, image_info, read_region, read_windows

if TYPE_CHECKING:
    from distributed import Client

ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class TileWindow:
    """One tile: its core (the pixels it owns) and the larger window read around it.

    All values are pixels of the full image: ``x, y, w, h`` the core, ``rx, ry, rw, rh``
    the read window (core + overlap, clipped); ``x1, y1, rx1, ry1`` their exclusive ends.
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
        return self.x + self.w

    @property
    def y1(self) -> int:
        return self.y + self.h

    @property
    def rx1(self) -> int:
        return self.rx + self.rw

    @property
    def ry1(self) -> int:
        return self.ry + self.rh

    @property
    def core_in_read(self) -> tuple[slice, slice]:
        """``(rows, cols)`` slices of the core inside the read window's array."""
        oy, ox = self.y - self.ry, self.x - self.rx
        return slice(oy, oy + self.h), slice(ox, ox + self.w)


def tile_windows(
    width: int, height: int, tile: int | tuple[int, int] = 1024, overlap: int = 0
) -> list[TileWindow]:
    """Cover a ``width x height`` image with tiles of ``tile`` (int or (tw, th)) pixels,
    each read with ``overlap`` pixels of context a side (clipped); the last column and
    row of tiles are smaller. Returns the windows row by row, left to right.
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


class Scheduler(enum.Enum):
    """Where tile jobs run in this process (a ``distributed.Client`` runs them on its cluster)."""

    #: one tile after the other in this process
    SERIAL = "serial"


TileJob = Callable[..., object]
TileSink = Callable[[TileWindow, object], None]
TilePart = Callable[[TileWindow], object]


def _run_shared(item: tuple[TileWindow, tuple], shared: tuple) -> object:
    """A tile and its :func:`_part_of` on a cluster worker (``shared``: path, job, dtype, bands)."""
    (win, part), (path, job, dtype, bands) = item, shared
    return job(win, read_region(path, win.rx, win.ry, win.rw, win.rh, dtype=dtype, bands=bands),
               *part)


def _run_given(item: tuple[TileWindow, tuple], job: TileJob) -> object:
    """A tile whose pixels came with it (and its :func:`_part_of`) on a cluster worker."""
    win, (pixels, *part) = item
    return job(win, pixels, *part)


def _part_of(parts: TilePart | None, win: TileWindow) -> tuple:
    return () if parts is None else (parts(win),)


def _describe(win: TileWindow) -> str:
    return f"at ({win.x}, {win.y}) of {win.w} x {win.h}"


def run_tiles(
    path: str | os.PathLike,
    job: TileJob,
    sink: TileSink,
    *,
    tile: int | tuple[int, int] = 1024,
    overlap: int = 0,
    dtype: np.dtype | str | None = None,
    scheduler: Scheduler | Client = Scheduler.SERIAL,
    batch: int | None = None,
    windows: list[TileWindow] | None = None,
    progress: ProgressFn | None = None,
    bands: Bands = Bands.ALL,
    parts: TilePart | None = None,
) -> int:
    """Run ``job(window, pixels)`` on every tile of a file and hand each result to ``sink``.

    ``job`` is a pure function of one (rh, rw, C) tile (it must pickle on a cluster, whose
    workers must run this terratheme and read ``path``, checked first); ``sink(window,
    result)`` is called here in tile order. ``batch``: results in flight on a cluster
    (default 2 per worker thread); ``windows`` replaces the regular tiling;
    ``progress(done, total)`` starts at 0. ``parts(window)`` gives the tile's share of this
    process's data, sent with the tile and passed as ``job(window, pixels, part)``.
    Returns the number of tiles.
    """
    info = image_info(path)
    wins = windows if windows is not None else tile_windows(info.width, info.height, tile, overlap)
    total = len(wins)
    path = str(path)
    if progress is not None:
        progress(0, total)
    boxes = [(w.rx, w.ry, w.rw, w.rh) for w in wins]
    if scheduler is Scheduler.SERIAL:
        # One opening of the file: a JPEG or PNG is decoded once, top to bottom.
        with contextlib.closing(read_windows(path, boxes, dtype=dtype, bands=bands)) as tiles:
            for done, (win, pixels) in enumerate(zip(wins, tiles, strict=True), start=1):
                sink(win, job(win, pixels, *_part_of(parts, win)))
                if progress is not None:
                    progress(done, total)
        return total
    from terratheme.core.io.cluster import check_workers, map_ordered

    # Workers open the file by its absolute path and must run this code: checked first.
    path = os.path.abspath(path)
    check_workers(scheduler, path)
    if not info.tiled:
        # A scanline file (JPEG, PNG: no random access) is read here once, top to bottom,
        # each tile's pixels sent with its task (tasks are submitted in tile order).
        with contextlib.closing(read_windows(path, boxes, dtype=dtype, bands=bands)) as tiles:
            return map_ordered(scheduler, _run_given, wins, job, sink, in_flight=batch,
                               progress=progress, describe=_describe,
                               payload=lambda win: (next(tiles), *_part_of(parts, win)))
    return map_ordered(scheduler, _run_shared, wins, (path, job, dtype, bands), sink,
                       in_flight=batch, progress=progress, describe=_describe,
                       payload=lambda win: _part_of(parts, win))
