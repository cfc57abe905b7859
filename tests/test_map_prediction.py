"""Predicted colour maps: the grid's theme colours under the coded map (issue 34)."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.codec import decode_image, encode_image
from terratheme.core.model.colour_map import ColourMap, residual, restored
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.map_prediction import class_colours, class_prediction
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.themes.library import ThemeLibrary, flat_theme


def test_class_colours_are_each_themes_mean_over_the_pixels_nearest_its_vertices():
    # Vertices at texels 0, 8, 16 (cell 8); map pixels of 4 texels, centres 2, 6, 10, 14:
    # nearest vertices 0, 1, 1, 2 on each axis.
    indices = np.array([[0, 0, 1], [0, 0, 1], [2, 2, 1]], np.uint8)
    stored = np.zeros((4, 4, 3), np.uint8)
    stored[..., 0] = [[10, 20, 30, 40], [50, 60, 70, 80], [90, 100, 110, 120],
                      [130, 140, 150, 160]]
    stored[..., 1] = 7
    got = class_colours(stored, indices, (8, 8), 4, 4)
    # Theme 0: rows 0-2 x columns 0-2; theme 1: column 3; theme 2: row 3, columns 0-2.
    assert got[0, 0] == round(np.mean([10, 20, 30, 50, 60, 70, 90, 100, 110]))
    assert got[1, 0] == round(np.mean([40, 80, 120, 160]))
    assert got[2, 0] == round(np.mean([130, 140, 150]))
    assert (got[:3, 1] == 7).all()
    # A theme no vertex shows: neutral.
    assert got[3].tolist() == [128, 128, 128]


def test_one_theme_predicts_its_colour_everywhere():
    colours = np.array([[1, 2, 3], [40, 120, 250]], np.uint8)
    indices = np.ones((5, 7), np.uint8)
    got = class_prediction(indices, (16, 16), colours, 4, (16, 24))
    assert got.shape == (16, 24, 3) and (got == [40, 120, 250]).all()


def test_the_prediction_is_bilinear_between_vertices_at_each_pixel_centre():
    # Cell 8, map pixels of 4 texels: sigma half a cell = 1 map pixel is blurred; a cell of
    # 4 at scale 4 has sigma 0.5; cell 2 at scale 4 (sigma 0.25) is not blurred at all.
    colours = np.array([[0, 0, 0], [200, 100, 40]], np.uint8)
    indices = np.array([[0, 1, 0, 0], [0, 1, 0, 0]], np.uint8)  # vertices at x = 0, 2, 4, 6
    got = class_prediction(indices, (2, 2), colours, 4, (1, 2))
    # Pixel centres at x = 2 (vertex 1 exactly) and x = 6 (vertex 3, clamped to it).
    assert got[0, 0].tolist() == [200, 100, 40] and got[0, 1].tolist() == [0, 0, 0]
    got = class_prediction(indices, (2, 2), colours, 3, (2, 3))
    # Centres at x = 1.5, 4.5, 7.5: vertex coordinates 0.75, 2.25 and 3.75 (clamped at 3).
    assert got[0].tolist() == got[1].tolist() == [[150, 75, 30], [0, 0, 0], [0, 0, 0]]


def test_the_blur_is_half_a_cell_and_keeps_the_mean_of_a_step():
    colours = np.array([[0, 0, 0], [200, 200, 200]], np.uint8)
    indices = np.zeros((3, 9), np.uint8)
    indices[:, 5:] = 1
    got = class_prediction(indices, (16, 16), colours, 2, (16, 64))[..., 0].astype(int)
    row = got[8]
    # Monotone across the step, level far from it, symmetric about its middle.
    assert (np.diff(row) >= 0).all() and row[0] == 0 and row[-1] == 200
    mid = 4.5 * 16 / 2 - 0.5  # the vertex ramp's middle, in map pixels
    left, right = row[int(np.floor(mid)) - 3], row[int(np.ceil(mid)) + 3]
    assert abs(left + right - 200) <= 1
    # Wider than the bilinear ramp alone (one cell, 8 map pixels): the blur spreads it.
    assert np.count_nonzero((row > 0) & (row < 200)) > 8


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_residual_then_restored_is_the_map_within_the_codes_range(seed):
    rng = np.random.default_rng(seed)
    prediction = rng.integers(0, 256, (5, 6, 3)).astype(np.uint8)
    offset = rng.integers(-127, 128, (5, 6, 3))
    stored = np.clip(prediction.astype(int) + offset, 0, 255).astype(np.uint8)
    assert np.array_equal(restored(residual(stored, prediction), prediction), stored)


def test_a_predicted_map_codes_its_residual_and_decodes_to_the_map():
    rng = np.random.default_rng(1)
    stored = rng.integers(80, 180, (12, 10, 3)).astype(np.uint8)
    prediction = rng.integers(80, 180, (12, 10, 3)).astype(np.uint8)
    colours = [(1, 2, 3)]
    cmap = ColourMap.encode(stored, 4, "png", 50, colours=colours, prediction=prediction)
    assert np.array_equal(cmap.pixels, stored) and cmap.colours == ((1, 2, 3),)
    assert np.array_equal(decode_image(cmap.data, codec="png"), residual(stored, prediction))
    # Redrawn from its bytes, with its prediction.
    assert np.array_equal(cmap.redrawn(0, (40, 48)).pixels, stored)
    with pytest.raises(TerrathemeError, match="prediction"):
        ColourMap.encode(stored, 4, "png", 50, colours=colours, prediction=prediction[:5])
    with pytest.raises(TerrathemeError, match="colours and its prediction"):
        ColourMap(stored, 4, "png", cmap.data, colours=colours)
    with pytest.raises(TerrathemeError, match="coded in one image"):
        ColourMap(stored, 4, colours=colours, prediction=prediction)


def _predicted_project(upsample=2, sharpen=2):
    rng = np.random.default_rng(5)
    indices = rng.integers(0, 3, (9, 13)).astype(np.uint8)
    grid = IndexGrid(indices, (8, 8))  # 96 x 64 texels
    lib = ThemeLibrary([flat_theme("a", (128, 128, 128)), flat_theme("b", (128, 128, 128)),
                        flat_theme("c", (128, 128, 128))])
    scale = 4
    mh, mw = ColourMap.shape_for(grid.texture_size, scale)
    stored = rng.integers(70, 190, (mh, mw, 3)).astype(np.uint8)
    colours = class_colours(stored, indices, grid.cell, scale, len(lib))
    prediction = class_prediction(indices, grid.cell, colours, scale, (mh, mw))
    cmap = ColourMap.encode(stored, scale, "avif", 60, upsample=upsample, sharpen=sharpen,
                            texture_size=grid.texture_size, colours=colours,
                            prediction=prediction)
    return ThematicTexture(grid, lib, {}, colour_map=cmap)


def _manifest(path):
    with zipfile.ZipFile(path) as zf:
        return json.loads(zf.read("manifest.json"))


def test_a_predicted_map_round_trips_as_version_5(tmp_path):
    proj = _predicted_project()
    save_project(tmp_path / "p.ttproj", proj)
    manifest = _manifest(tmp_path / "p.ttproj")
    assert manifest["version"] == 5
    assert manifest["colour_map"]["colours"] == [list(c) for c in proj.colour_map.colours]
    back = load_project(tmp_path / "p.ttproj")
    assert back == proj and back.colour_map.colours == proj.colour_map.colours
    assert np.array_equal(back.colour_map.pixels, proj.colour_map.pixels)
    assert (back.colour_map.upsample, back.colour_map.sharpen) == (2, 2)


def test_a_grid_or_themes_changed_under_a_predicted_map_save_the_map_shown(tmp_path):
    proj = _predicted_project()
    indices = proj.grid.indices.copy()
    indices[4, 6] = (indices[4, 6] + 1) % 3
    edited = ThematicTexture(IndexGrid(indices, proj.grid.cell), proj.library, {},
                             colour_map=proj.colour_map)
    more = ThemeLibrary([*proj.library, flat_theme("d", (128, 128, 128))])
    added = ThematicTexture(proj.grid, more, {}, colour_map=proj.colour_map)
    for k, changed in enumerate((edited, added)):
        save_project(tmp_path / f"{k}.ttproj", changed)
        manifest = _manifest(tmp_path / f"{k}.ttproj")
        assert "colours" not in manifest["colour_map"] and manifest["version"] == 1
        back = load_project(tmp_path / f"{k}.ttproj")
        assert back.colour_map.codec is None
        assert np.array_equal(back.colour_map.pixels, proj.colour_map.pixels)
        assert back.colour_map.scale == proj.colour_map.scale


def _forged(tmp_path, change):
    save_project(tmp_path / "p.ttproj", _predicted_project(upsample=1, sharpen=0))
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    manifest = json.loads(members["manifest.json"])
    change(manifest, members)
    members["manifest.json"] = json.dumps(manifest).encode()
    with zipfile.ZipFile(tmp_path / "f.ttproj", "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return tmp_path / "f.ttproj"


def _set(key, value):
    return lambda m, _: m["colour_map"].__setitem__(key, value)


def _png_map(manifest, members):
    png = encode_image(decode_image(members.pop("colour_map.avif"), codec="avif"), codec="png")
    members["colour_map.png"] = png
    manifest["colour_map"].update(codec="png", member="colour_map.png")


def _huge_cell(manifest, _members):
    manifest["cell"] = [4096, 4096]


@pytest.mark.parametrize(("change", "match"), [
    (_set("colours", [[1, 2, 3]] * 2), "colours must be"),
    (_set("colours", [[1, 2, 3]] * 4), "colours must be"),
    (_set("colours", [[1, 2, 256]] * 3), "colours must be"),
    (_set("colours", [[1, 2, True]] * 3), "colours must be"),
    (_set("colours", [[1, 2]] * 3), "colours must be"),
    (_set("colours", "red"), "colours must be"),
    (_png_map, "colours must be"),
])
def test_a_forged_predicted_map_is_one_line(tmp_path, change, match):
    path = _forged(tmp_path, change)
    with pytest.raises(CorruptFileError, match=match) as info:
        load_project(path)
    assert "\n" not in str(info.value)


def test_a_grid_index_past_the_themes_under_a_predicted_map_is_refused(tmp_path):
    import io

    def bad_grid(_manifest, members):
        arr = np.load(io.BytesIO(members["grid.npy"]))
        arr[0, 0] = 7
        buf = io.BytesIO()
        np.save(buf, arr)
        members["grid.npy"] = buf.getvalue()

    with pytest.raises(CorruptFileError):
        load_project(_forged(tmp_path, bad_grid))


def test_a_grid_that_claims_a_larger_map_is_refused_on_the_header_before_a_prediction(
        tmp_path, monkeypatch):
    import terratheme.core.model.project as project

    def never(*_args):
        raise AssertionError("a prediction made for a map the image does not have")

    path = _forged(tmp_path, _huge_cell)  # 49152 x 32768 texels: a 12288 x 8192 map
    monkeypatch.setattr(project, "class_prediction", never)
    with pytest.raises(CorruptFileError, match="expected 12288 x 8192"):
        load_project(path)


def test_bands_give_the_whole_maps_prediction_colours_and_residual(monkeypatch):
    import terratheme.core.model.colour_map as cm
    import terratheme.core.model.map_prediction as mp

    rng = np.random.default_rng(9)
    indices = rng.integers(0, 4, (40, 30)).astype(np.uint8)
    colours = rng.integers(0, 256, (4, 3)).astype(np.uint8)
    stored = rng.integers(0, 256, (300, 230, 3)).astype(np.uint8)
    whole = (mp.class_prediction(indices, (16, 16), colours, 2, (300, 230)),
             mp.class_colours(stored, indices, (16, 16), 2, 5))
    res = residual(stored, whole[0])
    monkeypatch.setattr(mp, "BAND_ROWS", 7)
    monkeypatch.setattr(cm, "SHARPEN_ROWS", 5)
    assert np.array_equal(mp.class_prediction(indices, (16, 16), colours, 2, (300, 230)),
                          whole[0])
    assert np.array_equal(mp.class_colours(stored, indices, (16, 16), 2, 5), whole[1])
    assert np.array_equal(residual(stored, whole[0]), res)
    # By hand, one pixel: the image less the prediction's offset from neutral.
    assert int(res[3, 4, 1]) == int(np.clip(int(stored[3, 4, 1]) - int(whole[0][3, 4, 1]) + 128,
                                            0, 255))


def test_a_samples_prediction_is_the_regions_at_each_window():
    from terratheme.core.convert.region_sample import SamplePrediction

    rng = np.random.default_rng(4)
    indices = rng.integers(0, 3, (31, 41)).astype(np.uint8)
    grid = IndexGrid(indices, (16, 16))  # 640 x 480 texels
    # Two rows of two 96-pixel windows, side by side in a 192 x 192 joined image.
    wins = [(0, 0, 96, 96), (288, 48, 96, 96), (96, 240, 96, 96), (528, 384, 96, 96)]
    places = [(0, 0), (96, 0), (0, 96), (96, 96)]
    predict = SamplePrediction(grid, 3, "avif", tuple(zip(wins, places, strict=True)))
    scale = 4
    stored = rng.integers(40, 220, (48, 48, 3)).astype(np.uint8)
    got = predict(stored, scale)
    colours = got["colours"]
    whole = class_prediction(indices, grid.cell, colours, scale,
                             ColourMap.shape_for(grid.texture_size, scale))
    for (x, y, w, h), (jx, jy) in zip(wins, places, strict=True):
        assert np.array_equal(got["prediction"][jy // 4:(jy + h) // 4, jx // 4:(jx + w) // 4],
                              whole[y // 4:(y + h) // 4, x // 4:(x + w) // 4])
    # The colours are the themes' means over the windows' own map pixels.
    counts = np.zeros(3, int)
    sums = np.zeros((3, 3))
    from terratheme.core.model.map_prediction import nearest_vertices
    rows = nearest_vertices(120, scale, 16, 31)
    cols = nearest_vertices(160, scale, 16, 41)
    for (x, y, w, h), (jx, jy) in zip(wins, places, strict=True):
        for i in range(h // 4):
            for j in range(w // 4):
                t = indices[rows[y // 4 + i], cols[x // 4 + j]]
                counts[t] += 1
                sums[t] += stored[jy // 4 + i, jx // 4 + j]
    assert np.array_equal(colours, np.rint(sums / counts[:, None]).astype(np.uint8))
    # A codec whose header does not give the size: no prediction.
    assert SamplePrediction(grid, 3, "png", predict.blocks)(stored, scale) is None
