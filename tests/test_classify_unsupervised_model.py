"""fit_unsupervised / UnsupervisedModel: fit on a sample, the same themes in every tile."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import (
    UnsupervisedModel,
    UnsupervisedOptions,
    classify_unsupervised,
    fit_unsupervised,
)
from terratheme.core.errors import TerrathemeError

GREEN, SAND, BLUE = (40, 120, 40), (200, 180, 150), (50, 70, 170)


def three_bands(h=96, w=240, seed=0):
    """Vertical bands green | sand | blue (80 px each) with a little noise."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float64)
    for i, c in enumerate((GREEN, SAND, BLUE)):
        img[:, i * w // 3 : (i + 1) * w // 3] = c
    return np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)


def test_fit_then_predict_equals_classify_unsupervised():
    img = three_bands()
    model = fit_unsupervised(img)
    assert isinstance(model, UnsupervisedModel) and model.classes == (1, 2, 3)
    a, b = model.predict(img), classify_unsupervised(img)
    assert (a.labels == b.labels).all()
    np.testing.assert_allclose(a.confidence, b.confidence, atol=1e-6)


def test_same_colour_same_label_in_every_tile():
    img = three_bands()
    model = fit_unsupervised(img)
    whole = model.predict(img).labels
    # Band interiors by hand: green 0..79, sand 80..159, blue 160..239.
    green, sand, blue = whole[:, 30], whole[:, 120], whole[:, 200]
    assert len({green[0], sand[0], blue[0]}) == 3
    # A tile holding only green and sand, and one holding only sand and blue.
    left, right = model.predict(img[:, :150]).labels, model.predict(img[:, 90:]).labels
    assert (left[:, 30] == green[0]).all() and (left[:, 120] == sand[0]).all()
    assert (right[:, 30] == sand[0]).all() and (right[:, 110] == blue[0]).all()
    # A tile of one colour keeps its theme number (k-means on it alone would say 1).
    only_blue = model.predict(img[:, 170:]).labels
    assert (only_blue == blue[0]).all()


def test_tiles_with_context_reproduce_the_whole_photo():
    img = three_bands(h=128, w=240)
    model = fit_unsupervised(img)
    whole = model.predict(img).labels
    ctx = model.context_pixels
    assert ctx % model.options.features.scale == 0
    # Cut at x = 120 (a multiple of the scale), each side read with ctx pixels of context.
    cut = 120
    left = model.predict(img[:, : cut + ctx]).labels[:, :cut]
    right = model.predict(img[:, cut - ctx :]).labels[:, ctx:]
    assert (np.concatenate([left, right], axis=1) == whole).all()


def test_fit_on_pieces_finds_the_themes_of_the_whole():
    img = three_bands()
    pieces = [img[:, :60], img[:, 90:150], img[:, 180:]]  # one band each
    model = fit_unsupervised(pieces)
    assert model.classes == (1, 2, 3)
    whole = fit_unsupervised(img)
    # Each centre of one fit has a centre of the other within 5 Delta-E (the whole photo's
    # centres are pulled a little by the blended features along the band borders).
    d = np.linalg.norm(model.centres[:, None] - whole.centres[None], axis=2)
    assert d.min(1).max() < 5.0 and sorted(d.argmin(1)) == [0, 1, 2]
    # Same regions (theme numbers may differ: the pieces have equal areas).
    a, b = model.predict(img).labels, whole.predict(img).labels
    pairs = {(int(x), int(y)) for x, y in zip(a[:, ::10].ravel(), b[:, ::10].ravel(), strict=True)}
    assert len(pairs) == 3


def test_fixed_themes_and_sample_budget_shared_by_area():
    img = three_bands()
    assert fit_unsupervised(img, themes=2).classes == (1, 2)
    opts = UnsupervisedOptions(max_samples=300)
    model = fit_unsupervised([img, img[:, :60]], themes=3, options=opts)
    assert model.options is opts and len(model.centres) == 3


@pytest.mark.parametrize("bad", [0, 256, "many", 2.5, True])
def test_bad_theme_count_is_refused(bad):
    with pytest.raises(TerrathemeError, match="themes must be"):
        fit_unsupervised(three_bands(), themes=bad)


def test_no_pieces_is_refused():
    with pytest.raises(TerrathemeError, match="at least one piece"):
        fit_unsupervised([])
    with pytest.raises(TerrathemeError, match="shape"):
        fit_unsupervised([np.zeros((4, 4, 3, 2), np.uint8)])


def test_classify_unsupervised_computes_each_tiles_features_once(monkeypatch):
    """The fit samples the features the prediction uses (issue 37): one pass per tile."""
    import terratheme.core.classify.tiled as tiled

    calls = []
    real = tiled.image_features

    def counting(rgb, options):
        calls.append(rgb.shape)
        return real(rgb, options)

    monkeypatch.setattr(tiled, "image_features", counting)
    img = three_bands()
    result = classify_unsupervised(img, options=UnsupervisedOptions(tile=64))
    windows = tiled.prediction_windows(96, 240, UnsupervisedOptions().features,
                                       UnsupervisedOptions().regularisation, 64)
    assert len(calls) == len(windows) > 1
    assert result.classes == (1, 2, 3)


def test_prepared_photo_keeps_its_transparent_pixels():
    """A PreparedPhoto passed on classifies as its RGBA photo: no data stays label 0."""
    from terratheme.core.classify.photo import prepare_photo

    rgba = np.dstack([three_bands(), np.full((96, 240), 255, np.uint8)])
    rgba[:20, :30, 3] = 0
    prepared = prepare_photo(rgba)
    assert prepare_photo(prepared) is prepared
    a, b = classify_unsupervised(rgba), classify_unsupervised(prepared)
    assert (a.labels[:20, :30] == 0).all() and (a.labels[20:] > 0).all()
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.confidence, b.confidence)


def test_tile_features_given_to_the_fit_must_be_of_one_photo():
    img = three_bands()
    with pytest.raises(TerrathemeError, match="single photo"):
        fit_unsupervised([img, img], tiles={})
