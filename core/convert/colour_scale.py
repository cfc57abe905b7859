"""The colour map's scale on a window of a photo larger than memory, chosen during the grid stage.

:func:`core.convert.tiled.convert_file_tiled` chooses the map's scale on the
photo's centre window (:func:`core.convert.colour_fit.choose_colour_map`,
the scale choice of docs/design.md's colour map) before fitting the map tile
by tile; that choice needs only the grid's vertices around the window, so on
a cluster it runs while the workers vote the rest (:class:`CentreScale`).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
from terratheme.core.convert.colour_fit import ColourMapOptions, choose_colour_map, grid_window
from terratheme.core.io.tiles import TileWindow
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.renderer import RenderOptions, render_cells


def window_scale(grid: IndexGrid, textures: list[np.ndarray], photo: np.ndarray,
                 window: tuple[int, int, int, int], render: RenderOptions,
                 options: ColourMapOptions = ColourMapOptions()) -> int:
    """The colour map's scale chosen on one window of the photo (:func:`choose_colour_map`).

    Parameters
    ----------
    grid : IndexGrid
        Only its vertices around ``window`` are read (:func:`grid_window`), so
        the choice can start once those are final.
    textures : list of (h, w, 3) uint8 ndarray
    photo : (h, w, 3) uint8 ndarray
        The photo over ``window``.
    window : (x, y, w, h)
    render : RenderOptions

    Returns
    -------
    scale : int
    """
    x, y, w, h = window
    origin, block = grid_window(grid, TileWindow(x, y, w, h, x, y, w, h))
    shown = render_cells(block, textures, grid.cell, region=window, options=render,
                         origin=origin)
    return choose_colour_map(photo, shown, options).colour_map.scale


class CentreScale:
    """The colour map's scale on the centre window, started as soon as its vertices are final.

    On a cluster the choice (about 2 s: a 2048^2 render and the fits of
    :func:`core.convert.colour_fit.choose_colour_map`) runs on a thread of
    this process while the workers vote the rest of the grid, instead of
    between the two tile stages with every worker idle; serially it runs
    after the grid (numba's pools are not shared between threads here). The
    scale is the same either way (:func:`window_scale` reads only the
    finished vertices around the window).
    """

    def __init__(self, textures: list[np.ndarray], photo: np.ndarray,
                 window: tuple[int, int, int, int], render: RenderOptions,
                 options: ColourMapOptions | None, *, background: bool) -> None:
        self._args = (textures, photo, window, render, options)
        self._background = background
        self._future: Future | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._needed: int | None = None

    def _needed_rows(self, grid: IndexGrid) -> int:
        """Vertex rows the window's render reads: to the end of its :func:`grid_window`."""
        if self._needed is None:
            x, y, w, h = self._args[2]
            (r0, _), block = grid_window(grid, TileWindow(x, y, w, h, x, y, w, h))
            self._needed = r0 + block.shape[0]
        return self._needed

    def rows_final(self, grid: IndexGrid, rows: int) -> None:
        """Start the choice once the window's rows are final (``grid_from_file(rows_final=)``)."""
        if not self._background or self._future is not None or rows < self._needed_rows(grid):
            return
        # A copy of the finished rows: the sink goes on writing the ones below.
        done = IndexGrid(grid.indices[:rows].copy(), grid.cell)
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="terratheme-colour-scale")
        self._future = self._pool.submit(window_scale, done, *self._args)

    @property
    def started(self) -> bool:
        """Whether the choice runs (or ran) beside the grid stage."""
        return self._future is not None

    def result(self, grid: IndexGrid) -> int:
        """The scale (waits for the thread, or chooses it now on the whole ``grid``)."""
        if self._future is None:
            return window_scale(grid, *self._args)
        try:
            return self._future.result()
        finally:
            self._pool.shutdown()
