"""Random access into runs without unpacking (seed section 2.3, ``getColor``).

``(x, y) -> step s`` along the curve, then the first run whose last step is
``>= s``. Beyond the seed, the binary search is made short and cache-resident
by a **block directory**: the square's steps are cut into blocks of
``2^shift`` steps, ``directory[k]`` is the first run whose last step lies in
block ``k`` or later, and only the low ``shift`` bits of each run's last step
are kept, packed with ``P`` in one 32-bit word, so a run costs 4 bytes in
memory instead of the seed's 5, plus 4 bytes per directory block (about one
per 8 runs). Everything lives in one ``uint32`` array so that a scalar call
passes three arguments to the compiled kernel (numba's call overhead grows
with the number of array arguments).
"""

from __future__ import annotations

import numba
import numpy as np

from core.curves.steps import HILBERT_TABLES, hilbert_step, morton_step
from core.errors import TerrathemeError
from core.packing.layout import (
    TABLE_AT,
    W_DIR,
    W_HEIGHT,
    W_LEVELS,
    W_MORTON,
    W_RUNS,
    W_SHIFT,
    W_WIDTH,
    directory_shift,
)


@numba.njit(cache=True, nogil=True, inline="always")
def _step(x, row, data, base):  # pragma: no cover - numba
    # Curve step of texel (x, row), row 0 = top, in the table at data[base:]; bounds checked.
    y = np.int64(data[base + W_HEIGHT]) - 1 - row
    if data[base + W_MORTON]:
        return morton_step(x, y)
    n = np.int64(data[base + W_LEVELS])
    # Even level counts use the transposed square curve (core.curves.steps.hilbert_transposed).
    if n % 2 == 0:
        x, y = y, x
    return hilbert_step(x, y, n, data[base + TABLE_AT:base + TABLE_AT + HILBERT_TABLES.size])


@numba.njit(cache=True, nogil=True, inline="always")
def _search(data, base, s, lo, hi):  # pragma: no cover - numba
    # Packed word of the first run in [lo, hi) whose low step bits are >= those of s
    # (branch-free lower bound), or of run hi when there is none.
    shift = np.uint64(data[base + W_SHIFT])
    runs = base + np.int64(data[base + W_RUNS])
    t = np.uint32(s & ((np.uint64(1) << shift) - np.uint64(1))) << np.uint32(8)
    at = lo
    m = hi - lo
    while m > 1:
        half = m >> 1
        at = at + half if data[runs + at + half - 1] < t else at
        m -= half
    if m == 1 and data[runs + at] < t:
        at += 1
    return data[runs + at]


@numba.njit(cache=True, nogil=True, inline="always")
def _inside(x, row, data, base):  # pragma: no cover - numba
    return (0 <= x < np.int64(data[base + W_WIDTH])
            and 0 <= row < np.int64(data[base + W_HEIGHT]))


@numba.njit(cache=True, nogil=True, inline="always")
def _range(data, base, s):  # pragma: no cover - numba
    # The directory's run range [lo, hi) for step s.
    blk = np.int64(s >> np.uint64(data[base + W_SHIFT]))
    d0 = base + np.int64(data[base + W_DIR])
    return np.int64(data[d0 + blk]), np.int64(data[d0 + blk + 1])


@numba.njit(cache=True, nogil=True, inline="always")
def _find(x, row, data, base):  # pragma: no cover - numba
    # Packed run word (low step bits << 8 | P) of texel (x, row), or -1 outside the layer.
    if not _inside(x, row, data, base):
        return np.int64(-1)
    s = _step(x, row, data, base)
    # Directory block of the step, then a binary search over that block's runs only.
    lo, hi = _range(data, base, s)
    return np.int64(_search(data, base, s, lo, hi))


@numba.njit(cache=True, nogil=True, inline="always")
def _tile_of(x, row, tiles):  # pragma: no cover - numba
    # Table offset and local coordinates of texel (x, row) in a tiled layer, or base -1.
    # tiles: width, height, log2 tile side, tiles across, then one offset per tile.
    if not (0 <= x < np.int64(tiles[0]) and 0 <= row < np.int64(tiles[1])):
        return np.int64(-1), x, row
    tb = np.int64(tiles[2])
    mask = (np.int64(1) << tb) - 1
    t = (row >> tb) * np.int64(tiles[3]) + (x >> tb)
    return np.int64(tiles[4 + t]), x & mask, row & mask


@numba.njit(cache=True, nogil=True)
def lookup_batch(xs, ys, data, tiles, out):  # pragma: no cover - numba
    """Palette index of each texel ``(xs[k], ys[k])`` (row 0 = top) into ``out``.

    ``tiles`` is ``[width, height, log2 tile side, tiles across, offsets...]``
    (int64) for a tiled layer, whose tile tables lie end to end in ``data``,
    or empty for one layer's table. Works in chunks of 32: first every step
    and directory range of the chunk (independent loads the CPU overlaps),
    then the short searches. Returns the position of the first coordinate
    outside the layer, or -1.
    """
    chunk = 32
    steps = np.empty(chunk, np.uint64)
    los = np.empty(chunk, np.int64)
    his = np.empty(chunk, np.int64)
    bases = np.zeros(chunk, np.int64)
    tiled = tiles.size > 0
    for c0 in range(0, xs.size, chunk):
        c1 = min(xs.size, c0 + chunk)
        for k in range(c0, c1):
            x = np.int64(xs[k])
            row = np.int64(ys[k])
            base = np.int64(0)
            if tiled:
                base, x, row = _tile_of(x, row, tiles)
                if base < 0:
                    return k
            elif not _inside(x, row, data, base):
                return k
            s = _step(x, row, data, base)
            steps[k - c0] = s
            bases[k - c0] = base
            los[k - c0], his[k - c0] = _range(data, base, s)
        for k in range(c0, c1):
            i = k - c0
            out[k] = _search(data, bases[i], steps[i], los[i], his[i]) & 255
    return -1


@numba.njit(cache=True, nogil=True, parallel=True)
def lookup_batch_parallel(xs, ys, data, tiles, out):  # pragma: no cover - numba
    """:func:`lookup_batch` over all cores; returns how many coordinates were outside."""
    bad = 0
    tiled = tiles.size > 0
    for k in numba.prange(xs.size):
        x = np.int64(xs[k])
        row = np.int64(ys[k])
        base = np.int64(0)
        if tiled:
            base, x, row = _tile_of(x, row, tiles)
        word = np.int64(-1) if base < 0 else _find(x, row, data, base)
        if word < 0:
            bad += 1
            out[k] = 0
        else:
            out[k] = word & 255
    return bad


@numba.njit(cache=True, nogil=True)
def lookup_one(x, y, data):  # pragma: no cover - numba
    """Palette index of one texel, or -1 outside the image (three arguments: cheap to call)."""
    word = _find(np.int64(x), np.int64(y), data, np.int64(0))
    return word if word < 0 else word & 255


_SCALAR_CALL: list = []


def scalar_lookup_function():
    """:func:`lookup_one` compiled for ``(int64, int64, uint32[::1])``, called without dispatch.

    numba's dispatcher works out the argument types on every call (about half
    of a scalar lookup's cost); the compiled entry point of the one signature
    a layer uses skips that.
    """
    if not _SCALAR_CALL:
        sig = (numba.types.int64, numba.types.int64, numba.types.Array(numba.types.uint32, 1, "C"))
        lookup_one.compile(sig)
        _SCALAR_CALL.append(lookup_one.overloads[sig].entry_point)
    return _SCALAR_CALL[0]


def build_table(
    width: int, height: int, n: int, morton: bool, steps: np.ndarray, indices: np.ndarray
) -> np.ndarray:
    """The random-access structure of a layer, as one uint32 array.

    Layout: 8 header words (width, height, levels, morton, shift, directory
    offset, runs offset, run count), the 1040-entry Hilbert tables, the directory
    (``2^(2n-shift) + 1`` words: ``directory[k]`` = first run whose last step is
    ``>= k * 2^shift``), then one word per run: ``(step & (2^shift - 1)) << 8 | P``.

    Returns
    -------
    data : (8 + 1040 + blocks + 1 + R,) uint32 ndarray
    """
    if steps.size >= 2**32 - 1:
        raise TerrathemeError(f"{steps.size} runs: a layer holds at most 2^32 - 2 runs")
    shift = directory_shift(n, steps.size)
    blocks = ((1 << (2 * n)) >> shift) + 1
    first = np.arange(blocks, dtype=np.uint64) << np.uint64(shift)
    directory = np.searchsorted(steps.astype(np.uint64), first, side="left")
    low = steps.astype(np.uint64) & np.uint64((1 << shift) - 1)
    words = (low << np.uint64(8)) | np.asarray(indices, np.uint64)
    dir_at = TABLE_AT + HILBERT_TABLES.size
    runs_at = dir_at + blocks
    head = [width, height, n, int(morton), shift, dir_at, runs_at, steps.size]
    return np.concatenate([
        np.array(head, np.uint32), HILBERT_TABLES.astype(np.uint32),
        directory.astype(np.uint32), words.astype(np.uint32),
    ])


def table_runs(data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`build_table`: 0-based steps (R,) uint32 and P (R,) uint8."""
    shift = int(data[W_SHIFT])
    directory = data[int(data[W_DIR]): int(data[W_RUNS])].astype(np.int64)
    words = data[int(data[W_RUNS]):]
    block = np.repeat(np.arange(directory.size - 1, dtype=np.uint64), np.diff(directory))
    steps = (block << np.uint64(shift)) | (words >> np.uint32(8)).astype(np.uint64)
    return steps.astype(np.uint32), (words & np.uint32(255)).astype(np.uint8)
