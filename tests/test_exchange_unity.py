"""Unity export: RGBA8 splatmaps read back by an independent decoder (OpenCV), tiles, sizes."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from exchange_cases import theme_weights
from terratheme.core import exchange
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import Engine, ExportOptions, plan_export, write_export
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import shipped_theme_library

NAMES = ("water", "sand", "forest", "grass", "town")


def _project(grid: np.ndarray, cell: tuple[int, int]) -> ThematicTexture:
    return ThematicTexture(IndexGrid(grid, cell), shipped_theme_library().select(NAMES), {})


def _rgba(path) -> np.ndarray:
    """A PNG's stored RGBA bytes, decoded by OpenCV (not OpenImageIO)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert image is not None and image.dtype == np.uint8 and image.shape[2] == 4, path
    return image[:, :, [2, 1, 0, 3]]


def _rebuild(weights: np.ndarray, textures: list[np.ndarray]) -> np.ndarray:
    """sum_k w_k T_k / 255 at texel positions, themes sampled at global coordinates, wrapping."""
    h, w = weights.shape[1:]
    ys, xs = np.mgrid[:h, :w]
    out = sum(weights[k, :, :, None].astype(float) * t[ys % t.shape[0], xs % t.shape[1]]
              for k, t in enumerate(textures)) / 255
    return np.floor(out + 0.5)


@pytest.fixture
def grid() -> np.ndarray:
    # 8 x 8 vertices with cell 9: a 63-texel texture, so Unity's 64 alphamap is one pixel per texel.
    rng = np.random.default_rng(11)
    g = rng.integers(0, len(NAMES), (8, 8)).astype(np.uint8)
    g[1:4, 1:4] = [[0, 1, 0], [1, 0, 1], [0, 1, 0]]
    return g


def test_splatmaps_sum_to_255_and_rebuild_the_render(tmp_path, grid):
    project = _project(grid, (9, 9))
    plan = plan_export(project, ExportOptions(Engine.UNITY))
    assert plan.layout.size == (64, 64) and plan.layout.tiles == (1, 1)
    paths = write_export(project, plan, tmp_path)
    assert all(p.is_file() for p in paths) and paths[-1].name == "terratheme_unity.json"
    planes = np.concatenate([np.moveaxis(_rgba(tmp_path / f"splatmap_{s}.png"), 2, 0)
                             for s in range(2)])
    assert planes.shape == (8, 64, 64)
    assert (planes[:5].sum(axis=0, dtype=int) == 255).all()
    assert not planes[5:].any()
    ref = render_cells(grid, project.library.textures, (9, 9)).astype(float)
    assert np.abs(_rebuild(planes[:5, :63, :63], project.library.textures) - ref).max() <= 2
    # Texels on vertices hold their vertex's theme alone.
    np.testing.assert_array_equal(planes[:5, ::9, ::9].argmax(axis=0), grid)
    theme = cv2.imread(str(tmp_path / "theme_02_forest.png"))[:, :, ::-1]
    np.testing.assert_array_equal(theme, project.library[2].texture)


def test_manifest_describes_layers_and_the_script_builds_them(tmp_path, grid):
    project = _project(grid, (9, 9))
    project.metadata["georeference"] = {"ModelPixelScale": [0.5, 0.25, 0.0],
                                        "ModelTiepoint": [0, 0, 0, 1000.0, 2000.0, 0]}
    write_export(project, plan_export(project, ExportOptions(Engine.UNITY)), tmp_path)
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    assert manifest["format"] == "terratheme-unity" and manifest["alphamap_resolution"] == 64
    # 63 texels of 0.5 x 0.25 units; texel (0, 0)'s sample is the photo pixel's centre.
    assert manifest["terrain_size"] == [31.5, 15.75]
    assert manifest["origin"] == [1000.25, 1999.875]
    layer = manifest["layers"][1]
    assert layer["name"] == "sand" and layer["texture"] == "theme_01_sand.png"
    assert layer["tile_size"] == [128.0, 64.0]
    assert manifest["tiles"] == [{"x": 0, "y": 0, "splatmaps": ["splatmap_0.png", "splatmap_1.png"],
                                  "position": [0.0, 0.0]}]
    script = (tmp_path / "Editor" / "TerrathemeImporter.cs").read_text()
    for call in ("SetAlphamaps", "alphamapResolution", "TerrainLayer", "tileSize", "tileOffset"):
        assert call in script


def test_tiles_share_their_border_texels(tmp_path, grid):
    project = _project(grid, (9, 9))
    plan = plan_export(project, ExportOptions(Engine.UNITY, tile=32))
    # 64 pixels needed; 32-pixel tiles sharing borders: 3 * 31 + 1 = 94.
    assert plan.layout.size == (94, 94) and plan.layout.tiles == (3, 3)
    write_export(project, plan, tmp_path)

    def tile(tx, ty):
        return np.concatenate([_rgba(tmp_path / f"splatmap_{s}_x{tx}_y{ty}.png")
                               for s in range(2)], axis=2)

    for ty in range(3):
        for tx in range(3):
            t = tile(tx, ty)
            assert t.shape == (32, 32, 8) and (t[:, :, :5].sum(axis=2, dtype=int) == 255).all()
            if tx:
                np.testing.assert_array_equal(tile(tx - 1, ty)[:, -1], t[:, 0])
            if ty:
                np.testing.assert_array_equal(tile(tx, ty - 1)[-1], t[0])
    whole = theme_weights(grid, (94, 94), n_themes=5)
    np.testing.assert_array_equal(np.moveaxis(tile(1, 2)[:, :, :5], 2, 0),
                                  whole[:, 62:94, 31:63])
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    spacing = 63 / 93
    assert manifest["tile_world_size"] == pytest.approx([31 * spacing] * 2)
    north_west = next(t for t in manifest["tiles"] if (t["x"], t["y"]) == (0, 0))
    assert north_west["position"] == pytest.approx([0.0, 2 * 31 * spacing])


def test_sizes_unity_refuses(grid):
    project = _project(grid, (9, 9))
    with pytest.raises(TerrathemeError, match="not a Unity alphamap resolution"):
        plan_export(project, ExportOptions(Engine.UNITY, size=(100, 100)))
    with pytest.raises(TerrathemeError, match="square"):
        plan_export(project, ExportOptions(Engine.UNITY, size=(64, 128)))
    with pytest.raises(TerrathemeError, match="^tile 17 is not a Unity"):
        plan_export(project, ExportOptions(Engine.UNITY, tile=17))
    with pytest.raises(TerrathemeError, match=r"k \* 31 \+ 1"):
        plan_export(project, ExportOptions(Engine.UNITY, size=(100, 94), tile=32))
    wide = _project(np.zeros((2, 313), np.uint8), (16, 16))
    plan = plan_export(wide, ExportOptions(Engine.UNITY))
    assert plan.layout.size == (4096, 4096) and "tiles of 4096" in plan.notes[0]


SCRIPTS = Path(exchange.__file__).resolve().parent / "scripts"


def _cs_classes(source: str) -> dict[str, dict[str, str]]:
    """The serialisable classes of a C# file: class name -> {field: C# type}."""
    return {name: dict((f, t) for t, f in re.findall(r"public ([\w\[\]]+) (\w+);", body))
            for name, body in re.findall(r"public class (\w+)\s*\{(.*?)\}", source, re.S)}


def _json_type_ok(cs_type: str, value) -> bool:
    if cs_type.endswith("[]"):
        return isinstance(value, list)
    return {"int": lambda v: isinstance(v, int), "float": lambda v: isinstance(v, int | float),
            "string": lambda v: isinstance(v, str)}.get(cs_type, lambda v: isinstance(v, dict))(
                value)


def test_the_importer_and_shaders_ship_and_name_what_the_export_writes(tmp_path, grid):
    project = _project(grid, (9, 9))
    project.colour_map = ColourMap(np.full((8, 8, 3), 128, np.uint8), 8)
    write_export(project, plan_export(project, ExportOptions(Engine.UNITY)), tmp_path)
    shipped = {"Editor/TerrathemeImporter.cs": "TerrathemeImporter.cs",
               "Shaders/TerrathemeTerrain.shader": "TerrathemeTerrain.shader",
               "Shaders/TerrathemeTerrainAddPass.shader": "TerrathemeTerrainAddPass.shader",
               "Shaders/TerrathemeColourMap.cginc": "TerrathemeColourMap.cginc"}
    for name, source in shipped.items():
        assert (tmp_path / name).read_bytes() == (SCRIPTS / source).read_bytes(), name
    script = (tmp_path / "Editor/TerrathemeImporter.cs").read_text()
    main = (tmp_path / "Shaders/TerrathemeTerrain.shader").read_text()
    add = (tmp_path / "Shaders/TerrathemeTerrainAddPass.shader").read_text()
    cginc = (tmp_path / "Shaders/TerrathemeColourMap.cginc").read_text()
    # The script finds the main shader by its name; the main shader names its add pass.
    main_name = re.search(r'^Shader "([^"]+)"', main, re.M)[1]
    add_name = re.search(r'^Shader "([^"]+)"', add, re.M)[1]
    assert f'Shader.Find("{main_name}")' in script
    assert re.search(r'Dependency "AddPassShader"\s*=\s*"([^"]+)"', main)[1] == add_name
    # Both passes multiply by the colour map's gain, from the include shipped beside them.
    for shader in (main, add):
        assert '#include "TerrathemeColourMap.cginc"' in shader
        assert "o.Albedo = mixedDiffuse.rgb * TerrathemeColourGain(IN.tc.xy);" in shader
    # What the script sets is what the shader reads (SetTextureScale/Offset write _ST).
    assert set(re.findall(r'Set(?:Texture|Float)\("(\w+)"', script)) == {"_ColourMap",
                                                                          "_ColourGain"}
    for shader in (main, add):
        props = set(re.findall(r"^\s*(?:\[HideInInspector\] )?(_\w+) \(", shader, re.M))
        for prop in set(re.findall(r'Set(?:Texture|Float)\("(\w+)"', script)):
            assert prop in props, prop
    for uniform in ("sampler2D _ColourMap;", "float4 _ColourMap_ST;", "float _ColourGain;"):
        assert uniform in cginc
    # Every field the script reads from the manifest is there, with a JSON type that fits.
    manifest = json.loads((tmp_path / "terratheme_unity.json").read_text())
    assert '.EndsWith("terratheme_unity.json")' in script
    classes = _cs_classes(script)
    objects = {"Manifest": [manifest], "Layer": manifest["layers"], "Tile": manifest["tiles"],
               "ColourMap": [manifest["colour_map"]]}
    assert set(classes) == set(objects)
    for name, fields in classes.items():
        for obj in objects[name]:
            for field, cs_type in fields.items():
                assert field in obj and _json_type_ok(cs_type, obj[field]), (name, field)
    # The files the manifest names are in the export.
    for name in [manifest["colour_map"]["file"], *(layer["texture"]
                                                   for layer in manifest["layers"]),
                 *(f for t in manifest["tiles"] for f in t["splatmaps"])]:
        assert (tmp_path / name).is_file(), name
    assert len(manifest["tiles"][0]["colour_map_st"]) == 4
