"""Features for photos of other areas: relative lightness and per-photo colour normalisation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.classify import FeatureOptions, Normalise
from terratheme.core.classify.features import (
    REFERENCE_MEAN,
    REFERENCE_STD,
    RELATIVE_FLOOR,
    features_from_lab,
    normalise_lab,
)
from terratheme.core.errors import TerrathemeError

SIGMAS = (0.5, 1.0, 2.0)


def relative_columns(options: FeatureOptions) -> slice:
    """The relative-lightness features: the last len(sigmas) image features."""
    return slice(options.n_image_features - len(options.sigmas), options.n_image_features)


def test_relative_lightness_of_a_flat_photo_is_l_over_l_plus_floor():
    lab = np.zeros((12, 14, 3), np.float32)
    lab[:, :, 0] = 40.0
    options = FeatureOptions(sigmas=SIGMAS, hessian=True, relative=True)
    feats = features_from_lab(lab, np.zeros((12, 14), np.float32), options)
    assert feats.shape == (12, 14, options.n_features)
    assert options.n_image_features == FeatureOptions(sigmas=SIGMAS, hessian=True
                                                      ).n_image_features + len(SIGMAS)
    np.testing.assert_allclose(feats[:, :, relative_columns(options)],
                               40.0 / (40.0 + RELATIVE_FLOOR), rtol=1e-6)


def test_relative_lightness_says_brighter_or_darker_than_the_surroundings():
    lab = np.zeros((21, 21, 3), np.float32)
    lab[:, :, 0] = 30.0
    lab[10, 10, 0] = 90.0   # a bright pixel
    lab[3, 3, 0] = 5.0      # a dark one
    options = FeatureOptions(sigmas=SIGMAS, relative=True)
    rel = features_from_lab(lab, np.zeros((21, 21), np.float32), options)[
        :, :, relative_columns(options)]
    # Column 0 is the pixel itself over its widest context.
    assert rel[10, 10, 0] > 1.5 and rel[3, 3, 0] < 0.5
    assert abs(rel[17, 17, 0] - 30.0 / 35.0) < 1e-5


def test_relative_lightness_needs_a_sigma():
    with pytest.raises(TerrathemeError, match="relative lightness needs at least one sigma"):
        FeatureOptions(sigmas=(), relative=True)


def test_relative_lightness_is_off_by_default_outside_supervised():
    assert FeatureOptions().relative is False


def lab_image(seed: int, shape=(10, 12)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lab = np.empty(shape + (3,), np.float32)
    lab[:, :, 0] = rng.uniform(10, 90, shape)
    lab[:, :, 1:] = rng.uniform(-30, 30, shape + (2,))
    return lab


def statistics(lab: np.ndarray) -> np.ndarray:
    pix = lab.reshape(-1, 3).astype(np.float64)
    return np.stack([pix.mean(0), pix.std(0)]).astype(np.float32)


def test_lab_normalisation_maps_the_statistics_to_the_reference_exactly():
    lab = lab_image(1)
    out, _ = normalise_lab(lab, np.zeros(lab.shape[:2], np.float32), statistics(lab),
                           Normalise.LAB)
    np.testing.assert_allclose(statistics(out)[0], REFERENCE_MEAN, atol=1e-3)
    np.testing.assert_allclose(statistics(out)[1], REFERENCE_STD, rtol=1e-4)


def test_lightness_normalisation_leaves_a_and_b():
    lab = lab_image(2)
    out, _ = normalise_lab(lab, np.zeros(lab.shape[:2], np.float32), statistics(lab),
                           Normalise.LIGHTNESS)
    np.testing.assert_array_equal(out[:, :, 1:], lab[:, :, 1:])
    assert abs(float(out[:, :, 0].mean()) - REFERENCE_MEAN[0]) < 1e-3


@settings(max_examples=25, deadline=None)
@given(gain=st.tuples(*[st.floats(0.5, 2.0)] * 3), offset=st.tuples(*[st.floats(-20, 20)] * 3))
def test_normalised_features_do_not_see_a_change_of_exposure_and_tint(gain, offset):
    # A photo whose Lab is gain * Lab + offset (another exposure, another tint) gives the
    # same normalised features as the photo itself: each photo is matched to the same
    # statistics, so matching to a reference equals matching to the training set's.
    lab = lab_image(3)
    block_std = np.random.default_rng(4).uniform(0, 5, lab.shape[:2]).astype(np.float32)
    g, o = np.asarray(gain, np.float32), np.asarray(offset, np.float32)
    shifted, shifted_std = lab * g + o, block_std * g[0]
    options = FeatureOptions(sigmas=SIGMAS, hessian=True, normalise=Normalise.LAB)
    a = features_from_lab(lab, block_std, options, statistics(lab))
    b = features_from_lab(shifted, shifted_std, options, statistics(shifted))
    np.testing.assert_allclose(a, b, atol=2e-3 * max(1.0, float(np.abs(a).max())))
