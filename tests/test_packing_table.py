"""The random-access table: its grid of curve blocks checked against the image itself."""

from __future__ import annotations

import numpy as np
import pytest

from core.packing import layout as lay
from core.packing import pack


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
