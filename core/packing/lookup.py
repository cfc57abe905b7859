"""Random access into runs without unpacking (seed section 2.3, ``getColor``).

``(x, y) -> step s`` along the curve, then the first run whose last step is ``>= s``.
Beyond the seed, a grid over the curve's aligned blocks answers a texel of a block one
run covers in one read, and keeps any other block's search inside its own few runs;
all in one ``uint32`` table (:mod:`.layout`, docs/formats.md P3).
"""

from __future__ import annotations

import numba
import numpy as np
from terratheme.core.curves.plan import block_grid
from terratheme.core.curves.square import Curve
from terratheme.core.curves.steps import HILBERT_TABLES, hilbert_walk, morton_step
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing.layout import (
    ENDS,
    HEAD_WORDS,
    JOINED,
    MAX_GRID_BITS,
    MORTON_BLOCK,
    QUARTER_FROM,
    SPAN_LAST,
    SPAN_OFFSET_MASK,
    TABLE_AT,
    UNIFORM,
    W_CUT,
    W_GRID,
    W_GRID_BITS,
    W_GRID_WIDTH,
    W_HEIGHT,
    W_MORTON,
    W_RUNS,
    W_SPANS,
    W_WIDTH,
    grid_bits,
)


@numba.njit(cache=True, nogil=True, inline="always")
def _inside(x, row, data, base):  # pragma: no cover - numba
    return (0 <= x < np.int64(data[base + W_WIDTH])
            and 0 <= row < np.int64(data[base + W_HEIGHT]))


@numba.njit(cache=True, nogil=True, inline="always")
def grid_word(x, row, data, grid, grid_width, height, cut, gb):  # pragma: no cover - numba
    """``(g, gi, lx, ly)``: grid word of texel ``(x, row)`` (row 0 = top), its index in the
    grid at ``data[grid:]``, its place in the block (y up); rows above a joined table's
    ``cut`` (0: none) are read ``pad`` higher (:mod:`.layout`)."""
    mask = (np.int64(1) << gb) - 1
    yup = height - 1 - row + ((cut - height) & mask) * (row < cut)
    gi = (yup >> gb) * grid_width + (x >> gb)
    return np.int64(data[grid + gi]), gi, x & mask, yup & mask


@numba.njit(cache=True, nogil=True, inline="always")
def _grid_word(x, row, data, base):  # pragma: no cover - numba
    # grid_word of texel (x, row) of the table at data[base:], and the grid bits.
    gb = np.int64(data[base + W_GRID_BITS])
    g, _gi, lx, ly = grid_word(x, row, data, base + np.int64(data[base + W_GRID]),
                               np.int64(data[base + W_GRID_WIDTH]),
                               np.int64(data[base + W_HEIGHT]), np.int64(data[base + W_CUT]), gb)
    return g, lx, ly, gb


@numba.njit(cache=True, nogil=True, inline="always")
def local_step(g, lx, ly, gb, curve):  # pragma: no cover - numba
    # Step within its block of a texel at (lx, ly) (y up), the block's grid word g, the
    # table's curve word (W_MORTON; the Hilbert tables are every table's own).
    if curve == 1 or (curve == JOINED and g & MORTON_BLOCK):
        return np.int64(morton_step(lx, ly))
    return np.int64(hilbert_walk(lx, ly, gb, HILBERT_TABLES, np.int64(g & 3))[0])


@numba.njit(cache=True, nogil=True, inline="always")
def run_span(g, local, gb, data, base):  # pragma: no cover - numba
    # The runs [lo, hi) to search for local step `local` of the block with grid word g:
    # the block's, or its quarter's when the block has a quarter directory (branch-free).
    at = (base + np.int64(data[base + W_SPANS]) + ((g >> 3) & SPAN_OFFSET_MASK)
          + ((local >> max(2 * gb - 2, 0)) & -((g >> 2) & 1)))
    return np.int64(data[at]), np.int64(data[at + 1]) & (SPAN_LAST - 1)


@numba.njit(cache=True, nogil=True, inline="always")
def search_runs(data, base, local, lo, hi):  # pragma: no cover - numba
    # Packed word of the first run in [lo, hi) whose low step bits are >= local
    # (branch-free lower bound), or of run hi when there is none.
    runs = base + np.int64(data[base + W_RUNS])
    t = np.uint32(local) << np.uint32(8)
    at = lo
    m = hi - lo
    while m > 1:
        half = m >> 1
        at = at + half if data[runs + at + half - 1] < t else at
        m -= half
    if m == 1 and data[runs + at] < t:
        at += 1
    return np.int64(data[runs + at])


@numba.njit(cache=True, nogil=True, inline="always")
def _find(x, row, data, base):  # pragma: no cover - numba
    # Palette index of texel (x, row) in its low byte (run word or grid word), -1 outside.
    if not _inside(x, row, data, base):
        return np.int64(-1)
    g, lx, ly, gb = _grid_word(x, row, data, base)
    if g & UNIFORM:
        return g
    local = local_step(g, lx, ly, gb, data[base + W_MORTON])
    lo, hi = run_span(g, local, gb, data, base)
    return search_runs(data, base, local, lo, hi)


@numba.njit(cache=True, nogil=True)
def lookup_one(x, y, data):  # pragma: no cover - numba
    """Palette index of one texel, or -1 outside the image (three arguments: cheap to call)."""
    word = _find(np.int64(x), np.int64(y), data, np.int64(0))
    return word if word < 0 else word & 255


_SCALAR_CALL: list = []


def scalar_lookup_function():
    """:func:`lookup_one` compiled for ``(int64, int64, uint32[::1])``, called without dispatch.

    numba's dispatcher types the arguments on every call, about half a scalar lookup's cost.
    """
    if not _SCALAR_CALL:
        sig = (numba.types.int64, numba.types.int64, numba.types.Array(numba.types.uint32, 1, "C"))
        lookup_one.compile(sig)
        _SCALAR_CALL.append(lookup_one.overloads[sig].entry_point)
    return _SCALAR_CALL[0]


def block_runs(steps: np.ndarray, coarse: np.ndarray, bits: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(run0, run1, uniform)``, (B,): the runs covering the first and last steps of each
    block of side ``2^bits`` at coarse steps ``coarse`` (``R`` past the last run), and
    whether one run covers it.
    """
    first = np.asarray(coarse, np.uint64) << np.uint64(2 * bits)
    run0 = np.searchsorted(steps, first)
    run1 = np.searchsorted(steps, first + np.uint64((1 << (2 * bits)) - 1))
    return run0, run1, run0 == run1


def build_table(
    width: int, height: int, n: int, morton: bool, steps: np.ndarray, indices: np.ndarray,
    bits: int | None = None,
) -> np.ndarray:
    """The random-access table of a layer, one uint32 array (:mod:`.layout`).

    ``steps`` (R,): 0-based last step of each run, increasing, the last one the layer's
    last texel; ``indices`` (R,) uint8; ``bits``: grid block side (log2), default
    :func:`.layout.grid_bits`'s (the tiles of a tiled layer share one).
    """
    if steps.size >= SPAN_LAST:
        raise TerrathemeError(f"{steps.size} runs: a layer holds at most 2^31 - 1 runs")
    steps = np.asarray(steps, np.uint64)
    indices = np.asarray(indices, np.uint8)
    r = steps.size
    curve = Curve.MORTON if morton else Curve.HILBERT
    gb = grid_bits(n, width, height, r) if bits is None else min(int(bits), n)
    if not 0 <= gb <= MAX_GRID_BITS:
        raise TerrathemeError(f"grid block bits {bits}: 0 to {MAX_GRID_BITS}")
    coarse, state = block_grid(width, height, curve, gb)
    gh, gw = coarse.shape
    coarse, state = coarse.ravel(), state.ravel()
    first = coarse.astype(np.uint64) << np.uint64(2 * gb)
    last = first + np.uint64((1 << (2 * gb)) - 1)
    run0, run1, uniform = block_runs(steps, coarse, gb)
    # Whether a run ends on the block's last step (or, past the layer's end, inside it).
    cover = np.minimum(run1, r - 1)
    ends = (run1 >= r) | (steps[cover] == last)
    # Spans of the blocks that are not uniform, in grid order: [first run, covering run],
    # with the runs at each quarter's first step between them when the block has many.
    nu = np.flatnonzero(~uniform)
    quarter = np.uint64(1 << (2 * gb - 2)) if gb else np.uint64(1)
    split = (np.minimum(run1[nu], r - 1) - run0[nu] > QUARTER_FROM) & (gb > 0)
    rows = [run0[nu]]
    for q in (1, 2, 3):
        rows.append(np.minimum(np.searchsorted(steps, first[nu] + quarter * np.uint64(q)),
                               cover[nu]))
    rows.append(cover[nu] | np.where(ends[nu], SPAN_LAST, 0))
    table = np.stack(rows, axis=1)
    size = np.where(split, 5, 2)
    offset = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
    # A block without quarters keeps [first, covering] only.
    table = np.where(split[:, None], table, table[:, [0, 4, 0, 0, 0]])
    spans = table[split[:, None] | (np.arange(5) < 2)[None, :]]
    grid = np.where(uniform, UNIFORM | np.where(ends, ENDS, 0) | indices[cover].astype(np.int64),
                    0)
    grid[nu] = (offset << 3) | (split.astype(np.int64) << 2) | state[nu].astype(np.int64)
    words = ((steps & np.uint64((1 << (2 * gb)) - 1)) << np.uint64(8)) | indices
    grid_at = TABLE_AT + HILBERT_TABLES.size
    spans_at = grid_at + grid.size
    runs_at = spans_at + spans.size
    head = [width, height, n, int(morton), gb, grid_at, spans_at, runs_at, r, gw, gh, 0]
    assert len(head) == HEAD_WORDS
    return np.concatenate([
        np.array(head, np.uint32), HILBERT_TABLES.astype(np.uint32),
        grid.astype(np.uint32), spans.astype(np.uint32), words.astype(np.uint32),
    ])


def table_runs(data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`build_table`: 0-based steps (R,) uint32 and P (R,) uint8.

    Runs end, block by block in curve order, inside the blocks that are not
    uniform (their span, and the covering run when flagged) and on the last
    step of uniform blocks flagged ENDS; each run keeps its low step bits.
    """
    width, height, _, morton, gb = (int(v) for v in data[:5])
    grid = data[int(data[W_GRID]): int(data[W_SPANS])].astype(np.int64)
    spans = data[int(data[W_SPANS]): int(data[W_RUNS])].astype(np.int64)
    words = data[int(data[W_RUNS]):]
    coarse = block_grid(width, height, Curve.MORTON if morton else Curve.HILBERT, gb)[0].ravel()
    uniform = (grid & UNIFORM) != 0
    # Runs ending in each block: 1 or 0 for uniform ones, from the span for the others.
    count = ((grid & ENDS) != 0).astype(np.int64)
    g = grid[~uniform]
    at = g >> 3
    last = spans[at + np.where(g & 4, 4, 1)]
    count[~uniform] = (last & (SPAN_LAST - 1)) - spans[at] + (last >= SPAN_LAST)
    order = np.argsort(coarse, kind="stable")
    block = np.repeat(coarse[order].astype(np.uint64), count[order])
    steps = (block << np.uint64(2 * gb)) | (words >> np.uint32(8)).astype(np.uint64)
    return steps.astype(np.uint32), (words & np.uint32(255)).astype(np.uint8)
