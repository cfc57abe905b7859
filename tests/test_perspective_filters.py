"""Issue 6: the parallelogram filter, the baselines, stability, and the CLI."""

from __future__ import annotations

import numpy as np
import pytest

from app.cli import main
from core.errors import TerrathemeError
from core.io.images import read_image, write_image
from core.perspective import (
    Camera,
    FilterOptions,
    Method,
    PlaneMapping,
    PreparedTexture,
    render_perspective,
)
from core.perspective.family import build_family, skew_values
from core.perspective.texture import power_of_two_square

ALL = list(Method)
SEED = dict(skew_oversampling=1, long_oversampling=1, long_probes=1)  # the paper exactly


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
    if method in (Method.REFERENCE, Method.EWA):
        # a box over the pixel of the bilinear texture, and pbrt's EWA (its
        # Gaussian covers at least a texel), blur a little
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


# ------------------------------------------------------ the seed's family


def test_family_diagonal_copies_are_mip_levels_and_skew_zero_is_a_box():
    tex = _random_texture(8, 8, 1).astype(np.float32) / 255
    fam = build_family(tex, 2, 1, 1)
    # lambda = 1: 2^a x 2^a block means
    for a in range(4):
        r = 8 >> a
        want = tex.reshape(r, 1 << a, r, 1 << a).mean(axis=(1, 3))
        np.testing.assert_allclose(fam.copy(0, a, a, 0)[:, :, 0], want, atol=1e-6)
    # lambda = 2, toward U, skew 0: pairs of columns
    np.testing.assert_allclose(fam.copy(0, 1, 0, 0)[:, :, 0],
                               tex[:, :, 0].reshape(8, 4, 2).mean(axis=2), atol=1e-6)
    # toward V: pairs of rows, stored transposed
    np.testing.assert_allclose(fam.copy(1, 1, 0, 0)[:, :, 0],
                               tex[:, :, 0].reshape(4, 2, 8).mean(axis=1).T, atol=1e-6)


def test_family_memory_is_accounted():
    n_size, k = 16, 2
    fam = build_family(np.zeros((n_size, n_size, 3), np.float32), k, 1, 1)
    # by hand: (N >> a) * (N >> b) texels per copy, skews 1, 1, 3 for a - b = 0, 1, 2,
    # lambda = 1 stored once, the others for both orientations
    texels = 0
    for b in range(5):
        for a in range(b, min(4, b + k) + 1):
            count = {0: 1, 1: 2, 2: 6}[a - b]
            texels += count * (n_size >> a) * (n_size >> b)
    assert fam.texel_count == texels
    assert fam.nbytes == texels * 3 * 4


def test_oversampled_family_memory_is_accounted():
    # N = 16, k = 2, seed skews, long_oversampling = 2: a copy (a, b) holds
    # (N >> b) rows and min(N >> b, 2 (N >> a)) columns, skews 1, 2, 6 (both
    # orientations) for a - b = 0, 1, 2. By hand, per b:
    # b=0: 1*16*16 + 2*16*16 + 6*16*8 = 1536; b=1: 1*8*8 + 2*8*8 + 6*8*4 = 384;
    # b=2: 1*4*4 + 2*4*4 + 6*4*2 = 96; b=3: 1*2*2 + 2*2*2 = 12; b=4: 1
    fam = build_family(np.zeros((16, 16, 3), np.float32), 2, 1, 2, dtype=np.uint8)
    assert fam.texel_count == 1536 + 384 + 96 + 12 + 1
    assert fam.nbytes == 2029 * 3


def test_oversampled_family_keeps_mip_levels_for_square_footprints():
    # lambda = 1 copies are not oversampled (columns never closer than L), so
    # they are the 2^a x 2^a block means and a square footprint reads them exactly
    tex = _random_texture(16, 16, 1).astype(np.float32) / 255
    fam = build_family(tex, 2, 1, 4)
    for a in range(5):
        r = 16 >> a
        want = tex.reshape(r, 1 << a, r, 1 << a).mean(axis=(1, 3))
        np.testing.assert_allclose(fam.copy(0, a, a, 0)[:, :, 0], want, atol=1e-6)
    # U = 2x, V = 2y: footprint 2 x 2 texels centred on the 2 x 2 blocks
    img = render_perspective(tex, PlaneMapping(2, 0, 0, 0, 2, 0, 0, 0, 1), (8, 8),
                             FilterOptions(long_oversampling=4))
    np.testing.assert_allclose(img[:, :, 0], tex.reshape(8, 2, 8, 2).mean(axis=(1, 3)),
                               atol=1e-5)


def test_skew_sets():
    np.testing.assert_allclose(skew_values(1), [0.0])
    np.testing.assert_allclose(skew_values(2), [-1.0, 0.0, 1.0])
    np.testing.assert_allclose(skew_values(3), [-1.0, -0.5, 0.0, 0.5, 1.0])
    np.testing.assert_allclose(skew_values(2, 2), [-1.0, -0.5, 0.0, 0.5, 1.0])


@pytest.mark.parametrize("along_v", [False, True])
def test_parallelogram_equals_box_over_pixel_when_footprint_is_a_copy(along_v):
    # U = 4x (or V = 4y): footprint 4 x 1 texels, exactly the copy H = 4, L = 1
    tex = _random_texture(16, 16).astype(np.float32) / 255
    if along_v:
        mapping, size = PlaneMapping(1, 0, 0, 0, 4, 0, 0, 0, 1), (16, 4)
        want = tex.reshape(4, 4, 16, 3).mean(axis=1)
    else:
        mapping, size = PlaneMapping(4, 0, 0, 0, 1, 0, 0, 0, 1), (4, 16)
        want = tex.reshape(16, 4, 4, 3).mean(axis=2)
    img = render_perspective(tex, mapping, size, FilterOptions(**SEED))
    np.testing.assert_allclose(img, want, atol=1e-5)


@pytest.mark.parametrize("over", [dict(SEED), {}, dict(skew_blend=True)])
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


@pytest.mark.slow
def test_two_probes_match_eq5_at_powers_of_two_and_do_better_between():
    tex = _random_texture(64, 64).astype(np.float32) / 255
    eq5, probes = FilterOptions(long_probes=1), FilterOptions(long_probes=2)
    # H = 8: a copy's own length, both read that copy once
    m8 = PlaneMapping(8, 0, 0, 0, 1, 0, 0, 0, 1)
    np.testing.assert_allclose(render_perspective(tex, m8, (8, 8), eq5),
                               render_perspective(tex, m8, (8, 8), probes), atol=1e-6)
    # a grazing checkerboard: the two boxes spanning H beat eq. 5's blend
    yy, xx = np.mgrid[0:128, 0:128]
    board = (((xx // 8) + (yy // 8)) % 2).astype(np.float32)
    pt = PreparedTexture(board)
    cam = Camera(height=10, pitch=6, yaw=25, fov=60)
    ref = pt.render(cam, (96, 64), _opt(Method.REFERENCE)).image
    err = [np.sqrt(np.mean((pt.render(cam, (96, 64), o).image - ref) ** 2)) for o in (eq5, probes)]
    assert err[1] < err[0]


def test_prepared_texture_is_reused_across_frames():
    tex = _random_texture(32, 32)
    pt = PreparedTexture(tex)
    fam = pt.family()
    for yaw in (0, 90):
        cam = Camera(height=8, pitch=20, yaw=yaw)
        got = pt.render(cam, (20, 12))
        assert pt.family() is fam
        np.testing.assert_array_equal(got.image, render_perspective(tex, cam, (20, 12)))
        assert got.texel_reads.max() <= 16
    assert pt.memory_bytes() == fam.nbytes


@pytest.mark.parametrize("method", [Method.PARALLELOGRAM, Method.TRILINEAR, Method.EWA])
def test_eight_bit_textures_store_eight_bit_copies(method):
    tex = _random_texture(32, 32)
    opt = FilterOptions(method=method)
    p8, pf = PreparedTexture(tex, opt), PreparedTexture(tex.astype(np.float32) / 255, opt)
    assert p8.memory_bytes() * 4 == pf.memory_bytes()
    cam = Camera(height=6, pitch=10, yaw=20)
    a, b = p8.render(cam, (30, 20)).image, pf.render(cam, (30, 20)).image
    assert np.abs(a - b).max() <= 0.5 / 255 + 1e-6


def test_non_power_of_two_texture_is_resampled_up():
    tex = _random_texture(3, 5).astype(np.float32) / 255
    sq, su, sv = power_of_two_square(tex)
    assert sq.shape == (8, 8, 3) and (su, sv) == (8 / 5, 8 / 3)
    assert sq.min() >= tex.min() - 1e-6 and sq.max() <= tex.max() + 1e-6


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


# ---------------------------------------------------------------- CLI


def test_cli_identity_mapping_nearest_round_trips(tmp_path):
    tex = _random_texture(6, 9)
    src, out = tmp_path / "tex.png", tmp_path / "out.png"
    write_image(src, tex)
    rc = main(["perspective", str(src), str(out), "--method", "nearest", "--size", "9x6",
               "--mapping", "1,0,0,0,1,0,0,0,1"])
    assert rc == 0
    np.testing.assert_array_equal(read_image(out), tex)


def test_cli_max_texture_downscales_and_keeps_the_view_in_input_texels(tmp_path):
    # 2 x 2 blocks of one value: area-averaging to half size keeps every block.
    small = _random_texture(4, 6)
    big = np.repeat(np.repeat(small, 2, axis=0), 2, axis=1)
    src, out = tmp_path / "tex.png", tmp_path / "out.png"
    write_image(src, big)
    # the identity mapping of the big texture, sampled at every other pixel
    rc = main(["perspective", str(src), str(out), "--method", "nearest", "--size", "6x4",
               "--mapping", "2,0,0,0,2,0,0,0,1", "--max-texture", "6"])
    assert rc == 0
    np.testing.assert_array_equal(read_image(out), small)


def test_cli_camera_renders_every_method(tmp_path):
    src = tmp_path / "tex.png"
    write_image(src, _random_texture(16, 16))
    for method in ("parallelogram", "ewa", "reference"):
        out = tmp_path / f"{method}.png"
        rc = main(["perspective", str(src), str(out), "--method", method, "--size", "20x10",
                   "--camera", "4,12,30,60,3,3"])
        assert rc == 0
        img = read_image(out)
        assert img.shape == (10, 20, 3) and img.dtype == np.uint8


def test_cli_errors_exit_2(tmp_path, capsys):
    src = tmp_path / "tex.png"
    write_image(src, _random_texture(4, 4))
    rc = main(["perspective", str(src), str(tmp_path / "o.png"),
               "--mapping", "1,0,0,0,1,0,0,0,0"])
    assert rc == 2
    assert "singular" in capsys.readouterr().err
    rc = main(["perspective", str(tmp_path / "missing.png"), str(tmp_path / "o.png"),
               "--camera", "4,12,30,60"])
    assert rc == 2
    with pytest.raises(SystemExit) as exc:
        main(["perspective", str(src), str(tmp_path / "o.png"), "--camera", "4,12"])
    assert exc.value.code == 2


def test_cli_renders_a_project(tmp_path):
    from core.model.grid import IndexGrid
    from core.model.project import ThematicTexture, save_project
    from core.render.project import render_project
    from core.themes.library import ThemeLibrary, flat_theme

    lib = ThemeLibrary([flat_theme("field", (200, 180, 40)), flat_theme("water", (20, 60, 200))])
    grid = IndexGrid(np.array([[0, 1, 0], [1, 0, 1], [0, 0, 1]], np.uint8), (8, 8))
    project = ThematicTexture(grid, lib)
    path, out = tmp_path / "tiny.ttproj", tmp_path / "out.png"
    save_project(path, project)
    texture = render_project(project)
    h, w = texture.shape[:2]
    rc = main(["perspective", str(path), str(out), "--method", "nearest", "--size", f"{w}x{h}",
               "--mapping", "1,0,0,0,1,0,0,0,1"])
    assert rc == 0
    np.testing.assert_array_equal(read_image(out), texture)
