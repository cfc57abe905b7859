"""Scribble models: class-prior correction (core.classify.prior) and position features."""

from __future__ import annotations

import json
import zipfile
from dataclasses import replace

import numpy as np
import pytest
from terratheme.core.classify import Classifier, FeatureOptions, SupervisedOptions, train_classifier
from terratheme.core.classify.position import position_features
from terratheme.core.classify.prior import SCRIBBLE_PRIOR_POWER, predicted_shares, prior_weights
from terratheme.core.errors import CorruptFileError, TerrathemeError

COLOURS = {1: (40, 110, 40), 2: (60, 80, 170), 3: (200, 185, 150)}


def stripes(widths=(0.6, 0.3, 0.1), h=96, w=200, seed=0):
    """Vertical stripes of classes 1, 2, 3 with the given width shares, and the truth."""
    img = np.empty((h, w, 3), np.float64)
    truth = np.empty((h, w), np.uint8)
    edges = np.round(np.cumsum((0,) + widths) * w).astype(int)
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True), 1):
        img[:, a:b] = COLOURS[k]
        truth[:, a:b] = k
    rng = np.random.default_rng(seed)
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8), truth


def strokes(truth):
    """A 3 x 8 stroke in the middle of each class region (the same amount per class)."""
    mask = np.zeros_like(truth)
    for k in np.unique(truth):
        ys, xs = np.nonzero(truth == k)
        y, x = int(np.median(ys)), int(np.median(xs))
        mask[y - 1 : y + 2, x - 4 : x + 4] = k
    return mask


def test_predicted_shares_count_arg_max_classes():
    probs = np.array([[0.7, 0.2, 0.1], [0.1, 0.8, 0.1], [0.5, 0.4, 0.1], [0.2, 0.3, 0.5]])
    np.testing.assert_allclose(predicted_shares(probs), [0.5, 0.25, 0.25])
    np.testing.assert_allclose(predicted_shares(np.zeros((0, 4))), [0.25] * 4)


def test_prior_weights_by_hand():
    # (share / (1/3)) ** 0.5 = sqrt(1.8), sqrt(0.9), sqrt(0.3), over the largest.
    w = prior_weights(np.array([0.6, 0.3, 0.1]), np.full(3, 1 / 3), 0.5)
    np.testing.assert_allclose(w, [1.0, np.sqrt(0.5), np.sqrt(1 / 6)], rtol=1e-9)
    np.testing.assert_allclose(prior_weights(np.array([0.6, 0.3, 0.1]), np.full(3, 1 / 3), 0),
                               [1, 1, 1])
    # A class predicted nowhere keeps a small weight (share floored at 0.001).
    w = prior_weights(np.array([1.0, 0.0]), np.array([0.5, 0.5]), 1.0)
    np.testing.assert_allclose(w, [1.0, 0.001])


def test_scribbles_get_weights_from_the_photos_class_areas():
    img, truth = stripes()
    model = train_classifier([(img, strokes(truth))])
    # Equal scribbles per class, areas 60 / 30 / 10 %: weights = area ratios ** power.
    expect = np.array([1.0, 0.5, 1 / 6]) ** SCRIBBLE_PRIOR_POWER
    np.testing.assert_allclose(model.class_weights, expect, atol=0.05)
    half = train_classifier([(img, strokes(truth))], SupervisedOptions(prior_power=0.5))
    np.testing.assert_allclose(half.class_weights, [1.0, np.sqrt(0.5), np.sqrt(1 / 6)],
                               atol=0.05)
    res = model.predict(img)
    inner = np.abs(np.arange(200)[None, :] - np.array([[120], [180]])).min(0) > 8
    assert (res.labels[:, inner] == truth[:, inner]).all()


def test_full_masks_and_power_zero_have_no_correction():
    img, truth = stripes()
    assert train_classifier([(img, truth)]).class_weights is None
    opts = SupervisedOptions(prior_power=0.0)
    assert train_classifier([(img, strokes(truth))], opts).class_weights is None
    # Forced on for a full mask: the weights follow the areas there too.
    forced = train_classifier([(img, truth)], SupervisedOptions(prior_power=1.0))
    np.testing.assert_allclose(forced.class_weights, [1.0, 0.5, 1 / 6], atol=0.05)


def test_weights_scale_the_probabilities():
    img, truth = stripes()
    model = train_classifier([(img, strokes(truth))])
    plain = Classifier(model.forest, model.classes, model.options)
    feats = np.random.default_rng(0).normal(50, 20, (4, 5, model.options.features.n_features))
    p0 = plain.probabilities(feats.astype(np.float32))
    p1 = model.probabilities(feats.astype(np.float32))
    expect = p0 * np.asarray(model.class_weights)
    expect /= expect.sum(2, keepdims=True)
    np.testing.assert_allclose(p1, expect, rtol=1e-5, atol=1e-6)


def test_weights_survive_save_and_load(tmp_path):
    img, truth = stripes()
    model = train_classifier([(img, strokes(truth))])
    model.save(tmp_path / "m.model")
    back = Classifier.load(tmp_path / "m.model")
    np.testing.assert_allclose(back.class_weights, model.class_weights)
    assert (back.predict(img).labels == model.predict(img).labels).all()
    # A file whose weights do not match its classes is damaged.
    with zipfile.ZipFile(tmp_path / "m.model") as zf:
        meta = json.loads(zf.read("meta.json"))
        forest = zf.read("forest.npz")
    meta["class_weights"] = [1.0, 0.5]
    with zipfile.ZipFile(tmp_path / "bad.model", "w") as zf:
        zf.writestr("meta.json", json.dumps(meta))
        zf.writestr("forest.npz", forest)
    with pytest.raises(CorruptFileError, match="class weights"):
        Classifier.load(tmp_path / "bad.model")


def test_bad_prior_power_is_refused():
    with pytest.raises(TerrathemeError, match="prior_power"):
        SupervisedOptions(prior_power=1.5)
    with pytest.raises(TerrathemeError, match="class weights"):
        Classifier(None, (1, 2), SupervisedOptions(), class_weights=(1.0,))


def test_position_features_by_hand():
    pos = position_features((2, 3), (8, 16), (40, 64), 8)
    # Rows: centres at 8 + 4 and 8 + 12 over 40; columns 16 + 4, 16 + 12, 16 + 20 over 64.
    np.testing.assert_allclose(pos[:, 0, 0], [12 / 40, 20 / 40])
    np.testing.assert_allclose(pos[0, :, 1], [20 / 64, 28 / 64, 36 / 64])
    assert FeatureOptions(position=True).n_features == FeatureOptions().n_features + 2


def test_with_positions_changes_only_the_position_flag():
    base = SupervisedOptions(n_trees=7, features=FeatureOptions(hessian=True, scale=4))
    on = base.with_positions()
    assert on.features == replace(base.features, position=True)
    assert replace(on, features=base.features) == base
    assert on.with_positions(False) == base


def test_position_model_is_the_same_whole_and_tiled():
    img, truth = stripes(h=160, w=200)
    mask = strokes(truth)
    fo = FeatureOptions(position=True)
    whole = train_classifier([(img, mask)], SupervisedOptions(features=fo, tile=4096))
    # The same forest and weights, predicting in 64-pixel tiles (global positions).
    tiled = Classifier(whole.forest, whole.classes, replace(whole.options, tile=64),
                       whole.class_weights)
    a, b = whole.predict(img), tiled.predict(img)
    assert (a.labels == b.labels).all()
    np.testing.assert_allclose(a.confidence, b.confidence, atol=1e-5)
    inner = np.abs(np.arange(200)[None, :] - np.array([[120], [180]])).min(0) > 8
    assert (a.labels[:, inner] == truth[:, inner]).all()
