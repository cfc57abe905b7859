"""Quick cells: what a scalar lookup from Python reads first (docs/formats.md, P3).

A scalar call is bound by the interpreter, so a few integer operations and a ``bytes``
index beat a call into a compiled kernel. A byte per aligned ``2^c x 2^c`` curve
block holds the palette index of a cell one run covers, 255 for any other (left to the
compiled lookup); the image rows of a cell row share one ``bytes``, so a texel's byte
is ``rows[y][x >> c]``. Built on the first scalar lookup.
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
    """A byte per quick cell of a layer's table (not a joined table).

    Returns ``(bits, rows)``: the cells' side (log2), and H ``bytes`` with
    ``rows[y][x >> bits]`` (row 0 = top) the palette index of texel ``(x, y)``'s cell
    when one run covers it, else 255 (index 255 itself is looked up as any other).
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
    """A tiled layer's quick cells: its tiles' (:func:`quick_cells`) side by side.

    ``tables`` are the tiles' own tables, rows of tiles from the top-left, ``tiles_x``
    a row; a tile whose cells are not :data:`QUICK_MIN_BITS` a side is all 255.
    Returns H ``bytes`` as :func:`quick_cells`' rows, or None past :data:`QUICK_CELLS`.
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
