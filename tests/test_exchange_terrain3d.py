"""Terrain3D export: the control map decoded as Terrain3D defines it, the way back, errors.

The bit layout checked here is copied from TokisanGames/Terrain3D
``doc/docs/controlmap_format.md`` (Decode column): base ``x >> 27 & 0x1F``,
overlay ``x >> 22 & 0x1F``, blend ``x >> 14 & 0xFF``, UV angle ``x >> 10 & 0xF``,
UV scale ``x >> 7 & 0x7``, hole ``x >> 2 & 0x1``, navigation ``x >> 1 & 0x1``,
autoshader ``x & 0x1``.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import OpenImageIO as oiio
import pytest
from hypothesis import given
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import (
    Engine,
    ExportOptions,
    decode_control,
    encode_control,
    plan_export,
    write_export,
)
from terratheme.core.exchange.maps_to_grid import grid_from_maps
from terratheme.core.io.images import write_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.themes.library import ThemeLibrary, flat_theme, shipped_theme_library

NAMES = ("water", "sand", "forest", "grass", "town", "road")


def _project(grid: np.ndarray, cell=(16, 16), library=None) -> ThematicTexture:
    return ThematicTexture(IndexGrid(grid, cell), library or shipped_theme_library().select(NAMES),
                           {})


def _read_exr_bits(path) -> tuple[tuple[str, ...], np.ndarray]:
    """Channel names and the raw 32-bit words of a one-channel float EXR, read by OpenImageIO."""
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    assert spec.format == oiio.TypeDesc(oiio.FLOAT) and spec.nchannels == 1
    pixels = inp.read_image(0, 0, 0, 1, oiio.FLOAT)
    inp.close()
    return tuple(spec.channelnames), np.asarray(pixels, np.float32).reshape(
        spec.height, spec.width).view(np.uint32)


def test_encoding_matches_terrain3ds_layout():
    # (5 & 0x1F) << 27 | (17 & 0x1F) << 22 | (200 & 0xFF) << 14, worked out by hand.
    assert encode_control(np.array([5]), np.array([17]), np.array([200]))[0] == 0x2C720000
    assert encode_control(np.array([31]), np.array([31]), np.array([255]))[0] == 0xFFFFC000


@given(st.integers(0, 2**32 - 1))
def test_decoding_matches_terrain3ds_formulas(x):
    f = decode_control(np.array([[x]], np.uint32))
    want = (x >> 27 & 0x1F, x >> 22 & 0x1F, x >> 14 & 0xFF, x >> 10 & 0xF, x >> 7 & 0x7,
            x >> 2 & 0x1, x >> 1 & 0x1, x & 0x1)
    got = (f.base, f.overlay, f.blend, f.uv_angle, f.uv_scale, f.hole, f.navigation,
           f.autoshader)
    assert tuple(int(v[0, 0]) for v in got) == want


def test_control_map_holds_one_vertex_per_pixel(tmp_path):
    rng = np.random.default_rng(7)
    grid = rng.integers(0, 6, (9, 13)).astype(np.uint8)
    project = _project(grid)
    plan = plan_export(project, ExportOptions(Engine.GODOT))
    assert plan.layout.size == (13, 9)
    write_export(project, plan, tmp_path)
    names, x = _read_exr_bits(tmp_path / "terrain3d_control.exr")
    assert names == ("R",)  # Godot's EXR loader reads a lone R channel as FORMAT_RF
    np.testing.assert_array_equal(x >> 27 & 0x1F, grid)
    np.testing.assert_array_equal(x >> 22 & 0x1F, grid)
    assert not (x >> 14 & 0xFF).any() and not (x & 0x3FFF).any()  # blend 0, autoshader off
    manifest = json.loads((tmp_path / "terratheme_godot.json").read_text())
    assert manifest["vertex_spacing"] == 16.0 and manifest["control_map_size"] == [13, 9]
    assert [t["albedo"] for t in manifest["textures"]][:2] == ["theme_00_water.png",
                                                              "theme_01_sand.png"]
    assert manifest["textures"][0]["uv_scale"] == 1 / 256
    assert manifest["region_size"] == 64 and manifest["colour_map"] is None
    # Centred on the origin, on a region boundary, in vertices (the importer's units).
    assert manifest["import_position"] == [-64, -64]
    np.testing.assert_array_equal(grid_from_maps([str(tmp_path / "terrain3d_control.exr")],
                                                 "terrain3d", len(project.library), 1), grid)


def test_finer_control_maps_blend_the_two_strongest_themes(tmp_path):
    grid = np.array([[3, 1], [3, 1]], np.uint8)  # no equal diagonal: split MAIN
    project = _project(grid)
    write_export(project, plan_export(project, ExportOptions(Engine.GODOT, size=(5, 5))),
                 tmp_path)
    _, x = _read_exr_bits(tmp_path / "terrain3d_control.exr")
    base, overlay, blend = x >> 27 & 0x1F, x >> 22 & 0x1F, x >> 14 & 0xFF
    # Halfway along the top edge: 1 and 3 weigh 1/2 each: base the lower theme, blend 128.
    assert (base[0, 2], overlay[0, 2], blend[0, 2]) == (1, 3, 128)
    # A quarter of the way: theme 3 weighs 3/4, theme 1 1/4 (overlay weight 64/255).
    assert (base[0, 1], overlay[0, 1], blend[0, 1]) == (3, 1, 64)
    assert (base[4, 4], blend[4, 4]) == (1, 0)


def test_textures_of_different_sizes_are_resampled_to_one(tmp_path):
    lib = ThemeLibrary([flat_theme("a", (10, 20, 30), 8), flat_theme("b", (200, 100, 0), 16)])
    project = _project(np.array([[0, 1], [1, 0]], np.uint8), library=lib)
    plan = plan_export(project, ExportOptions(Engine.GODOT))
    assert "resampled to 16 x 16" in plan.notes[0]
    write_export(project, plan, tmp_path)
    inp = oiio.ImageInput.open(str(tmp_path / "theme_00_a.png"))
    assert (inp.spec().width, inp.spec().height) == (16, 16)
    inp.close()
    manifest = json.loads((tmp_path / "terratheme_godot.json").read_text())
    assert [t["uv_scale"] for t in manifest["textures"]] == [1 / 8, 1 / 16]


def test_what_terrain3d_cannot_take_is_refused(tmp_path):
    project = _project(np.zeros((3, 5), np.uint8))
    with pytest.raises(TerrathemeError, match="without tile"):
        plan_export(project, ExportOptions(Engine.GODOT, tile=64))
    with pytest.raises(TerrathemeError, match="one vertex spacing"):
        plan_export(project, ExportOptions(Engine.GODOT, size=(9, 9)))
    many = ThemeLibrary(flat_theme(f"t{k}", (k, k, k)) for k in range(33))
    with pytest.raises(TerrathemeError, match="holds 32 textures; the project has 33"):
        plan_export(_project(np.zeros((2, 2), np.uint8), library=many),
                    ExportOptions(Engine.GODOT))
    write_image(tmp_path / "control.png", np.zeros((4, 4, 1), np.uint8))
    with pytest.raises(TerrathemeError, match="32-bit floats"):
        grid_from_maps([str(tmp_path / "control.png")], "terrain3d", 1, 1)
    write_image(tmp_path / "half.exr", np.zeros((4, 4, 1), np.float16))
    with pytest.raises(TerrathemeError, match="float16"):
        grid_from_maps([str(tmp_path / "half.exr")], "terrain3d", 1, 1)


def test_the_colour_map_is_the_renderers_gain_at_every_vertex_worked_by_hand(tmp_path):
    # 2 x 3 vertices of cell 4: 8 x 4 texels; a colour map of 2 x 1 pixels at scale 4.
    project = _project(np.zeros((2, 3), np.uint8), (4, 4))
    a, b = (100, 40, 0), (200, 80, 255)
    project.colour_map = ColourMap(np.array([[a, b]], np.uint8), 4)
    plan = plan_export(project, ExportOptions(Engine.GODOT))
    assert "terrain3d_colour.png" in plan.files
    write_export(project, plan, tmp_path)
    # Stored RGBA as written (OpenCV: OpenImageIO would premultiply by the alpha).
    colour = cv2.imread(str(tmp_path / "terrain3d_colour.png"), cv2.IMREAD_UNCHANGED)
    assert colour.dtype == np.uint8
    colour = colour[:, :, [2, 1, 0, 3]]
    # The control map's size (Terrain3D's importer slices both maps into regions together).
    assert colour.shape == (2, 3, 4)
    # Vertices at texels x = 0, 4, 8; the renderer samples map x = (x + 0.5) / 4 - 0.5, clamped:
    # 0 -> a; 4 -> 0.625: 3/8 a + 5/8 b = (162.5, 65, 159.375), rounded half up; 8 -> b.
    # One map row: every vertex row the same.
    want = np.array([[a, (163, 65, 159), b]] * 2, np.uint8)
    np.testing.assert_array_equal(colour[:, :, :3], want)
    assert (colour[:, :, 3] == 128).all()  # Terrain3D's neutral roughness (alpha 0.5)
    manifest = json.loads((tmp_path / "terratheme_godot.json").read_text())
    assert manifest["colour_map"]["file"] == "terrain3d_colour.png"
    # Every texture's albedo_color brings a decoded 128 to 1: the colour map's neutral.
    srgb_128 = ((128 / 255 + 0.055) / 1.055) ** 2.4  # IEC 61966-2-1
    for texture in manifest["textures"]:
        assert texture["albedo_color"] == pytest.approx([1 / srgb_128] * 3)
