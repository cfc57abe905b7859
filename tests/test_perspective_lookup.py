"""Issue 6: the parallelogram lookup's footprint bounds, magnification probes
and skew blend (core/perspective/lookup.py)."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import TerrathemeError
from core.perspective import Camera, FilterOptions, PlaneMapping, render_perspective


def _random_texture(h, w, c=3, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, c)).astype(np.float32) / 255


@pytest.mark.parametrize("blend", [False, True])
@pytest.mark.parametrize("probes", [1, 2])
def test_constant_texture_stays_constant_down_to_the_horizon(blend, probes):
    tex = np.empty((32, 32, 3), np.float32)
    tex[:] = (0.2, 0.5, 0.9)
    opt = FilterOptions(skew_blend=blend, long_probes=probes, sky=(0.0, 0.0, 0.0))
    # the horizon crosses the frame: footprints up to far beyond the texture
    img = render_perspective(tex, Camera(height=4, pitch=4, yaw=33, fov=70), (48, 32), opt)
    ground = img.reshape(-1, 3)[img.reshape(-1, 3).sum(axis=1) > 0]
    assert ground.shape[0] > 100
    np.testing.assert_allclose(ground - (0.2, 0.5, 0.9), 0, atol=1e-5)


@pytest.mark.parametrize("probes", [1, 2])
@pytest.mark.parametrize("toward_v", [False, True])
def test_footprint_far_longer_than_the_texture_reads_the_mean(probes, toward_v):
    # U = 5000 x (or V = 5000 y), skew 0.3: the footprint winds ~80 times round
    # the 64-texel texture; its turns fill it, so the pixel is the texture's mean
    tex = _random_texture(64, 64)
    if toward_v:
        m = PlaneMapping(1, 0.3 * 5000, 0, 0, 5000, 0, 0, 0, 1)
        size = (3, 2)
    else:
        m = PlaneMapping(5000, 0, 0, 0.3 * 5000, 1, 0, 0, 0, 1)
        size = (2, 3)
    img = render_perspective(tex, m, size, FilterOptions(long_probes=probes))
    want = tex.reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(img.reshape(-1, 3) - want, 0, atol=1e-5)


def test_footprint_within_the_texture_is_not_widened():
    # H = 32 < N = 64, L = 2: exactly the copy H = 32, L = 2 (pixel centres
    # U = 8, 40 on its lattice: boxes [-8, 24) and [24, 56) of 2 rows), not
    # folded toward the mean
    tex = _random_texture(64, 64)
    img = render_perspective(tex, PlaneMapping(32, 0, -8, 0, 2, 0, 0, 0, 1), (2, 32),
                             FilterOptions())
    want = np.roll(tex, 8, axis=1).reshape(32, 2, 2, 32, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(img, want, atol=1e-5)


def _bilinear_1d(row, x):
    """Wrapping linear interpolation of ``row`` (texel centres at i + 0.5)."""
    n = row.shape[0]
    xs = x - 0.5
    i0 = np.floor(xs).astype(int)
    f = (xs - i0)[:, None]
    return (1 - f) * row[i0 % n] + f * row[(i0 + 1) % n]


def test_magnified_long_side_probes_at_plus_minus_sigma():
    # dX = (1.2, 0), dY = (0, 0.3): H = 1.2 < 2 texels, L = 0.3, toward U, tan = 0;
    # probes at U +- sigma, sigma^2 = 1.2^2 / 12 (a box of 1.2 texels), each
    # bilinear in the texture itself
    row = _random_texture(1, 16)[0]
    tex = np.repeat(row[None], 16, axis=0)
    m = PlaneMapping(1.2, 0, 0.37, 0, 0.3, 0, 0, 0, 1)
    img = render_perspective(tex, m, (12, 3), FilterOptions())
    u = 1.2 * (np.arange(12) + 0.5) + 0.37
    sigma = np.sqrt(1.2**2 / 12)
    want = 0.5 * (_bilinear_1d(row, u - sigma) + _bilinear_1d(row, u + sigma))
    for r in range(3):
        np.testing.assert_allclose(img[r], want, atol=1e-5)


def test_magnified_isotropic_footprint_stays_bilinear():
    # H = 1, L = 1 (one texel per pixel): a plain bilinear read, exact at centres
    tex = _random_texture(16, 16)
    img = render_perspective(tex, PlaneMapping(1, 0, 0, 0, 1, 0, 0, 0, 1), (16, 16),
                             FilterOptions())
    np.testing.assert_allclose(img, tex, atol=1e-5)


@pytest.mark.parametrize("probes", [1, 2])
@pytest.mark.parametrize("skew", [0.5, -0.5, 1.0, 0.0])
def test_skew_blend_at_a_family_skew_equals_the_single_skew_read(probes, skew):
    # dX = (8, 8 skew), dY = (0, 1): H = 8, L = 1, lambda = 8, whose copies have
    # skews -1, -0.5, 0, 0.5, 1: the blend reads exactly one of them
    tex = _random_texture(32, 32)
    m = PlaneMapping(8, 0, 0.3, 8 * skew, 1, 0.7, 0, 0, 1)
    one = render_perspective(tex, m, (6, 9), FilterOptions(long_probes=probes))
    blend = render_perspective(tex, m, (6, 9),
                               FilterOptions(long_probes=probes, skew_blend=True))
    np.testing.assert_allclose(blend, one, atol=1e-6)


def test_skew_blend_is_continuous_where_the_nearest_skew_jumps():
    # skew 0.25 is halfway between the copies 0 and 0.5 at lambda = 8: the
    # nearest copy switches there, the blend moves by O(eps)
    tex = _random_texture(32, 32, seed=3)
    eps = 1e-6

    def frame(skew, blend):
        m = PlaneMapping(8, 0, 0.3, 8 * skew, 1, 0.7, 0, 0, 1)
        return render_perspective(tex, m, (6, 9), FilterOptions(skew_blend=blend))

    jump = np.abs(frame(0.25 + eps, False) - frame(0.25 - eps, False)).max()
    step = np.abs(frame(0.25 + eps, True) - frame(0.25 - eps, True)).max()
    assert jump > 0.01
    assert step < 1e-4


def test_skew_blend_halfway_is_the_mean_of_the_neighbouring_copies():
    # skew 0.75 is halfway between the copies 0.5 and 1 at lambda = 8; the
    # nearest-skew lookup just below / above 0.75 reads copy 0.5 / copy 1 alone
    # (same coordinates to 1e-9), so the blend must be their mean
    tex = _random_texture(32, 32, seed=5)

    def frame(skew, blend):
        m = PlaneMapping(8, 0, 0.3, 8 * skew, 1, 0.7, 0, 0, 1)
        return render_perspective(tex, m, (6, 9), FilterOptions(skew_blend=blend))

    lo, hi = frame(0.75 - 1e-9, False), frame(0.75 + 1e-9, False)
    assert np.abs(lo - hi).max() > 0.01
    np.testing.assert_allclose(frame(0.75, True), 0.5 * (lo + hi), atol=1e-5)


@pytest.mark.parametrize("view", [
    Camera(height=5, pitch=3, yaw=17, fov=70),  # horizon row inside the frame
    PlaneMapping(1, -90, 0, 0, 100, 0, 0, 0, 1),  # 100:1 with a negative skew
    PlaneMapping(1e9, 0, 0, 0, 1e9, 0, 0, 1, 1e-300),  # near-infinite footprints
])
@pytest.mark.parametrize("shape", [(1, 1), (3, 5)])
def test_skew_blend_never_nan_never_out_of_range(view, shape):
    tex = _random_texture(*shape)
    opt = FilterOptions(skew_blend=True)
    img = render_perspective(tex, view, (17, 11), opt)
    assert np.all(np.isfinite(img))
    lo, hi = min(float(tex.min()), min(opt.sky)), max(float(tex.max()), max(opt.sky))
    assert img.min() >= lo - 1e-4 and img.max() <= hi + 1e-4


def test_skew_blend_must_be_a_bool():
    with pytest.raises(TerrathemeError, match="skew_blend"):
        FilterOptions(skew_blend=1)
