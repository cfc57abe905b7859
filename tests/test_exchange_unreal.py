"""Unreal export: one 8-bit weight map per theme at a recommended landscape size, tiles, sizes."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from terratheme.core import exchange
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import (
    Engine,
    ExportOptions,
    plan_export,
    write_export,
)
from terratheme.core.exchange.maps_to_grid import grid_from_maps
from terratheme.core.model.colour_map import ColourMap
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


class _Object:
    """An Unreal object as the material script sees it: editor properties by name."""

    def __init__(self, kind: str, **props) -> None:
        self.kind, self.props = kind, dict(props)

    def set_editor_property(self, name, value) -> None:
        self.props[name] = value

    def get_editor_property(self, name):
        return self.props[name]


class _Enum:
    def __init__(self, name: str) -> None:
        self.name = name

    def __getattr__(self, value: str) -> str:
        return f"{self.name}.{value}"


class _FakeUnreal:
    """The few calls of Unreal's ``unreal`` module the material script makes, recorded."""

    def __init__(self) -> None:
        self.assets, self.links, self.imported, self.base = {}, [], [], None
        for enum in ("TextureAddress", "TextureCompressionSettings", "TextureMipGenSettings",
                     "TextureFilter", "LandscapeLayerBlendType", "MaterialProperty"):
            setattr(self, enum, _Enum(enum))
        self.AssetToolsHelpers = self.EditorAssetLibrary = self.MaterialEditingLibrary = self

    def __getattr__(self, name: str) -> str:
        assert name.startswith("MaterialExpression"), name
        return name

    Material = "Material"

    # Unreal's own names for what the script creates
    def AssetImportTask(self):
        return _Object("AssetImportTask")

    def LayerBlendInput(self):
        return _Object("LayerBlendInput")

    def MaterialFactoryNew(self):
        return None

    def get_asset_tools(self):
        return self

    def import_asset_tasks(self, tasks) -> None:
        for task in tasks:
            source = Path(task.props["filename"])
            assert source.is_file(), source
            path = f"{task.props['destination_path']}/{source.stem}.{source.stem}"
            self.assets[path] = _Object("Texture2D", file=source.name)
            task.props["imported_object_paths"] = [path]
            self.imported.append(source.name)

    def load_asset(self, path):
        return self.assets[path]

    def does_asset_exist(self, path) -> bool:
        return False

    def save_loaded_asset(self, asset, only_if_is_dirty) -> bool:
        return True

    def create_asset(self, name, path, cls, factory):
        return _Object(cls, path=f"{path}/{name}")

    def create_material_expression(self, material, cls, x, y):
        return _Object(cls)

    def connect_material_expressions(self, source, output, target, input_name) -> bool:
        if target.kind == "MaterialExpressionLandscapeLayerBlend":
            names = [entry.props["layer_name"] for entry in target.props["layers"]]
            assert input_name in [f"Layer {n}" for n in names], input_name
        self.links.append((source, output, target, input_name))
        return True

    def connect_material_property(self, expression, output, prop) -> bool:
        assert prop == "MaterialProperty.MP_BASE_COLOR"
        self.base = expression
        return True

    def recompile_material(self, material) -> None:
        pass

    def log(self, text) -> None:
        pass

    def input(self, target, name):
        """The expression and output connected to ``target``'s input ``name``."""
        found = [(s, o) for s, o, t, i in self.links if t is target and i == name]
        assert len(found) == 1, (target.kind, name)
        return found[0]

    def value(self, expression, x, y):
        """Evaluate a UV graph (coordinates, constants, multiply, add) at landscape vertex x, y."""
        kind, p = expression.kind, expression.props
        if kind == "MaterialExpressionLandscapeLayerCoords":
            return np.array([x, y], float) / p["mapping_scale"]
        if kind == "MaterialExpressionConstant2Vector":
            return np.array([p["r"], p["g"]])
        a = self.value(self.input(expression, "A")[0], x, y)
        b = self.value(self.input(expression, "B")[0], x, y)
        return {"MaterialExpressionMultiply": a * b, "MaterialExpressionAdd": a + b}[kind]


def _material_script(folder):
    spec = importlib.util.spec_from_file_location("material_script", folder / MATERIAL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


MATERIAL = "terratheme_unreal_material.py"


@pytest.mark.parametrize("colour", [True, False])
def test_the_material_script_blends_the_layers_and_multiplies_the_colour_map(tmp_path, colour):
    grid = np.random.default_rng(3).integers(0, 4, (15, 15)).astype(np.uint8)
    project = _project(grid, (9, 9))
    if colour:
        rng = np.random.default_rng(5)
        project.colour_map = ColourMap(rng.integers(80, 171, (11, 11, 3)).astype(np.uint8), 12)
    write_export(project, plan_export(project, ExportOptions(Engine.UNREAL)), tmp_path)
    shipped = Path(exchange.__file__).resolve().parent / "scripts" / MATERIAL
    assert (tmp_path / MATERIAL).read_bytes() == shipped.read_bytes()
    manifest = json.loads((tmp_path / "terratheme_unreal.json").read_text())
    unreal = _FakeUnreal()
    material = _material_script(tmp_path).build(unreal, str(tmp_path))
    assert material.props["path"] == f"/Game/Terratheme/{tmp_path.name}/M_Terratheme"
    themes = [f"theme_{k:02d}_{n}.png" for k, n in enumerate(SAFE)]
    assert unreal.imported == themes + (["colour_map.png"] if colour else [])
    # One weight-blended layer per weight map, named as the weight maps' layers.
    blends = {s for s, _, t, _ in unreal.links} | {t for _, _, t, _ in unreal.links}
    (blend,) = [e for e in blends if e.kind == "MaterialExpressionLandscapeLayerBlend"]
    entries = blend.props["layers"]
    assert [e.props["layer_name"] for e in entries] == list(SAFE)
    assert {e.props["blend_type"] for e in entries} == {"LandscapeLayerBlendType.LB_WEIGHT_BLEND"}
    for layer, theme in zip(manifest["layers"], themes, strict=True):
        assert (tmp_path / layer["weightmap"]).is_file()
        sample, output = unreal.input(blend, f"Layer {layer['name']}")
        assert output == "RGB" and sample.props["texture"].props["file"] == theme
        coords = unreal.input(sample, "UVs")[0]
        assert coords.props["mapping_scale"] == layer["mapping_scale"] == 256.0
    if not colour:
        assert unreal.base is blend
        return
    # Base Color = blend x (colour map sample x 1 / srgb_to_linear(128 / 255)).
    assert unreal.input(unreal.base, "A")[0] is blend
    gain = unreal.input(unreal.base, "B")[0]
    srgb_128 = ((128 / 255 + 0.055) / 1.055) ** 2.4  # IEC 61966-2-1
    assert gain.kind == "MaterialExpressionMultiply"
    assert gain.props["const_b"] == pytest.approx(1 / srgb_128)
    sample, output = unreal.input(gain, "A")
    assert output == "RGB" and sample.props["texture"].props["file"] == "colour_map.png"
    texture = sample.props["texture"].props
    assert texture["srgb"] is True and texture["address_x"] == texture["address_y"] == \
        "TextureAddress.TA_CLAMP"
    assert texture["compression_settings"] == "TextureCompressionSettings.TC_EDITOR_ICON"
    assert texture["mip_gen_settings"] == "TextureMipGenSettings.TMGS_NO_MIPMAPS"
    # Its UV at every vertex: the manifest's transform (tests/test_exchange_colour.py shows that
    # a bilinear sample there is the renderer's gain).
    entry = manifest["colour_map"]
    uv = unreal.input(sample, "UVs")[0]
    for x, y in ((0, 0), (126, 0), (17, 93), (126, 126)):
        want = np.array(entry["uv_per_vertex"]) * (x, y) + entry["uv_offset"]
        np.testing.assert_allclose(unreal.value(uv, x, y), want)
