"""Property tests: any small photo gives a well-formed classification."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from terratheme.core.classify import classify_unsupervised, train_classifier
from terratheme.core.classify.features import FeatureOptions, FeatureSet
from terratheme.core.classify.regularise import Regularisation, RegulariseOptions
from terratheme.core.classify.tiled import predict_tiled

photos = st.integers(1, 24).flatmap(
    lambda h: st.integers(1, 24).flatmap(
        lambda w: st.sampled_from([3, 4]).flatmap(
            lambda c: arrays(np.uint8, (h, w, c), elements=st.integers(0, 255))
        )
    )
)


def _well_formed(res, photo):
    h, w = photo.shape[:2]
    assert res.labels.shape == (h, w) and res.labels.dtype == np.uint8
    assert res.confidence.shape == (h, w) and res.confidence.dtype == np.float32
    assert np.all((res.confidence >= 0.0) & (res.confidence <= 1.0))
    opaque = photo[:, :, 3] > 0 if photo.shape[2] == 4 else np.ones((h, w), bool)
    assert set(np.unique(res.labels[opaque])) <= set(res.classes)
    assert (res.labels[~opaque] == 0).all() and (res.confidence[~opaque] == 0).all()


@settings(max_examples=25, deadline=None)
@given(photos)
def test_unsupervised_is_well_formed(photo):
    if photo.shape[2] == 4 and not (photo[:, :, 3] > 0).any():
        photo[0, 0, 3] = 255
    res = classify_unsupervised(photo)
    _well_formed(res, photo)
    assert res.classes == tuple(range(1, res.n_classes + 1))


@pytest.mark.slow
@settings(max_examples=15, deadline=None)
@given(photos, st.integers(0, 2**31 - 1))
def test_supervised_is_well_formed(photo, seed):
    if photo.shape[2] == 4:
        photo[:, :, 3] = np.maximum(photo[:, :, 3], 1)
    rng = np.random.default_rng(seed)
    mask = np.zeros(photo.shape[:2], np.uint8)
    mask.flat[rng.choice(mask.size, max(1, mask.size // 10), replace=False)] = rng.choice(
        [2, 5], max(1, mask.size // 10))
    res = train_classifier([(photo, mask)]).predict(photo)
    _well_formed(res, photo)
    # A coarse pixel takes the majority class of its labelled pixels, so a class painted
    # only where another one wins can drop out, never appear from nowhere.
    assert res.classes and set(res.classes) <= set(np.unique(mask)) - {0}


@settings(max_examples=25, deadline=None)
@given(arrays(np.float32, (3, 4, 3), elements=st.sampled_from([0.0, 0.25, 0.5, 1.0])))
def test_labels_are_the_first_most_probable_class_and_confidence_its_share(coarse):
    # predict_tiled's arg-max: the first of equal maxima (numpy's argmax), confidence the max.
    photo = np.zeros((3, 4, 3), np.uint8)
    res = predict_tiled(photo, None, lambda feats: coarse[: feats.shape[0], : feats.shape[1]],
                        (7, 3, 9), FeatureOptions(feature_set=FeatureSet.COLOUR, scale=1),
                        RegulariseOptions(method=Regularisation.NONE), 16)
    np.testing.assert_array_equal(res.labels, np.array([7, 3, 9], np.uint8)[coarse.argmax(2)])
    np.testing.assert_array_equal(res.confidence, np.clip(coarse.max(2), 0, 1))
