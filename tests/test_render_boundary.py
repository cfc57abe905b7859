"""Shaped boundaries (core.render.boundary) against an independent per-texel reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.render.boundary import BoundaryOptions, noise_value
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells
from terratheme.core.render.rules import cell_splits

M32 = 0xFFFFFFFF


def _hash(ix: int, iy: int, theme: int, seed: int) -> int:
    """The documented 32-bit lattice hash, in plain Python integers."""
    h = ((ix * 0x8DA6B343) ^ (iy * 0xD8163841) ^ (theme * 0xCB1AB31F) ^ seed) & M32
    h ^= h >> 16
    h = (h * 0x7FEB352D) & M32
    h ^= h >> 15
    h = (h * 0x846CA68B) & M32
    h ^= h >> 16
    return h >> 24


def _noise(x: int, y: int, theme: int, lat: int, seed: int) -> int:
    ix, iy, fx, fy = x // lat, y // lat, x % lat, y % lat
    v = ((lat - fx) * (lat - fy) * _hash(ix, iy, theme, seed)
         + fx * (lat - fy) * _hash(ix + 1, iy, theme, seed)
         + (lat - fx) * fy * _hash(ix, iy + 1, theme, seed)
         + fx * fy * _hash(ix + 1, iy + 1, theme, seed))
    return (v * 4) // (lat * lat) - 512


def _weights(split: int, xi: int, yi: int, d: int) -> tuple[int, int, int, int]:
    # DESIGN.md section 1: barycentric weights of ind[0][0], [0][1], [1][0], [1][1] times D.
    if split == 1:
        return (d - yi, 0, yi - xi, xi) if xi <= yi else (d - xi, xi - yi, 0, yi)
    return (d - xi - yi, xi, yi, 0) if xi + yi <= d else (0, d - yi, d - xi, xi + yi - d)


def _reference(grid, themes, n, m, opts):
    p = opts.parameters(n, m)
    splits = cell_splits(grid)
    gh, gw = grid.shape[0] - 1, grid.shape[1] - 1
    out = np.zeros((gh * m, gw * n, 3), np.uint8)
    d = n * m
    for y in range(gh * m):
        for x in range(gw * n):
            cx, cy = x // n, y // m
            ks = [int(grid[cy, cx]), int(grid[cy, cx + 1]), int(grid[cy + 1, cx]),
                  int(grid[cy + 1, cx + 1])]
            texel = {k: themes[k][y % themes[k].shape[0], x % themes[k].shape[1]].astype(int)
                     for k in set(ks)}
            sp = int(splits[cy, cx])
            if sp == 0:
                out[y, x] = texel[ks[0]]
                continue
            w = _weights(sp, (x - cx * n) * m, (y - cy * m) * n, d)
            merged: dict[int, int] = {}
            for k, wk in zip(ks, w, strict=True):
                merged[k] = merged.get(k, 0) + wk
            score = {}
            for k, wk in merged.items():
                if wk == 0:
                    continue
                r, g, b = texel[k]
                luma = (77 * r + 150 * g + 29 * b) >> 8
                score[k] = ((wk * 1024) // d + (p.noise * _noise(x, y, k, p.lattice, p.seed)) // 256
                            + (p.height * (luma - 128) * 4) // 256)
            best = max(score.values())
            v = {k: max(0, s - best + p.width) for k, s in score.items()}
            total = sum(v.values())
            for c in range(3):
                acc = sum(v[k] * texel[k][c] for k in v)
                out[y, x, c] = (2 * acc + total) // (2 * total)
    return out


def _scene(seed: int, shape=(5, 6), k=3):
    rng = np.random.default_rng(seed)
    grid = rng.integers(0, k, shape).astype(np.uint8)
    themes = [rng.integers(0, 256, (7 + 2 * i, 9 + i, 3), dtype=np.uint8) for i in range(k)]
    return grid, themes


SHAPED = RenderOptions(boundary=BoundaryOptions())


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 13), m=st.integers(1, 13))
def test_every_texel_equals_the_reference(seed, n, m):
    grid, themes = _scene(seed)
    got = render_cells(grid, themes, (n, m), options=SHAPED)
    assert np.array_equal(got, _reference(grid, themes, n, m, BoundaryOptions()))


def test_reference_with_strong_noise_and_height_on_big_cells():
    grid, themes = _scene(7, (3, 4), 4)
    opts = BoundaryOptions(width=2.0, noise=120, height=60, features=3.0, seed=99)
    got = render_cells(grid, themes, (16, 12), options=RenderOptions(boundary=opts))
    assert np.array_equal(got, _reference(grid, themes, 16, 12, opts))


def test_vertices_keep_their_theme_and_uniform_cells_are_copies():
    grid, themes = _scene(11, (6, 7))
    n = m = 10
    got = render_cells(grid, themes, (n, m), options=SHAPED)
    for j in range(grid.shape[0] - 1):
        for i in range(grid.shape[1] - 1):
            k = grid[j, i]
            assert np.array_equal(got[j * m, i * n], themes[k][(j * m) % themes[k].shape[0],
                                                             (i * n) % themes[k].shape[1]])
    flat = np.zeros((4, 4), np.uint8)
    assert np.array_equal(render_cells(flat, themes, (n, m), options=SHAPED),
                          render_cells(flat, themes, (n, m)))


def test_region_equals_the_crop_of_the_full_render():
    grid, themes = _scene(3, (8, 9))
    full = render_cells(grid, themes, (12, 9), options=SHAPED)
    for x, y, w, h in [(0, 0, 96, 63), (5, 7, 40, 30), (95, 62, 1, 1), (37, 0, 11, 63)]:
        part = render_cells(grid, themes, (12, 9), (x, y, w, h), options=SHAPED)
        assert np.array_equal(part, full[y:y + h, x:x + w])


def test_a_cell_edge_depends_on_its_own_vertices_only():
    # No seam: the texels on vertex column i see only that column's two vertices,
    # whatever the cells on either side hold.
    grid, themes = _scene(5, (4, 6))
    n = 8
    base = render_cells(grid, themes, (n, n), options=SHAPED)
    other = grid.copy()
    other[:, 3] = (other[:, 3] + 1) % 3
    changed = render_cells(other, themes, (n, n), options=SHAPED)
    # Vertex columns 2 and 4 bound the cells that changed: their texels stay.
    assert np.array_equal(base[:, 2 * n], changed[:, 2 * n])
    assert np.array_equal(base[:, 4 * n], changed[:, 4 * n])
    assert not np.array_equal(base[:, 3 * n], changed[:, 3 * n])


def test_borders_are_narrower_than_the_paper_ramp():
    # Two themes, one vertical border: most texels of the shaped render are pure.
    a = np.zeros((8, 8, 3), np.uint8)
    b = np.full((8, 8, 3), 255, np.uint8)
    grid = np.array([[0, 1], [0, 1]], np.uint8)
    linear = render_cells(grid, [a, b], (64, 64))[:, :, 0]
    shaped = render_cells(grid, [a, b], (64, 64), options=SHAPED)[:, :, 0]
    pure = lambda img: float(((img == 0) | (img == 255)).mean())  # noqa: E731
    assert pure(linear) < 0.05 and pure(shaped) > 0.85


def test_noise_is_bounded_and_seeded():
    def field(seed):
        return np.array([[noise_value(x, y, 2, 8, seed) for x in range(64)] for y in range(64)])

    f = field(5)
    assert f.min() >= -512 and f.max() <= 508 and f.std() > 30
    assert not np.array_equal(f, field(6))


def test_parameters_keep_the_continuity_budget():
    p = BoundaryOptions(width=3.0, noise=200, height=100).parameters(8, 8)
    assert 2 * (p.noise + p.height) <= 512 - p.width
    assert BoundaryOptions(width=0.0).parameters(64, 64).width == 1


@pytest.mark.parametrize("kwargs, match", [
    ({"width": -1}, "width"), ({"noise": 300}, "noise and height"),
    ({"features": 0}, "features"), ({"seed": -1}, "seed"),
])
def test_bad_options(kwargs, match):
    with pytest.raises(TerrathemeError, match=match):
        BoundaryOptions(**kwargs)


def test_shaped_borders_need_the_linear_blend():
    with pytest.raises(TerrathemeError, match="blend linearly"):
        RenderOptions(blend=BlendMode.HISTOGRAM, boundary=BoundaryOptions())
