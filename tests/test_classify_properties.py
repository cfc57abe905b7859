"""Property tests: any small photo gives a well-formed classification."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from core.classify import classify_unsupervised, train_classifier

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
