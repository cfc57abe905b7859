"""Where the classifier is unsure, the kept class prior, and the document keeping them (no Qt)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.edit import (
    ClassificationUpdate,
    ConfidenceChange,
    EditDocument,
    KeptPrior,
    Layer,
    next_kept_prior,
    scribble_classes,
    uncertain_mask,
    uncertainty_rgba,
)
from terratheme.core.edit.uncertainty import TINT
from terratheme.core.errors import TerrathemeError


def test_the_lowest_tenth_without_filter_is_the_smallest_values():
    conf = np.random.default_rng(3).random((25, 40)).astype(np.float32)
    mask = uncertain_mask(conf, size=1)
    # 1000 distinct values: the 10% quantile (linear) sits between the 100th and 101st.
    smallest = np.zeros(conf.size, bool)
    smallest[np.argsort(conf, axis=None)[:100]] = True
    np.testing.assert_array_equal(mask.ravel(), smallest)


def test_majority_filter_keeps_regions_and_drops_specks():
    conf = np.full((40, 40), 0.9, np.float32)
    conf[10:20, 10:20] = 0.3  # a 10 x 10 unsure region (6.25% of the photo)
    conf[15, 15] = 0.9  # a pinhole in it
    conf[30, 5] = conf[5, 32] = conf[34, 34] = 0.5  # isolated specks
    # Quantile 0.1 is the top value 0.9: only the 102 pixels below it are candidates.
    assert uncertain_mask(conf, size=1).sum() == 99 + 3
    mask = uncertain_mask(conf)
    assert mask[15, 15] and mask[12:18, 12:18].all()  # the pinhole is filled
    assert not mask[30, 5] and not mask[5, 32] and not mask[34, 34]  # specks are gone
    assert not mask[:6].any() and not mask[25:].any()
    # A 9 x 9 window at a region corner sees 5 x 5 = 25 of 81 unsure pixels: not a majority.
    assert not mask[10, 10] and mask[10, 14]


def test_flat_and_tied_confidence():
    assert not uncertain_mask(np.ones((20, 30), np.float32)).any()
    conf = np.full((20, 30), 0.8, np.float32)
    conf[:, :15] = 0.2  # half the photo tied at the lowest value: all of it counts
    np.testing.assert_array_equal(uncertain_mask(conf), conf == 0.2)
    assert uncertain_mask(np.zeros((0, 0), np.float32)).shape == (0, 0)


def test_overlay_colours():
    mask = np.array([[True, False], [False, True]])
    rgba = uncertainty_rgba(mask)
    assert rgba.shape == (2, 2, 4) and rgba.dtype == np.uint8
    assert tuple(rgba[0, 0]) == TINT and tuple(rgba[1, 1]) == TINT
    assert not rgba[0, 1].any() and not rgba[1, 0].any()


def test_kept_prior_lifecycle():
    assert scribble_classes(None) == frozenset()
    assert scribble_classes(np.array([[0, 3], [2, 3]], np.uint8)) == {2, 3}
    first = next_kept_prior(None, frozenset({2, 3}), {2: 1.0, 3: 0.4})
    assert first == KeptPrior({2: 1.0, 3: 0.4}, frozenset({2, 3}))
    # Correction strokes of the same classes: the first run's weights stay.
    assert next_kept_prior(first, frozenset({2, 3}), {2: 0.7, 3: 1.0}) is first
    # A new class: the run estimated afresh, and that becomes the kept prior.
    fresh = next_kept_prior(first, frozenset({2, 3, 4}), {2: 1.0, 3: 0.5, 4: 0.2})
    assert fresh.classes == {2, 3, 4} and fresh.weights[4] == 0.2
    # No weights (one class, no correction) or no scribbles: nothing kept.
    assert next_kept_prior(first, frozenset({2}), None) is None
    assert next_kept_prior(None, frozenset(), {1: 1.0}) is None
    assert not first.applies_to(frozenset())


@pytest.fixture
def doc(small_texture) -> EditDocument:
    return EditDocument(small_texture(photo=np.zeros((64, 96, 3), np.uint8)))


def test_document_keeps_the_confidence_through_grid_edits(doc):
    seen = []
    doc.events.confidence.connect(lambda e: seen.append((e, doc.confidence is not None)))
    assert doc.confidence is None and doc.uncertain() is None
    with pytest.raises(TerrathemeError, match=r"\(10, 10\) confidence map does not fit"):
        doc.apply_classification(ClassificationUpdate(doc.indices, confidence=np.ones((10, 10))))
    with pytest.raises(TerrathemeError, match=r"finite and in \[0, 1\]"):
        doc.apply_classification(ClassificationUpdate(doc.indices,
                                                      confidence=np.full((64, 96), np.nan)))
    conf = np.full((64, 96), 0.9)
    conf[20:40, 30:60] = 0.2
    doc.apply_classification(ClassificationUpdate(doc.indices, confidence=conf))
    assert doc.confidence.dtype == np.float32 and seen == [(ConfidenceChange(), True)]
    np.testing.assert_array_equal(doc.uncertain(), uncertain_mask(conf))
    # Grid edits keep it (the user corrects where it was unsure).
    doc.fill_rect((1, 1), (4, 3), 1)
    assert doc.confidence is not None


def test_document_kept_prior(doc):
    # Strokes of classes 1 and 2 (themes grass and water), in photo pixels.
    for value, (a, b) in ((1, ((5, 5), (20, 5))), (2, ((50, 40), (70, 40)))):
        doc.begin_stroke(value, a, 1.0, Layer.SCRIBBLES)
        doc.stroke_to(b, 1.0)
        doc.end_stroke()
    assert doc.scribble_classes() == {1, 2} and doc.prior_for_scribbles() is None
    grid = doc.indices.copy()
    doc.apply_classification(ClassificationUpdate(grid, scribble_classes=frozenset({1, 2}),
                                                  class_weights={1: 1.0, 2: 0.3}))
    assert doc.prior_for_scribbles() == {1: 1.0, 2: 0.3}
    # Correction strokes of the same classes keep it; the kept run's own weights do not win.
    doc.begin_stroke(2, (10, 50), 1.0, Layer.SCRIBBLES)
    doc.end_stroke()
    doc.apply_classification(ClassificationUpdate(grid, scribble_classes=frozenset({1, 2}),
                                                  class_weights={1: 0.6, 2: 1.0}))
    assert doc.prior_for_scribbles() == {1: 1.0, 2: 0.3}
    # A new class: estimate afresh (and that run's weights are kept).
    doc.begin_stroke(3, (60, 60), 1.0, Layer.SCRIBBLES)
    doc.end_stroke()
    assert doc.prior_for_scribbles() is None
    doc.apply_classification(ClassificationUpdate(grid, scribble_classes=frozenset({1, 2, 3}),
                                                  class_weights={1: 1.0, 2: 0.5, 3: 0.25}))
    assert doc.kept_prior.classes == {1, 2, 3}
    # Erasing every stroke drops it, in the erasing step; undo brings both back.
    doc.begin_stroke(0, (48, 32), 200.0, Layer.SCRIBBLES)
    doc.end_stroke()
    assert doc.kept_prior is None and doc.scribble_classes() == frozenset()
    doc.undo()
    assert doc.kept_prior.classes == {1, 2, 3} and doc.scribble_classes() == {1, 2, 3}
