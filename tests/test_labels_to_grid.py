"""Labels -> vertex grid (vote) and the automatic cell size."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.convert.cell_choice import agreement, choose_cell_size
from terratheme.core.convert.labels_to_grid import (
    apply_lut,
    grid_shape_for,
    labels_to_grid,
    vote_grid,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid


def _naive_vote(labels: np.ndarray, n: int, m: int) -> np.ndarray:
    """Independent loop version: window of N x M pixels starting N//2, M//2 before the vertex."""
    h, w = labels.shape
    rows, cols = -(-h // m) + 1, -(-w // n) + 1
    out = np.zeros((rows, cols), dtype=np.uint8)
    for j in range(rows):
        for i in range(cols):
            x0, y0 = i * n - n // 2, j * m - m // 2
            votes: dict[int, float] = {}
            for y in range(y0, y0 + m):
                for x in range(x0, x0 + n):
                    inside = 0 <= x < w and 0 <= y < h
                    v = int(labels[min(max(y, 0), h - 1), min(max(x, 0), w - 1)])
                    wgt = 1.0 if inside else 1e-9
                    if x == i * n and y == j * m:
                        wgt *= 1.001
                    votes[v] = votes.get(v, 0.0) + wgt
            best = max(votes.values())
            out[j, i] = min(k for k, c in votes.items() if c == best)
    return out


def test_two_half_planes_known_grid():
    # Left half 0, right half 1 on an 8 x 6 photo; with cell 4 the vertices sit on columns 0, 4, 8.
    labels = np.zeros((6, 8), np.uint8)
    labels[:, 4:] = 1
    grid = vote_grid(labels, (4, 4))
    # Vertex column 1 (x=4) votes over columns 2..5: two 0s and two 1s, tie -> pixel under it (1).
    assert grid.tolist() == [[0, 1, 1]] * 3
    # Cell 2: vertices on columns 0, 2, 4, 6, 8; windows [-1,1), [1,3), [3,5), [5,7), [7,9).
    assert vote_grid(labels, (2, 2)).tolist() == [[0, 0, 1, 1, 1]] * 4
    # Odd cell 3: vertices on columns 0, 3, 6, 9 with windows [-1,2), [2,5), [5,8), [8,11).
    assert vote_grid(labels, (3, 3)).tolist() == [[0, 0, 1, 1]] * 3


def test_half_planes_agreement_is_exact_at_cell_2():
    labels = np.zeros((6, 8), np.uint8)
    labels[:, 4:] = 1
    grid = labels_to_grid(labels, 2)
    assert grid.cell == (2, 2)
    assert agreement(labels, grid) == 1.0


def test_horizontal_half_planes_rows():
    labels = np.zeros((8, 5), np.uint8)
    labels[4:] = 3
    assert vote_grid(labels, (5, 4))[:, 0].tolist() == [0, 3, 3]


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 13), w=st.integers(1, 13), n=st.integers(1, 6), m=st.integers(1, 6),
    seed=st.integers(0, 2**16), k=st.integers(1, 4),
)
def test_vote_matches_naive_loops(h, w, n, m, seed, k):
    labels = np.random.default_rng(seed).integers(0, k, (h, w)).astype(np.uint8)
    assert np.array_equal(vote_grid(labels, (n, m)), _naive_vote(labels, n, m))


def test_grid_covers_photo():
    assert grid_shape_for(10, 7, (4, 3)) == (4, 4)
    grid = labels_to_grid(np.zeros((7, 10), np.uint8), (4, 3))
    assert grid.texture_size == (12, 9)


def test_cell_1_reproduces_labels():
    labels = np.random.default_rng(1).integers(0, 5, (9, 11)).astype(np.uint8)
    grid = labels_to_grid(labels, 1)
    assert np.array_equal(grid.indices[:-1, :-1], labels)
    assert agreement(labels, grid) == 1.0


def test_lut_merges_classes_before_vote():
    labels = np.array([[1, 2, 3, 3]] * 4, np.uint8)
    lut = np.zeros(256, np.int64)
    lut[1], lut[2], lut[3] = 0, 0, 1
    assert apply_lut(labels, lut).tolist() == [[0, 0, 1, 1]] * 4
    # Classes 1 and 2 share theme 0, so together they outvote class 3 in a 4 x 4 window.
    assert labels_to_grid(labels, 4, lut=lut).indices[0, 0] == 0
    with pytest.raises(TerrathemeError, match="256 integers"):
        apply_lut(labels, [0, 1])


def _blocks(seed=0, block=24, shape=(6, 8)):
    rng = np.random.default_rng(seed)
    return np.kron(rng.integers(0, 4, shape), np.ones((block, block), int)).astype(np.uint8)


def test_choose_cell_size_monotone_in_target():
    labels = _blocks()
    cells = [choose_cell_size(labels, t).cell[0] for t in (0.5, 0.7, 0.8, 0.9, 0.95, 0.99, 1.0)]
    assert cells == sorted(cells, reverse=True)
    assert cells[-1] >= 1
    choice = choose_cell_size(labels, 0.9)
    assert choice.target_met and choice.agreement >= 0.9
    # The choice is the largest cell on the curve meeting the target.
    ok = [p.cell for p in choice.curve if p.agreement >= 0.9]
    assert choice.cell == (max(ok), max(ok))
    # Bytes fall as the cell grows.
    sizes = [p.grid_bytes for p in choice.curve]
    assert sizes == sorted(sizes, reverse=True)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), block=st.integers(2, 20),
       target=st.sampled_from([0.6, 0.8, 0.9, 0.97]), class_target=st.sampled_from([0.0, 0.5]))
def test_stopping_at_the_first_cell_that_meets_the_targets_chooses_the_same_cell(
        seed, block, target, class_target):
    labels = _blocks(seed, block, (5, 7))
    full = choose_cell_size(labels, target, class_target=class_target)
    quick = choose_cell_size(labels, target, class_target=class_target, full_curve=False)
    assert (quick.cell, quick.agreement, quick.target_met) == (
        full.cell, full.agreement, full.target_met)
    # The quick curve is the full curve's points from the chosen cell up.
    assert quick.curve == tuple(p for p in full.curve if p.cell >= quick.cell[0])


def test_the_quick_choice_without_a_cell_that_meets_the_target_measures_every_cell():
    labels = _blocks(3, 5, (6, 6))
    full = choose_cell_size(labels, 1.0, candidates=(4, 8, 16))
    quick = choose_cell_size(labels, 1.0, candidates=(4, 8, 16), full_curve=False)
    assert not full.target_met and quick == full


def test_flat_labels_choose_the_largest_cell():
    labels = np.full((40, 30), 2, np.uint8)
    choice = choose_cell_size(labels, 0.99)
    assert choice.cell == (32, 32)  # the largest default candidate <= 40
    assert choice.agreement == 1.0


def test_sampled_agreement_close_to_full():
    labels = _blocks(seed=3, block=37, shape=(20, 20))
    grid = labels_to_grid(labels, 16)
    full = agreement(labels, grid)
    sampled = agreement(labels, grid, max_pixels=labels.size // 4)
    assert abs(full - sampled) < 0.03


def test_tiny_photos():
    one = np.array([[3]], np.uint8)
    assert vote_grid(one, (1, 1)).tolist() == [[3, 3], [3, 3]]
    assert choose_cell_size(one, 0.9).cell == (1, 1)
    three = np.arange(9, dtype=np.uint8).reshape(3, 3)
    choice = choose_cell_size(three, 0.9)
    assert choice.cell == (1, 1) and choice.agreement == 1.0
    assert [p.cell for p in choice.curve] == [1, 2, 3]


def test_errors():
    with pytest.raises(TerrathemeError, match="single-channel"):
        vote_grid(np.zeros((2, 2, 3), np.uint8), (1, 1))
    with pytest.raises(TerrathemeError, match="no pixels"):
        vote_grid(np.zeros((0, 4), np.uint8), (1, 1))
    with pytest.raises(TerrathemeError, match="integers"):
        vote_grid(np.zeros((2, 2), np.float32), (1, 1))
    with pytest.raises(TerrathemeError, match="0..255"):
        vote_grid(np.full((2, 2), 300, np.int32), (1, 1))
    with pytest.raises(TerrathemeError, match="at least 1 x 1"):
        vote_grid(np.zeros((2, 2), np.uint8), (0, 2))
    with pytest.raises(TerrathemeError, match="target agreement"):
        choose_cell_size(np.zeros((4, 4), np.uint8), 1.5)
    with pytest.raises(TerrathemeError, match="no candidate"):
        choose_cell_size(np.zeros((4, 4), np.uint8), 0.9, candidates=[8, 16])
    with pytest.raises(TerrathemeError, match="smaller than"):
        agreement(np.zeros((9, 9), np.uint8), IndexGrid(np.zeros((2, 2), np.uint8), (4, 4)))
