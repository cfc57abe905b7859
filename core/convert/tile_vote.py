"""The tile jobs of the grid path: the vertices each tile owns, and how it votes them.

The jobs are module-level frozen dataclasses holding what they need (the
classifier, the class-to-theme table, the photo and cell sizes), so they
pickle for dask.distributed worker processes; each tile window carries its
own vertex block (:class:`VertexTile`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from terratheme.core.convert.labels_to_grid import grid_shape_for, vertex_window, vote_vertices
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import TileWindow

ClassifyFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class VertexTile(TileWindow):
    """A tile window of the grid path and the block of vertices it owns.

    ``rows``, ``cols``: ``(first, end)`` vertex ranges; the core ``x, y, w, h``
    is their :func:`core.convert.labels_to_grid.vertex_window`.
    """

    rows: tuple[int, int] = (0, 0)
    cols: tuple[int, int] = (0, 0)


def vertex_tiles(
    size: tuple[int, int], cell: tuple[int, int], tile: int, overlap: int
) -> list[VertexTile]:
    """Tile windows, each with the vertex block it owns.

    Parameters
    ----------
    size : (W, H) photo size
    cell : (N, M)
    tile : int
        About this many pixels per tile side (rounded to whole cells).
    overlap : int
        Context pixels read around each tile's vote window.

    Returns
    -------
    tiles : list of VertexTile, row by row
    """
    w, h = size
    n, m = cell
    rows, cols = grid_shape_for(w, h, (n, m))
    out = []
    for vr in _blocks(rows, max(1, int(tile) // m)):
        for vc in _blocks(cols, max(1, int(tile) // n)):
            x, y, ww, hh = vertex_window(vr, vc, (n, m), (w, h))
            rx, ry = max(0, x - overlap), max(0, y - overlap)
            rx1, ry1 = min(w, x + ww + overlap), min(h, y + hh + overlap)
            out.append(VertexTile(x, y, ww, hh, rx, ry, rx1 - rx, ry1 - ry, vr, vc))
    return out


def _blocks(count: int, size: int) -> list[tuple[int, int]]:
    """``(first, end)`` blocks of ``size`` over ``count`` vertices, the last one up to 1.5x long.

    A last block under half a block joins the one before it: a photo of 2^k
    cells has 2^k + 1 vertices, and a tile of one vertex row costs a whole
    read window of context.
    """
    starts = list(range(0, count, size))
    if len(starts) > 1 and count - starts[-1] < size / 2:
        starts.pop()
    return [(s, e) for s, e in zip(starts, [*starts[1:], count], strict=True)]


@dataclass(frozen=True)
class PredictLabels:
    """A classifier as a tile classifier: ``model.predict(pixels).labels`` (it pickles)."""

    model: object

    def __call__(self, pixels: np.ndarray) -> np.ndarray:
        return self.model.predict(pixels).labels


@dataclass(frozen=True)
class VoteJob:
    """The tile job of :func:`grid_from_file`: classify with context, map, crop, vote.

    Attributes
    ----------
    classify : callable((h, w, C) ndarray) -> (h, w) integer ndarray
    table : (256,) uint8 ndarray or None
        Class value -> theme index.
    size : (W, H) photo size
    cell : (N, M)
    """

    classify: ClassifyFn
    table: np.ndarray | None
    size: tuple[int, int]
    cell: tuple[int, int]

    def __call__(self, win: VertexTile, pixels: np.ndarray) -> np.ndarray:
        # Classify with context, map to themes, crop to the vote window, vote.
        labels = np.asarray(self.classify(pixels))
        if labels.shape[:2] != pixels.shape[:2]:
            raise TerrathemeError(
                f"classifier returned {labels.shape} labels for a {pixels.shape[:2]} tile"
            )
        labels = labels.reshape(pixels.shape[:2]).astype(np.uint8)
        if self.table is not None:
            labels = self.table[labels]
        core = labels[win.core_in_read]
        return vote_vertices(core, (win.x, win.y), self.size, self.cell, win.rows, win.cols)
