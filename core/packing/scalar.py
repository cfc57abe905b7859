"""What a scalar lookup from Python reads: a byte per small cell of the layer (issue 19).

A scalar lookup from Python is bound by the interpreter: numpy's ``img[y, x]``
costs 0.08-0.4 us on this project's 2-core machine (by its load), a call into
a compiled kernel 0.1 us when the table is in cache and up to 0.8 us when it
is not (numba's entry point unboxes the arguments, then the search's
dependent loads miss), while a method that does a few integer operations and
indexes a ``bytes`` costs 1-2 times numpy's index (a Python call alone costs
0.025 us). So a scalar lookup reads the **quick cells** first: a byte per
aligned ``2^c x 2^c`` curve block, the palette index of a cell that one run
covers, 255 for any other; rows of cells shared by the image rows they hold,
so a texel's byte is
``rows[y][x >> c]`` (no arithmetic on ``y``). ``c`` is the smallest from
:data:`QUICK_MIN_BITS` whose cells fit :data:`QUICK_CELLS` bytes, so memory
stays bounded whatever the layer's size. 16 x 16 cells leave 7-19% of the
shared maps' random texels to the compiled call (the table's 32 x 32 blocks:
12-29%); finer cells leave fewer, but their bytes (1-5 MB) fall out of cache
and were no faster in total. The cells are built on the first scalar lookup,
from the runs (:func:`core.packing.lookup.block_runs`, the test the table's
grid uses); they cost a byte per cell and a pointer per image row: 61 + 40 KB
(Chesapeake 3115 x 5010), 147 + 49 KB (ESA 6144^2), 327 + 73 KB (DRCOG 9144^2).
A tiled container's cells are its tiles' side by side (:func:`tiled_quick_cells`,
built with its tables), the other cells answered by the compiled call on its
joined table: DRCOG in 4096^2 tiles 1.39 -> 0.33 us a call against the single
layer's 0.26 and numpy's 0.24 in the same run (each call had gone through the
tile arithmetic, ``int()`` and the palette's numpy gather).

The method itself is kept short (its array path in another method) and tests
bounds with ``(x | y) >= 0 and x < W`` (a row past the end is not in
``rows``): measured in 31 paired rounds of 20,000 random texels (load 3.2 on
the 2 cores), us per call, the path before / this one / numpy's ``img[y, x]``:
Chesapeake 0.140 / 0.127 / 0.081, ESA 0.154 / 0.134 / 0.085, DRCOG 0.199 /
0.184 / 0.094 (paired ratios 0.91, 0.87, 0.93); 8.6%, 7.1%, 18.4% of the
texels took the compiled call. Two pure-Python answers for the other cells
were measured in the same rounds, behind the same fast path, and dropped:

* each such cell's runs as their last local curve steps (a byte each, 16 x 16
  cells) beside their palette indices in one ``bytes``, a word per cell
  (offset, run count, Hilbert state) in an ``array`` row shared like
  ``rows``, the texel's local step from a (state, y & 15, x & 15) table
  inverted from :func:`core.curves.plan.local_patterns`, then
  ``bisect.bisect_left``: 1.01 / 0.98 / 1.09 x the path before, 12-18% slower
  than the compiled call, for 0.7 / 1.7 / 5.0 MB more. Its dozen bytecodes
  and dependent reads (row list, array, its buffer, the run bytes) cost more
  than numba's entry point (0.08 us with the table's unboxing) and kernel;
* those cells kept dense (``4^c`` bytes each, at ``((y & m) << c) | (x & m)``):
  2-6% faster than the compiled call (0.88 / 0.85 / 0.87 x the path before),
  but 256 bytes per such cell, 1.9 / 4.0 / 18.7 MB more: up to the dense
  image's size on a busy map.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.curves.plan import block_grid
from terratheme.core.curves.square import Curve
from terratheme.core.packing.layout import W_HEIGHT, W_LEVELS, W_MORTON, W_WIDTH, grid_words
from terratheme.core.packing.lookup import block_runs, table_runs

#: Most cells the quick cells keep a byte for (4 MiB).
QUICK_CELLS = 1 << 22
#: Smallest cell side (log2): 16 x 16 texels.
QUICK_MIN_BITS = 4


def quick_bits(width: int, height: int, levels: int) -> int:
    """Side (log2) of the quick cells: the smallest from :data:`QUICK_MIN_BITS` (at most
    the curve's ``levels``) whose cells fit :data:`QUICK_CELLS` bytes."""
    c = min(QUICK_MIN_BITS, levels)
    while c < levels and grid_words(width, height, c) > QUICK_CELLS:
        c += 1
    return c


def quick_cells(data: np.ndarray) -> tuple[int, list[bytes]]:
    """A byte per quick cell of a layer's table (:mod:`.layout`; not a joined table).

    Returns
    -------
    bits : int
        The cells' side (log2).
    rows : list of H bytes
        ``rows[y][x >> bits]`` (row 0 = top) is the palette index of the cell of
        texel ``(x, y)`` when one run covers that cell, else 255 (also for index
        255, which is then looked up as in any other cell). The image rows of a
        cell row share one ``bytes`` (the cells are aligned to the curve's origin,
        the image's bottom-left corner).
    """
    width, height = int(data[W_WIDTH]), int(data[W_HEIGHT])
    c = quick_bits(width, height, int(data[W_LEVELS]))
    steps, indices = table_runs(data)
    curve = Curve.MORTON if data[W_MORTON] else Curve.HILBERT
    coarse = block_grid(width, height, curve, c)[0]
    _, run1, uniform = block_runs(steps.astype(np.uint64), coarse.ravel(), c)
    quick = np.where(uniform, indices[np.minimum(run1, steps.size - 1)], 255).astype(np.uint8)
    cell_rows = [r.tobytes() for r in quick.reshape(coarse.shape)]  # from the bottom
    return c, [cell_rows[(height - 1 - y) >> c] for y in range(height)]


def tiled_quick_cells(tables: list[np.ndarray], tiles_x: int, width: int,
                      height: int) -> list[bytes] | None:
    """The quick cells of a tiled layer: its tiles' (:func:`quick_cells`) side by side.

    Parameters
    ----------
    tables : list of (M_t,) uint32 ndarrays
        Each tile's own table, rows of tiles from the top-left, ``tiles_x`` a row
        (tile sides are powers of two from 64, so cells of every tile but the
        last of a row end on the tile's right edge).
    tiles_x : int
    width, height : int
        The tiled layer's size in texels.

    Returns
    -------
    rows : list of H bytes, or None
        ``rows[y][x >> QUICK_MIN_BITS]`` as :func:`quick_cells`' rows, over the
        whole layer (a tile whose cells are not :data:`QUICK_MIN_BITS` a side, a
        tiny one at the layer's corner, is all 255). None when the layer has
        more cells than :data:`QUICK_CELLS`.
    """
    bits = QUICK_MIN_BITS
    if (-(-width >> bits)) * (-(-height >> bits)) > QUICK_CELLS:
        return None
    rows: list[bytes] = []
    for first in range(0, len(tables), tiles_x):
        # One tile row: every tile's image rows, joined per cell row (all share one height).
        per_tile = []
        for data in tables[first:first + tiles_x]:
            c, tile_rows = quick_cells(data)
            if c != bits:
                mixed = b"\xff" * (-(-int(data[W_WIDTH]) >> bits))
                tile_rows = [mixed] * int(data[W_HEIGHT])
            per_tile.append(tile_rows)
        tile_height = len(per_tile[0])
        joined: dict[int, bytes] = {}
        for y in range(tile_height):
            key = (tile_height - 1 - y) >> bits
            if key not in joined:
                joined[key] = b"".join(tile_rows[y] for tile_rows in per_tile)
            rows.append(joined[key])
    return rows
