"""Layout of a layer's random-access table, the flat ``uint32`` array of :mod:`.lookup`.

Kept free of numba so that ``terratheme info`` can size a layer from its file
header without loading any kernel. The table (also read by GPU shaders, so
its layout is part of the format documentation, ``docs/formats-ttpack.md``)::

    word               content
    0 .. 7             width, height, curve levels n, morton flag, directory shift k,
                       directory offset D, runs offset U, run count R
    8 .. 1047          the Hilbert state tables (core.curves.steps.HILBERT_TABLES)
    D .. D + B         directory, B = 2^(2n - k) blocks + 1 words: entry j is the
                       first run whose last step is >= j * 2^k
    U .. U + R - 1     one word per run: (last step & (2^k - 1)) << 8 | palette index

A texel at curve step ``s`` lies in the first run of ``[dir[s >> k],
dir[(s >> k) + 1]]`` whose low step bits are ``>= s & (2^k - 1)``.
"""

from __future__ import annotations

import math

#: Header words of the table, then their positions.
HEAD_WORDS = 8
W_WIDTH, W_HEIGHT, W_LEVELS, W_MORTON, W_SHIFT, W_DIR, W_RUNS, W_COUNT = range(HEAD_WORDS)
#: Where the Hilbert tables start, and their length (16 one-level + 1024 four-level entries).
TABLE_AT = HEAD_WORDS
HILBERT_TABLE_WORDS = 16 + 1024
#: Largest directory block, log2 steps: the low step bits must fit 24 bits beside P.
MAX_SHIFT = 16
#: Runs per directory entry the shift aims at.
RUNS_PER_ENTRY = 8


def directory_shift(n: int, run_count: int) -> int:
    """Block size (log2 steps) giving about one directory entry per 8 runs, at most 2^16."""
    want = (1 << (2 * n)) * RUNS_PER_ENTRY / max(run_count, 1)
    return int(min(MAX_SHIFT, 2 * n, max(0, math.ceil(math.log2(max(want, 1.0))))))


def table_words(n: int, run_count: int) -> int:
    """Length of the table of a layer with ``n`` curve levels and ``run_count`` runs."""
    blocks = ((1 << (2 * n)) >> directory_shift(n, run_count)) + 1
    return HEAD_WORDS + HILBERT_TABLE_WORDS + blocks + run_count
