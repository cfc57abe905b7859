"""Issue 6: plane mapping (eq. 1), camera, derivatives (eq. 2), footprint (eqs. 3-4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective import Camera, FilterOptions, PlaneMapping, camera_mapping
from terratheme.core.perspective.footprint import TOWARD_U, TOWARD_V, footprint_sides


def test_straight_down_camera_is_one_texel_per_pixel():
    # fov 90 -> focal length w/2; height w/2 -> one texel per pixel
    w, h = 24, 16
    m = camera_mapping(Camera(height=w / 2, pitch=90, yaw=0, fov=90, x=w / 2, y=h / 2), (w, h))
    u, v, z = m.evaluate(np.array([0.5, 10.5]), np.array([0.5, 3.5]))
    np.testing.assert_allclose(u, [0.5, 10.5], atol=1e-9)
    np.testing.assert_allclose(v, [0.5, 3.5], atol=1e-9)
    assert np.all(z > 0)


def test_straight_down_yaw_90_turns_the_frame():
    # heading east: up on screen is +U, right on screen is +V
    m = camera_mapping(Camera(height=10, pitch=90, yaw=90, fov=90, x=100, y=50), (20, 20))
    u, v, _ = m.evaluate(np.array([10.0, 10.0, 15.0]), np.array([10.0, 5.0, 10.0]))
    np.testing.assert_allclose(u, [100, 105, 100], atol=1e-9)
    np.testing.assert_allclose(v, [50, 50, 55], atol=1e-9)


@pytest.mark.parametrize("pitch", [10.0, 30.0, 60.0])
@pytest.mark.parametrize("yaw", [0.0, 45.0, 200.0])
def test_frame_centre_hits_ground_at_height_over_tan_pitch(pitch, yaw):
    cam = Camera(height=7.0, pitch=pitch, yaw=yaw, fov=50, x=3.0, y=-2.0)
    m = camera_mapping(cam, (64, 48))
    u, v, _ = m.evaluate(np.array([32.0]), np.array([24.0]))
    d = 7.0 / math.tan(math.radians(pitch))
    # yaw 0 looks toward -V, clockwise seen from above
    want_u = 3.0 + d * math.sin(math.radians(yaw))
    want_v = -2.0 - d * math.cos(math.radians(yaw))
    np.testing.assert_allclose([u[0], v[0]], [want_u, want_v], atol=1e-9)


def test_level_camera_puts_horizon_on_the_centre_row():
    m = camera_mapping(Camera(height=5, pitch=0, fov=60), (40, 30))
    _, _, z = m.evaluate(np.array([3.0, 3.0, 3.0]), np.array([14.0, 15.0, 16.0]))
    assert z[0] < 0 and z[1] == pytest.approx(0.0, abs=1e-12) and z[2] > 0


def test_default_position_is_texture_centre():
    m = camera_mapping(Camera(height=4, pitch=90, fov=90), (8, 8), texture_size=(30, 10))
    u, v, _ = m.evaluate(np.array([4.0]), np.array([4.0]))
    assert (u[0], v[0]) == pytest.approx((15.0, 5.0))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=9, max_size=9),
       st.floats(0, 60), st.floats(0, 40))
def test_derivatives_match_finite_differences(coefs, x, y):
    # keep z comfortably positive around the point
    coefs[8] = abs(coefs[6]) * 61 + abs(coefs[7]) * 41 + 1.0
    m = PlaneMapping.from_sequence(coefs)
    e = 1e-5
    xs = np.array([x, x + e, x - e, x, x])
    ys = np.array([y, y, y, y + e, y - e])
    u, v, z = m.evaluate(xs, ys)
    dux, dvx, duy, dvy = m.derivatives(u[:1], v[:1], z[:1])
    np.testing.assert_allclose(dux, (u[1] - u[2]) / (2 * e), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(dvx, (v[1] - v[2]) / (2 * e), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(duy, (u[3] - u[4]) / (2 * e), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(dvy, (v[3] - v[4]) / (2 * e), rtol=1e-5, atol=1e-6)


def test_pixel_grid_samples_pixel_centres_and_flags_the_sky():
    m = PlaneMapping(1, 0, 0, 0, 1, 0, 0, 1, -2)  # z = y - 2: rows 0, 1 are sky
    u, v, z, dux, *_ = m.pixel_grid((3, 4))
    assert u.shape == (4, 3)
    assert np.all(np.isnan(u[:2])) and np.all(z[:2] <= 0)
    # row 2: z = 0.5, U = x / z
    np.testing.assert_allclose(u[2], np.array([0.5, 1.5, 2.5]) / 0.5)
    assert np.all(np.isfinite(dux))


@pytest.mark.parametrize(
    "d, want",
    [
        # U compressed 5:1 along x: long side along U, no skew
        ((5.0, 0.0, 0.0, 1.0), (5.0, 1.0, 0.0, TOWARD_U)),
        # V compressed, long side along V
        ((1.0, 0.0, 0.0, 8.0), (8.0, 1.0, 0.0, TOWARD_V)),
        # long side (0.5 s, s) tilted toward V by tan 0.5, base 1 along U
        ((1.0, 0.0, 4.0, 8.0), (8.0, 1.0, 0.5, TOWARD_V)),
        # negative skew
        ((1.0, 0.0, -4.0, 8.0), (8.0, 1.0, -0.5, TOWARD_V)),
        # long side (s, -0.25 s) tilted toward U
        ((8.0, -2.0, 0.0, 1.0), (8.0, 1.0, -0.25, TOWARD_U)),
        # a square turned 45 degrees: H = L = 2, tan -1
        ((1.0, 1.0, -1.0, 1.0), (2.0, 2.0, -1.0, TOWARD_U)),
        # magnification: below a texel (ties go to the y side, then to V)
        ((0.25, 0.0, 0.0, 0.25), (0.25, 0.25, 0.0, TOWARD_V)),
    ],
)
def test_footprint_sides_on_known_footprints(d, want):
    # eq. 4: H = A + |bs| along the tilted side, L = |Ls| across it
    along, short_along, short_across, tan, toward = footprint_sides(*d)
    assert (along + abs(short_along), abs(short_across), tan) == pytest.approx(want[:3])
    assert toward == want[3]


def test_footprint_of_zero_derivatives_is_finite():
    along, short_along, short_across, tan, _ = footprint_sides(0.0, 0.0, 0.0, 0.0)
    assert along + abs(short_along) == 0 and short_across == 0 and tan == 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(height=0, pitch=10), "height"),
        (dict(height=5, pitch=100), "pitch"),
        (dict(height=5, pitch=10, fov=0), "fov"),
        (dict(height=float("nan"), pitch=10), "finite"),
    ],
)
def test_bad_camera_is_a_clear_error(kwargs, match):
    with pytest.raises(TerrathemeError, match=match):
        Camera(**kwargs)


def test_bad_mappings_are_clear_errors():
    with pytest.raises(TerrathemeError, match="singular"):
        PlaneMapping(1, 0, 0, 0, 1, 0, 0, 0, 0)
    with pytest.raises(TerrathemeError, match="non-finite"):
        PlaneMapping(1, 0, float("inf"), 0, 1, 0, 0, 0, 1)
    with pytest.raises(TerrathemeError, match="9 coefficients"):
        PlaneMapping.from_sequence([1, 2, 3])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(method="blurry"), "unknown filter method"),
        (dict(max_anisotropy=0.5), "max_anisotropy"),
        (dict(aperture=0), "aperture"),
        (dict(skew_oversampling=3), "skew_oversampling"),
        (dict(skew_oversampling=4), "skew_oversampling"),
        (dict(cells_per_footprint=0.5), "cells_per_footprint"),
        (dict(cells_per_footprint=float("nan")), "cells_per_footprint"),
        (dict(sky=()), "sky"),
        (dict(reference_min_samples=8, reference_max_samples=4), "reference_min_samples"),
    ],
)
def test_bad_options_are_clear_errors(kwargs, match):
    with pytest.raises(TerrathemeError, match=match):
        FilterOptions(**kwargs)


@pytest.mark.parametrize("size", [(0, 10), (10, 0), (16385, 4), (-1, 5), ("a", 3), (3,)])
def test_a_frame_size_out_of_range_is_refused_by_the_mapping(size):
    with pytest.raises(TerrathemeError, match="frame size"):
        camera_mapping(Camera(height=50.0, pitch=10.0), size)
