"""The colour map in every export: the file equals the project's, and splat x gain is the render.

The engines' side is modelled independently of core.exchange: the weights
are splatted linearly, the colour map is sampled as a GPU samples a clamped
bilinear texture (texel centres at ``(i + 0.5) / size``) at the UV the
manifest's transform gives, and the product is compared with
``render_project`` (the project's shaped borders and colour map).
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from terratheme.core.exchange import Engine, ExportOptions, WeightStyle, plan_export, write_export
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import render_project
from terratheme.core.render.renderer import RenderOptions, render_cells
from terratheme.core.themes.library import Theme, ThemeLibrary, flat_theme

STYLE = {"width": 3.0, "noise": 90, "height": 40, "features": 2.0, "seed": 3}


def _project(grid, cell, scale, seed=0, k=5) -> ThematicTexture:
    rng = np.random.default_rng(seed)
    library = ThemeLibrary(Theme(f"t{j}", (50 * j, 100, 200 - 40 * j),
                                 rng.integers(0, 256, (10 + 3 * j, 12, 3)).astype(np.uint8))
                           for j in range(k))
    gh, gw = grid.shape[0] - 1, grid.shape[1] - 1
    mh, mw = ColourMap.shape_for((gw * cell[0], gh * cell[1]), scale)
    # Gains 0.625 .. 1.33: what convert's colour maps hold.
    cmap = ColourMap(rng.integers(80, 171, (mh, mw, 3)).astype(np.uint8), scale)
    return ThematicTexture(IndexGrid(grid, cell), library, {"render": {"boundary": STYLE}},
                           colour_map=cmap)


def _grid(shape, k, seed):
    g = np.random.default_rng(seed).integers(0, k, shape).astype(np.uint8)
    g[1:4, 1:4] = [[0, 1, 0], [1, 0, 1], [0, 1, 0]]
    return g


def _png(path) -> np.ndarray:
    """A PNG's stored channels in RGB(A) order, decoded by OpenCV."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert image is not None and image.dtype == np.uint8, path
    if image.ndim == 2:
        return image
    return image[:, :, [2, 1, 0, 3][: image.shape[2]]]


def _bilinear(image: np.ndarray, u: np.ndarray, v_top: np.ndarray) -> np.ndarray:
    """A clamped bilinear texture lookup at texture coordinates (u, v from the top row)."""
    h, w = image.shape[:2]
    a = np.clip(u * w - 0.5, 0, w - 1)
    b = np.clip(v_top * h - 0.5, 0, h - 1)
    i0, j0 = np.floor(a).astype(int), np.floor(b).astype(int)
    i1, j1 = np.minimum(i0 + 1, w - 1), np.minimum(j0 + 1, h - 1)
    fa, fb = (a - i0)[..., None], (b - j0)[..., None]
    img = image.astype(float)
    top = img[j0, i0] * (1 - fa) + img[j0, i1] * fa
    bottom = img[j1, i0] * (1 - fa) + img[j1, i1] * fa
    return top * (1 - fb) + bottom * fb


def _splat(weights: np.ndarray, textures, x0=0, y0=0) -> np.ndarray:
    k, h, w = weights.shape
    ys, xs = np.mgrid[y0 : y0 + h, x0 : x0 + w]
    return sum(weights[j, :, :, None].astype(float) * t[ys % t.shape[0], xs % t.shape[1]]
               for j, t in enumerate(textures)) / 255


def _unity_planes(folder, names) -> np.ndarray:
    return np.concatenate([np.moveaxis(_png(folder / n), 2, 0) for n in names]).astype(int)


# One alphamap pixel per texel: 8 x 8 vertices of cell 9 (63 texels) on Unity's 64 alphamap,
# and 4 x 4 vertices of cell 31 (93 texels) in 3 x 3 tiles of 32 sharing their borders.
@pytest.mark.parametrize(("shape", "cell", "tile", "scale"), [((8, 8), 9, None, 8),
                                                              ((4, 4), 31, 32, 20)])
def test_unity_splat_times_colour_map_is_the_render(tmp_path, shape, cell, tile, scale):
    grid = _grid(shape, 5, 1)
    project = _project(grid, (cell, cell), scale=scale)
    texels = (shape[0] - 1) * cell
    plan = plan_export(project, ExportOptions(Engine.UNITY, tile=tile))
    assert plan.layout.size == (texels + 1, texels + 1)
    write_export(project, plan, tmp_path)
    np.testing.assert_array_equal(_png(tmp_path / "colour_map.png"), project.colour_map.pixels)
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    entry = manifest["colour_map"]
    assert entry["file"] == "colour_map.png" and entry["neutral"] == 128
    assert entry["scale"] == scale and entry["size"] == [-(-texels // scale)] * 2
    ref = render_project(project).astype(float)
    for t in manifest["tiles"]:
        planes = _unity_planes(tmp_path, t["splatmaps"])[:5]
        n = planes.shape[1]
        px, py = t["x"] * (n - 1), t["y"] * (n - 1)
        # Texels of this tile inside the texture (map pixel p is texel p at this size).
        hh, ww = min(n, texels - py), min(n, texels - px)
        rows, cols = np.mgrid[:hh, :ww]
        # Unity's terrain UV: u east, v north from the tile's south edge; texture v up.
        u, v = cols / (n - 1), 1 - rows / (n - 1)
        su, sv, ou, ov = t["colour_map_st"]
        gain = _bilinear(_png(tmp_path / "colour_map.png"), u * su + ou,
                         1 - (v * sv + ov)) / 128
        shown = np.minimum(np.floor(_splat(planes[:, :hh, :ww], project.library.textures,
                                           px, py) * gain + 0.5), 255)
        assert np.abs(shown - ref[py : py + hh, px : px + ww]).max() <= 2, t


def test_unreal_splat_times_colour_map_is_the_render(tmp_path):
    # 15 x 15 vertices of cell 9: 126 texels, a 127-vertex landscape.
    grid = _grid((15, 15), 4, 2)
    project = _project(grid, (9, 9), scale=12, seed=1, k=4)
    write_export(project, plan_export(project, ExportOptions(Engine.UNREAL)), tmp_path)
    manifest = json.loads((tmp_path / "terratheme_unreal.json").read_text())
    weights = np.stack([_png(tmp_path / layer["weightmap"]) for layer in manifest["layers"]])
    assert (weights.sum(axis=0, dtype=int) == 255).all()
    cmap = _png(tmp_path / "colour_map.png")
    np.testing.assert_array_equal(cmap, project.colour_map.pixels)
    entry = manifest["colour_map"]
    rows, cols = np.mgrid[:126, :126]
    (au, av), (bu, bv) = entry["uv_per_vertex"], entry["uv_offset"]
    # LandscapeCoords at Mapping Scale 1 counts vertices from the north-west corner.
    gain = _bilinear(cmap, cols * au + bu, rows * av + bv) / 128
    shown = np.minimum(np.floor(_splat(weights[:, :126, :126], project.library.textures)
                                * gain + 0.5), 255)
    assert np.abs(shown - render_project(project)).max() <= 2


def test_terrain3d_colour_map_is_the_gain_at_every_vertex(tmp_path):
    grid = _grid((9, 13), 5, 3)
    project = _project(grid, (16, 16), scale=24, seed=2)
    plan = plan_export(project, ExportOptions(Engine.GODOT))
    assert "terrain3d_colour.png" in plan.files
    assert not any("colour map" in note for note in plan.notes)  # a vertex per 16 texels, map 1/24
    finer = plan_export(_project(grid, (16, 16), scale=8), ExportOptions(Engine.GODOT))
    assert any("a 193 x 129 map keeps it" in note for note in finer.notes)
    write_export(project, plan, tmp_path)
    colour = _png(tmp_path / "terrain3d_colour.png")
    assert colour.shape == (9, 13, 4)  # the control map's size, as Terrain3D's import needs
    assert (colour[:, :, 3] == 128).all()  # neutral roughness (COLOR_ROUGHNESS alpha 0.5)
    # What the renderer makes of a flat 128 theme at the vertex texels (the far edge aside).
    grey = ThemeLibrary([flat_theme("grey", (128, 128, 128))])
    flat = render_cells(np.zeros_like(grid), grey.textures, (16, 16),
                        colour_map=project.colour_map)
    np.testing.assert_array_equal(colour[:-1, :-1, :3], flat[::16, ::16])
    # The far edge: the map clamps at its last pixel centre (the renderer's rule).
    cmap = project.colour_map.pixels.astype(float)
    xs = np.clip((np.arange(13) * 16 + 0.5) / 24 - 0.5, 0, cmap.shape[1] - 1)
    want = _bilinear(cmap, (xs[-1:] + 0.5) / cmap.shape[1],
                     (np.clip((np.arange(9) * 16 + 0.5) / 24 - 0.5, 0, cmap.shape[0] - 1)
                      + 0.5)[:, None] / cmap.shape[0])
    assert np.abs(colour[:, -1:, :3] - want).max() <= 0.5 + 1e-9
    manifest = json.loads((tmp_path / "terratheme_godot.json").read_text())
    srgb_128 = ((128 / 255 + 0.055) / 1.055) ** 2.4  # IEC 61966-2-1, decoded as Godot does
    tint = manifest["textures"][0]["albedo_color"]
    assert tint == pytest.approx([1 / srgb_128] * 3)
    assert manifest["colour_map"]["file"] == "terrain3d_colour.png"
    # One vertex per grid vertex: each its own theme, blend 0 (not the shaped borders).
    assert manifest["borders"] == "vertex"
    # The control map's vertices still carry their themes alone (a vertex is on a texel).
    from terratheme.core.io.images import read_image

    control = read_image(tmp_path / "terrain3d_control.exr")[:, :, 0].copy().view(np.uint32)
    np.testing.assert_array_equal(control >> 27 & 0x1F, grid)
    assert not (control >> 14 & 0xFF).any()


def test_gis_texture_is_the_project_render_in_its_style(tmp_path):
    from terratheme.core.io.images import read_image

    grid = _grid((6, 9), 4, 4)
    project = _project(grid, (16, 16), scale=10, seed=3, k=4)
    write_export(project, plan_export(project, ExportOptions(Engine.GEOTIFF)), tmp_path / "a")
    texture = read_image(tmp_path / "a" / "texture.tif")
    np.testing.assert_array_equal(texture, render_project(project))
    plain = render_project(project, options=RenderOptions())
    assert (texture != plain).any()  # shaped borders, not the paper's ramp
    manifest = json.loads((tmp_path / "a" / "terratheme_geotiff.json").read_text())
    assert manifest["colour_map"]["baked_into"] == "texture.tif"
    linear = ExportOptions(Engine.GEOTIFF, style=WeightStyle.LINEAR)
    write_export(project, plan_export(project, linear), tmp_path / "b")
    np.testing.assert_array_equal(read_image(tmp_path / "b" / "texture.tif"), plain)


def test_projects_without_a_colour_map_write_none(tmp_path):
    project = _project(_grid((8, 8), 5, 5), (9, 9), scale=8)
    project.colour_map = None
    plan = plan_export(project, ExportOptions(Engine.UNITY))
    assert "colour_map.png" not in plan.files
    write_export(project, plan, tmp_path)
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    assert manifest["colour_map"] is None and "colour_map_st" not in manifest["tiles"][0]
    plan = plan_export(project, ExportOptions(Engine.GODOT))
    assert "terrain3d_colour.png" not in plan.files


@pytest.mark.slow
def test_a_converted_photo_exports_its_look():
    # convert's defaults: shaped borders and a colour map; one weight pixel per texel.
    from pathlib import Path

    from terratheme.core.convert import convert_photo
    from terratheme.core.exchange import map_weights
    from terratheme.core.exchange.colour import vertex_colour_uv
    from terratheme.core.exchange.layout import ExportLayout
    from terratheme.core.io.images import read_image
    from terratheme.core.render.project import project_style

    photo = read_image(Path(__file__).resolve().parents[1] / "sample_maps" / "dubai_marina.jpg")
    project = convert_photo(photo[:640, :640]).project
    assert project.colour_map is not None and project_style(project).boundary is not None
    wtex, htex = project.grid.texture_size
    size = (wtex + 1, htex + 1)
    uv = vertex_colour_uv(project, ExportLayout(size))
    rows, cols = np.mgrid[:htex, :wtex]
    (au, av), (bu, bv) = uv["uv_per_vertex"], uv["uv_offset"]
    gain = _bilinear(project.colour_map.pixels, cols * au + bu, rows * av + bv) / 128
    ref = render_project(project, (0, 0, wtex, htex)).astype(float)

    def shown(style: WeightStyle) -> np.ndarray:
        weights = map_weights(project, size, None, ExportOptions(Engine.UNREAL, style=style))
        splat = _splat(weights[:, :htex, :wtex], project.library.textures)
        return np.minimum(np.floor(splat * gain + 0.5), 255)

    assert np.abs(shown(WeightStyle.PROJECT) - ref).max() <= 2
    # The paper's weights smear every border over its cell: far from the render.
    assert np.abs(shown(WeightStyle.LINEAR) - ref).max() > 50
