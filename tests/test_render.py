"""The renderer against an independent per-texel reference (DESIGN.md §1)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells, render_labels
from terratheme.core.render.rules import (
    ANTI,
    MAIN,
    UNIFORM,
    SaddleRule,
    cell_splits,
    corner_weights,
)


def _split_ref(g: np.ndarray, i: int, j: int) -> str:
    """Reference split of cell (row j, column i), written from the documented rule."""
    a, b, c, d = int(g[j, i]), int(g[j, i + 1]), int(g[j + 1, i]), int(g[j + 1, i + 1])
    if a == b == c == d:
        return "uniform"
    if a == d and b != c:
        return "main"
    if b == c and a != d:
        return "anti"
    if a == d and b == c:
        # Saddle: count the 12 ring vertices around the cell.
        na = nb = 0
        for r in range(j - 1, j + 3):
            for q in range(i - 1, i + 3):
                if j <= r <= j + 1 and i <= q <= i + 1:
                    continue
                if 0 <= r < g.shape[0] and 0 <= q < g.shape[1]:
                    na += int(g[r, q]) == a
                    nb += int(g[r, q]) == b
        if nb < na or (nb == na and b < a):
            return "anti"
        return "main"
    return "main"


def _weights_ref(split: str, x: Fraction, y: Fraction) -> dict[tuple[int, int], Fraction]:
    """DESIGN.md §1 formulas, corner (row, col) -> weight."""
    if split == "uniform":
        return {(0, 0): Fraction(1)}
    if split == "main":
        if x <= y:
            return {(1, 0): y - x, (0, 0): 1 - y, (1, 1): x}
        return {(0, 1): x - y, (0, 0): 1 - x, (1, 1): y}
    if x + y <= 1:
        return {(0, 0): 1 - x - y, (0, 1): x, (1, 0): y}
    return {(1, 1): x + y - 1, (0, 1): 1 - y, (1, 0): 1 - x}


def render_ref(g: np.ndarray, themes: list[np.ndarray], n: int, m: int) -> np.ndarray:
    """Straightforward per-texel render with exact fractions, rounded half up."""
    gh, gw = g.shape[0] - 1, g.shape[1] - 1
    out = np.zeros((gh * m, gw * n, 3), dtype=np.uint8)
    for Y in range(gh * m):
        for X in range(gw * n):
            j, i = Y // m, X // n
            x, y = Fraction(X - i * n, n), Fraction(Y - j * m, m)
            ws = _weights_ref(_split_ref(g, i, j), x, y)
            assert sum(ws.values()) == 1
            for ch in range(3):
                v = Fraction(0)
                for (dr, dc), w in ws.items():
                    t = themes[int(g[j + dr, i + dc])]
                    v += w * int(t[Y % t.shape[0], X % t.shape[1], ch])
                out[Y, X, ch] = int(v + Fraction(1, 2))  # floor(v + 1/2), v >= 0
    return out


def _themes(rng: np.random.Generator, k: int) -> list[np.ndarray]:
    sizes = [(3, 5), (4, 4), (7, 2), (5, 6), (1, 1), (2, 9)]
    return [rng.integers(0, 256, (*sizes[i % len(sizes)], 3), dtype=np.uint8) for i in range(k)]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("cell", [(4, 4), (5, 3), (1, 1), (3, 7)])
def test_matches_reference(seed: int, cell: tuple[int, int]) -> None:
    rng = np.random.default_rng(seed)
    k = 2 + seed % 3
    g = rng.integers(0, k, (4 + seed % 2, 5), dtype=np.uint8)
    themes = _themes(rng, k)
    got = render_cells(g, themes, cell)
    assert got.shape == ((g.shape[0] - 1) * cell[1], (g.shape[1] - 1) * cell[0], 3)
    np.testing.assert_array_equal(got, render_ref(g, themes, *cell))


@settings(max_examples=25, deadline=None)
@given(
    st.integers(0, 10_000),
    st.integers(1, 6),
    st.integers(1, 6),
    st.integers(2, 4),
)
def test_matches_reference_hypothesis(seed: int, n: int, m: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    g = rng.integers(0, k, (rng.integers(2, 5), rng.integers(2, 5)), dtype=np.uint8)
    themes = _themes(rng, k)
    np.testing.assert_array_equal(render_cells(g, themes, (n, m)), render_ref(g, themes, n, m))


def test_large_cell_division_fallback_matches_reference() -> None:
    # D = N*M large enough that the multiply-shift reciprocal is not used.
    rng = np.random.default_rng(5)
    themes = _themes(rng, 2)
    g = np.array([[0, 1], [1, 1]])
    n, m = 3000, 1500
    region = (2990, 1480, 10, 20)
    got = render_cells(g, themes, (n, m), region)
    x = Fraction(2995, n)
    y = Fraction(1490, m)
    ws = _weights_ref("anti", x, y)
    for ch in range(3):
        v = sum(w * int(themes[int(g[r, c])][1490 % themes[int(g[r, c])].shape[0],
                                            2995 % themes[int(g[r, c])].shape[1], ch])
                for (r, c), w in ws.items())
        assert got[10, 5, ch] == int(v + Fraction(1, 2))


def test_weights_sum_to_one_and_are_nonnegative() -> None:
    for n, m in [(4, 4), (5, 3), (16, 9)]:
        d = n * m
        xi = (np.arange(n) * m)[None, :]
        yi = (np.arange(m) * n)[:, None]
        for split in (UNIFORM, MAIN, ANTI):
            ws = corner_weights(np.full((m, n), split), xi, yi, d)
            total = sum(w.astype(np.int64) for w in ws)
            assert np.all(total == d)
            assert all(np.all(w >= 0) for w in ws)
            # Each triangle blends at most three themes: one corner weight is 0.
            if split != UNIFORM:
                assert np.all(np.min(np.stack(ws), axis=0) == 0)


def test_cell_corner_reproduces_theme() -> None:
    rng = np.random.default_rng(1)
    themes = _themes(rng, 4)
    g = rng.integers(0, 4, (5, 6))
    n, m = 5, 4
    img = render_cells(g, themes, (n, m))
    for j in range(g.shape[0] - 1):
        for i in range(g.shape[1] - 1):
            t = themes[g[j, i]]
            X, Y = i * n, j * m
            np.testing.assert_array_equal(img[Y, X], t[Y % t.shape[0], X % t.shape[1]])


def test_shared_cell_edges_agree() -> None:
    """Along a cell edge the blend is the 1-D interpolation of the edge's two vertices.

    Cell (i, j)'s left column must equal what cell (i-1, j) gives at x = 1 (its
    right edge, evaluated from its own formula), whatever either cell's split.
    """
    rng = np.random.default_rng(2)
    flat = [np.full((1, 1, 3), v, dtype=np.uint8) for v in (0, 90, 200, 255)]
    g = rng.integers(0, 4, (6, 7))
    n, m = 6, 5
    img = render_cells(g, flat, (n, m)).astype(int)
    splits = cell_splits(g.astype(np.uint8))
    for j in range(g.shape[0] - 1):
        for i in range(1, g.shape[1] - 1):
            for ys in range(m):
                y = Fraction(ys, m)
                name = {UNIFORM: "uniform", MAIN: "main", ANTI: "anti"}[int(splits[j, i - 1])]
                ws = _weights_ref(name, Fraction(1), y)
                v = sum(w * int(flat[g[j + r, i - 1 + c]][0, 0, 0]) for (r, c), w in ws.items())
                assert img[j * m + ys, i * n, 0] == int(v + Fraction(1, 2))


def test_uniform_cells_equal_theme_and_wrap() -> None:
    rng = np.random.default_rng(3)
    themes = _themes(rng, 3)
    g = np.full((4, 5), 2)
    img = render_cells(g, themes, (7, 6))
    t = themes[2]
    tiled = np.tile(t, (-(-img.shape[0] // t.shape[0]), -(-img.shape[1] // t.shape[1]), 1))
    np.testing.assert_array_equal(img, tiled[: img.shape[0], : img.shape[1]])


def test_wraparound_continuity_across_theme_period() -> None:
    # A 3-column theme in 4-wide cells: every column X samples theme column X % 3.
    t = np.zeros((2, 3, 3), dtype=np.uint8)
    t[:, :, 0] = [[10, 20, 30], [40, 50, 60]]
    img = render_cells(np.zeros((3, 4)), [t], (4, 4))
    assert list(img[0, :7, 0]) == [10, 20, 30, 10, 20, 30, 10]
    assert list(img[:5, 5, 0]) == [30, 60, 30, 60, 30]


def test_saddle_rule_deterministic_and_connects_thin_feature() -> None:
    # A river (1) running along the anti-diagonal through forest (0).
    g = np.array([[0, 0, 0, 1], [0, 0, 1, 0], [0, 1, 0, 0], [1, 0, 0, 0]], dtype=np.uint8)
    s = cell_splits(g)
    assert s[1, 1] == ANTI  # the saddle cell keeps the river connected
    assert np.array_equal(s, cell_splits(g.copy()))
    assert cell_splits(g, SaddleRule.MAIN)[1, 1] == MAIN
    # Isolated saddle, tie: the lower index connects.
    assert cell_splits(np.array([[1, 0], [0, 1]], dtype=np.uint8))[0, 0] == ANTI
    assert cell_splits(np.array([[0, 1], [1, 0]], dtype=np.uint8))[0, 0] == MAIN
    flat = [np.full((1, 1, 3), v, dtype=np.uint8) for v in (0, 200)]
    a = render_cells(g, flat, (8, 8))
    b = render_cells(g, flat, (8, 8))
    np.testing.assert_array_equal(a, b)
    # The river is at full strength at the centre of the saddle cell.
    assert a[8 + 4, 8 + 4, 0] == 200


def test_no_equal_diagonal_uses_main() -> None:
    assert cell_splits(np.array([[0, 1], [2, 3]], dtype=np.uint8))[0, 0] == MAIN
    assert cell_splits(np.array([[0, 0], [1, 2]], dtype=np.uint8))[0, 0] == MAIN
    assert cell_splits(np.array([[0, 1], [1, 2]], dtype=np.uint8))[0, 0] == ANTI


@pytest.mark.parametrize("blend", list(BlendMode))
def test_region_equals_crop(blend: BlendMode) -> None:
    rng = np.random.default_rng(4)
    themes = _themes(rng, 4)
    g = rng.integers(0, 4, (9, 11))
    opts = RenderOptions(blend=blend)
    full = render_cells(g, themes, (7, 5), options=opts)
    for x, y, w, h in [(0, 0, 1, 1), (3, 2, 20, 9), (69, 39, 1, 1), (5, 4, 65, 36), (0, 0, 70, 40)]:
        np.testing.assert_array_equal(
            render_cells(g, themes, (7, 5), (x, y, w, h), options=opts), full[y : y + h, x : x + w]
        )


def test_threads_do_not_change_result() -> None:
    rng = np.random.default_rng(7)
    themes = [rng.integers(0, 256, (32, 32, 3), dtype=np.uint8) for _ in range(3)]
    g = rng.integers(0, 3, (40, 40))
    a = render_cells(g, themes, (16, 16), options=RenderOptions(threads=1))
    b = render_cells(g, themes, (16, 16), options=RenderOptions(threads=2))
    np.testing.assert_array_equal(a, b)


def test_index_grid_and_progress() -> None:
    calls = []
    g = IndexGrid(np.array([[0, 1], [1, 1]]), (300, 300))
    img = render_cells(g, [np.zeros((2, 2, 3), np.uint8)] * 2,
                       progress=lambda d, t: calls.append((d, t)))
    assert img.shape == (300, 300, 3)
    assert calls and calls[-1][0] == calls[-1][1]


def test_labels_match_reference() -> None:
    rng = np.random.default_rng(8)
    g = rng.integers(0, 4, (5, 6))
    n, m = 4, 3
    lab = render_labels(g, (n, m))
    for Y in range(lab.shape[0]):
        for X in range(lab.shape[1]):
            j, i = Y // m, X // n
            ws = _weights_ref(_split_ref(g, i, j), Fraction(X - i * n, n), Fraction(Y - j * m, m))
            total: dict[int, Fraction] = {}
            for (r, c), w in ws.items():
                total[int(g[j + r, i + c])] = total.get(int(g[j + r, i + c]), 0) + w
            best = min(total, key=lambda k: (-total[k], k))
            assert lab[Y, X] == best
    np.testing.assert_array_equal(render_labels(g, (n, m), (3, 2, 9, 7)), lab[2:9, 3:12])


def test_histogram_blend_keeps_pure_theme_texels_and_contrast() -> None:
    rng = np.random.default_rng(9)
    themes = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8) for _ in range(2)]
    g = np.array([[0, 1], [1, 1]])
    lin = render_cells(g, themes, (32, 32)).astype(float)
    his = render_cells(g, themes, (32, 32), options=RenderOptions(blend=BlendMode.HISTOGRAM))
    # Corner texel and uniform parts: exactly the theme.
    assert np.array_equal(his[0, 0], themes[0][0, 0])
    assert np.array_equal(his[31, 31], themes[1][31 % 16, 31 % 16])
    # Where X + Y = 16 the two themes are mixed 50/50: linear loses contrast.
    diag = [(16 - k, k) for k in range(17)]
    std_lin = np.std([lin[y, x, 0] for y, x in diag])
    std_his = np.std([his[y, x, 0].astype(float) for y, x in diag])
    assert std_his > 1.2 * std_lin


def test_bad_grids() -> None:
    t = [np.zeros((2, 2, 3), np.uint8)] * 2
    with pytest.raises(TerrathemeError, match="negative"):
        render_cells(np.array([[0, -1], [0, 0]]), t, (2, 2))
    with pytest.raises(TerrathemeError, match="theme index 2"):
        render_cells(np.array([[0, 2], [0, 0]]), t, (2, 2))
    with pytest.raises(TerrathemeError, match="2-D"):
        render_cells(np.zeros((2, 2, 2), int), t, (2, 2))
    with pytest.raises(TerrathemeError, match="at least 2 x 2"):
        render_cells(np.zeros((0, 0), int), t, (2, 2))
    with pytest.raises(TerrathemeError, match="at least 2 x 2"):
        render_cells(np.zeros((1, 5), int), t, (2, 2))
    with pytest.raises(TerrathemeError, match="integers"):
        render_cells(np.full((2, 2), 0.5), t, (2, 2))
    with pytest.raises(TerrathemeError, match="cell size"):
        render_cells(np.zeros((2, 2), int), t, (0, 2))
    with pytest.raises(TerrathemeError, match="cell size"):
        render_cells(np.zeros((2, 2), int), t)


def test_bad_themes_and_regions() -> None:
    g = np.zeros((2, 2), int)
    with pytest.raises(TerrathemeError, match="no themes"):
        render_cells(g, [], (2, 2))
    with pytest.raises(TerrathemeError, match="sequence"):
        render_cells(g, np.zeros((4, 4, 3), np.uint8), (2, 2))
    # A stacked (K, h, w, 3) array is a sequence of K textures.
    assert render_cells(g, np.full((1, 4, 4, 3), 9, np.uint8), (2, 2)).max() == 9
    with pytest.raises(TerrathemeError, match="empty"):
        render_cells(g, [np.zeros((0, 4, 3), np.uint8)], (2, 2))
    with pytest.raises(TerrathemeError, match="RGB"):
        render_cells(g, [np.zeros((4, 4), np.uint8)], (2, 2))
    with pytest.raises(TerrathemeError, match="RGB"):
        render_cells(g, [np.zeros((4, 4, 2), np.uint8)], (2, 2))
    t = [np.zeros((2, 2, 3), np.uint8)]
    with pytest.raises(TerrathemeError, match="outside"):
        render_cells(g, t, (2, 2), (1, 1, 2, 2))
    with pytest.raises(TerrathemeError, match="empty"):
        render_cells(g, t, (2, 2), (0, 0, 0, 2))
    with pytest.raises(TerrathemeError, match="four integers"):
        render_cells(g, t, (2, 2), (0, 0, 2))


def test_region_saddles_see_the_same_ring() -> None:
    # Two themes at random: many saddle cells whose split depends on the ring around them.
    rng = np.random.default_rng(11)
    g = rng.integers(0, 2, (12, 12))
    flat = [np.full((1, 1, 3), v, dtype=np.uint8) for v in (0, 240)]
    full = render_cells(g, flat, (4, 4))
    assert (cell_splits(g.astype(np.uint8)) == ANTI).any()
    for y in range(0, 44, 4):
        for x in range(0, 44, 4):
            np.testing.assert_array_equal(
                render_cells(g, flat, (4, 4), (x, y, 4, 4)), full[y : y + 4, x : x + 4]
            )


def test_render_into_out_buffer() -> None:
    rng = np.random.default_rng(12)
    themes = _themes(rng, 3)
    g = rng.integers(0, 3, (5, 6))
    want = render_cells(g, themes, (4, 3), (2, 1, 9, 7))
    buf = np.full((7, 9, 3), 77, np.uint8)
    got = render_cells(g, themes, (4, 3), (2, 1, 9, 7), out=buf)
    assert got is buf
    np.testing.assert_array_equal(buf, want)
    with pytest.raises(TerrathemeError, match="out must be"):
        render_cells(g, themes, (4, 3), (2, 1, 9, 7), out=np.zeros((7, 9, 3), np.uint16))
    with pytest.raises(TerrathemeError, match="out must be"):
        render_cells(g, themes, (4, 3), (2, 1, 9, 7), out=np.zeros((9, 7, 3), np.uint8))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 1000), st.data())
def test_random_regions_equal_crop(seed: int, data) -> None:
    rng = np.random.default_rng(seed)
    themes = _themes(rng, 3)
    g = rng.integers(0, 3, (6, 7))
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 6))
    full = render_cells(g, themes, (n, m))
    H, W = full.shape[:2]
    x = data.draw(st.integers(0, W - 1))
    y = data.draw(st.integers(0, H - 1))
    w = data.draw(st.integers(1, W - x))
    h = data.draw(st.integers(1, H - y))
    np.testing.assert_array_equal(render_cells(g, themes, (n, m), (x, y, w, h)),
                                  full[y : y + h, x : x + w])
    np.testing.assert_array_equal(render_labels(g, (n, m), (x, y, w, h)),
                                  render_labels(g, (n, m))[y : y + h, x : x + w])
