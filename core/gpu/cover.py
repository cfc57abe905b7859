"""Rectangles of cells that one shader pass fills: runs of uniform cells and of blended cells.

The exact GPU render draws every rectangle of uniform cells (the four
corners carry one theme) with a copy shader and every rectangle of blended
cells with the blend shader, so the per-pixel grid reads happen only where
themes meet. Rectangles are horizontal runs of equal cells merged with the
identical runs of the rows below them.
"""

from __future__ import annotations

import numpy as np

#: the rectangle "theme" of blended cells
BLENDED = -1


def cell_rectangles(grid: np.ndarray, splits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cover a block of cells with rectangles of equal cells.

    Parameters
    ----------
    grid : (bh+1, bw+1) uint8 ndarray
        Vertex indices of the block.
    splits : (bh, bw) uint8 ndarray
        Their cells' splits (0 uniform, ``core.render.rules.cell_splits``).

    Returns
    -------
    rects : (R, 4) int32 ndarray
        ``x0, y0, x1, y1`` in cells of the block (half-open); together they
        cover every cell exactly once.
    themes : (R,) int32 ndarray
        The theme of a rectangle of uniform cells, ``BLENDED`` (-1) for
        blended cells.
    """
    bh, bw = splits.shape
    key = np.where(splits == 0, grid[:-1, :-1].astype(np.int32), BLENDED)
    # Horizontal runs: a run starts where the key changes or a row begins.
    starts = np.ones((bh, bw), dtype=bool)
    starts[:, 1:] = key[:, 1:] != key[:, :-1]
    flat = np.flatnonzero(starts)
    rows = flat // bw
    x0 = flat - rows * bw
    # A run ends where the next one starts (every row starts one, so runs stay in their row).
    x1 = np.append(flat[1:], bh * bw) - rows * bw
    kind = key.reshape(-1)[flat]
    # Vertical merge: a run continues the rectangle of the identical run one row up.
    order = np.lexsort((rows, kind, x1, x0))
    r, a, b, k = rows[order], x0[order], x1[order], kind[order]
    cont = np.zeros(len(order), dtype=bool)
    cont[1:] = (a[1:] == a[:-1]) & (b[1:] == b[:-1]) & (k[1:] == k[:-1]) & (r[1:] == r[:-1] + 1)
    first = np.flatnonzero(~cont)
    last = np.append(first[1:], len(order)) - 1
    rects = np.stack([a[first], r[first], b[first], r[last] + 1], axis=1).astype(np.int32)
    return rects, k[first].astype(np.int32)
