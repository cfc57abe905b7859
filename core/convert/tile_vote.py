"""The tile jobs of the grid path: the vertices each tile owns, and how it votes them.

Module-level frozen dataclasses, so they pickle for dask.distributed workers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.convert.labels_to_grid import grid_shape_for, vertex_window, vote_vertices
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import TileWindow
from terratheme.core.themes.calm import CalmTwin, class_log_energy, split_calm

ClassifyFn = Callable[[np.ndarray], np.ndarray]
#: a tile's read window starts at a multiple of this many pixels (see :func:`vertex_tiles`)
READ_ALIGN = 32


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
    """Tile windows row by row, each with the vertex block it owns.

    ``size``: (W, H) photo; ``cell``: (N, M); ``tile``: about this many pixels a side
    (whole cells); ``overlap``: context pixels read around each vote window, at least
    (the read window starts on the ``READ_ALIGN`` lattice: a classifier's coarse blocks
    then fall where they fall on the whole photo; a cell of 12 starts its windows off it).
    """
    w, h = size
    n, m = cell
    rows, cols = grid_shape_for(w, h, (n, m))
    out = []
    for vr in _blocks(rows, max(1, int(tile) // m)):
        for vc in _blocks(cols, max(1, int(tile) // n)):
            x, y, ww, hh = vertex_window(vr, vc, (n, m), (w, h))
            # The read window starts on the photo's READ_ALIGN lattice, where a classifier's
            # coarse blocks (8 px features) start on the whole photo too.
            rx = max(0, (x - overlap) // READ_ALIGN * READ_ALIGN)
            ry = max(0, (y - overlap) // READ_ALIGN * READ_ALIGN)
            rx1, ry1 = min(w, x + ww + overlap), min(h, y + hh + overlap)
            out.append(VertexTile(x, y, ww, hh, rx, ry, rx1 - rx, ry1 - ry, vr, vc))
    return out


def _blocks(count: int, size: int) -> list[tuple[int, int]]:
    """``(first, end)`` blocks of ``size`` over ``count`` vertices; a short last one joins.

    A photo of 2^k cells has 2^k + 1 vertices; a one-row tile would cost a read window.
    """
    starts = list(range(0, count, size))
    if len(starts) > 1 and count - starts[-1] < size / 2:
        starts.pop()
    return [(s, e) for s, e in zip(starts, [*starts[1:], count], strict=True)]


def transparent(pixels: np.ndarray) -> bool:
    """Whether an (h, w, C) tile has an alpha band and no opaque pixel (8 bits, as a photo's).

    Such a tile is no data: a classifier has no pixel in it (:func:`prepare_photo` refuses it).
    """
    arr = np.asarray(pixels)
    if arr.ndim != 3 or arr.shape[2] not in (2, 4):
        return False
    return not prepare_photo(arr[:, :, -1:]).rgb.any()


@dataclass(frozen=True)
class PredictLabels:
    """A classifier as a tile classifier: ``model.predict(pixels).labels`` (it pickles).

    A :func:`transparent` tile is label 0 (no data) throughout, as transparent pixels are.
    """

    model: object

    def __call__(self, pixels: np.ndarray) -> np.ndarray:
        if transparent(pixels):
            return np.zeros(np.shape(pixels)[:2], np.uint8)
        return self.model.predict(pixels).labels


@dataclass(frozen=True)
class VoteJob:
    """The tile job of :func:`grid_from_file`: classify with context, map, crop, vote.

    ``classify``: (h, w, C) -> (h, w) labels; ``table``: (256,) uint8 class -> theme or
    None; ``size``: (W, H) photo; ``cell``: (N, M). ``calm``: the table's calm twins; the
    job then returns the vertices voted from its themes and from its twin-split themes
    (split by the tile's pixels; its context must reach ``core.themes.calm.ENERGY_REACH``
    past the classifier's own).
    """

    classify: ClassifyFn
    table: np.ndarray | None
    size: tuple[int, int]
    cell: tuple[int, int]
    calm: tuple[CalmTwin, ...] = ()

    def __call__(self, win: VertexTile,
                 pixels: np.ndarray) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        # Classify with context, map to themes, crop to the vote window, vote.
        labels = np.asarray(self.classify(pixels))
        if labels.shape[:2] != pixels.shape[:2]:
            raise TerrathemeError(
                f"classifier returned {labels.shape} labels for a {pixels.shape[:2]} tile"
            )
        labels = labels.reshape(pixels.shape[:2]).astype(np.uint8)
        if self.table is not None:
            labels = self.table[labels]
        votes = self._vote(labels[win.core_in_read], win)
        if not self.calm:
            return votes
        if transparent(pixels):  # no data: nothing to split
            return votes, votes
        energy = class_log_energy(prepare_photo(pixels).rgb, labels,
                                  [t.theme for t in self.calm], (win.rx, win.ry))
        split = split_calm(labels, self.calm, energy)
        return votes, self._vote(split[win.core_in_read], win)

    def _vote(self, core: np.ndarray, win: VertexTile) -> np.ndarray:
        return vote_vertices(core, (win.x, win.y), self.size, self.cell, win.rows, win.cols)
