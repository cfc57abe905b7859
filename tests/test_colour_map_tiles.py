"""Colour maps beyond their codec's single-image limit ship in tiles (JPEG XL level 5 is 2^28 px).

The limit is forced small here (a 400 x 400 km region's 25000^2 map would be
the real case); projects whose map fits one image are written and read as before.
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
import terratheme.core.model.colour_map as colour_map_module
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.codec import decode_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import ThemeLibrary, flat_theme


@pytest.fixture
def small_limit(monkeypatch):
    """JPEG XL and PNG maps of more than 40 pixels a side or 1200 in all go in 16-pixel tiles."""
    limits = dict(colour_map_module.ONE_IMAGE_LIMITS, jpegxl=(40, 1200), png=(40, 1200))
    monkeypatch.setattr(colour_map_module, "ONE_IMAGE_LIMITS", limits)
    monkeypatch.setattr(colour_map_module, "MAP_TILE", 16)


def _gains(shape, seed=0):
    rng = np.random.default_rng(seed)
    return rng.integers(90, 170, (*shape, 3), dtype=np.uint8)


def _project(cmap: ColourMap, texture_size):
    w, h = texture_size
    grid = IndexGrid(np.zeros((h // 8 + 1, w // 8 + 1), np.uint8), (8, 8))
    return ThematicTexture(grid, ThemeLibrary([flat_theme("sand", (200, 180, 140))]),
                           colour_map=cmap)


def test_a_map_within_the_limit_is_one_image(small_limit):
    cmap = ColourMap.encode(_gains((30, 40)), 4, "png", 100)
    assert cmap.tiles is None and cmap.data is not None


@pytest.mark.parametrize("shape", [(50, 70), (20, 41), (36, 36)])
def test_a_map_beyond_the_limit_is_tiles_each_within_it(small_limit, shape):
    gains = _gains(shape)
    cmap = ColourMap.encode(gains, 4, "png", 100)
    assert cmap.data is None and cmap.tile == 16
    rows, cols = -(-shape[0] // 16), -(-shape[1] // 16)
    assert len(cmap.tiles) == rows * cols
    for k, data in enumerate(cmap.tiles):
        piece = decode_image(data, codec="png")
        y, x = (k // cols) * 16, (k % cols) * 16
        # Row by row; every tile within the single-image limit; lossless here: the gains.
        assert ColourMap.fits_one_image(piece.shape[:2], "png")
        assert np.array_equal(piece[:, :, :3], gains[y:y + 16, x:x + 16])
    assert np.array_equal(cmap.pixels, gains)
    assert cmap.nbytes == sum(len(t) for t in cmap.tiles)


def test_jpegxl_tiles_render_what_they_decode_to(small_limit):
    import cv2

    # A smooth gain field, as colour maps are.
    gains = cv2.resize(_gains((5, 7), seed=3), (70, 50), interpolation=cv2.INTER_LINEAR)
    cmap = ColourMap.encode(gains, 8, "jpegxl", 99)
    assert cmap.tiles is not None
    # Close at quality 99, and the map is the tiles decoded.
    assert np.abs(cmap.pixels.astype(int) - gains).mean() < 1
    again = ColourMap.from_tiles(cmap.tiles, "jpegxl", 8, gains.shape[:2], 16)
    assert np.array_equal(again.pixels, cmap.pixels)


def test_project_round_trip_of_a_tiled_map_is_version_2(small_limit, tmp_path):
    cmap = ColourMap.encode(_gains((50, 70)), 8, "jpegxl", 99)
    project = _project(cmap, (70 * 8, 50 * 8))
    save_project(tmp_path / "t.ttproj", project)
    back = load_project(tmp_path / "t.ttproj")
    assert back.colour_map == cmap and back.colour_map.tiles == cmap.tiles
    with zipfile.ZipFile(tmp_path / "t.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 2
    entry = manifest["colour_map"]
    assert entry["tile"] == 16 and len(entry["members"]) == 4 * 5
    assert entry["members"][:2] == ["colour_map/000_000.jxl", "colour_map/000_001.jxl"]
    grid, themes = back.grid, back.library.textures
    assert np.array_equal(render_cells(grid, themes, colour_map=back.colour_map),
                          render_cells(grid, themes, colour_map=cmap))


def test_an_upsampled_tiled_map_is_enlarged_whole_and_round_trips(small_limit, tmp_path):
    import cv2

    gains = _gains((25, 63), seed=2)
    # A 1000 x 392 texture: at 8 texels a pixel it needs 125 x 49, one less than 2 x 63 / 2 x 25.
    cmap = ColourMap.encode(gains, 16, "png", 100, upsample=2, texture_size=(1000, 392))
    assert cmap.tiles is not None and cmap.pixels.shape == (49, 125, 3)
    # The tiles are enlarged as one map (no seams where tiles meet): PNG is lossless.
    want = cv2.resize(gains, (126, 50), interpolation=cv2.INTER_CUBIC)[:49, :125]
    assert np.array_equal(cmap.pixels, want)
    project = _project(cmap, (1000, 392))
    save_project(tmp_path / "u.ttproj", project)
    with zipfile.ZipFile(tmp_path / "u.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 3 and manifest["colour_map"]["upsample"] == 2
    back = load_project(tmp_path / "u.ttproj")
    assert back.colour_map == cmap and back.colour_map.tiles == cmap.tiles


def test_a_project_whose_map_fits_stays_version_1(tmp_path):
    cmap = ColourMap.encode(_gains((12, 14)), 8, "jpegxl", 99)
    save_project(tmp_path / "s.ttproj", _project(cmap, (14 * 8, 12 * 8)))
    with zipfile.ZipFile(tmp_path / "s.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 1
    assert manifest["colour_map"] == {"scale": 8, "codec": "jpegxl", "member": "colour_map.jxl"}
    assert load_project(tmp_path / "s.ttproj").colour_map.data == cmap.data


def _rewrite(src, dst, change):
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        manifest = json.loads(zin.read("manifest.json"))
        change(manifest)
        zout.writestr("manifest.json", json.dumps(manifest))
        for name in zin.namelist():
            if name != "manifest.json":
                zout.writestr(name, zin.read(name))


@pytest.mark.parametrize(("change", "match"), [
    (lambda m: m["colour_map"]["members"].pop(), "tile members"),
    (lambda m: m["colour_map"].update(tile=32), "tiles are 16 pixels a side"),
    # One small member listed once per map pixel (minutes of decoding before the fix).
    (lambda m: m["colour_map"].update(tile=1, members=["colour_map/000_000.png"] * 50 * 70),
     "tiles of 1 pixels"),
    (lambda m: m["colour_map"]["members"].__setitem__(1, m["colour_map"]["members"][0]),
     "listed twice"),
    (lambda m: m["colour_map"].update(tile=0), "positive integer"),
    (lambda m: m["colour_map"].update(codec="gif"), "codec"),
    (lambda m: m["colour_map"].update(codec=[]), "codec"),  # was a TypeError (unhashable)
    (lambda m: m["colour_map"]["members"].reverse(), "expected"),
])
def test_damaged_tiled_maps_are_refused_in_one_line(small_limit, tmp_path, change, match):
    cmap = ColourMap.encode(_gains((50, 70)), 8, "png", 100)
    save_project(tmp_path / "t.ttproj", _project(cmap, (70 * 8, 50 * 8)))
    _rewrite(tmp_path / "t.ttproj", tmp_path / "bad.ttproj", change)
    with pytest.raises(CorruptFileError, match=match):
        load_project(tmp_path / "bad.ttproj")


def test_tiles_that_do_not_match_the_map_are_refused():
    with pytest.raises(TerrathemeError, match="has 4 tiles, not 3"):
        ColourMap(_gains((20, 20)), 4, "png", None, (b"", b"", b""), 16)
    with pytest.raises(TerrathemeError, match="no single image"):
        ColourMap(_gains((20, 20)), 4, "png", b"x", (b"",) * 4, 16)


def test_tiled_conversion_gives_the_untiled_gains(small_limit, tmp_path, monkeypatch):
    from terratheme.core.convert.colour_fit import ColourMapOptions, colour_map_from_file
    from terratheme.core.io.images import write_image

    rng = np.random.default_rng(8)
    photo = rng.integers(30, 220, (300, 420, 3), dtype=np.uint8)
    write_image(tmp_path / "p.png", photo)
    grid = IndexGrid(rng.integers(0, 2, (20, 28)).astype(np.uint8), (16, 16))
    themes = [np.full((8, 8, 3), 90, np.uint8), np.full((8, 8, 3), 160, np.uint8)]
    opts = ColourMapOptions(codec="png")
    tiled = colour_map_from_file(tmp_path / "p.png", grid, themes, 8, options=opts, tile=64)
    assert tiled.colour_map.tiles is not None and tiled.data is None
    limits = dict(colour_map_module.ONE_IMAGE_LIMITS, png=((1 << 31) - 1, 1 << 62))
    monkeypatch.setattr(colour_map_module, "ONE_IMAGE_LIMITS", limits)
    whole = colour_map_from_file(tmp_path / "p.png", grid, themes, 8, options=opts, tile=64)
    assert whole.colour_map.tiles is None
    assert np.array_equal(tiled.colour_map.pixels, whole.colour_map.pixels)


def test_outputs_of_a_tiled_map_ship_it_in_the_project_only(small_limit, tmp_path):
    from terratheme.core.convert.photo import write_outputs
    from terratheme.core.fidelity import texture_cost

    cmap = ColourMap.encode(_gains((50, 70)), 8, "jpegxl", 99)
    project = _project(cmap, (70 * 8, 50 * 8))
    written = write_outputs(project, tmp_path / "t.ttproj", packed_path=tmp_path / "t.ttpack")
    # No single <stem>_colour.jxl exists for it: the tiles are in the project.
    assert set(written) == {"project", "packed"}
    assert load_project(written["project"]).colour_map.tiles == cmap.tiles
    assert texture_cost(project).colour_map_bytes == cmap.nbytes
