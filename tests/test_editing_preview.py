"""The live preview (core.edit.preview) and the fidelity map (core.edit.fidelity)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.edit import EditDocument, RenderPreview
from terratheme.core.edit.fidelity import fidelity_map, heat_colours
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import Theme, ThemeLibrary


def textured_library(k: int, seed: int = 0) -> ThemeLibrary:
    rng = np.random.default_rng(seed)
    sizes = [(5, 7), (8, 8), (6, 3), (9, 4)]
    return ThemeLibrary(
        Theme(f"t{i}", (60 * i, 30, 200 - 40 * i),
              rng.integers(0, 256, (*sizes[i % 4], 3), dtype=np.uint8))
        for i in range(k)
    )


@pytest.mark.parametrize("cell", [(4, 4), (5, 3)])
def test_preview_after_edits_equals_a_fresh_render(cell):
    rng = np.random.default_rng(7)
    # Random two-theme grid: many saddle cells, whose split depends on the 12-vertex ring.
    tex = ThematicTexture(IndexGrid(rng.integers(0, 2, (23, 31), dtype=np.uint8), cell),
                          textured_library(3))
    preview = RenderPreview(tex)
    s = EditDocument(tex)
    s.events.grid.connect(preview.refresh)
    s.begin_stroke(2, (3.2, 4.1), 1.5)
    s.stroke_to((12.7, 9.3), 1.5)
    s.end_stroke()
    s.fill_rect((0, 0), (2, 22), 0)  # at the grid's edge
    s.begin_stroke(1, (30, 21), 0.5)  # a single vertex in the far corner
    s.end_stroke()
    s.flood_fill((20, 5), 2)
    s.undo()
    fresh = render_cells(tex.grid.indices, tex.library.textures, cell)
    np.testing.assert_array_equal(preview.image, fresh)
    s.undo()
    s.undo()
    s.redo()
    fresh = render_cells(tex.grid.indices, tex.library.textures, cell)
    np.testing.assert_array_equal(preview.image, fresh)


def test_preview_follows_saddle_decisions_of_neighbouring_cells():
    # Single-vertex flips in a 0/1 grid change ring counts two cells away.
    rng = np.random.default_rng(11)
    tex = ThematicTexture(IndexGrid(rng.integers(0, 2, (14, 14), dtype=np.uint8), (3, 3)),
                          textured_library(2))
    preview = RenderPreview(tex)
    s = EditDocument(tex)
    s.events.grid.connect(preview.refresh)
    for _ in range(40):
        x, y = rng.integers(0, 14, 2)
        s.fill_rect((x, y), (x, y), 1 - int(tex.grid.indices[y, x]))
    fresh = render_cells(tex.grid.indices, tex.library.textures, (3, 3))
    np.testing.assert_array_equal(preview.image, fresh)


def test_refresh_reports_the_replaced_region():
    tex = ThematicTexture(IndexGrid(np.zeros((11, 11), dtype=np.uint8), (4, 2)),
                          textured_library(2))
    preview = RenderPreview(tex)
    s = EditDocument(tex)
    regions = []
    s.events.grid.connect(lambda ch: regions.append(preview.refresh(ch)))
    s.fill_rect((5, 5), (5, 5), 1)
    # Vertex (5, 5) touches cells 4..5; with the one-cell ring: cells 3..6 -> texels.
    assert regions == [(12, 6, 16, 8)]


def test_fidelity_is_zero_where_render_matches_photo_and_high_where_not():
    render = np.zeros((8, 12, 3), dtype=np.uint8)
    render[:, :6] = (200, 30, 30)
    render[:, 6:] = (30, 160, 40)
    photo = render.copy()
    photo[:4, 6:] = (30, 30, 200)  # top-right cell painted the wrong theme
    d = fidelity_map(render, photo, (2, 2))
    assert d.shape == (2, 2) and d.dtype == np.float32
    assert d[0, 1] > 30
    np.testing.assert_allclose(d[[0, 1, 1], [0, 0, 1]], 0, atol=1e-4)
    # A photo at another resolution still lines up cell for cell.
    big = np.repeat(np.repeat(photo, 3, axis=0), 3, axis=1)
    np.testing.assert_allclose(fidelity_map(render, big, (2, 2)), d, atol=1e-3)
    heat = heat_colours(d)
    assert heat.shape == (2, 2, 3) and heat.dtype == np.uint8
    assert int(heat[0, 1].sum()) > int(heat[0, 0].sum())
    with pytest.raises(TerrathemeError, match="photo must be"):
        fidelity_map(render, photo[..., 0], (2, 2))



def test_a_texture_past_the_preview_limit_is_refused_before_rendering():
    # found: a 16 KB project of 4001 x 4001 vertices at cell 16 asked for a 64000^2 render
    grid = IndexGrid(np.zeros((6, 6), np.uint8), (4096, 4096))  # 20480 x 20480 texels
    with pytest.raises(TerrathemeError, match=r"20480 x 20480 texels is over its limit"):
        RenderPreview(ThematicTexture(grid, textured_library(1)))
    # a texture under the limit renders as before
    assert RenderPreview(ThematicTexture(IndexGrid(np.zeros((2, 2), np.uint8), (64, 32)),
                                         textured_library(1))).image.shape == (32, 64, 3)
