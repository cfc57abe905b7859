"""Lone single-vertex specks of a vertex grid, replaced by their neighbours' theme (issue 13).

A vertex none of whose 8 neighbours shares its index renders as a diamond of its theme
in another. Every vertex is judged on the original grid (order-independent); a vertex
with one neighbour of its own, diagonals included, stays, so one-vertex lines (roads)
are kept. :class:`SpeckStream` does the same on a grid filled band by band.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.errors import TerrathemeError

#: vertices cleaned per band of rows (bounded memory on large grids)
_BAND_VERTICES = 1 << 22
#: the 8 neighbour offsets (row, column)
_OFFSETS = tuple((dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0))


def remove_specks(indices: np.ndarray) -> np.ndarray:
    """(rows, cols) uint8: a new grid, each lone vertex given its neighbours' most frequent index.

    Ties go to the lowest index; every other vertex, and a one-vertex grid, is unchanged.
    """
    grid = _check_grid(indices)
    rows, cols = grid.shape
    out = np.empty_like(grid)
    band = max(1, _BAND_VERTICES // max(cols, 1))
    for r0 in range(0, rows, band):
        r1 = min(rows, r0 + band)
        top = max(r0 - 1, 0)
        out[r0:r1] = clean_rows(grid[top:min(r1 + 1, rows)], r0 - top, r1 - top)
    return out


def clean_rows(window: np.ndarray, first: int, end: int) -> np.ndarray:
    """(end-first, cols) uint8: rows ``first .. end-1`` of ``window`` cleaned.

    ``window``: (h, cols) uint8 consecutive rows, with the rows above and below where the
    grid has them (a window's edge is taken for the grid's).
    """
    h, cols = window.shape
    # -1 around the window: no neighbour there.
    padded = np.full((h + 2, cols + 2), -1, np.int16)
    padded[1:-1, 1:-1] = window
    centre = padded[1 + first:1 + end, 1:-1]
    neighbours = [padded[1 + first + dy:1 + end + dy, 1 + dx:1 + cols + dx]
                  for dy, dx in _OFFSETS]
    shared = np.zeros(centre.shape, bool)
    present = np.zeros(centre.shape, bool)
    for nb in neighbours:
        shared |= nb == centre
        present |= nb >= 0
    out = window[first:end].copy()
    lone = np.nonzero(present & ~shared)
    if lone[0].size == 0:
        return out
    around = np.stack([nb[lone] for nb in neighbours], axis=1).astype(np.int32)  # (n, 8)
    # How many neighbours share each neighbour's index; the most wins, then the lowest index
    # (absent neighbours, -1, never win: some neighbour is present).
    count = (around[:, :, None] == around[:, None, :]).sum(axis=2)
    key = np.where(around >= 0, count * 512 + (255 - around), -1)
    out[lone] = around[np.arange(around.shape[0]), key.argmax(axis=1)].astype(np.uint8)
    return out


class SpeckStream:
    """Clean an (rows, cols) uint8 grid in place as its rows become final, top to bottom.

    Rows are written in order and never again once final (the tiled sink). Row ``r`` is
    cleaned once row ``r+1`` is final; the result equals :func:`remove_specks`.
    """

    def __init__(self, indices: np.ndarray) -> None:
        self._grid = _check_grid(indices)
        self._done = 0
        self._above: np.ndarray | None = None  # the original of row done-1

    def advance(self, final: int) -> int:
        """Clean what the first ``final`` final (original) rows allow; returns :attr:`cleaned`."""
        rows = self._grid.shape[0]
        end = rows if final >= rows else final - 1
        start = self._done
        if end <= start:
            return start
        below = min(end + 1, rows)
        window = self._grid[start:below]
        if self._above is not None:
            window = np.concatenate([self._above[None, :], window])
        first = 0 if self._above is None else 1
        cleaned = clean_rows(window, first, first + end - start)
        self._above = self._grid[end - 1].copy()
        self._grid[start:end] = cleaned
        self._done = end
        return end

    def finish(self) -> np.ndarray:
        """Clean every row left (all rows final); returns the grid."""
        self.advance(self._grid.shape[0])
        return self._grid


def _check_grid(indices: np.ndarray) -> np.ndarray:
    grid = np.asarray(indices)
    if grid.ndim != 2 or grid.dtype != np.uint8:
        raise TerrathemeError(
            f"vertex indices must be a 2-D uint8 array, got {grid.dtype} of shape {grid.shape}"
        )
    return grid
