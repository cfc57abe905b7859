"""Unsupervised classification on synthetic photos with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import (
    FeatureOptions,
    Regularisation,
    RegulariseOptions,
    UnsupervisedOptions,
    classify_unsupervised,
)
from terratheme.core.errors import TerrathemeError


def two_colours(h=64, w=100, split=60, left=(40, 120, 40), right=(200, 180, 150)):
    img = np.empty((h, w, 3), np.uint8)
    img[:, :split] = left
    img[:, split:] = right
    return img


def test_two_flat_colours_give_two_themes_with_the_right_regions():
    res = classify_unsupervised(two_colours())
    assert res.classes == (1, 2)
    assert res.labels.shape == (64, 100) and res.labels.dtype == np.uint8
    # The larger (left, 60 columns) region is theme 1; a strip at the edge may blur.
    assert (res.labels[:, :56] == 1).all()
    assert (res.labels[:, 64:] == 2).all()
    assert res.confidence.dtype == np.float32
    assert 0.0 <= res.confidence.min() and res.confidence.max() <= 1.0
    assert (res.confidence[:, :50] > 0.99).all()


def test_texture_separates_regions_of_equal_mean_colour():
    rng = np.random.default_rng(1)
    img = np.full((96, 96, 3), 128, np.uint8)
    # Left half: salt-and-pepper of 68 and 188 (mean 128, like the flat right half).
    noise = rng.choice(np.array([68, 188], np.uint8), size=(96, 48))
    img[:, :48] = noise[:, :, None]
    res = classify_unsupervised(img)
    assert res.classes == (1, 2)
    left, right = res.labels[:, :40], res.labels[:, 56:]
    # Each side is (almost) one theme and the two sides differ.
    lk = np.bincount(left.ravel()).argmax()
    rk = np.bincount(right.ravel()).argmax()
    assert lk != rk
    assert (left == lk).mean() > 0.98 and (right == rk).mean() > 0.98


@pytest.mark.parametrize("noise", [0.0, 2.0])
def test_auto_on_a_flat_photo_gives_one_theme(noise):
    rng = np.random.default_rng(0)
    img = np.clip(110 + rng.normal(0, noise, (50, 70, 3)), 0, 255).astype(np.uint8)
    res = classify_unsupervised(img, themes="auto")
    assert res.classes == (1,)
    assert (res.labels == 1).all()
    assert np.allclose(res.confidence, 1.0)


def test_two_nearly_equal_colours_are_one_theme_and_distinct_ones_two():
    # RGB grey 120 vs 122 is about Delta-E 0.7: not two themes.
    near = classify_unsupervised(two_colours(left=(120, 120, 120), right=(122, 122, 122)))
    assert near.classes == (1,)
    # Grey 100 vs 140 is about Delta-E 15: two themes.
    far = classify_unsupervised(two_colours(left=(100, 100, 100), right=(140, 140, 140)))
    assert far.classes == (1, 2)


def test_fixed_number_of_themes():
    img = np.zeros((60, 90, 3), np.uint8)
    img[:, :30] = (200, 30, 30)
    img[:, 30:60] = (30, 200, 30)
    img[:, 60:] = (30, 30, 200)
    res = classify_unsupervised(img, themes=3)
    assert res.classes == (1, 2, 3)
    cols = [np.bincount(res.labels[:, a:b].ravel()).argmax() for a, b in
            ((0, 24), (36, 54), (66, 90))]
    assert sorted(cols) == [1, 2, 3]


def test_fixed_themes_beyond_the_distinct_pixels_gives_fewer():
    res = classify_unsupervised(np.full((8, 8, 3), 50, np.uint8), themes=4)
    assert res.classes == (1,)


@pytest.mark.parametrize("bad", [0, 256, "three", 2.5, True])
def test_bad_theme_count_is_a_clear_error(bad):
    with pytest.raises(TerrathemeError, match="themes"):
        classify_unsupervised(two_colours(), themes=bad)


def blobs(h=192, w=256, seed=3):
    import cv2

    rng = np.random.default_rng(seed)
    base = rng.integers(0, 255, (12, 16, 3)).astype(np.float32)
    img = cv2.resize(base, (w, h), interpolation=cv2.INTER_CUBIC).clip(0, 255)
    return img.astype(np.uint8)


def mosaic(h=192, w=256, seed=4):
    # Flat rectangles of four colours on a 32-pixel grid.
    rng = np.random.default_rng(seed)
    colours = np.array([(30, 90, 30), (190, 170, 120), (60, 60, 160), (150, 150, 150)], np.uint8)
    cells = rng.integers(0, 4, (h // 32, w // 32))
    return colours[np.kron(cells, np.ones((32, 32), int))]


@pytest.mark.parametrize("method", [Regularisation.NONE, Regularisation.SMOOTH])
def test_tiles_do_not_show(method):
    # Labels must not change at all when the photo is cut into small tiles.
    img = blobs()
    reg = RegulariseOptions(method=method)
    whole = classify_unsupervised(img, themes=4, options=UnsupervisedOptions(
        regularisation=reg, tile=4096))
    tiled = classify_unsupervised(img, themes=4, options=UnsupervisedOptions(
        regularisation=reg, tile=64))
    assert (whole.labels == tiled.labels).all()
    np.testing.assert_allclose(whole.confidence, tiled.confidence, atol=1e-4)


def test_progress_is_reported_per_tile():
    calls = []
    classify_unsupervised(two_colours(h=80, w=130), options=UnsupervisedOptions(tile=64),
                          progress=lambda d, t: calls.append((d, t)))
    assert calls == [(1, 6), (2, 6), (3, 6), (4, 6), (5, 6), (6, 6)]


@pytest.mark.parametrize("scale", [1, 3])
def test_other_scales_keep_the_photo_size(scale):
    opts = UnsupervisedOptions(features=FeatureOptions(scale=scale))
    res = classify_unsupervised(two_colours(h=95, w=143, split=61), options=opts)
    assert res.labels.shape == (95, 143)
    assert res.classes == (1, 2)
    assert (res.labels[:, :55] == 2).all() and (res.labels[:, 67:] == 1).all()


def test_distinct_rows_cap_k_even_when_their_first_feature_is_the_same():
    from terratheme.core.classify.unsupervised import UnsupervisedOptions, choose_themes

    rows = np.array([[1.0, 0.0, 0.0], [1.0, 40.0, 0.0], [1.0, 0.0, 40.0]], np.float32)
    samples = np.repeat(rows, 50, axis=0)
    centres, sizes, _ = choose_themes(samples, UnsupervisedOptions(), themes=5)
    assert len(centres) == 3 and np.allclose(sizes, 1 / 3)
    # Distinct in the first feature already: K as asked.
    step = np.array([1e-3, 0.0, 0.0], np.float32)
    spread = samples + np.arange(len(samples), dtype=np.float32)[:, None] * step
    assert len(choose_themes(spread, UnsupervisedOptions(), themes=5)[0]) == 5
