"""Batched lookups sorted by bucket, and the scalar path's quick cells (issue 19)."""

from __future__ import annotations

import dataclasses
import threading

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing import PackedLayer, TiledLayer, pack, scalar
from terratheme.core.packing.batch import (
    BUCKET_RUNS,
    CHUNK,
    SWEEP_BYTES,
    batch_strategy,
    bucket_shift,
    layer_batch,
    lookup_batch,
    tiled_batch,
)
from terratheme.core.packing.layout import JOINED, W_GRID_BITS, W_MORTON
from terratheme.core.packing.prefetch import prefetch
from terratheme.core.packing.scalar import quick_cells
from terratheme.core.packing.sweep import sweep_layer
from terratheme.core.packing.threads import on_threads


def _blocks(rng: np.random.Generator, h: int, w: int, cell: int, k: int) -> np.ndarray:
    # Rectangles of one index with noise on top: uniform blocks and busy ones.
    img = rng.integers(0, k, (-(-h // cell), -(-w // cell))).repeat(cell, 0).repeat(cell, 1)
    img = img[:h, :w].astype(np.uint8)
    noise = rng.random((h, w)) < 0.02
    img[noise] = rng.integers(0, k, int(noise.sum()))
    return img


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(1, 300), st.sampled_from(["hilbert", "morton"]),
       st.integers(1, 40), st.integers(1, 4), st.integers(0, 2**31))
def test_batch_equals_dense_on_any_parts(w, h, curve, cell, parts, seed):
    rng = np.random.default_rng(seed)
    img = _blocks(rng, h, w, cell, 6)
    layer = pack(img, curve)
    xs = rng.integers(0, w, 3000)
    ys = rng.integers(0, h, 3000)
    out = np.zeros(xs.size, np.uint8)
    assert layer_batch(xs, ys, layer.table, out) == -1
    assert np.array_equal(out, img[ys, xs])
    out[:] = 0
    assert on_threads(layer_batch, xs, ys, (layer.table,), out, parts) == -1
    assert np.array_equal(out, img[ys, xs])
    # Every texel once, in scan order and in reverse.
    rows, cols = np.mgrid[0:h, 0:w]
    assert np.array_equal(layer.lookup(cols, rows), img)
    assert np.array_equal(layer.lookup(cols[::-1, ::-1], rows[::-1, ::-1]), img[::-1, ::-1])


@pytest.mark.parametrize("parts", [1, 2, 3])
def test_first_bad_texel_is_reported(parts):
    img = _blocks(np.random.default_rng(1), 70, 90, 5, 4)
    layer = pack(img)
    xs = np.arange(5000) % 90
    ys = np.arange(5000) % 70
    xs[4000], xs[4500] = 90, -1
    out = np.zeros(xs.size, np.uint8)
    bad = (layer_batch(xs, ys, layer.table, out) if parts == 1
           else on_threads(layer_batch, xs, ys, (layer.table,), out, parts))
    assert bad == 4000


def test_batch_over_several_chunks():
    rng = np.random.default_rng(4)
    img = _blocks(rng, 400, 500, 7, 9)
    layer = pack(img)
    xs = rng.integers(0, 500, CHUNK + 4321)
    ys = rng.integers(0, 400, CHUNK + 4321)
    assert np.array_equal(layer.lookup(xs, ys), img[ys, xs])
    assert np.array_equal(dataclasses.replace(layer, threads=1).lookup(xs, ys), img[ys, xs])
    ys[CHUNK + 7] = 400
    with pytest.raises(TerrathemeError, match=r"\(\d+, 400\) is outside the 500 x 400"):
        layer.lookup(xs, ys)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 200), st.integers(1, 200), st.integers(6, 7), st.integers(1, 3),
       st.booleans(), st.integers(0, 2**31))
def test_tiled_batch_equals_dense(w, h, tile_bits, parts, join, seed):
    # Through the joined table (when the tiles join) or each tile's own table.
    rng = np.random.default_rng(seed)
    img = _blocks(rng, h, w, 3, 5)
    layer = dataclasses.replace(pack(img, tile_bits=tile_bits), join=join)
    table, words = layer._tables()
    assert join or words is not None
    xs = rng.integers(0, w, 4000)
    ys = rng.integers(0, h, 4000)
    out = np.zeros(xs.size, np.uint8)
    if words is None:
        assert table[W_MORTON] == JOINED
        assert on_threads(layer_batch, xs, ys, (table,), out, parts) == -1
    else:
        assert on_threads(tiled_batch, xs, ys, (table, *words), out, parts) == -1
    assert np.array_equal(out, img[ys, xs])
    assert np.array_equal(dataclasses.replace(layer, threads=1).lookup(xs, ys), img[ys, xs])
    k = int(rng.integers(0, xs.size))
    assert layer.lookup(int(xs[k]), int(ys[k])) == img[ys[k], xs[k]]


@settings(max_examples=15, deadline=None)
@given(st.integers(1, 330), st.integers(1, 330), st.integers(0, 2**31))
def test_joined_table_of_mixed_curves_equals_dense(w, h, seed):
    # Tiles of both curves (chosen at random) in one joined table, the last tile row
    # shorter than the others (the cut): every texel, both strategies, 1 and 2 threads.
    rng = np.random.default_rng(seed)
    img = _blocks(rng, h, w, int(rng.integers(1, 20)), 4)
    blobs = [pack(np.ascontiguousarray(img[y: y + 64, x: x + 64]),
                  ("hilbert", "morton")[int(rng.integers(0, 2))]).to_bytes()
             for y in range(0, h, 64) for x in range(0, w, 64)]
    layer = TiledLayer.from_tile_bytes(w, h, 6, blobs, np.arange(4, dtype=np.uint8)[:, None],
                                       identity=True, squeeze=True)
    table, words = layer._tables()
    if words is not None:
        # Only a corner tile smaller than the grid's blocks keeps the tiles apart.
        bits = int(layer.tile(0).table[W_GRID_BITS])
        assert max(w % 64 or 64, h % 64 or 64) <= 1 << (bits - 1)
        return
    ys, xs = (a.ravel() for a in np.mgrid[:h, :w])
    for strategy in ("sweep", "buckets"):
        for threads in (1, 2):
            out = np.zeros(xs.size, np.uint8)
            assert lookup_batch(xs, ys, table, out, threads, None, strategy) == -1
            assert np.array_equal(out, img[ys, xs])
    assert all(layer.lookup(int(x), int(y)) == img[y, x]
               for x, y in zip(xs[::97], ys[::97], strict=True))


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 260), st.integers(1, 260), st.sampled_from(["hilbert", "morton"]),
       st.sampled_from([None, 6, 7]), st.integers(1, 3), st.integers(0, 2**31))
def test_both_strategies_answer_alike(w, h, curve, tile_bits, threads, seed):
    # Sweeps and buckets on the same table (one layer or a tiled one): the same
    # indices, those of the dense image, and the same first bad texel.
    rng = np.random.default_rng(seed)
    img = _blocks(rng, h, w, int(rng.integers(1, 30)), 7)
    layer = pack(img, curve, tile_bits=tile_bits)
    table, words = layer._tables() if tile_bits else (layer.table, None)
    xs = rng.integers(0, w, 5000)
    ys = rng.integers(0, h, 5000)
    answers = {}
    for strategy in ("sweep", "buckets"):
        out = np.zeros(xs.size, np.uint8)
        assert lookup_batch(xs, ys, table, out, threads, words, strategy) == -1
        answers[strategy] = out
    assert np.array_equal(answers["sweep"], answers["buckets"])
    assert np.array_equal(answers["sweep"], img[ys, xs])
    k = int(rng.integers(0, xs.size))
    xs[k] = w
    xs[min(xs.size - 1, k + 17)] = -1
    assert [lookup_batch(xs, ys, table, np.zeros(xs.size, np.uint8), threads, words, s)
            for s in ("sweep", "buckets")] == [k, k]


@pytest.mark.parametrize(("parts", "piece"), [(2, 1), (2, 777), (3, 1000), (3, 4096), (2, None)])
def test_pieces_cover_the_batch_once(parts, piece):
    # Whichever thread takes a piece, every texel is looked up once, in a slice of
    # `piece` texels starting at a multiple of it (one slice per thread without one).
    n = 10007
    taken = []

    def record(xs, ys, out):
        taken.append((int(xs[0]), xs.size))
        out[:] = 1
        return -1

    xs = np.arange(n, dtype=np.int64)
    out = np.zeros(n, np.uint8)
    assert on_threads(record, xs, xs, (), out, parts, piece) == -1
    size = -(-n // parts) if piece is None else piece
    assert sorted(taken) == [(a, min(size, n - a)) for a in range(0, n, size)]
    assert out.all()


def test_a_thread_held_back_leaves_its_share_to_the_others():
    # The pool's thread stops in its first piece until the calling thread has done
    # all the others: the batch ends with every piece done, 1 by the pool's thread.
    pieces = 9
    started, rest_done = threading.Event(), threading.Event()
    done = {"main": 0, "pool": 0}
    main = threading.get_ident()

    def held(xs, ys, out):
        out[:] = 1
        if threading.get_ident() != main:
            started.set()
            assert rest_done.wait(10)
            done["pool"] += 1
            return -1
        assert started.wait(10)
        done["main"] += 1
        if done["main"] == pieces - 1:
            rest_done.set()
        return -1

    xs = np.zeros(pieces * 10, np.int64)
    out = np.zeros(xs.size, np.uint8)
    assert on_threads(held, xs, xs, (), out, 2, 10) == -1
    assert done == {"main": pieces - 1, "pool": 1}
    assert out.all()


@pytest.mark.parametrize(("parts", "piece"), [(2, 100), (3, 1), (2, None)])
def test_pieces_answer_as_dense_and_report_the_first_bad_texel(parts, piece):
    rng = np.random.default_rng(5)
    img = _blocks(rng, 90, 70, 6, 5)
    table = pack(img).table
    xs = rng.integers(0, 70, 4000)
    ys = rng.integers(0, 90, 4000)
    out = np.zeros(xs.size, np.uint8)
    assert on_threads(sweep_layer, xs, ys, (table,), out, parts, piece) == -1
    assert np.array_equal(out, img[ys, xs])
    # Bad texels in several pieces: the first of them, whichever piece ends first.
    xs[[3500, 2100, 650]] = [70, -3, 71]
    assert on_threads(sweep_layer, xs, ys, (table,), out, parts, piece) == 650
    assert on_threads(sweep_layer, xs[:0], ys[:0], (table,), out[:0], parts, piece) == -1


def test_strategy_follows_table_size():
    small = np.zeros(SWEEP_BYTES // 4, np.uint32)
    assert batch_strategy(small) == "sweep"
    assert batch_strategy(np.zeros(small.size + 1, np.uint32)) == "buckets"
    with pytest.raises(ValueError, match="batch strategy 'fast'"):
        lookup_batch(np.zeros(1, np.int64), np.zeros(1, np.int64), small, np.zeros(1, np.uint8),
                     strategy="fast")


@given(st.integers(1, 2**26), st.integers(1, 2**30))
def test_bucket_shift_holds_about_bucket_runs(blocks, runs):
    s = bucket_shift(blocks, runs)
    # The most grid words per bucket whose share of the runs stays within BUCKET_RUNS.
    assert s == 0 or (1 << s) * runs <= BUCKET_RUNS * blocks
    assert (2 << s) * runs > BUCKET_RUNS * blocks or s == 40


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 300), st.integers(1, 300), st.sampled_from(["hilbert", "morton"]),
       st.sampled_from([1 << 22, 64, 1]), st.integers(0, 2**31))
def test_quick_cells_are_the_uniform_cells_index(w, h, curve, cap, seed):
    # Every cell (aligned to the bottom-left corner) with a byte below 255 holds that index
    # only; every cell inside the image of one index (below 255) says so; the cells fit
    # the cap when any can.
    rng = np.random.default_rng(seed)
    img = _blocks(rng, h, w, int(rng.integers(1, 40)), 5)
    layer = pack(img, curve)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(scalar, "QUICK_CELLS", cap)
        bits, rows = quick_cells(layer.table)
    assert len(rows) == h
    side = 1 << bits
    cells_across = -(-w >> bits)
    assert all(len(r) == cells_across for r in rows)
    assert bits == 0 or cells_across * -(-h >> bits) <= cap or side >= max(w, h)
    yup = h - 1 - np.arange(h)
    for cy in range(-(-h >> bits)):
        band = img[(yup >> bits) == cy]
        row = rows[int(np.flatnonzero((yup >> bits) == cy)[0])]
        for cx in range(cells_across):
            cell = band[:, cx * side: (cx + 1) * side]
            if row[cx] != 255:
                assert np.all(cell == row[cx])
            elif cell.size == side * side and cell.min() == cell.max():
                assert cell.min() == 255  # (cells at the edges may be marked 255 anyway)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 90), st.integers(1, 90), st.sampled_from(["hilbert", "morton"]),
       st.integers(0, 2**31))
def test_scalar_lookup_equals_dense(w, h, curve, seed):
    rng = np.random.default_rng(seed)
    # 256 colours: uniform blocks of index 255 (the quick grid's "look it up") too.
    img = _blocks(rng, h, w, 17, 3)
    img = np.where(img == 0, 255, img * 100).astype(np.uint8)
    layer = pack(img, curve)
    for y in range(h):
        for x in range(w):
            assert layer.lookup(x, y) == img[y, x]
    x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
    for kind in (np.int64, np.int32, np.uint16, np.uint8):
        if x < 256 and y < 256:
            assert layer.lookup(kind(x), kind(y)) == img[y, x]


def test_scalar_lookup_colours_and_errors():
    rng = np.random.default_rng(8)
    idx = _blocks(rng, 50, 70, 9, 4)
    colours = np.array([[10, 20, 30], [40, 50, 60], [70, 80, 90], [1, 2, 3]], np.uint8)
    img = colours[idx]
    layer = pack(img)
    assert all(np.array_equal(layer.lookup(x, y), img[y, x])
               for y in range(0, 50, 3) for x in range(0, 70, 4))
    for x, y in ((70, 0), (0, 50), (-1, 0), (0, -1), (2**70, 0), (0, -(2**70))):
        with pytest.raises(TerrathemeError, match="outside the 70 x 50 layer"):
            layer.lookup(x, y)
    # A copy over another table (with_table, with_grid_bits) answers from its own table.
    other = layer.with_grid_bits(6)
    assert isinstance(other, PackedLayer)
    assert all(np.array_equal(other.lookup(x, y), img[y, x])
               for y in range(0, 50, 5) for x in range(0, 70, 3))


def test_prefetch_takes_a_1d_array_and_an_integer():
    @numba.njit
    def hint(a, i):
        prefetch(a, i)

    with pytest.raises(numba.TypingError, match="prefetch"):
        hint(np.zeros((2, 2), np.uint32), 0)
    with pytest.raises(numba.TypingError, match="prefetch"):
        hint(np.zeros(4, np.uint32), 1.5)
