"""The random-access table: its grid of curve blocks checked against the image itself."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from terratheme.core.packing import layout as lay
from terratheme.core.packing import pack
from terratheme.core.packing.batch import T_GRID_BITS, TILE_COLUMNS


def _words(layer):
    t = layer.table
    head = {name: int(t[i]) for i, name in enumerate(
        ["W", "H", "n", "morton", "b", "G", "N", "U", "R", "gw", "gh"])}
    grid = t[head["G"]: head["G"] + head["gw"] * head["gh"]].reshape(head["gh"], head["gw"])
    return head, grid


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
@pytest.mark.parametrize("shape", [(64, 64), (100, 77), (37, 260)])
def test_grid_words_say_which_blocks_are_uniform(curve, shape):
    rng = np.random.default_rng(sum(shape))
    h, w = shape
    img = np.kron(rng.integers(0, 3, (h // 12 + 1, w // 12 + 1)),
                  np.ones((12, 12), int))[:h, :w].astype(np.uint8)
    img[rng.random(img.shape) < 0.01] = 5
    layer = pack(img, curve)
    head, grid = _words(layer)
    side = 1 << head["b"]
    assert (head["W"], head["H"], head["R"]) == (w, h, layer.run_count)
    assert (head["gw"], head["gh"]) == (-(-w // side), -(-h // side))
    up = img[::-1]  # grid rows count from the bottom
    for by in range(head["gh"]):
        for bx in range(head["gw"]):
            block = up[by * side: (by + 1) * side, bx * side: (bx + 1) * side]
            word = int(grid[by, bx])
            # A block inside the image whose texels are all equal is answered by its word.
            full = block.shape == (side, side)
            if full and block.min() == block.max():
                assert word & lay.UNIFORM and word & 255 == block[0, 0]
            if word & lay.UNIFORM:
                assert block.min() == block.max() == word & 255


def test_grid_stays_small_and_spans_quarter_dense_blocks():
    rng = np.random.default_rng(4)
    img = np.kron(rng.integers(0, 4, (120, 120)), np.ones((2, 2), int)).astype(np.uint8)
    layer = pack(img)
    head, grid = _words(layer)
    assert grid.size <= max(1, head["R"] // 4) or head["b"] == min(head["n"], lay.MAX_GRID_BITS)
    quartered = (grid & np.uint32(lay.UNIFORM)) == 0
    assert ((grid[quartered] >> 2) & 1).any()  # dense blocks carry a quarter directory
    assert layer.memory_bytes == 4 * layer.table.size
    assert layer.memory_bytes <= 4 * lay.table_words_max(240, 240, head["n"], head["R"])
    ys, xs = np.mgrid[0:240, 0:240]
    assert np.array_equal(layer.lookup(xs, ys), img)


def test_table_is_read_only():
    layer = pack(np.zeros((5, 5), np.uint8))
    with pytest.raises(ValueError):
        layer.table[0] = 1


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_every_grid_block_side_gives_the_same_lookups(curve):
    # Block sides from 1 texel to the whole square (odd ones walk the one-level table).
    import dataclasses

    from terratheme.core.errors import TerrathemeError

    rng = np.random.default_rng(9)
    img = np.kron(rng.integers(0, 4, (9, 14)), np.ones((7, 7), int))[:61, :93].astype(np.uint8)
    img[rng.random(img.shape) < 0.05] = 6
    layer = pack(img, curve)
    ys, xs = np.mgrid[: img.shape[0], : img.shape[1]]
    for bits in range(0, 9):
        other = dataclasses.replace(layer.with_grid_bits(bits), threads=1)
        assert int(other.table[lay.W_GRID_BITS]) == min(bits, 7)
        np.testing.assert_array_equal(other.lookup(xs, ys), img)
        np.testing.assert_array_equal(other.S, layer.S)
        assert other.lookup(int(xs[5, 7]), int(ys[5, 7])) == img[5, 7]
    with pytest.raises(TerrathemeError, match="grid block bits -1"):
        layer.with_grid_bits(-1)


def test_tiles_of_a_tiled_layer_share_one_block_side():
    rng = np.random.default_rng(4)
    img = np.zeros((300, 200), np.uint8)
    img[:128, :128] = rng.integers(0, 5, (128, 128))  # busy tile; the others nearly empty
    img[200, 150] = 3
    tiled = dataclasses.replace(pack(img, tile_bits=7), join=False)
    table, words = tiled._tables()
    bits = words[1].reshape(-1, TILE_COLUMNS)[:, T_GRID_BITS]
    assert len(set(bits.tolist())) == 1
    assert [int(pack(tiled.tile(i).unpack()).table[lay.W_GRID_BITS])
            for i in range(len(bits))] != bits.tolist()  # their own choice would differ
    ys, xs = np.mgrid[:300, :200]
    np.testing.assert_array_equal(tiled.lookup(xs, ys), img)
