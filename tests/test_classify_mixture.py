"""Themes as a diagonal Gaussian mixture, and the split of a theme by hue (criterion 3)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from terratheme.core.classify import UnsupervisedOptions, classify_unsupervised
from terratheme.core.classify.mixture import (
    VARIANCE_FLOOR,
    fit_diagonal_mixture,
    isotropic_variances,
    posterior_fn,
)


def test_isotropic_posterior_is_the_softmax_of_scaled_squared_distances():
    centres = np.array([[0.0, 0.0], [3.0, 4.0]], np.float32)
    sizes = np.array([0.5, 0.5])
    variances = isotropic_variances(8.0, centres)
    assert variances.shape == (2, 2) and (variances == 4.0).all()
    feats = np.array([[[0.0, 0.0], [3.0, 4.0], [1.5, 2.0]]], np.float32)
    p = posterior_fn(centres, sizes, variances, np.ones(2, np.float32))(feats)
    # d^2 = 0 and 25 at the centres: p = 1 / (1 + exp(-25 / 8)); halfway: 1/2 each.
    near = 1.0 / (1.0 + np.exp(-25.0 / 8.0))
    np.testing.assert_allclose(p[0, 0], [near, 1 - near], rtol=1e-5)
    np.testing.assert_allclose(p[0, 1], [1 - near, near], rtol=1e-5)
    np.testing.assert_allclose(p[0, 2], [0.5, 0.5], rtol=1e-5)


def test_isotropic_variances_keep_the_floor():
    assert (isotropic_variances(0.0, np.zeros((3, 5))) == VARIANCE_FLOOR).all()


def test_the_mixture_finds_each_blob_its_own_spread():
    rng = np.random.default_rng(1)
    # Wide in feature 0, narrow in feature 1; then the reverse, offset in both.
    a = rng.normal([0.0, 0.0], [20.0, 2.0], (3000, 2))
    b = rng.normal([10.0, 30.0], [2.0, 20.0], (1000, 2))
    samples = np.concatenate([a, b]).astype(np.float32)
    start = np.repeat([0, 1], [3000, 1000])
    # A rough start: a tenth of each blob starts in the other theme.
    start[::10] = 1 - start[::10]
    labels, means, weights, variances = fit_diagonal_mixture(samples, start)
    np.testing.assert_allclose(means, [[0.0, 0.0], [10.0, 30.0]], atol=1.5)
    np.testing.assert_allclose(np.sqrt(variances), [[20.0, 2.0], [2.0, 20.0]], rtol=0.1)
    np.testing.assert_allclose(weights, [0.75, 0.25], atol=0.02)
    assert np.mean(labels == np.repeat([0, 1], [3000, 1000])) > 0.97


def test_constant_features_keep_their_value_and_the_floor():
    rng = np.random.default_rng(2)
    samples = np.zeros((400, 3), np.float32)
    samples[:, 1] = np.concatenate([rng.normal(0, 3, 200), rng.normal(50, 3, 200)])
    samples[:, 2] = 7.0
    labels, means, _, variances = fit_diagonal_mixture(samples, np.repeat([0, 1], 200))
    assert (means[:, 0] == 0).all() and (means[:, 2] == 7).all()
    assert (variances[:, [0, 2]] == VARIANCE_FLOOR).all()
    assert (labels == np.repeat([0, 1], 200)).all()


def town_and_channel(size=256, patch=48, seed=0):
    """Grey 'town' of 32 px blocks of random lightness, a flat pale-green 'channel' inside."""
    rng = np.random.default_rng(seed)
    blocks = rng.integers(40, 220, (size // 32, size // 32))
    img = np.repeat(np.repeat(blocks, 32, 0), 32, 1)[..., None].repeat(3, 2).astype(np.uint8)
    y0 = (size - patch) // 2
    img[y0:y0 + patch, y0:y0 + patch] = (120, 135, 115)  # Lab about (54, -9, 7)
    channel = np.zeros((size, size), bool)
    channel[y0:y0 + patch, y0:y0 + patch] = True
    return img, channel


def _channel_theme(labels, channel):
    return labels == np.bincount(labels[channel]).argmax()


def test_a_theme_of_another_hue_inside_a_textured_one_is_split_off():
    img, channel = town_and_channel()
    res = classify_unsupervised(img)
    theme = _channel_theme(res.labels, channel)
    iou = (theme & channel).sum() / (theme | channel).sum()
    assert iou > 0.85
    # Without criterion 3 the pale green shares a theme with grey blocks of its lightness.
    off = replace(UnsupervisedOptions(), min_hue_separation=float("inf"))
    merged = _channel_theme(classify_unsupervised(img, options=off).labels, channel)
    assert merged.sum() > 3 * channel.sum()
    assert res.n_classes == classify_unsupervised(img, options=off).n_classes + 1


def test_a_theme_too_small_to_be_a_theme_is_not_split_off():
    img, channel = town_and_channel()
    share = channel.mean()
    opts = replace(UnsupervisedOptions(), min_hue_share=2 * share)
    off = replace(UnsupervisedOptions(), min_hue_separation=float("inf"))
    assert classify_unsupervised(img, options=opts).n_classes == \
        classify_unsupervised(img, options=off).n_classes


@pytest.mark.parametrize("themes", [2, 3])
def test_a_fixed_number_of_themes_is_never_split(themes):
    img, _ = town_and_channel()
    assert classify_unsupervised(img, themes=themes).n_classes == themes
