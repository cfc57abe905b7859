"""One random-access table over all the tiles of a tiled layer (docs/formats.md, P3).

The tiles' grids side by side, their spans and runs end to end with offsets shifted,
so the single-layer kernels read a tiled layer with no tile arithmetic. A container
joins when its tiles share one grid block side and its offsets fit the table's words;
otherwise its tiles are looked up through their own tables.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.curves.steps import HILBERT_TABLES
from terratheme.core.packing.layout import (
    HEAD_WORDS,
    JOINED,
    MORTON_BLOCK,
    SPAN_LAST,
    SPAN_OFFSET_MASK,
    TABLE_AT,
    UNIFORM,
    W_COUNT,
    W_GRID,
    W_GRID_BITS,
    W_GRID_HEIGHT,
    W_GRID_WIDTH,
    W_MORTON,
    W_RUNS,
    W_SPANS,
)


def join_tables(tables: list[np.ndarray], width: int, height: int, tile_bits: int,
                across: int) -> np.ndarray | None:
    """The joined ``uint32`` table of a tiled layer's tiles, or None when they cannot be joined.

    ``tables`` are the tiles' tables, rows of tiles from the top-left, ``across`` a row;
    ``width, height`` the layer's size, ``tile_bits`` log2 of the tile side. None when the
    grid block sides differ or the spans (2^27 words) or runs (2^31 - 1) overflow.
    """
    heads = np.stack([t[:HEAD_WORDS] for t in tables]).astype(np.int64)
    gb = int(heads[0, W_GRID_BITS])
    spans_n = heads[:, W_RUNS] - heads[:, W_SPANS]
    if (np.any(heads[:, W_GRID_BITS] != gb) or spans_n.sum() > SPAN_OFFSET_MASK
            or heads[:, W_COUNT].sum() >= SPAN_LAST):
        return None
    down = len(tables) // across
    per_tile = 1 << (tile_bits - gb)          # grid words along a full tile's side
    last_rows = int(heads[-1, W_GRID_HEIGHT])  # grid rows of the last tile row
    gw = -(-width >> gb)
    gh = last_rows + (down - 1) * per_tile
    span_at = np.cumsum(spans_n) - spans_n
    run_at = np.cumsum(heads[:, W_COUNT]) - heads[:, W_COUNT]
    grid = np.empty((gh, gw), np.uint32)
    spans, runs = [], []
    for i, t in enumerate(tables):
        ty, tx = divmod(i, across)
        h = heads[i]
        g = t[h[W_GRID]: h[W_SPANS]].reshape(h[W_GRID_HEIGHT], h[W_GRID_WIDTH])
        # Not uniform: span offset shifted past the earlier tiles' spans, Morton flagged.
        shifted = (g + np.uint32(span_at[i] << 3)) | np.uint32(
            MORTON_BLOCK if h[W_MORTON] else 0)
        row0 = 0 if ty == down - 1 else last_rows + (down - 2 - ty) * per_tile
        col0 = tx * per_tile
        grid[row0: row0 + g.shape[0], col0: col0 + g.shape[1]] = np.where(
            (g & np.uint32(UNIFORM)) != 0, g, shifted)
        s = t[h[W_SPANS]: h[W_RUNS]]
        spans.append(((s & np.uint32(SPAN_LAST - 1)) + np.uint32(run_at[i]))
                     | (s & np.uint32(SPAN_LAST)))
        runs.append(t[h[W_RUNS]:])
    cut = (down - 1) << tile_bits
    grid_at = TABLE_AT + HILBERT_TABLES.size
    spans_at = grid_at + grid.size
    runs_at = spans_at + int(spans_n.sum())
    head = [width, height, tile_bits, JOINED, gb, grid_at, spans_at, runs_at,
            int(heads[:, W_COUNT].sum()), gw, gh, cut]
    return np.concatenate([np.array(head, np.uint32), HILBERT_TABLES.astype(np.uint32),
                           grid.ravel(), *spans, *runs])
