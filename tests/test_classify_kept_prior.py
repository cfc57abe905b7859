"""train_classifier(class_weights=...): a prior correction kept from a first round of strokes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.classify.prior import kept_weights
from terratheme.core.errors import TerrathemeError

COLOURS = {1: (40, 110, 40), 2: (60, 80, 170), 3: (200, 185, 150)}


def stripes(widths=(0.6, 0.3, 0.1), h=64, w=160):
    """Vertical stripes of classes 1, 2, 3 with the given width shares, and one stroke each."""
    img = np.empty((h, w, 3), np.float64)
    mask = np.zeros((h, w), np.uint8)
    edges = np.round(np.cumsum((0,) + widths) * w).astype(int)
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True), 1):
        img[:, a:b] = COLOURS[k]
        x = (a + b) // 2
        mask[h // 2 - 1 : h // 2 + 2, x - 4 : x + 4] = k
    rng = np.random.default_rng(0)
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8), mask


def test_kept_weights_by_hand():
    assert kept_weights({3: 0.5, 1: 1.0, 2: 0.25}, (1, 2, 3)) == (1.0, 0.25, 0.5)
    # Extra classes are ignored; a missing class gives None (estimate afresh).
    assert kept_weights({1: 1.0, 2: 0.5, 9: 3.0}, (1, 2)) == (1.0, 0.5)
    assert kept_weights({1: 1.0, 2: 0.5}, (1, 2, 3)) is None


@pytest.mark.parametrize("bad", [-0.5, 0.0, math.nan, math.inf, "heavy"])
def test_bad_weights_are_refused(bad):
    with pytest.raises(TerrathemeError, match="must be a finite number > 0"):
        kept_weights({1: 1.0, 2: bad}, (1, 2))
    img, mask = stripes()
    with pytest.raises(TerrathemeError, match=r"class 2 must be a finite number > 0"):
        train_classifier([(img, mask)], class_weights={1: 1.0, 2: bad, 3: 1.0})


def test_given_weights_are_used_exactly():
    img, mask = stripes()
    model = train_classifier([(img, mask)], class_weights={3: 0.125, 1: 1.0, 2: 0.5, 7: 2.0})
    assert model.classes == (1, 2, 3)
    assert model.class_weights == (1.0, 0.5, 0.125)


def test_given_unit_weights_skip_the_estimate():
    img, mask = stripes()
    estimated = train_classifier([(img, mask)])
    # Areas 60 / 30 / 10 %: the estimate is far from uniform.
    assert min(estimated.class_weights) < 0.5
    kept = train_classifier([(img, mask)], class_weights={1: 1.0, 2: 1.0, 3: 1.0})
    assert kept.class_weights == (1.0, 1.0, 1.0)
    # Unit weights predict like no correction at all (the same seeded forest).
    off = train_classifier([(img, mask)], SupervisedOptions(prior_power=0.0))
    assert off.class_weights is None
    a, b = kept.predict(img), off.predict(img)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_allclose(a.confidence, b.confidence, atol=1e-6)


def test_a_mapping_missing_a_class_falls_back_to_the_estimate():
    img, mask = stripes()
    estimated = train_classifier([(img, mask)])
    partial = train_classifier([(img, mask)], class_weights={1: 1.0, 2: 1.0})
    assert partial.class_weights == estimated.class_weights


def test_one_class_has_no_weights():
    img, mask = stripes()
    mask[mask > 1] = 0
    model = train_classifier([(img, mask)], class_weights={1: 0.5})
    assert model.forest is None and model.class_weights is None
