"""The colour map: exact gains, region renders, overviews and the project file."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.render.colour_map import apply_colour_map, axis_weights, gain_image
from terratheme.core.render.overview import render_overview
from terratheme.core.render.project import render_project
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import ThemeLibrary, flat_theme


def _reference_gain(pixels: np.ndarray, s: int, x: int, y: int) -> list[Fraction]:
    """Bilinear gain at texel (x, y), written from the documented convention with fractions."""
    mh, mw = pixels.shape[:2]

    def axis(t: int, size: int) -> tuple[int, int, Fraction]:
        u = Fraction(2 * t + 1, 2 * s) - Fraction(1, 2)
        u = min(max(u, Fraction(0)), Fraction(size - 1))
        i0 = int(u)
        return i0, min(i0 + 1, size - 1), u - i0

    a, b, fy = axis(y, mh)
    c, d, fx = axis(x, mw)
    return [((1 - fy) * ((1 - fx) * int(pixels[a, c, ch]) + fx * int(pixels[a, d, ch]))
             + fy * ((1 - fx) * int(pixels[b, c, ch]) + fx * int(pixels[b, d, ch]))) / 128
            for ch in range(3)]


def _round_half_up(v: Fraction) -> int:
    return min(255, int(v + Fraction(1, 2)))


def test_a_uniform_half_gain_halves_every_texel_rounding_half_up():
    img = np.arange(256, dtype=np.uint8).reshape(16, 16, 1).repeat(3, axis=2).copy()
    cmap = ColourMap(np.full((1, 2, 3), 64, np.uint8), 8)
    apply_colour_map(img, cmap, (0, 0, 16, 16))
    want = (np.arange(256).reshape(16, 16) + 1) // 2
    assert np.array_equal(img[:, :, 0], want)


def test_gain_is_clamped_at_255():
    img = np.full((4, 4, 3), 200, np.uint8)
    apply_colour_map(img, ColourMap(np.full((1, 1, 3), 255, np.uint8), 4), (0, 0, 4, 4))
    assert (img == 255).all()


def test_axis_weights_match_the_convention():
    i0, i1, w0, w1 = axis_weights(0, 8, 4, 2)
    assert i0.tolist() == [0, 0, 0, 0, 0, 0, 1, 1]
    assert i1.tolist() == [1, 1, 1, 1, 1, 1, 1, 1]
    # u = (X + 0.5) / 4 - 0.5 -> fractions 0, 0, 1/8, 3/8, 5/8, 7/8, then the last pixel.
    assert (w1 / 8).tolist() == [0, 0, 0.125, 0.375, 0.625, 0.875, 0, 0]
    assert ((w0 + w1) == 8).all()


@settings(max_examples=30, deadline=None)
@given(s=st.integers(1, 9), w=st.integers(1, 30), h=st.integers(1, 20), seed=st.integers(0, 999))
def test_every_texel_equals_the_fraction_reference(s, w, h, seed):
    rng = np.random.default_rng(seed)
    cmap = ColourMap(rng.integers(0, 256, (-(-h // s), -(-w // s), 3), dtype=np.uint8), s)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    got = apply_colour_map(img.copy(), cmap, (0, 0, w, h))
    for y in range(h):
        for x in range(w):
            g = _reference_gain(cmap.pixels, s, x, y)
            assert got[y, x].tolist() == [_round_half_up(int(img[y, x, c]) * g[c])
                                          for c in range(3)]


def _project(colour_map=None):
    rng = np.random.default_rng(2)
    grid = IndexGrid(rng.integers(0, 3, (6, 9)).astype(np.uint8), (12, 10))  # 96 x 50
    lib = ThemeLibrary([flat_theme("a", (10, 20, 30)), flat_theme("b", (200, 100, 50)),
                        flat_theme("c", (90, 250, 140))])
    return ThematicTexture(grid, lib, {}, colour_map=colour_map)


def _map(scale=16, seed=4):
    rng = np.random.default_rng(seed)
    return ColourMap(rng.integers(40, 250, (-(-50 // scale), -(-96 // scale), 3),
                                  dtype=np.uint8), scale)


def test_region_render_equals_the_crop_of_the_full_render():
    proj = _project(_map())
    full = render_project(proj)
    for region in [(0, 0, 96, 50), (5, 7, 40, 30), (95, 49, 1, 1), (33, 0, 17, 50)]:
        x, y, w, h = region
        assert np.array_equal(render_project(proj, region), full[y:y + h, x:x + w])
    plain = render_project(_project())
    assert not np.array_equal(full, plain)
    assert np.array_equal(full, apply_colour_map(plain.copy(), proj.colour_map, (0, 0, 96, 50)))


def test_threads_and_bands_do_not_change_the_result():
    from terratheme.core.render.renderer import RenderOptions

    proj = _project(_map(scale=3))
    one = render_cells(proj.grid, proj.library.textures, colour_map=proj.colour_map,
                       options=RenderOptions(threads=1))
    two = render_cells(proj.grid, proj.library.textures, colour_map=proj.colour_map,
                       options=RenderOptions(threads=2))
    assert np.array_equal(one, two)


def test_overview_applies_the_gain_at_pixel_centres():
    proj = _project(ColourMap(np.full((4, 6, 3), 64, np.uint8), 16))
    half = render_overview(proj.grid.indices, proj.library.textures, proj.grid.cell,
                           scale=0.5, colour_map=proj.colour_map)
    plain = render_overview(proj.grid.indices, proj.library.textures, proj.grid.cell, scale=0.5)
    assert np.abs(half.astype(int) - plain.astype(int) / 2).max() <= 1
    g = gain_image(_map(), (0, 0, 96, 50), (96, 50))
    # Inside, and at the edges and corners, where the map's first and last pixels hold.
    for y, x in ((20, 40), (0, 0), (0, 95), (49, 0), (49, 95), (3, 7), (25, 90)):
        ref = _reference_gain(_map().pixels, 16, x, y)
        assert g[y, x].tolist() == pytest.approx([float(v) for v in ref], abs=1e-5)


def test_project_round_trip_keeps_the_colour_map(tmp_path):
    proj = _project(_map())
    save_project(tmp_path / "p.ttproj", proj)
    back = load_project(tmp_path / "p.ttproj")
    assert back == proj and back.colour_map.scale == 16


def test_a_map_that_does_not_cover_the_texture_is_refused():
    with pytest.raises(TerrathemeError, match="needs 6 x 4"):
        _project(ColourMap(np.full((3, 6, 3), 128, np.uint8), 16))
    proj = _project()
    with pytest.raises(TerrathemeError, match="needs"):
        render_cells(proj.grid, proj.library.textures,
                     colour_map=ColourMap(np.full((1, 1, 3), 128, np.uint8), 16))


@pytest.mark.parametrize("pixels, scale, match", [
    (np.zeros((2, 2), np.uint8), 4, r"\(h, w, 3\)"),
    (np.zeros((2, 2, 3), np.float32), 4, "uint8"),
    (np.zeros((2, 2, 3), np.uint8), 0, "integer 1..4096"),
    (np.zeros((2, 2, 3), np.uint8), 2.5, "integer 1..4096"),
    (np.zeros((0, 2, 3), np.uint8), 4, r"\(h, w, 3\)"),
])
def test_bad_colour_maps(pixels, scale, match):
    with pytest.raises(TerrathemeError, match=match):
        ColourMap(pixels, scale)


def _upsampled_map(scale=16, seed=5, codec="png"):
    """A map coded at ``scale`` over the 96 x 50 texture of :func:`_project`, drawn 2x finer."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(40, 250, (-(-50 // scale), -(-96 // scale), 3), dtype=np.uint8)
    return coarse, ColourMap.encode(coarse, scale, codec, 90, upsample=2, texture_size=(96, 50))


def test_an_upsampled_map_draws_the_bicubic_enlargement_of_its_coded_image():
    import cv2

    coarse, cmap = _upsampled_map()
    assert (cmap.scale, cmap.coded_scale, cmap.upsample) == (8, 16, 2)
    # 50 texels at 8 a pixel need 7 rows, not the enlargement's 8: the last is cut.
    assert cmap.coded_shape == coarse.shape[:2] and cmap.pixels.shape == (7, 12, 3)
    # PNG is lossless: the drawn pixels are OpenCV's bicubic 2x of the stored gains.
    want = cv2.resize(coarse, (12, 8), interpolation=cv2.INTER_CUBIC)[:7]
    assert np.array_equal(cmap.pixels, want)
    # A flat map stays flat, and a sharp step is sharper than bilinear's ramp.
    flat = ColourMap.encode(np.full((3, 4, 3), 77, np.uint8), 4, "png", 90, upsample=2,
                            texture_size=(16, 12))
    assert np.all(flat.pixels == 77) and flat.pixels.shape == (6, 8, 3)
    step = np.zeros((1, 4, 3), np.uint8)
    step[:, 2:] = 200
    row = ColourMap.encode(step, 2, "png", 90, upsample=2,
                           texture_size=(8, 2)).pixels[0, :, 0].astype(int)
    assert row[:3].max() <= 0 + 5 and row[5:].min() >= 200 - 5  # within a pixel of the step
    assert row[3] < 100 < row[4]


def test_an_upsampled_map_renders_as_a_plain_map_of_its_pixels():
    _, cmap = _upsampled_map()
    proj = _project(cmap)
    plain = ColourMap(cmap.pixels, cmap.scale)
    a = render_cells(proj.grid, proj.library.textures, colour_map=cmap)
    b = render_cells(proj.grid, proj.library.textures, colour_map=plain)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("codec", ["png", "avif"])
def test_project_round_trip_keeps_an_upsampled_map_as_version_3(tmp_path, codec):
    import json
    import zipfile

    _, cmap = _upsampled_map(codec=codec)
    proj = _project(cmap)
    save_project(tmp_path / "p.ttproj", proj)
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 3
    assert manifest["colour_map"]["scale"] == 16 and manifest["colour_map"]["upsample"] == 2
    back = load_project(tmp_path / "p.ttproj")
    assert back == proj and back.colour_map.upsample == 2
    assert back.colour_map.data == cmap.data


def test_a_plain_map_is_still_written_without_upsample(tmp_path):
    import json
    import zipfile

    save_project(tmp_path / "p.ttproj", _project(_map()))
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 1 and "upsample" not in manifest["colour_map"]


@pytest.mark.parametrize("upsample, scale, match", [
    (3, 16, "upsample"), (0, 16, "upsample"), (True, 16, "upsample"), ("2", 16, "upsample"),
    (2, 15, "upsample"),
])
def test_bad_upsamples_are_refused(upsample, scale, match):
    with pytest.raises(TerrathemeError, match=match):
        ColourMap.encode(np.full((2, 2, 3), 128, np.uint8), scale, "png", 90, upsample=upsample,
                         texture_size=(32, 32))


def test_an_upsampled_map_needs_its_texture_size():
    with pytest.raises(TerrathemeError, match="size of its texture"):
        ColourMap.encode(np.full((2, 2, 3), 128, np.uint8), 16, "png", 90, upsample=2)


def test_a_raw_map_cannot_claim_an_upsample():
    with pytest.raises(TerrathemeError, match="only for a coded map"):
        ColourMap(np.full((2, 2, 3), 128, np.uint8), 8, upsample=2)


@pytest.mark.parametrize("change, match", [
    ({"upsample": 3}, "upsample must be one of"),
    ({"upsample": True}, "upsample must be one of"),
    ({"upsample": 2, "scale": 15}, "upsample must be one of"),
    ({"upsample": 2, "codec": None, "member": "colour_map.npy"}, "upsample must be one of"),
    ({"sharpen": 9}, "sharpen must be"), ({"sharpen": -2}, "sharpen must be"),
    ({"sharpen": True}, "sharpen must be"), ({"sharpen": "4"}, "sharpen must be"),
    ({"sharpen": 1.5}, "sharpen must be"),
    ({"sharpen": 4, "upsample": 1, "codec": None, "member": "colour_map.npy"},
     "sharpen must be"),
])
def test_a_damaged_upsample_or_sharpen_entry_is_one_line(tmp_path, change, match):
    import json
    import zipfile

    from terratheme.core.errors import CorruptFileError

    _, cmap = _upsampled_map()
    save_project(tmp_path / "p.ttproj", _project(cmap))
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    manifest = json.loads(members["manifest.json"])
    manifest["colour_map"].update(change)
    members["manifest.json"] = json.dumps(manifest).encode()
    with zipfile.ZipFile(tmp_path / "bad.ttproj", "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    with pytest.raises(CorruptFileError, match=match) as err:
        load_project(tmp_path / "bad.ttproj")
    assert "\n" not in str(err.value)


def test_sharpened_is_the_unsharp_mask_of_a_step_worked_by_hand():
    from terratheme.core.model.colour_map import sharpened

    # A vertical step 0 | 100: the binomial blur's row weights are 1 4 6 4 1 (edges
    # replicated), so with amount 1 (q = 4) pixel 3 is 100 + (100 - 1100/16) = 131.25,
    # pixel 4 100 + (100 - 1500/16) = 106.25, and the dark side falls below 0 (clipped).
    step = np.zeros((4, 6, 3), np.uint8)
    step[:, 3:] = 100
    got = sharpened(step, 4)
    assert got[:, :, 0].tolist() == [[0, 0, 0, 131, 106, 100]] * 4
    assert np.array_equal(got[..., 0], got[..., 2])
    # Amount 1/2 (q = 2): 100 + 31.25 / 2 = 115.6 and 100 + 6.25 / 2 = 103.1.
    assert sharpened(step, 2)[0, :, 1].tolist() == [0, 0, 0, 116, 103, 100]
    assert sharpened(step, 0) is step
    # A flat map is left as it is at every amount.
    flat = np.full((5, 7, 3), 77, np.uint8)
    for q in range(9):
        assert np.array_equal(sharpened(flat, q), flat)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 40), st.integers(1, 12), st.integers(1, 8), st.integers(0, 2**31 - 1))
def test_sharpened_in_bands_is_the_whole_map_sharpened(rows, cols, q, seed):
    import terratheme.core.model.colour_map as cm

    pixels = np.random.default_rng(seed).integers(0, 256, (rows, cols, 3), dtype=np.uint8)
    whole = cm.sharpened(pixels, q)
    saved = cm.SHARPEN_ROWS
    try:
        cm.SHARPEN_ROWS = 3
        assert np.array_equal(cm.sharpened(pixels, q), whole)
    finally:
        cm.SHARPEN_ROWS = saved


def test_a_sharpened_map_draws_its_enlargement_sharpened_and_round_trips_as_version_4(tmp_path):
    import json
    import zipfile

    import cv2
    from terratheme.core.model.colour_map import sharpened

    coarse, plain = _upsampled_map()
    cmap = plain.redrawn(4, (96, 50))
    assert (cmap.sharpen, cmap.upsample, cmap.scale, cmap.data) == (4, 2, 8, plain.data)
    # Enlarged, sharpened whole, then cut to the texture's 7 rows.
    want = sharpened(cv2.resize(coarse, (12, 8), interpolation=cv2.INTER_CUBIC), 4)[:7]
    assert np.array_equal(cmap.pixels, want) and not np.array_equal(cmap.pixels, plain.pixels)
    proj = _project(cmap)
    save_project(tmp_path / "p.ttproj", proj)
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 4 and manifest["colour_map"]["sharpen"] == 4
    back = load_project(tmp_path / "p.ttproj")
    assert back == proj and back.colour_map.sharpen == 4
    assert np.array_equal(back.colour_map.pixels, cmap.pixels)
    # Unsharpened maps keep their older versions.
    save_project(tmp_path / "q.ttproj", _project(plain))
    with zipfile.ZipFile(tmp_path / "q.ttproj") as zf:
        manifest = json.loads(zf.read("manifest.json"))
    assert manifest["version"] == 3 and "sharpen" not in manifest["colour_map"]


@pytest.mark.parametrize("sharpen", [9, -1, True, "2", 2.5, None])
def test_bad_sharpens_are_refused(sharpen):
    with pytest.raises(TerrathemeError, match="sharpen must be"):
        ColourMap.encode(np.full((2, 2, 3), 128, np.uint8), 16, "png", 90, upsample=2,
                         sharpen=sharpen, texture_size=(32, 32))
    with pytest.raises(TerrathemeError, match="sharpen must be"):
        ColourMap(np.full((2, 2, 3), 128, np.uint8), 8, sharpen=4)
