"""What a scalar lookup from Python reads: a byte per small cell of the layer (issue 19).

A scalar lookup from Python is bound by the interpreter: numpy's ``img[y, x]``
costs 0.25-0.4 us on this project's 2-core machine, a call into a compiled
kernel 0.1 us when the table is in cache and up to 0.8 us when it is not
(numba's entry point unboxes the arguments, then the search's dependent
loads miss), while a method that does a few integer operations and indexes a
``bytes`` costs about what numpy's index costs. So a scalar lookup reads the
**quick cells** first: a byte per aligned ``2^c x 2^c`` curve block, the
palette index of a cell that one run covers, 255 for any other; rows of
cells shared by the image rows they hold, so a texel's byte is
``rows[y][x >> c]`` (no arithmetic on ``y``). ``c`` is the smallest from
:data:`QUICK_MIN_BITS` whose cells fit :data:`QUICK_CELLS` bytes, so memory
stays bounded whatever the layer's size. 16 x 16 cells leave 7-19% of the
shared maps' random texels to the compiled call (the table's 32 x 32 blocks:
12-29%); finer cells leave fewer, but their bytes (1-5 MB) fall out of cache
and were no faster in total. The cells are built on the first scalar lookup,
from the runs (:func:`core.packing.lookup.block_runs`, the test the table's
grid uses).
"""

from __future__ import annotations

import numpy as np

from core.curves.plan import block_grid
from core.curves.square import Curve
from core.packing.layout import W_HEIGHT, W_LEVELS, W_MORTON, W_WIDTH, grid_words
from core.packing.lookup import block_runs, table_runs

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
