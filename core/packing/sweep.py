"""Batched lookups in sweeps: the searches of a stretch advance together.

The other strategy of :mod:`.batch`. A batch is worked in stretches of :data:`STRETCH`
texels in branch-free loops: every texel's grid word, then the local steps and run
spans of the others, then their binary searches, one halving step of every open search
per sweep, so a sweep's loads are independent and overlap (the next probes prefetched).
No sort, little scratch: the cheaper strategy while the runs stay in cache.
"""

from __future__ import annotations

import numba
import numpy as np
from terratheme.core.packing import layout
from terratheme.core.packing.lookup import grid_word, local_step, run_span
from terratheme.core.packing.prefetch import prefetch

#: Columns of the tile rows (7 words a tile) that :func:`core.packing.batch.tiled_words` fills.
T_BASE, T_HEIGHT, T_GRID_BITS, T_GRID, T_GRID_WIDTH, T_BUCKET, T_RUNS = range(7)
TILE_COLUMNS = 7
#: Texels per stretch of the sweep kernels (and per parallel part).
STRETCH = 16384


@numba.njit(cache=True, nogil=True, inline="always")
def _sweep(xs, ys, data, tiled, joined, tiles, rows, out):  # pragma: no cover - numba
    # The body of the kernels; inlined with constant ``tiled`` and ``joined``, so each
    # keeps only its own branches (one layer: header read once, not per texel; a joined
    # table, :mod:`.joined`: its cut and each block's curve).
    if tiled:
        width, height, tb, across = tiles[0], tiles[1], tiles[2], tiles[3]
    else:
        width, height = np.int64(data[layout.W_WIDTH]), np.int64(data[layout.W_HEIGHT])
        tb, across = 62, 1
    tmask = (np.int64(1) << tb) - 1
    height0 = np.int64(data[layout.W_HEIGHT])
    gb0 = np.int64(data[layout.W_GRID_BITS])
    cut0 = np.int64(data[layout.W_CUT]) if joined else np.int64(0)
    grid0 = np.int64(data[layout.W_GRID])
    runs0 = np.int64(data[layout.W_RUNS])
    curve0 = np.int64(data[layout.W_MORTON])
    gw0 = np.int64(data[layout.W_GRID_WIDTH])
    n = min(STRETCH, xs.size)
    gs = np.empty(n, np.int64)
    local = np.empty(n, np.int64)
    los = np.empty(n, np.int64)
    his = np.empty(n, np.int64)
    which = np.empty(n, np.int64)
    tile = np.zeros(n, np.int64)
    for a in range(0, xs.size, STRETCH):
        b = min(xs.size, a + STRETCH)
        m = 0
        # Grid words: uniform blocks answer at once, the others wait for a search.
        for k in range(a, b):
            x = np.int64(xs[k])
            row = np.int64(ys[k])
            if not (0 <= x < width and 0 <= row < height):
                return k
            t = 0
            if tiled:
                t = ((row >> tb) * across + (x >> tb)) * TILE_COLUMNS
                g, _, lx, ly = grid_word(x & tmask, row & tmask, data, rows[t + T_GRID],
                                         rows[t + T_GRID_WIDTH], rows[t + T_HEIGHT], 0,
                                         rows[t + T_GRID_BITS])
            else:
                g, _, lx, ly = grid_word(x, row, data, grid0, gw0, height0, cut0, gb0)
            # Branch-free: every texel takes the next slot, which only searches keep.
            out[k] = g & 255
            gs[m] = g
            local[m] = (ly << 32) | lx
            which[m] = k
            tile[m] = t
            m += (g & layout.UNIFORM) == 0
        # Local steps, and the runs to search (the block's, or its quarter's).
        for i in range(m):
            g = gs[i]
            base, gb, runs, curve = ((rows[tile[i] + T_BASE], rows[tile[i] + T_GRID_BITS],
                                      rows[tile[i] + T_RUNS],
                                      np.int64(data[rows[tile[i] + T_BASE] + layout.W_MORTON]))
                                     if tiled else (0, gb0, runs0, curve0))
            step = local_step(g, local[i] & 0xFFFFFFFF, local[i] >> 32, gb, curve)
            lo, hi = run_span(g, step, gb, data, base)
            local[i] = np.int64(np.uint32(step) << np.uint32(8))
            los[i] = runs + lo
            his[i] = hi - lo
            # The first probe's line, asked for now: it arrives while the other texels'
            # steps are worked out.
            prefetch(data, los[i] + (his[i] >> 1) - 1)
        # The searches, a halving step of each open one per sweep (independent loads).
        openings = 0
        for i in range(m):
            gs[openings] = i
            openings += his[i] > 1
        while openings > 0:
            still = 0
            for j in range(openings):
                i = gs[j]
                left = his[i]
                half = left >> 1
                at = los[i]
                los[i] = at + half if data[at + half - 1] < local[i] else at
                his[i] = left - half
                # The next sweep's probe.
                prefetch(data, los[i] + (his[i] >> 1) - 1)
                gs[still] = i
                still += his[i] > 1
            openings = still
        # The last comparison: the run found, or the one after it.
        for i in range(m):
            at = los[i]
            at += (his[i] == 1) & (data[at] < local[i])
            out[which[i]] = data[at] & 255
    return -1


@numba.njit(cache=True, nogil=True)
def sweep_layer(xs, ys, data, out):  # pragma: no cover - numba
    """As :func:`.batch.layer_batch`, in sweeps (a joined table too)."""
    tiles, rows = np.zeros(4, np.int64), np.zeros(TILE_COLUMNS, np.int64)
    if data[layout.W_MORTON] == layout.JOINED:
        return _sweep(xs, ys, data, False, True, tiles, rows, out)
    return _sweep(xs, ys, data, False, False, tiles, rows, out)


@numba.njit(cache=True, nogil=True)
def sweep_tiled(xs, ys, data, tiles, rows, out):  # pragma: no cover - numba
    """:func:`sweep_layer` for a tiled layer (``tiles``, ``rows``: :func:`.batch.tiled_words`)."""
    return _sweep(xs, ys, data, True, False, tiles, rows, out)
