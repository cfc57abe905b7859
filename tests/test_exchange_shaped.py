"""Export weights in the project's style: the shaped blend's own weights (core.exchange.shaped)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from exchange_cases import theme_weights
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import (
    Engine,
    ExportOptions,
    WeightStyle,
    map_labels,
    map_weights,
    plan_export,
    shaped_slots,
    write_export,
)
from terratheme.core.exchange.layout import nearest_texels
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import RenderOptions, render_cells, render_labels
from terratheme.core.themes.library import Theme, ThemeLibrary

STYLE = BoundaryOptions(width=3.0, noise=90, height=40, features=2.0, seed=7)


def _grid(shape, k, seed) -> np.ndarray:
    rng = np.random.default_rng(seed)
    grid = rng.integers(0, k, shape).astype(np.uint8)
    grid[1:4, 1:4] = [[0, 1, 0], [1, 0, 1], [0, 1, 0]]  # saddles
    grid[-2, -2] = (grid[-2, -2] + 1) % k  # a single odd vertex
    return grid


def _textures(k, seed) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (11 + 3 * j, 13, 3)).astype(np.uint8) for j in range(k)]


def _project(grid, textures, cell, boundary=STYLE) -> ThematicTexture:
    library = ThemeLibrary(Theme(f"t{j}", (40 * j, 90, 200 - 40 * j), t)
                           for j, t in enumerate(textures))
    meta = {} if boundary is None else {"render": {"boundary": {
        "width": boundary.width, "noise": boundary.noise, "height": boundary.height,
        "features": boundary.features, "seed": boundary.seed}}}
    return ThematicTexture(IndexGrid(grid, cell), library, meta)


def _themes_at(textures, h, w) -> np.ndarray:
    """(K, h, w, 3): every theme's texel at global (x, y), wrapping."""
    ys, xs = np.mgrid[:h, :w]
    return np.stack([t[ys % t.shape[0], xs % t.shape[1]] for t in textures]).astype(np.int64)


def _splat(weights, textures) -> np.ndarray:
    """The engine's linear splat: sum_k w_k T_k / 255, in float."""
    k, h, w = weights.shape
    return np.einsum("khw,khwc->hwc", weights.astype(float), _themes_at(textures, h, w)) / 255


def test_nearest_texels():
    np.testing.assert_array_equal(nearest_texels(9, 8, 0, 9), np.arange(9))
    # 5 pixels over 8 texels: positions 0, 2, 4, 6, 8.
    np.testing.assert_array_equal(nearest_texels(5, 8, 0, 5), [0, 2, 4, 6, 8])
    # 4 pixels over 8 texels: 0, 2.67, 5.33, 8 -> 0, 3, 5, 8; a window starts where it says.
    np.testing.assert_array_equal(nearest_texels(4, 8, 1, 3), [3, 5, 8])
    # Half-way positions round up: 3 pixels over 3 texels sit at 0, 1.5, 3.
    np.testing.assert_array_equal(nearest_texels(3, 3, 0, 3), [0, 2, 3])


@pytest.mark.parametrize("cell", [(8, 8), (6, 9), (16, 4)])
def test_shaped_weights_give_the_renderers_colours_exactly(cell):
    grid = _grid((7, 8), 4, sum(cell))
    textures = _textures(4, 1)
    ref = render_cells(grid, textures, cell, options=RenderOptions(boundary=STYLE))
    h, w = ref.shape[:2]
    slots = shaped_slots(grid, textures, cell, (w + 1, h + 1), boundary=STYLE)
    assert slots.denominator.shape == (h + 1, w + 1) and (slots.denominator > 0).all()
    assert (slots.weights.sum(axis=0) == slots.denominator).all()
    themes = _themes_at(textures, h + 1, w + 1)
    acc = sum(slots.weights[a][:, :, None]
              * np.take_along_axis(themes, slots.ids[a][None, :, :, None].astype(int), 0)[0]
              for a in range(4))
    den = slots.denominator[:, :, None]
    # The renderer's rounding of sum(v_t T_t) / sum(v_t), half up.
    np.testing.assert_array_equal(((2 * acc + den) // (2 * den))[:h, :w], ref)


def test_exported_weights_rebuild_the_shaped_render_within_2_levels(tmp_path):
    # 8 x 8 vertices of cell 9: 63 texels, Unity's 64 alphamap holds one pixel per texel.
    grid = _grid((8, 8), 5, 3)
    textures = _textures(5, 4)
    project = _project(grid, textures, (9, 9))
    plan = plan_export(project, ExportOptions(Engine.UNITY))
    write_export(project, plan, tmp_path)
    planes = np.concatenate([np.moveaxis(cv2.imread(str(tmp_path / f"splatmap_{s}.png"),
                                                    cv2.IMREAD_UNCHANGED)[:, :, [2, 1, 0, 3]],
                                         2, 0) for s in range(2)])[:5].astype(int)
    assert (planes.sum(axis=0) == 255).all()
    ref = render_cells(grid, textures, (9, 9), options=RenderOptions(boundary=STYLE))
    rebuilt = np.floor(_splat(planes, textures) + 0.5)[:63, :63]
    assert np.abs(rebuilt - ref).max() <= 2
    # The borders are the shaped ones: the paper's weights miss the render by far more.
    linear = theme_weights(grid, (64, 64), n_themes=5).astype(int)
    assert np.abs(np.floor(_splat(linear, textures) + 0.5)[:63, :63] - ref).max() > 40
    # Texels on vertices hold their vertex's theme alone: the way back finds the grid.
    on_vertices = planes[:, ::9, ::9]
    np.testing.assert_array_equal(on_vertices.argmax(axis=0), grid)
    assert (on_vertices.max(axis=0) == 255).all()
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    assert manifest["borders"] == "shaped" and manifest["boundary"]["seed"] == 7


def test_windows_bands_and_tiles_agree(monkeypatch):
    grid = _grid((6, 7), 3, 9)
    project = _project(grid, _textures(3, 2), (5, 4))
    options = ExportOptions(Engine.UNREAL)
    whole = map_weights(project, (41, 29), None, options)
    part = map_weights(project, (41, 29), (7, 3, 20, 11), options)
    np.testing.assert_array_equal(part, whole[:, 3:14, 7:27])
    import terratheme.core.exchange.weights as weights_module

    monkeypatch.setattr(weights_module, "BAND_PIXELS", 50)
    np.testing.assert_array_equal(map_weights(project, (41, 29), None, options), whole)


def test_other_sizes_take_the_nearest_texels_weights():
    grid = _grid((5, 5), 3, 5)
    textures = _textures(3, 6)
    project = _project(grid, textures, (8, 8))  # 32 x 32 texels
    native = shaped_slots(grid, textures, (8, 8), (33, 33), boundary=STYLE)
    coarse = shaped_slots(grid, textures, (8, 8), (12, 9), boundary=STYLE)
    xs, ys = nearest_texels(12, 32, 0, 12), nearest_texels(9, 32, 0, 9)
    for field in ("ids", "weights"):
        np.testing.assert_array_equal(getattr(coarse, field),
                                      getattr(native, field)[:, ys][:, :, xs])
    np.testing.assert_array_equal(coarse.denominator, native.denominator[ys][:, xs])
    weights = map_weights(project, (12, 9), None, ExportOptions(Engine.UNREAL))
    assert (weights.sum(axis=0, dtype=int) == 255).all()


def test_linear_style_and_projects_without_a_style_keep_the_papers_weights():
    grid = _grid((5, 6), 4, 8)
    textures = _textures(4, 3)
    shaped = _project(grid, textures, (6, 6))
    plain = _project(grid, textures, (6, 6), boundary=None)
    want = theme_weights(grid, (31, 25), n_themes=4)
    linear = ExportOptions(Engine.UNREAL, style=WeightStyle.LINEAR)
    np.testing.assert_array_equal(map_weights(shaped, (31, 25), None, linear), want)
    np.testing.assert_array_equal(map_weights(plain, (31, 25), None, ExportOptions()), want)
    assert not np.array_equal(map_weights(shaped, (31, 25), None, ExportOptions()), want)


def test_class_map_follows_the_style():
    grid = _grid((5, 6), 4, 2)
    textures = _textures(4, 5)
    project = _project(grid, textures, (8, 8))
    labels = map_labels(project, (41, 33), (0, 0, 40, 32), ExportOptions())
    slots = shaped_slots(grid, textures, (8, 8), (41, 33), boundary=STYLE)
    np.testing.assert_array_equal(labels, np.argmax(
        np.stack([np.where(slots.ids == k, slots.weights, 0).sum(axis=0) for k in range(4)]),
        axis=0)[:32, :40])
    assert (labels != render_labels(grid, (8, 8))).any()
    linear = map_labels(project, (41, 33), (0, 0, 40, 32),
                        ExportOptions(style=WeightStyle.LINEAR))
    np.testing.assert_array_equal(linear, render_labels(grid, (8, 8)))


def test_a_bad_render_style_is_refused_before_any_work():
    project = _project(_grid((4, 4), 2, 1), _textures(2, 1), (8, 8))
    project.metadata["render"] = {"boundary": {"width": -1.0}}
    with pytest.raises(TerrathemeError, match="boundary width must be in 0..4096"):
        plan_export(project, ExportOptions(Engine.GODOT))
    project.metadata["render"] = {"blend": "cubic"}
    with pytest.raises(TerrathemeError, match="project render style must be"):
        plan_export(project, ExportOptions(Engine.UNITY))
    with pytest.raises(TerrathemeError, match="at least 2 x 2 pixels"):
        shaped_slots(project.grid.indices, _textures(2, 1), (8, 8), (1, 9), boundary=STYLE)
