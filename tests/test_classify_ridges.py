"""Fine ridge features (core.classify.ridges): known answers on tiny photos."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from classify_cases import assert_tiles_match_whole
from terratheme.core.classify.features import FeatureOptions, image_features
from terratheme.core.classify.lab import full_lab
from terratheme.core.classify.ridges import block_ridges, hessian_eigenvalues, ridge_halo
from terratheme.core.errors import TerrathemeError


def grey(h: int, w: int, value: int = 200) -> np.ndarray:
    return np.full((h, w, 3), value, np.uint8)


def ridges_of(photo: np.ndarray, sigmas) -> np.ndarray:
    return block_ridges(full_lab(photo)[:, :, 0], 8, sigmas)


def test_hessian_eigenvalues_of_a_quadratic():
    # f = x^2 + 3 y^2 + x y has the constant Hessian [[2, 1], [1, 6]]: 4 +/- sqrt(5).
    y, x = np.mgrid[0:12, 0:14].astype(np.float32)
    larger, smaller = hessian_eigenvalues(x * x + 3 * y * y + x * y)
    np.testing.assert_allclose(larger[1:-1, 1:-1], 4 + np.sqrt(5), rtol=1e-5)
    np.testing.assert_allclose(smaller[1:-1, 1:-1], 4 - np.sqrt(5), rtol=1e-5)


def test_flat_photo_has_no_ridges():
    out = ridges_of(grey(20, 28), (1.0, 2.0))
    assert out.shape == (3, 4, 4) and out.dtype == np.float32
    np.testing.assert_allclose(out, 0.0, atol=1e-4)


def test_a_dark_line_shows_in_its_blocks_only():
    photo = grey(32, 32)
    photo[:, 12] = 40  # a one-pixel dark line in block column 1 (pixels 8..15)
    out = ridges_of(photo, (1.0,))
    dark, bright = out[:, :, 0], out[:, :, 1]
    # Across a dark valley the second derivative is positive: lambda_1 > 0 on the line.
    assert (dark[:, 1] > 5.0).all()
    # Blocks whose pixels are all more than 4 sigma from the line see nothing.
    np.testing.assert_allclose(dark[:, 3], 0.0, atol=1e-4)
    np.testing.assert_allclose(bright[:, 3], 0.0, atol=1e-4)
    # A bright line shows in the other channel (negative across a ridge), of similar size.
    bright_line = ridges_of(255 - photo, (1.0,))[:, :, 1]
    assert (bright_line[:, 1] < -0.5 * dark[:, 1]).all()
    np.testing.assert_allclose(bright_line[:, 3], 0.0, atol=1e-4)


def test_blocks_past_the_edge_are_edge_replicated():
    photo = grey(10, 10)
    photo[:, 9] = 0
    out = ridges_of(photo, (1.0,))
    assert out.shape == (2, 2, 2)
    # The partial block column 1 holds pixels 8..9 (and copies of 9): it sees the edge line.
    assert out[0, 1, 0] > 0 and abs(out[0, 0, 0]) < out[0, 1, 0]


def test_halo_and_counts():
    assert ridge_halo(()) == 0 and ridge_halo((1.0, 4.0)) == 13
    fo = FeatureOptions(hessian=True, ridge_sigmas=(1.0, 2.0, 4.0))
    assert fo.n_features == FeatureOptions(hessian=True).n_features + 6
    # The coarse halo covers the 3-sigma kernel of the largest fine sigma.
    assert FeatureOptions(sigmas=(0.5,), ridge_sigmas=(40.0,)).halo * 8 >= ridge_halo((40.0,))
    with pytest.raises(TerrathemeError, match="sigmas must be positive"):
        FeatureOptions(ridge_sigmas=(0.0,))


def test_features_carry_the_ridges_last():
    rng = np.random.default_rng(5)
    photo = rng.integers(0, 256, (40, 48, 3), dtype=np.uint8)
    fo = FeatureOptions(hessian=True, ridge_sigmas=(1.0, 2.0))
    feats = image_features(photo, fo)[2]
    assert feats.shape == (5, 6, fo.n_features)
    np.testing.assert_allclose(feats[:, :, -4:], ridges_of(photo, (1.0, 2.0)), atol=1e-4)
    _lab, _std, plain = image_features(photo, FeatureOptions(hessian=True))
    np.testing.assert_allclose(feats[:, :, :-4], plain, atol=1e-4)


def test_tiles_with_the_halo_reproduce_the_whole_photo():
    photo = np.random.default_rng(6).integers(0, 256, (72, 96, 3), dtype=np.uint8)
    fo = FeatureOptions(sigmas=(0.5,), ridge_sigmas=(1.0, 4.0))
    assert_tiles_match_whole(photo, fo, 32, slice(-4, None))


def test_full_lab_is_opencvs_8_bit_lab_rescaled():
    # OpenCV's 8-bit codes: L * 100/255, a and b - 128, in float32 arithmetic.
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (64, 300, 3), dtype=np.uint8)
    lab8 = cv2.cvtColor(rgb, cv2.COLOR_RGB2Lab).astype(np.float32)
    expect = (lab8 * np.array([100.0 / 255.0, 1.0, 1.0], np.float32)
              - np.array([0.0, 128.0, 128.0], np.float32))
    np.testing.assert_array_equal(full_lab(rgb), expect)
    assert full_lab(rgb).dtype == np.float32
