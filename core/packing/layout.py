"""Layout of a layer's random-access table, the flat ``uint32`` array of :mod:`.lookup`.

Kept free of numba so that ``terratheme info`` can size a layer from its file
header without loading any kernel. The table (also read by GPU shaders, so
its layout is part of the format documentation, ``docs/formats.md`` (packed index layers))::

    word               content
    0 .. 11            width W, height H, curve levels n, morton flag, grid block bits b,
                       grid offset G, span offset N, runs offset U, run count R,
                       grid width gw, grid height gh, cut C (0; a joined table, below)
    12 .. 1051         the Hilbert state tables (core.curves.steps.HILBERT_TABLES)
    G .. G + gw*gh     one word per 2^b x 2^b curve block meeting the layer, rows from
                       the bottom (y up): a block inside one run is
                       UNIFORM | ENDS (if that run ends on the block's last step) | P;
                       any other is (o << 3) | (quartered << 2) | its pattern state,
                       o the offset of its span from N (o < 2^27)
    N ..               per block that is not uniform, in grid order: its span, the first
                       run ending in it, then (quartered blocks, more than 16 runs) the
                       first runs ending at or after its 2nd, 3rd and 4th quarter's first
                       step, then the run covering its last step (the layer's last run at
                       most) | SPAN_LAST if that run also ends in the block
    U .. U + R - 1     one word per run: (last step & (4^b - 1)) << 8 | palette index

A texel in a uniform block is answered by its grid word. In any other
block, its local step ``l`` (the Hilbert walk of its place in the block over
``b`` levels starting in the block's state; Morton: the bits interleaved)
selects the first run of ``[span[q], span[q + 1])`` (``q`` = its quarter,
or 0 without quarters) whose low step bits are ``>= l``, else run
``span[q + 1]``: a binary search over a few dozen runs at most.

A **joined table** (:mod:`.joined`) is one table over all the tiles of a tiled
layer, in this layout: its grid is the tiles' grids side by side, its spans
and runs theirs end to end (offsets shifted). Two things differ: the tiles'
blocks are aligned to each tile's bottom, so the rows above the last tile
row (``row < C``) are read ``pad = (C - H) & (2^b - 1)`` higher
(``y = H - 1 - row + pad``); and a block of a Morton tile among Hilbert ones
has :data:`MORTON_BLOCK` set in its grid word. Its word 3 is :data:`JOINED`
(a single layer's is 0 or 1, its ``C`` 0), which the batch kernels read to
take their joined variant; the scalar kernel reads both kinds alike.
"""

from __future__ import annotations

#: Header words of the table, then their positions.
HEAD_WORDS = 12
(W_WIDTH, W_HEIGHT, W_LEVELS, W_MORTON, W_GRID_BITS, W_GRID, W_SPANS, W_RUNS, W_COUNT,
 W_GRID_WIDTH, W_GRID_HEIGHT, W_CUT) = range(HEAD_WORDS)
#: Where the Hilbert tables start, and their length (16 one-level + 1024 four-level words).
TABLE_AT = HEAD_WORDS
HILBERT_TABLE_WORDS = 16 + 1024
#: Grid word flags of a block that one run covers (its palette index in the low byte).
UNIFORM = 1 << 31
ENDS = 1 << 30
#: Word 3 (W_MORTON) of a joined table: each block's curve is in its grid word.
JOINED = 2
#: Grid word flag of a block that is not uniform: its steps are Morton's (joined tables).
MORTON_BLOCK = 1 << 30
#: Bits of a grid word that are its span's offset, once shifted down by 3.
SPAN_OFFSET_MASK = (1 << 27) - 1
#: Flag on a span's last word: the covering run ends inside the block too.
SPAN_LAST = 1 << 31
#: Blocks with more runs than this get a quarter directory (5 span words instead of 2).
QUARTER_FROM = 16
#: Smallest grid block side (log2); larger ones are taken until the grid has <= R / 4 words.
MIN_GRID_BITS = 4
#: Largest grid block side (log2): a run's low step bits must fit 24 bits beside P.
MAX_GRID_BITS = 12


def grid_bits(n: int, width: int, height: int, run_count: int) -> int:
    """Side (log2) of the grid's blocks: the smallest from 16 texels with at most R / 4 words."""
    b = min(MIN_GRID_BITS, n)
    while b < min(n, MAX_GRID_BITS) and grid_words(width, height, b) > max(1, run_count // 4):
        b += 1
    return b


def grid_words(width: int, height: int, b: int) -> int:
    """Blocks of side ``2^b`` that meet a ``width x height`` layer."""
    return -(-width >> b) * -(-height >> b)


def table_words_max(width: int, height: int, n: int, run_count: int) -> int:
    """Largest table a layer of this size and run count can have (every block quartered)."""
    grid = grid_words(width, height, grid_bits(n, width, height, run_count))
    return HEAD_WORDS + HILBERT_TABLE_WORDS + 6 * grid + run_count
