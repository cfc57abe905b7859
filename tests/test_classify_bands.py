"""Border bands of a blend theme relabelled by pixel colour (core.classify.bands)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from terratheme.core.classify.bands import BandOptions, between_pairs, lies_between, relabel_bands
from terratheme.core.classify.features import FeatureOptions, FeatureSet
from terratheme.core.classify.unsupervised import UnsupervisedOptions
from terratheme.core.classify.unsupervised_model import classify_unsupervised, fit_unsupervised
from terratheme.core.errors import TerrathemeError

# Theme colours (Lab): 1 bright sand, 2 dark grass, 3 mid-grey town (between them),
# 4 green (not between any two).
MEANS = np.array([[90.0, 0.0, 0.0], [20.0, 0.0, 0.0], [55.0, 0.0, 0.0], [50.0, -40.0, 30.0]])
VARIANCES = np.array([[4.0, 1.0, 1.0], [4.0, 1.0, 1.0], [400.0, 4.0, 4.0], [9.0, 1.0, 1.0]])


def _rgb_of(lab: tuple[float, float, float]) -> np.ndarray:
    """The 8-bit sRGB of a Lab colour (L 0..100)."""
    px = np.array([[[lab[0], lab[1], lab[2]]]], np.float32)
    rgb = np.round(cv2.cvtColor(px, cv2.COLOR_Lab2RGB)[0, 0] * 255)
    return np.clip(rgb, 0, 255).astype(np.uint8)


def _shore(band_colour: tuple[float, float, float] | None):
    """Sand (x < 30) beside grass (x >= 30), 60 x 60, labels with a town band at x 26..33.

    The photo's band is sand-coloured left of x = 30 and grass-coloured right of it
    (``band_colour`` None), or of ``band_colour`` (a road of its own colour).
    """
    rgb = np.empty((60, 60, 3), np.uint8)
    rgb[:, :30] = _rgb_of(tuple(MEANS[0]))
    rgb[:, 30:] = _rgb_of(tuple(MEANS[1]))
    if band_colour is not None:
        rgb[:, 26:34] = _rgb_of(band_colour)
    labels = np.full((60, 60), 2, np.uint8)
    labels[:, :26] = 1
    labels[:, 26:34] = 3
    return rgb, labels


def test_a_blend_band_takes_the_side_its_pixels_look_like():
    rgb, labels = _shore(None)
    out = relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions())
    expected = np.full((60, 60), 2, np.uint8)
    expected[:, :30] = 1
    np.testing.assert_array_equal(out, expected)
    # The input is left alone.
    assert (labels[:, 26:34] == 3).all()


def test_a_road_of_its_own_colour_between_two_themes_survives():
    rgb, labels = _shore((55.0, 0.0, 0.0))
    np.testing.assert_array_equal(relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions()),
                                  labels)


def test_a_band_wider_than_twice_the_reach_keeps_its_middle():
    rgb, labels = _shore(None)
    out = relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions(reach=2))
    # Only pixels within 2 of both sand (x <= 25) and grass (x >= 34): none of an 8-wide band.
    np.testing.assert_array_equal(out, labels)


def test_a_town_pixel_beside_one_other_theme_only_keeps_its_theme():
    # Town with a sand-coloured patch beside sand, no grass anywhere near.
    rgb = np.empty((40, 40, 3), np.uint8)
    rgb[:] = _rgb_of(tuple(MEANS[0]))
    labels = np.full((40, 40), 3, np.uint8)
    labels[:, :10] = 1
    np.testing.assert_array_equal(relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions()),
                                  labels)


def test_a_theme_that_is_no_blend_of_its_neighbours_is_untouched():
    # Green (4) between sand and grass: its colour is off the sand-grass segment.
    rgb, labels = _shore(None)
    labels[labels == 3] = 4
    np.testing.assert_array_equal(relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions()),
                                  labels)


def test_a_low_contrast_border_is_left_alone():
    # Sand and grass 8 apart in lightness with variances 4 + 4: contrast2 = 64 / 8 = 8 < 16.
    means = np.array([[60.0, 0.0, 0.0], [52.0, 0.0, 0.0], [56.0, 0.0, 0.0]])
    variances = np.array([[4.0, 1.0, 1.0], [4.0, 1.0, 1.0], [100.0, 1.0, 1.0]])
    rgb = np.empty((60, 60, 3), np.uint8)
    rgb[:, :30] = _rgb_of((60.0, 0.0, 0.0))
    rgb[:, 30:] = _rgb_of((52.0, 0.0, 0.0))
    _, labels = _shore(None)
    np.testing.assert_array_equal(relabel_bands(labels, rgb, means, variances, BandOptions()),
                                  labels)
    # The same border counts as high contrast under a lower bar.
    out = relabel_bands(labels, rgb, means, variances, BandOptions(min_contrast2=4.0))
    assert (out[:, 26:30] == 1).all() and (out[:, 30:34] == 2).all()


def test_no_data_and_reach_zero_change_nothing():
    rgb, labels = _shore(None)
    labels[:, 28:32] = 0
    out = relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions())
    assert (out[:, 28:32] == 0).all()
    assert (out[:, 26:28] == 1).all() and (out[:, 32:34] == 2).all()
    rgb, labels = _shore(None)
    np.testing.assert_array_equal(
        relabel_bands(labels, rgb, MEANS, VARIANCES, BandOptions(reach=0)), labels)


def test_between_pairs_on_a_line():
    points = np.array([[0.0], [10.0], [5.0], [20.0]])
    assert between_pairs(points, 2) == [(0, 1), (0, 3)]
    assert between_pairs(points, 3) == []
    assert lies_between(points, 1) and not lies_between(points, 0)


def test_classify_unsupervised_removes_the_town_band_along_a_shore():
    # Sand beside grass with a sharp edge (columns 60 | 61), and a textured town block.
    rng = np.random.default_rng(0)
    rgb = np.empty((160, 160, 3), np.uint8)
    rgb[:, :61] = _rgb_of((88.0, 0.0, 2.0))
    rgb[:, 61:] = _rgb_of((22.0, -3.0, 8.0))
    town = rng.integers(0, 2, (12, 8)).repeat(8, 0).repeat(8, 1).astype(bool)
    block = np.where(town[..., None], _rgb_of((80.0, 0.0, -3.0)), _rgb_of((30.0, 0.0, -3.0)))
    rgb[64:160, 96:160] = block[:96, :64]
    rgb = np.clip(rgb.astype(np.int16) + rng.integers(-2, 3, rgb.shape), 0, 255).astype(np.uint8)
    off = UnsupervisedOptions(bands=BandOptions(reach=0))
    model = fit_unsupervised(rgb, themes=3, options=off)
    town_theme = int(np.bincount(model.predict(rgb).labels[100:150, 110:150].ravel()).argmax())
    shore = np.s_[:60, 48:74]
    before = np.count_nonzero(classify_unsupervised(rgb, themes=3, options=off).labels[shore]
                              == town_theme)
    after = np.count_nonzero(classify_unsupervised(rgb, themes=3).labels[shore] == town_theme)
    # Without the pass the edge takes the town theme in a band; with it hardly any pixel.
    assert before >= 60 * 4
    assert after <= 60


def test_band_options_and_arguments_are_checked():
    with pytest.raises(TerrathemeError, match="reach must be a whole number"):
        BandOptions(reach=-1)
    with pytest.raises(TerrathemeError, match="reach must be a whole number"):
        BandOptions(reach=1.5)
    with pytest.raises(TerrathemeError, match="max_distance2 must be positive"):
        BandOptions(max_distance2=0.0)
    with pytest.raises(TerrathemeError, match="min_contrast2 must be >= 0"):
        BandOptions(min_contrast2=-1.0)
    rgb, labels = _shore(None)
    with pytest.raises(TerrathemeError, match="do not match"):
        relabel_bands(labels[:10], rgb, MEANS, VARIANCES, BandOptions())
    with pytest.raises(TerrathemeError, match="do not match"):
        relabel_bands(labels, rgb, MEANS, VARIANCES[:3], BandOptions())
    with pytest.raises(TerrathemeError, match="positive colour variances"):
        relabel_bands(labels, rgb, MEANS, VARIANCES * 0.0, BandOptions())


def test_pixel_colours_are_the_themes_lab_and_none_without_smoothed_features():
    # Wide halves: the blurred coarse pixels along the border barely move the means.
    rgb = np.empty((64, 512, 3), np.uint8)
    rgb[:, :256] = _rgb_of((80.0, 10.0, 20.0))
    rgb[:, 256:] = _rgb_of((30.0, -10.0, 5.0))
    means, variances = fit_unsupervised(rgb, themes=2).pixel_colours()
    order = np.argsort(-means[:, 0])
    np.testing.assert_allclose(means[order], [[80.0, 10.0, 20.0], [30.0, -10.0, 5.0]], atol=1.5)
    assert (variances > 0.0).all()
    colour_only = UnsupervisedOptions(features=FeatureOptions(feature_set=FeatureSet.COLOUR))
    assert fit_unsupervised(rgb, themes=2, options=colour_only).pixel_colours() is None
