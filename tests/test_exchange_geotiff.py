"""GIS export: palette land-class GeoTIFF and baked texture, COG layout, georeference kept."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import tifffile
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange import Engine, ExportOptions, plan_export, write_export
from terratheme.core.io.georef import read_georeference
from terratheme.core.io.images import read_image
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import render_project
from terratheme.core.render.renderer import render_labels
from terratheme.core.themes.library import shipped_theme_library

NAMES = ("water", "sand", "forest", "town")
GEOREF = {
    "ModelPixelScale": [0.5, 0.5, 0.0],
    "ModelTiepoint": [0.0, 0.0, 0.0, 500000.0, 4100000.0, 0.0],
    "GeoKeyDirectory": [1, 1, 0, 4, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633,
                        3076, 0, 1, 9001],
    "GeoAsciiParams": "WGS 84 / UTM zone 33N|",
}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    rng = np.random.default_rng(8)
    grid = rng.integers(0, 4, (21, 37)).astype(np.uint8)
    # The photo was 1150 x 640 texels: the grid's last cells go past it.
    metadata = {"georeference": GEOREF, "photo_size": [1150, 640]}
    project = ThematicTexture(IndexGrid(grid, (32, 32)), shipped_theme_library().select(NAMES),
                              metadata)
    out = tmp_path_factory.mktemp("gis")
    write_export(project, plan_export(project, ExportOptions(Engine.GEOTIFF)), out)
    return project, out


def test_land_class_map_is_a_palette_geotiff(exported):
    project, out = exported
    labels = render_labels(project.grid.indices, project.grid.cell, (0, 0, 1150, 640))
    with tifffile.TiffFile(out / "landclass.tif") as tif:
        page = tif.pages.first
        assert page.shape == (640, 1150) and page.photometric == tifffile.PHOTOMETRIC.PALETTE
        assert page.is_tiled and page.tilewidth == 512
        np.testing.assert_array_equal(page.asarray(), labels)
        np.testing.assert_array_equal(page.colormap[:, :4].T // 257, project.library.colours)
        np.testing.assert_array_equal(tif.pages[1].asarray(), labels[::2, ::2])
    # OpenImageIO expands the palette: every pixel shows its theme's display colour.
    np.testing.assert_array_equal(read_image(out / "landclass.tif"),
                                  project.library.colours[labels])
    style = ET.parse(out / "landclass.qml").getroot()
    entries = style.findall(".//paletteEntry")
    assert [e.get("label") for e in entries] == list(NAMES)
    assert entries[0].get("color") == "#{:02x}{:02x}{:02x}".format(*project.library.colours[0])


def test_baked_texture_is_the_render(exported):
    project, out = exported
    render = render_project(project, (0, 0, 1150, 640))
    np.testing.assert_array_equal(read_image(out / "texture.tif"), render)
    with tifffile.TiffFile(out / "texture.tif") as tif:
        np.testing.assert_array_equal(tif.pages.first.asarray(), render)
        half = tif.pages[1].asarray().astype(int)
        # First overview: 2 x 2 means of the render.
        want = render[:640, :1150].reshape(320, 2, 575, 2, 3).mean(axis=(1, 3))
        assert np.abs(half - want).max() <= 0.5


@pytest.mark.parametrize("name", ["landclass.tif", "texture.tif"])
def test_georeference_survives(exported, name):
    _, out = exported
    geo = read_georeference(out / name)
    for key, value in GEOREF.items():
        assert geo[key] == value, key
    with tifffile.TiffFile(out / name) as tif:
        keys = tif.pages.first.geotiff_tags
        assert keys["ProjectedCSTypeGeoKey"] == 32633
        assert list(keys["ModelPixelScale"]) == GEOREF["ModelPixelScale"]


@pytest.mark.parametrize("name", ["landclass.tif", "texture.tif"])
def test_cog_layout(exported, name):
    _, out = exported
    with tifffile.TiffFile(out / name) as tif:
        pages = list(tif.pages)
        sizes = [p.shape[:2] for p in pages]
        assert sizes == [(640, 1150), (320, 575), (160, 288)]
        assert [p.subfiletype for p in pages] == [0, 1, 1]
        ifds = [p.offset for p in pages]
        first_data = [min(p.dataoffsets) for p in pages]
        last_data = [max(p.dataoffsets) for p in pages]
    # GDAL's COG rules: main IFD at byte 8, IFDs in order, all before any tile data...
    assert ifds[0] == 8 and ifds == sorted(ifds) and max(ifds) < min(first_data)
    # ...and the tile data of the smallest overview first, the full resolution last.
    for k in range(len(pages) - 1):
        assert last_data[k + 1] < first_data[k]


def test_manifest_and_no_georeference(tmp_path, exported):
    project, out = exported
    manifest = json.loads((out / "terratheme_geotiff.json").read_text())
    assert manifest["size"] == [1150, 640] and manifest["overviews"] == 2
    assert manifest["units"] == "metre" and manifest["texel_size"] == [0.5, 0.5]
    assert [c["name"] for c in manifest["classes"]] == list(NAMES)
    plain = ThematicTexture(project.grid, project.library, {})
    plan = plan_export(plain, ExportOptions(Engine.GEOTIFF))
    assert "no georeference" in plan.notes[0]
    with pytest.raises(TerrathemeError, match="size and tile are for engine exports"):
        plan_export(plain, ExportOptions(Engine.GEOTIFF, tile=512))


def test_a_real_georeference_in_us_survey_feet_survives(tmp_path, shared_data):
    # DRCOG's land cover tile: Colorado State Plane, US survey feet, 1 ft pixels.
    source = shared_data / "geotiff" / "DRCOG_2020_LULC_E2880000_N1680000.tif"
    if not source.is_file():
        pytest.skip(f"{source} is absent")
    georef = read_georeference(source)
    grid = np.array([[0, 1, 2], [3, 0, 1]], np.uint8)
    project = ThematicTexture(IndexGrid(grid, (16, 16)), shipped_theme_library().select(NAMES),
                              {"georeference": georef})
    write_export(project, plan_export(project, ExportOptions(Engine.GEOTIFF)), tmp_path)
    placement = ("ModelPixelScale", "ModelTiepoint", "GeoKeyDirectory", "GeoAsciiParams")
    for name in ("landclass.tif", "texture.tif"):
        back = read_georeference(tmp_path / name)
        assert {k: back[k] for k in placement} == {k: georef[k] for k in placement}
        # The photo's no-data value (0) is not the class map's: theme 0 stays visible.
        assert georef["GDAL_NODATA"] == "0" and "GDAL_NODATA" not in back
    manifest = json.loads((tmp_path / "terratheme_geotiff.json").read_text())
    assert manifest["crs_units"] == "US survey foot"
    assert manifest["texel_size"] == pytest.approx([1200 / 3937] * 2)


def test_a_texture_beyond_one_geotiff_level_is_refused_before_any_work(tmp_path, capsys):
    # 12 x 12 vertices at cell 4096: a 45056^2 texture, 5.7 GiB of RGB (the issue's
    # 10000^2 land-cover map at cell 32 failed after the work, reading a level back).
    from terratheme.app.cli import main
    from terratheme.core.model.project import save_project

    lib = shipped_theme_library().select(["water", "sand"])
    grid = IndexGrid((np.arange(144).reshape(12, 12) % 2).astype(np.uint8), (4096, 4096))
    save_project(tmp_path / "big.ttproj", ThematicTexture(grid, lib))
    out = tmp_path / "gis"
    assert main(["export", str(tmp_path / "big.ttproj"), str(out), "--engine", "geotiff"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--size" in err and "45056 x 45056" in err
    assert not out.exists() or not any(out.iterdir())


def test_the_colour_map_tiff_is_placed_at_its_scale(tmp_path):
    from terratheme.core.model.colour_map import ColourMap

    pixels = np.random.default_rng(3).integers(60, 200, (3, 4, 3)).astype(np.uint8)
    project = ThematicTexture(IndexGrid(np.zeros((6, 9), np.uint8), (16, 16)),
                              shipped_theme_library().select(NAMES[:1]),
                              {"georeference": GEOREF}, colour_map=ColourMap(pixels, 32))
    write_export(project, plan_export(project, ExportOptions(Engine.GEOTIFF)), tmp_path)
    np.testing.assert_array_equal(read_image(tmp_path / "colour_map.tif"), pixels)
    geo = read_georeference(tmp_path / "colour_map.tif")
    # 32 texels of 0.5 units a pixel, from the texture's own corner.
    assert geo["ModelPixelScale"][:2] == [16.0, 16.0]
    assert geo["ModelTiepoint"] == GEOREF["ModelTiepoint"]


@pytest.mark.parametrize("big", [False, True])
def test_write_cog_levels_layout_and_tags(tmp_path, monkeypatch, big):
    from terratheme.core.exchange import cog
    from terratheme.core.io.georef import tiff_extratags

    if big:
        monkeypatch.setattr(cog, "MAX_LEVEL_BYTES", 0)  # any tile data makes a BigTIFF
    image = np.random.default_rng(5).integers(0, 4, (70, 100), dtype=np.uint8)
    table = np.zeros((3, 256), np.uint16)
    table[:, :4] = [[0, 65535, 0, 900], [0, 0, 65535, 900], [65535, 0, 0, 900]]
    levels = cog.write_cog(tmp_path / "c.tif", lambda y0, y1: image[y0:y1], (100, 70),
                           channels=1, tile=32, photometric="minisblack", colormap=table,
                           downsample=cog.nearest_half, extratags=tiff_extratags(GEOREF))
    assert levels == 2 and sorted(p.name for p in tmp_path.iterdir()) == ["c.tif"]
    with tifffile.TiffFile(tmp_path / "c.tif") as tif:
        assert tif.is_bigtiff == big
        pages = list(tif.pages)
        for page, want in zip(pages, [image, image[::2, ::2], image[::4, ::4]], strict=True):
            assert page.photometric == tifffile.PHOTOMETRIC.PALETTE and page.tilewidth == 32
            np.testing.assert_array_equal(page.asarray(), want)
            np.testing.assert_array_equal(page.colormap, table)
        ifds = [p.offset for p in pages]
        first = [min(p.dataoffsets) for p in pages]
        last = [max(p.dataoffsets) for p in pages]
    assert ifds[0] == (16 if big else 8) and ifds == sorted(ifds) and max(ifds) < min(first)
    assert last[2] < first[1] and last[1] < first[0]
    assert read_georeference(tmp_path / "c.tif") == GEOREF


def test_a_latin1_citation_survives_the_export(tmp_path):
    # GeoAsciiParams is Latin-1 (validate_georeference); tifffile takes str as ASCII only.
    georef = {**GEOREF, "GeoAsciiParams": "Réseau géodésique français|"}
    project = ThematicTexture(IndexGrid(np.zeros((3, 4), np.uint8), (16, 16)),
                              shipped_theme_library().select(NAMES[:1]), {"georeference": georef})
    write_export(project, plan_export(project, ExportOptions(Engine.GEOTIFF)), tmp_path)
    for name in ("landclass.tif", "texture.tif"):
        assert read_georeference(tmp_path / name)["GeoAsciiParams"] == georef["GeoAsciiParams"]
