"""Issues 6 and 18: the parallelogram lookup's footprint bounds, the exact
coverage and quadrature reads (core/perspective/lookup.py, coverage.py)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.perspective import (
    Camera,
    FilterOptions,
    PlaneMapping,
    render_perspective,
)


def _random_texture(h, w, c=3, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, c)).astype(np.float32) / 255


LOOKUPS = [{}, dict(cells_per_footprint=1)]


@pytest.mark.parametrize("over", LOOKUPS)
def test_constant_texture_stays_constant_down_to_the_horizon(over):
    tex = np.empty((32, 32, 3), np.float32)
    tex[:] = (0.2, 0.5, 0.9)
    opt = FilterOptions(sky=(0.0, 0.0, 0.0), **over)
    # the horizon crosses the frame: footprints up to far beyond the texture
    img = render_perspective(tex, Camera(height=4, pitch=4, yaw=33, fov=70), (48, 32), opt)
    ground = img.reshape(-1, 3)[img.reshape(-1, 3).sum(axis=1) > 0]
    assert ground.shape[0] > 100
    np.testing.assert_allclose(ground - (0.2, 0.5, 0.9), 0, atol=1e-5)


@pytest.mark.parametrize("over", LOOKUPS)
@pytest.mark.parametrize("toward_v", [False, True])
def test_footprint_far_longer_than_the_texture_reads_the_mean(over, toward_v):
    # U = 5000 x (or V = 5000 y), skew 0.3: the footprint winds ~80 times round
    # the 64-texel texture; its turns fill it, so the pixel is the texture's mean
    tex = _random_texture(64, 64)
    if toward_v:
        m = PlaneMapping(1, 0.3 * 5000, 0, 0, 5000, 0, 0, 0, 1)
        size = (3, 2)
    else:
        m = PlaneMapping(5000, 0, 0, 0.3 * 5000, 1, 0, 0, 0, 1)
        size = (2, 3)
    img = render_perspective(tex, m, size, FilterOptions(**over))
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


@pytest.mark.parametrize("coefs", [
    (0.6, 0.2, 3.3, -0.1, 0.9, 5.1, 0.0, 0.0, 1.0),  # magnified, rotated
    (2.5, 0.4, 1.0, 0.3, 1.5, 2.0, 0.0, 0.0, 1.0),  # a few texels: still quadrature
    (0.3, 0.0, 7.0, 0.0, 0.2, 3.0, 0.0, 0.001, 1.0),  # perspective
])
def test_small_footprints_on_a_linear_ramp_give_the_ramp_at_the_pixel_centre(coefs):
    # the bilinear texture of a ramp is the ramp itself (away from the wrap), and the
    # box over a pixel of a linear function is its value at the pixel's centre
    yy, xx = np.mgrid[0:64, 0:64]
    tex = (0.003 * xx + 0.011 * yy).astype(np.float64)[:, :, None].astype(np.float32)
    m = PlaneMapping(*coefs)
    img = render_perspective(tex, m, (8, 6))
    u, v, _, *_ = m.pixel_grid((8, 6))
    np.testing.assert_allclose(img[:, :, 0], 0.003 * (u - 0.5) + 0.011 * (v - 0.5), atol=2e-6)


def test_magnified_isotropic_footprint_stays_bilinear_at_its_limit():
    # a pixel 1/1000 of a texel: the box over it is the bilinear value at its centre
    tex = _random_texture(16, 16)
    m = PlaneMapping(1e-3, 0, 3.3, 0, 1e-3, 7.9, 0, 0, 1)
    img = render_perspective(tex, m, (2, 2), FilterOptions())
    fx, fy = 3.3005 - 2.5, 7.9005 - 7.5  # the pixel centre (0.5, 0.5)
    want = ((1 - fx) * (1 - fy) * tex[7, 2] + fx * (1 - fy) * tex[7, 3]
            + (1 - fx) * fy * tex[8, 2] + fx * fy * tex[8, 3])
    np.testing.assert_allclose(img[0, 0], want, atol=1e-6)


def test_grazing_checkerboard_is_sharp_where_a_period_divides_the_copy():
    # the failure: H ~ 86 texels over a period of 32 along V; the seed's
    # boxes of 64 all read the mean (flat grey), the true box keeps a +-0.06 ripple
    yy, xx = np.mgrid[0:256, 0:256]
    board = (((xx // 16) + (yy // 16)) % 2).astype(np.float32)
    m = PlaneMapping(6, 0, -960, 0, 0, 2000, 0, 0.05, 1)
    ref = render_perspective(board, m, (320, 4), FilterOptions(
        method="reference", reference_min_samples=32, reference_max_samples=32))
    ours = render_perspective(board, m, (320, 4))
    assert ref[1].std() > 0.03 and ours[1].std() > 0.03
    assert np.sqrt(np.mean((ours - ref) ** 2)) < 0.5 * ref[1].std()


@pytest.mark.parametrize("view", [
    Camera(height=5, pitch=3, yaw=17, fov=70),  # horizon row inside the frame
    PlaneMapping(1, -90, 0, 0, 100, 0, 0, 0, 1),  # 100:1 with a negative skew
    PlaneMapping(1e9, 0, 0, 0, 1e9, 0, 0, 1, 1e-300),  # near-infinite footprints
])
@pytest.mark.parametrize("shape", [(1, 1), (3, 5)])
@pytest.mark.parametrize("over", LOOKUPS)
def test_never_nan_never_out_of_range(view, shape, over):
    tex = _random_texture(*shape)
    opt = FilterOptions(**over)
    img = render_perspective(tex, view, (17, 11), opt)
    assert np.all(np.isfinite(img))
    lo, hi = min(float(tex.min()), min(opt.sky)), max(float(tex.max()), max(opt.sky))
    assert img.min() >= lo - 1e-4 and img.max() <= hi + 1e-4

