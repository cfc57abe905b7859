"""Morphological profile by reconstruction (core.classify.profiles): known answers."""

from __future__ import annotations

import json

import numpy as np
import pytest
from classify_cases import assert_tiles_match_whole
from terratheme.core.classify import SupervisedOptions
from terratheme.core.classify.features import FeatureOptions, compute_features, image_features
from terratheme.core.classify.model_options import options_from_json, options_to_json
from terratheme.core.classify.profiles import (
    RECONSTRUCTION_STEPS,
    profile_halo,
    reconstruction_profile,
)
from terratheme.core.errors import TerrathemeError

SIGMAS = (1.0, 2.0)
OPTIONS = FeatureOptions(sigmas=SIGMAS, profile_radii=(1, 2))


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
    # A wide bright plateau with a one-pixel bright spur: the spur is reconstructed
    # from the plateau only within RECONSTRUCTION_STEPS of it.
    lum = np.full((9, 2 * RECONSTRUCTION_STEPS + 12), 20.0, np.float32)
    lum[:, :7] = 80.0
    lum[4, 7:] = 80.0
    opening = lum - reconstruction_profile(lum, (1,))[:, :, 0]
    spur = opening[4, 7:]
    assert (spur[:RECONSTRUCTION_STEPS] == 80.0).all()
    assert (spur[RECONSTRUCTION_STEPS:] == 20.0).all()


def test_counts_order_halo_and_errors():
    photo = np.random.default_rng(1).integers(0, 256, (48, 40, 3), dtype=np.uint8)
    plain = FeatureOptions(sigmas=SIGMAS)
    assert OPTIONS.n_features == plain.n_features + 4
    assert OPTIONS.halo == profile_halo((1, 2)) == 2 + RECONSTRUCTION_STEPS + 1
    assert profile_halo(()) == 0
    _lab, _std, without = image_features(photo, plain)
    feats = compute_features(photo, OPTIONS)
    assert feats.shape[2] == OPTIONS.n_features
    np.testing.assert_allclose(feats[:, :, :without.shape[2]], without, atol=1e-5)
    with pytest.raises(TerrathemeError, match="whole numbers >= 1"):
        FeatureOptions(profile_radii=(0,))
    assert SupervisedOptions().features.profile_radii == ()


def test_tiles_with_the_halo_reproduce_the_whole_photo():
    photo = np.random.default_rng(6).integers(0, 256, (200, 232, 3), dtype=np.uint8)
    assert_tiles_match_whole(photo, OPTIONS, 64)


def test_model_options_keep_the_radii_and_refuse_fractions():
    d = json.loads(json.dumps(options_to_json(SupervisedOptions(features=OPTIONS))))
    assert options_from_json(d).features == OPTIONS
    d["features"]["profile_radii"] = [1.5]
    with pytest.raises(ValueError, match="profile_radii"):
        options_from_json(d)
