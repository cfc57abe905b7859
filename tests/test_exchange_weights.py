"""Theme weights at export-map pixels: the renderer's rule, 8-bit weights summing to 255."""

from __future__ import annotations

import numpy as np
import pytest
from exchange_cases import theme_weights
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import ExportLayout, sample_corners, strongest_two
from terratheme.core.exchange.layout import tiled_length
from terratheme.core.render.renderer import render_cells, render_labels
from terratheme.core.render.rules import SaddleRule


def _onehot_render(grid: np.ndarray, cell: tuple[int, int], k: int) -> np.ndarray:
    """The renderer's own weight of theme ``k`` times 255 (rounded): flat themes 255 / 0."""
    n = int(grid.max()) + 1
    flats = [np.full((4, 4, 3), 255 if j == k else 0, np.uint8) for j in range(n)]
    return render_cells(grid, flats, cell)[:, :, 0].astype(int)


def test_known_weights_of_one_anti_diagonal_cell():
    # a b / c d = 0 1 / 1 1: the anti-diagonal has equal ends, so the cell splits along it;
    # theme 0 holds only the corner triangle x + y <= 1 with weight 1 - x - y.
    grid = np.array([[0, 1], [1, 1]], np.uint8)
    w = theme_weights(grid, (5, 5), n_themes=2)
    want0 = np.array([[255, 191, 128, 64, 0],
                      [191, 128, 64, 0, 0],
                      [128, 64, 0, 0, 0],
                      [64, 0, 0, 0, 0],
                      [0, 0, 0, 0, 0]])
    np.testing.assert_array_equal(w[0], want0)
    np.testing.assert_array_equal(w[1], 255 - want0)


def test_saddle_rule_decides_the_split():
    # Saddle cell 0 1 / 1 0 at the top left; theme 1 has no other vertex in the ring, theme 0
    # has five, so MINORITY connects theme 1 (anti-diagonal) and MAIN connects theme 0.
    grid = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 0]], np.uint8)
    # Pixel (1, 1) of a 5 x 5 map is the centre of cell (0, 0).
    minority = theme_weights(grid, (5, 5), n_themes=2)[:, 1, 1]
    main = theme_weights(grid, (5, 5), n_themes=2, saddle=SaddleRule.MAIN)[:, 1, 1]
    np.testing.assert_array_equal(minority, [0, 255])
    np.testing.assert_array_equal(main, [255, 0])


def test_largest_remainder_gives_the_missing_unit_to_the_lower_theme_on_a_tie():
    # Halfway along an edge between themes 2 and 1: 127.5 each; the lower theme (1) gets 128.
    grid = np.array([[2, 1], [2, 1]], np.uint8)
    w = theme_weights(grid, (3, 2), n_themes=3)
    np.testing.assert_array_equal(w[:, 0, 1], [0, 128, 127])


@pytest.mark.parametrize("cell", [(8, 8), (5, 7), (16, 4)])
def test_native_size_weights_are_the_renderers(cell):
    rng = np.random.default_rng(sum(cell))
    grid = rng.integers(0, 4, (6, 7)).astype(np.uint8)
    n, m = cell
    size = (6 * n + 1, 5 * m + 1)
    w = theme_weights(grid, size, n_themes=4).astype(int)
    assert (w.sum(axis=0) == 255).all()
    for k in range(4):
        # The renderer rounds 255 * weight half up; largest remainder stays within one unit.
        assert np.abs(w[k, :-1, :-1] - _onehot_render(grid, cell, k)).max() <= 1
    # A pixel on a vertex carries that vertex's theme alone.
    on_vertices = w[:, ::m, ::n]
    np.testing.assert_array_equal(on_vertices.argmax(axis=0), grid)
    assert (on_vertices.max(axis=0) == 255).all()


def test_native_size_weights_rebuild_the_render_within_2_levels():
    rng = np.random.default_rng(3)
    grid = rng.integers(0, 5, (9, 11)).astype(np.uint8)
    grid[2:5, 3:6] = [[0, 1, 0], [1, 0, 1], [0, 1, 0]]  # saddles
    textures = [rng.integers(0, 256, (13 + k, 11, 3)).astype(np.uint8) for k in range(5)]
    cell = (6, 5)
    ref = render_cells(grid, textures, cell).astype(float)
    h, w = ref.shape[:2]
    weights = theme_weights(grid, (w + 1, h + 1), n_themes=5)[:, :h, :w].astype(float)
    ys, xs = np.mgrid[:h, :w]
    rebuilt = sum(weights[k, :, :, None] * t[ys % t.shape[0], xs % t.shape[1]]
                  for k, t in enumerate(textures)) / 255
    assert np.abs(np.floor(rebuilt + 0.5) - ref).max() <= 2
    np.testing.assert_array_equal(weights.argmax(axis=0), render_labels(grid, cell))


def test_windows_and_bands_agree_with_the_whole_map(monkeypatch):
    rng = np.random.default_rng(5)
    grid = rng.integers(0, 3, (5, 6)).astype(np.uint8)
    whole = theme_weights(grid, (41, 29), n_themes=3)
    part = theme_weights(grid, (41, 29), (7, 3, 20, 11), n_themes=3)
    np.testing.assert_array_equal(part, whole[:, 3:14, 7:27])
    import terratheme.core.exchange.weights as weights_module

    monkeypatch.setattr(weights_module, "BAND_PIXELS", 50)
    np.testing.assert_array_equal(theme_weights(grid, (41, 29), n_themes=3), whole)


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.integers(2, 40), st.integers(2, 40),
       st.integers(0, 2**32 - 1))
def test_weights_sum_to_255_and_nest(gw, gh, w, h, seed):
    grid = np.random.default_rng(seed).integers(0, 5, (gh, gw)).astype(np.uint8)
    coarse = theme_weights(grid, (w, h), n_themes=5)
    assert coarse.dtype == np.uint8 and (coarse.sum(axis=0, dtype=int) == 255).all()
    # Pixel 2i of a (2W - 1)-pixel map lies where pixel i of the W-pixel map does.
    fine = theme_weights(grid, (2 * w - 1, 2 * h - 1), n_themes=5)
    np.testing.assert_array_equal(fine[:, ::2, ::2], coarse)


def test_sixteen_bit_weights_sum_to_65535():
    grid = np.array([[0, 1, 2], [2, 1, 0]], np.uint8)
    w = theme_weights(grid, (37, 11), n_themes=3, total=65535)
    assert w.dtype == np.uint16 and (w.sum(axis=0, dtype=int) == 65535).all()


def test_huge_denominators_are_rounded_not_overflowed():
    # (W - 1) and (H - 1) prime to the cell counts: D = 40960 * 30720 > 2**28.
    grid = np.array([[0, 1], [1, 2]], np.uint8)
    slots = sample_corners(grid, (40961, 30721), (20480, 15360, 2, 2))
    assert slots.denominator == (1 << 14) ** 2
    assert (slots.weights.sum(axis=0) == slots.denominator).all()


def test_huge_denominators_round_local_coordinates_half_up():
    # Left column theme 0, right column theme 1: theme 1's weight is the local x, whichever
    # way the cell splits. Pixel 20482 of a 40961-wide map over one cell lies at
    # 20482 / 40960 of it: 8192.8 / 16384 once rounded to 1/16384 (the exact denominator
    # 40960 * 30720 > 2**28), so 8193, not 8192.
    grid = np.array([[0, 1], [0, 1]], np.uint8)
    slots = sample_corners(grid, (40961, 30721), (20482, 15361, 1, 1))
    assert slots.denominator == (1 << 14) ** 2
    right = int(slots.weights[:, 0, 0][slots.ids[:, 0, 0] == 1].sum())
    assert right == 8193 * (1 << 14)


def test_strongest_two_and_their_share():
    # Centre of a MAIN-split cell 0 1 / 2 0: theme 0 alone on the diagonal; a quarter of the way
    # along the top edge: 0 (3/4) and 1 (1/4).
    grid = np.array([[0, 1], [2, 0]], np.uint8)
    slots = sample_corners(grid, (5, 5))
    first, second, share = strongest_two(slots)
    assert (first[2, 2], second[2, 2], share[2, 2]) == (0, 0, 0)
    assert (first[0, 1], second[0, 1], share[0, 1]) == (0, 1, 64)
    assert (first[0, 4], second[0, 4], share[0, 4]) == (1, 1, 0)


def test_bad_inputs_raise():
    grid = np.array([[0, 1], [1, 3]], np.uint8)
    with pytest.raises(TerrathemeError, match="theme index 3 but the library has only 2"):
        theme_weights(grid, (5, 5), n_themes=2)
    with pytest.raises(TerrathemeError, match="at least 2 x 2 pixels"):
        sample_corners(grid, (1, 5))
    with pytest.raises(TerrathemeError, match="outside the 5 x 5 map"):
        theme_weights(grid, (5, 5), (3, 0, 3, 2), n_themes=4)


def test_layout_tiles_share_their_borders():
    layout = ExportLayout((tiled_length(100, 32), tiled_length(40, 32)), 32)
    assert layout.size == (125, 63) and layout.tiles == (4, 2)
    pieces = layout.pieces()
    assert pieces[1].x == pieces[0].x + 31 and pieces[4].y == 31
    assert pieces[5].suffix == "_x1_y1"
    with pytest.raises(TerrathemeError, match=r"k \* 31 \+ 1"):
        ExportLayout((100, 63), 32)
    with pytest.raises(TerrathemeError, match="larger than"):
        ExportLayout((1 << 15, 1 << 14))


def test_world_frame_converts_crs_units_to_metres():
    from terratheme.core.exchange import world_frame

    feet = {"ModelPixelScale": [2.0, 2.0, 0.0], "ModelTiepoint": [0, 0, 0, 100.0, 50.0, 0],
            "GeoKeyDirectory": [1, 1, 0, 2, 1024, 0, 1, 1, 3076, 0, 1, 9003]}
    frame = world_frame(feet, (10, 10))
    assert frame.units == "metre" and frame.crs_units == "US survey foot"
    assert frame.texel_size == pytest.approx((2 * 1200 / 3937,) * 2)
    assert frame.origin == (101.0, 49.0)  # the centre of texel (0, 0), in CRS feet
    degrees = {"ModelPixelScale": [1e-4, 1e-4, 0.0], "ModelTiepoint": [0, 0, 0, 10.0, 60.0, 0],
               "GeoKeyDirectory": [1, 1, 0, 1, 1024, 0, 1, 2]}
    frame = world_frame(degrees, (100, 100))
    # At 60 degrees north a degree of longitude is half a degree of latitude.
    assert frame.texel_size[0] == pytest.approx(frame.texel_size[1] / 2, rel=1e-3)
    assert world_frame({}, (4, 4)).units == "texel"
