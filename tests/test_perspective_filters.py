"""Issues 6 and 18: every filter's conventions, the parallelogram filter against
the baselines, stability."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective import (
    Camera,
    FilterOptions,
    Method,
    PlaneMapping,
    PreparedTexture,
    render_perspective,
)

ALL = list(Method)


def _random_texture(h, w, c=3, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, c), dtype=np.uint8)


def _opt(method, **kw):
    return FilterOptions(method=method, reference_max_samples=32, **kw)


# ---------------------------------------------------------------- conventions


@pytest.mark.parametrize("shape", [(16, 24), (3, 5), (1, 1)])
def test_straight_down_camera_nearest_reproduces_texels(shape):
    h, w = shape
    tex = _random_texture(h, w)
    cam = Camera(height=w / 2, pitch=90, yaw=0, fov=90, x=w / 2, y=h / 2)
    img = render_perspective(tex, cam, (w, h), _opt(Method.NEAREST))
    np.testing.assert_array_equal(img, tex.astype(np.float32) / 255)


@pytest.mark.parametrize("cu, cv", [(3, 5), (-7, -2), (40, -33)])
def test_nearest_wraps_exactly(cu, cv):
    tex = _random_texture(6, 10)
    img = render_perspective(tex, PlaneMapping(1, 0, cu, 0, 1, cv, 0, 0, 1), (13, 9),
                             _opt(Method.NEAREST))
    py, px = np.mgrid[0:9, 0:13]
    want = tex[(py + cv) % 6, (px + cu) % 10].astype(np.float32) / 255
    np.testing.assert_array_equal(img, want)


def test_nearest_with_two_texels_per_pixel_takes_the_odd_texel():
    # pixel centre px + 0.5 maps to U = 2 px + 1: texel 2 px + 1
    tex = _random_texture(4, 8)
    img = render_perspective(tex, PlaneMapping(2, 0, 0, 0, 1, 0, 0, 0, 1), (4, 4),
                             _opt(Method.NEAREST))
    np.testing.assert_array_equal(img, tex[:, 1::2].astype(np.float32) / 255)


def test_bilinear_halfway_between_texel_centres_averages_neighbours():
    tex = _random_texture(5, 7).astype(np.float32) / 255
    img = render_perspective(tex, PlaneMapping(1, 0, 0.5, 0, 1, 0, 0, 0, 1), (7, 5),
                             _opt(Method.BILINEAR))
    want = 0.5 * (tex + np.roll(tex, -1, axis=1))
    np.testing.assert_allclose(img, want, atol=1e-6)


@pytest.mark.parametrize("method", ALL)
def test_every_filter_is_exact_at_texel_centres_one_to_one(method):
    tex = _random_texture(16, 16).astype(np.float32) / 255
    img = render_perspective(tex, PlaneMapping(1, 0, 0, 0, 1, 0, 0, 0, 1), (16, 16),
                             _opt(method))
    if method in (Method.REFERENCE, Method.PARALLELOGRAM):
        # the box over the pixel of the bilinear texture: 1/8, 3/4, 1/8 along each axis
        k = lambda t, ax: 0.125 * np.roll(t, 1, ax) + 0.75 * t + 0.125 * np.roll(t, -1, ax)  # noqa: E731
        np.testing.assert_allclose(img, k(k(tex, 0), 1), atol=1e-5)
    elif method == Method.EWA:
        # pbrt's EWA (its Gaussian covers at least a texel) blurs a little
        assert np.abs(img - tex).mean() < 0.15
    else:
        np.testing.assert_allclose(img, tex, atol=1e-5)


@pytest.mark.parametrize("method", ALL)
def test_constant_texture_gives_the_constant(method):
    tex = np.empty((32, 32, 3), np.float32)
    tex[:] = (0.2, 0.5, 0.9)
    cam = Camera(height=6, pitch=40, yaw=33, fov=50)  # the whole frame is ground
    img = render_perspective(tex, cam, (40, 24), _opt(method))
    np.testing.assert_allclose(img.reshape(-1, 3) - (0.2, 0.5, 0.9), 0, atol=1e-5)


def test_sky_above_the_horizon():
    tex = np.full((8, 8, 3), 0.25, np.float32)
    opt = FilterOptions(sky=(1.0, 0.0, 0.5))
    img = render_perspective(tex, Camera(height=3, pitch=0, fov=60), (20, 10), opt)
    np.testing.assert_allclose(img[:5].reshape(-1, 3) - (1.0, 0.0, 0.5), 0, atol=1e-6)
    np.testing.assert_allclose(img[6:], 0.25, atol=1e-5)


# ------------------------------------------------ the parallelogram filter


def test_a_footprint_of_whole_cells_reads_their_mean():
    # U = 8x: each pixel covers 8 whole texel columns, 4 cells of 2 (cells_per_footprint
    # 4); rows are equal, so the cross reading does not matter
    row = _random_texture(1, 64).astype(np.float32) / 255
    tex = np.repeat(row, 16, axis=0)
    img = render_perspective(tex, PlaneMapping(8, 0, 0, 0, 1, 0, 0, 0, 1), (8, 16))
    want = row[0].reshape(8, 8, 3).mean(axis=1)
    for r in range(16):
        np.testing.assert_allclose(img[r], want, atol=1e-5)


def test_a_sheared_footprint_of_one_cell_reads_that_cell():
    # dX = (32, 16), dY = (0, 2): H = 32 along U sloping 0.5, L = 2; with one cell
    # per footprint that is exactly a cell of copy (5, 1) with skew 0.5
    tex = _random_texture(64, 64).astype(np.float32) / 255
    opt = FilterOptions(cells_per_footprint=1)
    pt = PreparedTexture(tex, opt)
    img = pt.render(PlaneMapping(32, 0, 0, 16, 2, -8, 0, 0, 1), (2, 32), opt).image
    fam = pt.family()
    s = int(np.flatnonzero(np.isclose(np.linspace(-1, 1, int(fam.count[0, 5, 1])), 0.5))[0])
    copy = fam.copy(0, 5, 1, s)
    for px in range(2):
        for py in range(32):
            # pixel centre (32 px + 16, 16 px + 2 py + 1 - 8 + 8): cell row (16 px + 2 py + 1) / 2
            m = (16 * px + 2 * py) // 2
            np.testing.assert_allclose(img[py, px], copy[m % 32, px], atol=1e-5)


@pytest.mark.parametrize("over", [{}, dict(cells_per_footprint=1)])
@pytest.mark.parametrize("coefs", [
    (1.0, 2.0, 0.3, 0.0, 8.0, 0.1, 0.0, 0.0, 1.0),  # skew toward V
    (6.0, 0.0, 0.2, 3.0, 1.0, 0.4, 0.0, 0.0, 1.0),  # skew toward U
    (1.0, 0.3, 5.0, -0.2, 1.0, 9.0, 0.0, 0.01, 1.0),  # perspective
])
def test_negative_skews_mirror_positive_ones(over, coefs):
    # mirroring the texture left-right and U -> W - U flips every skew's sign
    tex = _random_texture(32, 32, 1).astype(np.float32) / 255
    au, bu, cu, av, bv, cv, az, bz, cz = coefs
    m = PlaneMapping(*coefs)
    w = 32
    mirror = PlaneMapping(w * az - au, w * bz - bu, w * cz - cu, av, bv, cv, az, bz, cz)
    opt = FilterOptions(**over)
    a = render_perspective(tex, m, (24, 20), opt)
    b = render_perspective(tex[:, ::-1], mirror, (24, 20), opt)
    np.testing.assert_allclose(a, b, atol=2e-5)


def test_parallelogram_beats_trilinear_on_a_grazing_checkerboard():
    yy, xx = np.mgrid[0:128, 0:128]
    tex = (((xx // 8) + (yy // 8)) % 2).astype(np.float32)
    pt = PreparedTexture(tex)
    cam = Camera(height=10, pitch=8, yaw=25, fov=60)
    ref = pt.render(cam, (96, 64), _opt(Method.REFERENCE, reference_density=2.0)).image
    err = {m: np.sqrt(np.mean((pt.render(cam, (96, 64), _opt(m)).image - ref) ** 2))
           for m in (Method.TRILINEAR, Method.PARALLELOGRAM)}
    assert err[Method.PARALLELOGRAM] < 0.6 * err[Method.TRILINEAR]


def test_parallelogram_beats_ewa_on_a_grazing_checkerboard():
    yy, xx = np.mgrid[0:128, 0:128]
    board = (((xx // 8) + (yy // 8)) % 2).astype(np.float32)
    pt = PreparedTexture(board)
    cam = Camera(height=10, pitch=6, yaw=25, fov=60)
    ref = pt.render(cam, (96, 64), _opt(Method.REFERENCE)).image
    err = {name: np.sqrt(np.mean((pt.render(cam, (96, 64), o).image - ref) ** 2))
           for name, o in (("cover", FilterOptions()), ("ewa", FilterOptions(method=Method.EWA)))}
    assert err["cover"] < 0.6 * err["ewa"]


def test_prepared_texture_is_reused_across_frames():
    tex = _random_texture(32, 32)
    pt = PreparedTexture(tex)
    fam = pt.family()
    for yaw in (0, 90):
        cam = Camera(height=8, pitch=20, yaw=yaw)
        got = pt.render(cam, (20, 12))
        assert pt.family() is fam
        np.testing.assert_array_equal(got.image, render_perspective(tex, cam, (20, 12)))
        assert got.mean_reads <= 16
    assert pt.memory_bytes() == fam.nbytes + tex.nbytes


@pytest.mark.parametrize("method", [Method.PARALLELOGRAM, Method.TRILINEAR, Method.EWA])
def test_eight_bit_textures_store_eight_bit_copies(method):
    tex = _random_texture(32, 32)
    opt = FilterOptions(method=method)
    p8, pf = PreparedTexture(tex, opt), PreparedTexture(tex.astype(np.float32) / 255, opt)
    assert p8.memory_bytes() * 4 == pf.memory_bytes()
    cam = Camera(height=6, pitch=10, yaw=20)
    a, b = p8.render(cam, (30, 20)).image, pf.render(cam, (30, 20)).image
    assert np.abs(a - b).max() <= 2.5 / 255


# ---------------------------------------------------------------- stability


def _check_finite_in_range(img, tex, sky):
    assert np.all(np.isfinite(img))
    lo = min(float(tex.min()), min(sky))
    hi = max(float(tex.max()), max(sky))
    assert img.min() >= lo - 1e-4 and img.max() <= hi + 1e-4


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("view", [
    Camera(height=5, pitch=3, yaw=17, fov=70),  # horizon row inside the frame
    Camera(height=5, pitch=90, yaw=0, fov=60),  # straight down
    PlaneMapping(1, 0, 0, 0, 100, 0, 0, 0, 1),  # anisotropy 100:1
    PlaneMapping(1, -90, 0, 0, 100, 0, 0, 0, 1),  # 100:1 with a negative skew
    PlaneMapping(0, 0, 3, 0, 0, 4, 0, 0, 1),  # singular: every pixel the same point
    PlaneMapping(0, 0, 0, 0, 0, 0, 0, 0, -1),  # z < 0 everywhere: all sky
    PlaneMapping(1e9, 0, 0, 0, 1e9, 0, 0, 1, 1e-300),  # near-infinite footprints
])
@pytest.mark.parametrize("shape", [(1, 1), (3, 5), (16, 16)])
def test_never_nan_never_out_of_range(method, view, shape):
    tex = _random_texture(*shape).astype(np.float32) / 255
    opt = _opt(method, max_anisotropy=16)
    img = render_perspective(tex, view, (17, 11), opt)
    assert img.shape == (11, 17, 3)
    _check_finite_in_range(img, tex, opt.sky)


@pytest.mark.parametrize("method", ALL)
def test_one_texel_texture_is_its_colour_everywhere(method):
    tex = np.array([[[0.1, 0.6, 0.3]]], np.float32)
    img = render_perspective(tex, Camera(height=2, pitch=35, fov=40), (9, 7), _opt(method))
    np.testing.assert_allclose(img.reshape(-1, 3) - (0.1, 0.6, 0.3), 0, atol=1e-5)


def test_bad_inputs_are_clear_errors():
    with pytest.raises(TerrathemeError, match="channels"):
        PreparedTexture(np.zeros((4, 4, 5), np.float32))
    with pytest.raises(TerrathemeError, match="non-empty"):
        PreparedTexture(np.zeros((0, 4, 3), np.float32))
    with pytest.raises(TerrathemeError, match="NaN"):
        PreparedTexture(np.full((4, 4), np.nan, np.float32))
    pt = PreparedTexture(np.zeros((4, 4, 3), np.float32))
    with pytest.raises(TerrathemeError, match="frame size"):
        pt.render(Camera(height=1, pitch=45), (0, 10))
    with pytest.raises(TerrathemeError, match="PlaneMapping or a Camera"):
        pt.render("north", (10, 10))
    with pytest.raises(TerrathemeError, match="sky colour"):
        pt.render(PlaneMapping(1, 0, 0, 0, 1, 0, 0, 1, -100), (2, 2), FilterOptions(sky=(1, 2)))


def test_grey_and_rgba_textures_keep_their_channels():
    for c in (1, 4):
        tex = np.full((8, 8, c), 0.5, np.float32)
        img = render_perspective(tex, Camera(height=3, pitch=5), (10, 6))
        assert img.shape == (6, 10, c)
        assert np.all(np.isfinite(img))
