"""Features for photos of other areas: the lightness relative to its context."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import FeatureOptions
from terratheme.core.classify.features import RELATIVE_FLOOR, features_from_lab
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
