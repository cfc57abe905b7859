"""Unreal export: one 8-bit weight map per theme at a recommended landscape size, tiles, sizes."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import (
    Engine,
    ExportOptions,
    plan_export,
    write_export,
)
from terratheme.core.exchange.maps_to_grid import grid_from_maps
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import shipped_theme_library

NAMES = ("water", "sand", "forest", "crop field")
SAFE = ("water", "sand", "forest", "crop_field")  # as file and layer names


def _project(grid: np.ndarray, cell: tuple[int, int]) -> ThematicTexture:
    return ThematicTexture(IndexGrid(grid, cell), shipped_theme_library().select(NAMES), {})


def _grey(path) -> np.ndarray:
    """A greyscale PNG decoded by OpenCV (not OpenImageIO), 8 or 16 bits as stored."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert image is not None and image.ndim == 2, path
    return image


def test_weight_maps_sum_to_255_and_rebuild_the_render(tmp_path):
    # 15 x 15 vertices of cell 9: 126 texels, so a 127-vertex landscape has a vertex per texel.
    rng = np.random.default_rng(2)
    grid = rng.integers(0, 4, (15, 15)).astype(np.uint8)
    project = _project(grid, (9, 9))
    plan = plan_export(project, ExportOptions(Engine.UNREAL))
    assert plan.layout.size == (127, 127)
    write_export(project, plan, tmp_path)
    files = [tmp_path / f"weight_{k:02d}_{n}.png" for k, n in enumerate(SAFE)]
    weights = np.stack([_grey(f) for f in files])
    assert weights.dtype == np.uint8 and weights.shape == (4, 127, 127)
    assert (weights.sum(axis=0, dtype=int) == 255).all()
    # Read back: the strongest theme per pixel, ties to the lower one.
    np.testing.assert_array_equal(grid_from_maps([str(f) for f in files], "weights", 4, 1),
                                  np.argmax(weights, axis=0))
    ref = render_cells(grid, project.library.textures, (9, 9)).astype(float)
    ys, xs = np.mgrid[:126, :126]
    rebuilt = sum(weights[k, :126, :126, None].astype(float) * t[ys % t.shape[0], xs % t.shape[1]]
                  for k, t in enumerate(project.library.textures)) / 255
    assert np.abs(np.floor(rebuilt + 0.5) - ref).max() <= 2
    height = _grey(tmp_path / "heightmap.png")
    assert height.dtype == np.uint16 and height.shape == (127, 127) and (height == 32768).all()
    manifest = json.loads((tmp_path / "terratheme_unreal.json").read_text())
    assert manifest["landscape_scale_cm"] == [100.0, 100.0, 100.0]
    assert manifest["component_quads"] == 126 and manifest["section_quads"] == 63
    assert [layer["name"] for layer in manifest["layers"]] == list(SAFE)
    assert manifest["layers"][3]["weightmap"] == "weight_03_crop_field.png"
    assert manifest["layers"][0]["mapping_scale"] == 256.0  # a 256-texel theme, a quad per texel


def test_tiles_use_unreal_names_and_share_their_border_vertices(tmp_path):
    rng = np.random.default_rng(4)
    grid = rng.integers(0, 4, (8, 15)).astype(np.uint8)
    project = _project(grid, (18, 18))  # 252 x 126 texels
    plan = plan_export(project, ExportOptions(Engine.UNREAL, tile=127))
    assert plan.layout.size == (253, 127) and plan.layout.tiles == (2, 1)
    write_export(project, plan, tmp_path)
    left = np.stack([_grey(tmp_path / f"weight_{k:02d}_{n}_x0_y0.png")
                     for k, n in enumerate(SAFE)])
    right = np.stack([_grey(tmp_path / f"weight_{k:02d}_{n}_x1_y0.png")
                      for k, n in enumerate(SAFE)])
    assert left.shape == right.shape == (4, 127, 127)
    np.testing.assert_array_equal(left[:, :, -1], right[:, :, 0])
    assert (right.sum(axis=0, dtype=int) == 255).all()
    assert _grey(tmp_path / "heightmap_x1_y0.png").shape == (127, 127)


def test_sizes_unreal_refuses():
    project = _project(np.zeros((3, 3), np.uint8), (16, 16))
    with pytest.raises(TerrathemeError, match="not a recommended Unreal landscape size"):
        plan_export(project, ExportOptions(Engine.UNREAL, size=(500, 505)))
    with pytest.raises(TerrathemeError, match="mixes component sizes"):
        plan_export(project, ExportOptions(Engine.UNREAL, size=(505, 8129)))
    with pytest.raises(TerrathemeError, match="^tile 100 is not"):
        plan_export(project, ExportOptions(Engine.UNREAL, tile=100))
    assert plan_export(project, ExportOptions(Engine.UNREAL, size=(1009, 505))).layout.size == \
        (1009, 505)


def test_weight_maps_that_differ_are_refused(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((5, 6), np.uint8))
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((6, 6), np.uint8))
    with pytest.raises(TerrathemeError, match="differs from the first weight map"):
        grid_from_maps([str(tmp_path / "a.png"), str(tmp_path / "b.png")], "weights", 2, 1)
    with pytest.raises(TerrathemeError, match="no weight map given"):
        grid_from_maps([], "weights", 2, 1)
