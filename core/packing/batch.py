"""Batched random access into packed layers and tiled containers: the bucket strategy.

A batch is worked :data:`CHUNK` texels at a time in three passes, a radix partition by
where the runs lie, so each search's runs stay in cache:

1. every texel's grid word (a uniform block answers at once); any other leaves an
   entry and its **bucket**, ``2^shift`` grid words holding about :data:`BUCKET_RUNS` runs;
2. a counting sort of the entries by bucket;
3. bucket by bucket, the searches.

:func:`lookup_batch` picks this or the sweeps (:mod:`.sweep`) per table
(docs/formats.md, P3; docs/decisions.md); both match the scalar lookup bit for bit.
"""

from __future__ import annotations

import numba
import numpy as np
from terratheme.core.packing import layout
from terratheme.core.packing.lookup import grid_word, local_step, run_span, search_runs
from terratheme.core.packing.sweep import (
    STRETCH,
    T_BASE,
    T_BUCKET,
    T_GRID,
    T_GRID_BITS,
    T_GRID_WIDTH,
    T_HEIGHT,
    T_RUNS,
    TILE_COLUMNS,
    sweep_layer,
    sweep_tiled,
)
from terratheme.core.packing.threads import on_threads

#: Texels per chunk of a batch.
CHUNK = 1 << 20
#: Runs in a bucket's blocks, about (their words and spans: a few kB, in L1).
BUCKET_RUNS = 1024


@numba.njit(cache=True, nogil=True)
def bucket_shift(blocks, runs):  # pragma: no cover - numba
    """log2 of the grid words per bucket: the most with about ``BUCKET_RUNS`` runs in them."""
    s = 0
    while s < 40 and (np.int64(2) << s) * max(runs, 1) <= BUCKET_RUNS * max(blocks, 1):
        s += 1
    return s


def tiled_words(data: np.ndarray, bases: np.ndarray, width: int, height: int, tile_bits: int,
                across: int) -> tuple[np.ndarray, np.ndarray]:
    """What the batch kernels read of a tiled layer whose tile ``t``'s table starts at ``bases[t]``.

    Returns ``tiles``, (6,) int64: width, height, log2 tile side, tiles across, bucket
    shift (:func:`bucket_shift` over all tiles), buckets; and ``rows``, (7 * tiles,) int64:
    per tile its table's offset, height, grid bits, grid offset, grid width, first bucket
    and runs offset (the columns ``T_*`` of :mod:`.sweep`).
    """
    heads = np.stack([data[b: b + layout.HEAD_WORDS] for b in np.asarray(bases, np.int64)]).astype(
        np.int64)
    blocks = heads[:, layout.W_GRID_WIDTH] * heads[:, layout.W_GRID_HEIGHT]
    shift = int(bucket_shift(int(blocks.sum()), int(heads[:, layout.W_COUNT].sum())))
    buckets = ((blocks - 1) >> shift) + 1
    rows = np.zeros((len(heads), TILE_COLUMNS), np.int64)
    rows[:, T_BASE] = bases
    rows[:, T_HEIGHT] = heads[:, layout.W_HEIGHT]
    rows[:, T_GRID_BITS] = heads[:, layout.W_GRID_BITS]
    rows[:, T_GRID] = rows[:, T_BASE] + heads[:, layout.W_GRID]
    rows[:, T_GRID_WIDTH] = heads[:, layout.W_GRID_WIDTH]
    rows[:, T_BUCKET] = np.cumsum(buckets) - buckets
    rows[:, T_RUNS] = rows[:, T_BASE] + heads[:, layout.W_RUNS]
    tiles = np.array([width, height, tile_bits, across, shift, buckets.sum()], np.int64)
    return tiles, rows.ravel()


@numba.njit(cache=True, nogil=True)
def _layer_words(data):  # pragma: no cover - numba
    # tiles and rows of one layer: a single tile as wide as the layer.
    blocks = np.int64(data[layout.W_GRID_WIDTH]) * np.int64(data[layout.W_GRID_HEIGHT])
    shift = bucket_shift(blocks, np.int64(data[layout.W_COUNT]))
    tiles = np.array([np.int64(data[layout.W_WIDTH]), np.int64(data[layout.W_HEIGHT]), 62, 1, shift,
                      ((blocks - 1) >> shift) + 1])
    rows = np.zeros(TILE_COLUMNS, np.int64)
    rows[T_HEIGHT] = data[layout.W_HEIGHT]
    rows[T_GRID_BITS] = data[layout.W_GRID_BITS]
    rows[T_GRID] = data[layout.W_GRID]
    rows[T_GRID_WIDTH] = data[layout.W_GRID_WIDTH]
    return tiles, rows


@numba.njit(cache=True, nogil=True, inline="always")
def _grid_pass(xs, ys, a, b, data, tiled, joined, tiles, rows, out, ent, bkt, counts):
    # Pass 1 over texels [a, b): uniform texels answered, the others' entries in
    # ent[a:], bkt[a:], counted in counts (per bucket). Returns (entries, bad texel or -1).
    width, height, tb, across, shift = tiles[0], tiles[1], tiles[2], tiles[3], tiles[4]
    tmask = (np.int64(1) << tb) - 1
    height0, gb0, grid0, gw0 = rows[T_HEIGHT], rows[T_GRID_BITS], rows[T_GRID], rows[T_GRID_WIDTH]
    cut0 = np.int64(data[layout.W_CUT]) if joined else np.int64(0)
    m = a
    for k in range(a, b):
        x = np.int64(xs[k])
        row = np.int64(ys[k])
        if not (0 <= x < width and 0 <= row < height):
            return m - a, k
        if tiled:
            r = ((row >> tb) * across + (x >> tb)) * TILE_COLUMNS
            gb = rows[r + T_GRID_BITS]
            g, gi, lx, ly = grid_word(x & tmask, row & tmask, data, rows[r + T_GRID],
                                      rows[r + T_GRID_WIDTH], rows[r + T_HEIGHT], 0, gb)
            bucket = rows[r + T_BUCKET] + (gi >> shift)
        else:
            gb = gb0
            g, gi, lx, ly = grid_word(x, row, data, grid0, gw0, height0, cut0, gb)
            bucket = gi >> shift
        # Branch-free: every texel takes the next slot, which only searches keep.
        out[k] = g & 255
        ent[m] = (np.int64(k) << 32) | (gi << (2 * gb)) | (ly << gb) | lx
        bkt[m] = bucket
        search = (g & layout.UNIFORM) == 0
        counts[bucket] += search
        m += search
    return m - a, -1


@numba.njit(cache=True, nogil=True)
def _grid_layer(xs, ys, a, b, data, tiles, rows, out, ent, bkt, counts):  # pragma: no cover
    if data[layout.W_MORTON] == layout.JOINED:
        return _grid_pass(xs, ys, a, b, data, False, True, tiles, rows, out, ent, bkt, counts)
    return _grid_pass(xs, ys, a, b, data, False, False, tiles, rows, out, ent, bkt, counts)


@numba.njit(cache=True, nogil=True)
def _grid_tiled(xs, ys, a, b, data, tiles, rows, out, ent, bkt, counts):  # pragma: no cover
    return _grid_pass(xs, ys, a, b, data, True, False, tiles, rows, out, ent, bkt, counts)


@numba.njit(cache=True, nogil=True)
def _offsets(counts):  # pragma: no cover - numba
    # Exclusive prefix sums: counts[bucket] becomes where that bucket's first entry
    # goes; also each bucket's first entry (and the end).
    buckets = counts.size
    starts = np.empty(buckets + 1, np.int64)
    pos = 0
    for bucket in range(buckets):
        starts[bucket] = pos
        c = counts[bucket]
        counts[bucket] = pos
        pos += c
    starts[buckets] = pos
    return starts


@numba.njit(cache=True, nogil=True)
def _place(ent, bkt, a, m, at, srt):  # pragma: no cover - numba
    # Pass 2: entries a .. a + m - 1 to their bucket's place (``at`` advances).
    for i in range(a, a + m):
        bucket = bkt[i]
        srt[at[bucket]] = ent[i]
        at[bucket] += 1


@numba.njit(cache=True, nogil=True)
def _answer(b0, b1, starts, srt, data, rows, out):  # pragma: no cover - numba
    # Pass 3: the searches of buckets [b0, b1), their tile found by walking the rows.
    t = 0
    while (t + 1) * TILE_COLUMNS < rows.size and rows[(t + 1) * TILE_COLUMNS + T_BUCKET] <= b0:
        t += 1
    for bucket in range(b0, b1):
        while (t + 1) * TILE_COLUMNS < rows.size and \
                rows[(t + 1) * TILE_COLUMNS + T_BUCKET] <= bucket:
            t += 1
        r = t * TILE_COLUMNS
        base, gb, grid = rows[r + T_BASE], rows[r + T_GRID_BITS], rows[r + T_GRID]
        curve = np.int64(data[base + layout.W_MORTON])
        mask = (np.int64(1) << gb) - 1
        for j in range(starts[bucket], starts[bucket + 1]):
            e = srt[j]
            place = e & 0xFFFFFFFF
            g = np.int64(data[grid + (place >> (2 * gb))])
            local = local_step(g, place & mask, (place >> gb) & mask, gb, curve)
            lo, hi = run_span(g, local, gb, data, base)
            out[e >> 32] = search_runs(data, base, local, lo, hi) & 255


@numba.njit(cache=True, nogil=True, inline="always")
def _batch(xs, ys, data, tiled, tiles, rows, out):  # pragma: no cover - numba
    # The three passes, chunk by chunk. Returns the first bad texel or -1.
    n = xs.size
    size = min(n, CHUNK)
    ent = np.empty(size, np.int64)
    bkt = np.empty(size, np.int32)
    srt = np.empty(size, np.int64)
    counts = np.zeros(tiles[5], np.int64)
    for c in range(0, n, CHUNK):
        cn = min(CHUNK, n - c)
        counts[:] = 0
        args = (xs[c: c + cn], ys[c: c + cn], 0, cn, data, tiles, rows, out[c: c + cn],
                ent, bkt, counts)
        found, bad = _grid_tiled(*args) if tiled else _grid_layer(*args)
        if bad >= 0:
            return c + bad
        starts = _offsets(counts)
        _place(ent, bkt, 0, found, counts, srt)
        _answer(0, starts.size - 1, starts, srt, data, rows, out[c: c + cn])
    return -1


@numba.njit(cache=True, nogil=True)
def layer_batch(xs, ys, data, out):  # pragma: no cover - numba
    """Palette indices of texels ``(xs[k], ys[k])`` into ``out``; first bad texel or -1."""
    tiles, rows = _layer_words(data)
    return _batch(xs, ys, data, False, tiles, rows, out)


@numba.njit(cache=True, nogil=True)
def tiled_batch(xs, ys, data, tiles, rows, out):  # pragma: no cover - numba
    """As :func:`layer_batch`, tiled (``tiles``, ``rows``: :func:`tiled_words`)."""
    return _batch(xs, ys, data, True, tiles, rows, out)


#: Tables up to this many bytes are looked up in sweeps (:mod:`.sweep`), larger ones by bucket.
SWEEP_BYTES = 1 << 26
#: Texels per piece of a swept batch on threads (:func:`~core.packing.threads.on_threads`);
#: the buckets take equal slices (larger slices fill fuller buckets).
SWEEP_PIECE = STRETCH
#: Each strategy's kernels, one layer's and a tiled layer's, and its pieces on threads.
KERNELS = {"sweep": (sweep_layer, sweep_tiled, SWEEP_PIECE),
           "buckets": (layer_batch, tiled_batch, None)}
STRATEGIES = tuple(KERNELS)


def batch_strategy(data: np.ndarray) -> str:
    """``"sweep"`` or ``"buckets"``: the faster batched lookup for a table of ``data.nbytes``."""
    return "sweep" if data.nbytes <= SWEEP_BYTES else "buckets"


def lookup_batch(xs: np.ndarray, ys: np.ndarray, data: np.ndarray, out: np.ndarray,
                 threads: int = 1, words: tuple[np.ndarray, np.ndarray] | None = None,
                 strategy: str | None = None) -> int:
    """Palette index of each texel ``(xs[k], ys[k])`` (row 0 = top, (N,) int64) into ``out``
    (N,) uint8; returns the first position outside the layer, or -1.

    ``data`` is one layer's (M,) uint32 table, or a tiled layer's tables end to end with
    ``words`` its :func:`tiled_words`. ``strategy`` (default :func:`batch_strategy`'s) and
    ``threads`` change the speed, never the answers.
    """
    strategy = strategy or batch_strategy(data)
    if strategy not in STRATEGIES:
        raise ValueError(f"batch strategy {strategy!r}: one of {', '.join(STRATEGIES)}")
    layer_kernel, tiled_kernel, piece = KERNELS[strategy]
    kernel, tables = (layer_kernel, (data,)) if words is None else (tiled_kernel, (data, *words))
    if threads > 1:
        return on_threads(kernel, xs, ys, tables, out, threads, piece)
    return int(kernel(xs, ys, *tables, out))
