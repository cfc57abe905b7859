"""Layout of a layer's random-access table, the flat ``uint32`` array of :mod:`.lookup`.

Word by word in docs/formats.md, P3 (GPU shaders read it too), the joined table of
:mod:`.joined` included. Free of numba, so ``terratheme info`` sizes a layer from its
header without loading a kernel.
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
