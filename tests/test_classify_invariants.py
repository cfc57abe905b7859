"""Invariant features (core.classify.invariants): known answers on tiny arrays."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from core.classify import SupervisedOptions
from core.classify.features import (
    FeatureOptions,
    compute_features,
    features_from_lab,
    image_features,
)
from core.classify.invariants import (
    LBP_CODES,
    RECONSTRUCTION_STEPS,
    colour_ratios,
    lbp_shares,
    local_rank,
    reconstruction_profile,
)
from core.classify.model_options import options_from_json, options_to_json
from core.classify.tiled import feature_windows
from core.errors import TerrathemeError

SIGMAS = (1.0, 2.0)
ALL = FeatureOptions(sigmas=SIGMAS, profile_radii=(1, 2), ratios=True, lbp=True,
                     rank_radii=(2,))


def square(value: float, background: float, size: int = 3, n: int = 15) -> np.ndarray:
    lum = np.full((n, n), background, np.float32)
    lo = (n - size) // 2
    lum[lo:lo + size, lo:lo + size] = value
    return lum


def test_bright_square_survives_a_disk_that_fits_and_not_one_that_does_not():
    lum = square(80.0, 20.0)
    profile = reconstruction_profile(lum, (1, 2))
    # Radius 1 (3 x 3 disk) fits the 3 x 3 square: the opening keeps it.
    np.testing.assert_allclose(profile[:, :, 0], 0.0)
    # Radius 2 does not: the residue is the square's contrast on it, 0 elsewhere.
    np.testing.assert_allclose(profile[:, :, 2], np.where(lum > 20.0, 60.0, 0.0))
    # Nothing is darker than its surroundings.
    np.testing.assert_allclose(profile[:, :, [1, 3]], 0.0)


def test_dark_square_is_a_closing_residue():
    lum = square(10.0, 70.0)
    profile = reconstruction_profile(lum, (2,))
    np.testing.assert_allclose(profile[:, :, 0], 0.0)
    np.testing.assert_allclose(profile[:, :, 1], np.where(lum < 70.0, 60.0, 0.0))


def test_reconstruction_reaches_only_its_steps():
    # A wide bright plateau with a one-pixel bright spur far from it: the spur is
    # reconstructed from the plateau only within RECONSTRUCTION_STEPS.
    n = 2 * RECONSTRUCTION_STEPS + 12
    lum = np.full((9, n), 20.0, np.float32)
    lum[:, :7] = 80.0
    lum[4, 7:] = 80.0
    opening = lum - reconstruction_profile(lum, (1,))[:, :, 0]
    spur = opening[4, 7:]
    assert (spur[:RECONSTRUCTION_STEPS] == 80.0).all()
    assert (spur[RECONSTRUCTION_STEPS:] == 20.0).all()


def test_colour_ratios_of_grey_and_under_a_change_of_exposure():
    rgb = np.array([[[0.5, 0.5, 0.5], [0.2, 0.4, 0.1], [0.1, 0.2, 0.05]]], np.float32)
    ratios = colour_ratios(cv2.cvtColor(rgb, cv2.COLOR_RGB2Lab))
    np.testing.assert_allclose(ratios[0, 0, :3], [1 / 3, 1 / 3, 0.0], atol=1e-3)
    np.testing.assert_allclose(ratios[0, 0, 4], 0.0, atol=1e-3)
    np.testing.assert_allclose(ratios[0, 1, :3], [2 / 7, 4 / 7, 1 / 3], atol=2e-3)
    # Half the sRGB values: the same chromaticity, nearly the same Lab hue.
    np.testing.assert_allclose(ratios[0, 2, :3], ratios[0, 1, :3], atol=2e-3)
    np.testing.assert_allclose(ratios[0, 2, 3], ratios[0, 1, 3], atol=0.02)


def test_colour_ratios_of_black_are_finite():
    ratios = colour_ratios(np.zeros((2, 2, 3), np.float32))
    np.testing.assert_allclose(ratios, 0.0, atol=1e-6)


def test_lbp_shares_of_a_flat_photo_are_all_one_code():
    shares = lbp_shares(np.full((16, 24), 40.0, np.float32), 8)
    assert shares.shape == (2, 3, LBP_CODES)
    # Every neighbour ties with the centre: all bits set, uniform code 8.
    np.testing.assert_allclose(shares[:, :, 8], 1.0, atol=1e-6)


def test_lbp_shares_ignore_gain_and_offset():
    rng = np.random.default_rng(2)
    levels = rng.integers(0, 6, (16, 16))
    # Half-resolution levels repeated 2 x 2, so the half-resolution codes are exact.
    lum = np.repeat(np.repeat(levels * 40 / 2.55, 2, 0), 2, 1).astype(np.float32)
    brighter = np.repeat(np.repeat((60 + levels * 20) / 2.55, 2, 0), 2, 1)
    shares = lbp_shares(lum, 8)
    np.testing.assert_allclose(shares.sum(2), 1.0, atol=1e-5)
    np.testing.assert_allclose(lbp_shares(brighter.astype(np.float32), 8), shares, atol=1e-6)


def test_lbp_needs_an_even_scale():
    with pytest.raises(TerrathemeError, match="even feature scale"):
        lbp_shares(np.zeros((9, 9), np.float32), 3)


def test_local_rank_of_a_peak_and_a_pit():
    lum = np.full((9, 9), 50.0, np.float32)
    lum[4, 4], lum[1, 1] = 90.0, 10.0
    rank = local_rank(lum, (2,))[:, :, 0]
    assert rank[4, 4] == 1.0
    # The pit is the only pixel at or below its value in its disk.
    assert rank[1, 1] < 0.1
    np.testing.assert_allclose(local_rank(lum * 0.5 + 20.0, (2,)), local_rank(lum, (2,)))


def test_counts_order_and_errors():
    photo = np.random.default_rng(1).integers(0, 256, (48, 40, 3), dtype=np.uint8)
    plain = FeatureOptions(sigmas=SIGMAS)
    assert ALL.n_features == plain.n_features + 2 * 2 + 5 + LBP_CODES + 1
    _lab, _std, without = image_features(photo, plain)
    feats = compute_features(photo, ALL)
    assert feats.shape[2] == ALL.n_features
    np.testing.assert_allclose(feats[:, :, :without.shape[2]], without, atol=1e-5)
    lab = np.zeros((4, 4, 3), np.float32)
    with pytest.raises(TerrathemeError, match="lbp needs"):
        features_from_lab(lab, lab[:, :, 0], ALL)
    with pytest.raises(TerrathemeError, match="whole numbers >= 1"):
        FeatureOptions(profile_radii=(0,))
    assert not SupervisedOptions().features.lbp


def test_tiles_with_the_halo_reproduce_the_whole_photo():
    rng = np.random.default_rng(6)
    photo = rng.integers(0, 256, (160, 184, 3), dtype=np.uint8)
    whole = compute_features(photo, ALL)
    for win in feature_windows(160, 184, 64, 8, ALL.halo):
        _lab, _std, part = image_features(photo[win.ry:win.ry1, win.rx:win.rx1], ALL)
        oy, ox = (win.y - win.ry) // 8, (win.x - win.rx) // 8
        core = part[oy:oy + (win.y1 - win.y) // 8, ox:ox + (win.x1 - win.x) // 8]
        np.testing.assert_allclose(
            core, whole[win.y // 8:win.y1 // 8, win.x // 8:win.x1 // 8], atol=1e-3)


def test_model_options_keep_the_invariant_options():
    opts = SupervisedOptions(features=ALL)
    d = json.loads(json.dumps(options_to_json(opts)))
    assert options_from_json(d).features == ALL
    d["features"]["profile_radii"] = [1.5]
    with pytest.raises(ValueError, match="profile_radii"):
        options_from_json(d)
