"""Test-time adaptation (core.classify.adapt): pseudo-labels, the two passes, the defaults."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import terratheme.core.classify.adapt as adapt
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.classify.adapt import pseudo_labels
from terratheme.core.classify.supervised_options import ADAPT_MAX_PAIRS


def test_pseudo_labels_keep_the_surest_share_of_each_class():
    probs = np.array([
        [0.9, 0.1], [0.6, 0.4], [0.8, 0.2], [0.7, 0.3],   # class 0: 0.9, 0.8 kept at share 0.5
        [0.2, 0.8], [0.45, 0.55], [0.1, 0.9], [0.3, 0.7],  # class 1: 0.9, 0.8 kept
    ])
    index, column = pseudo_labels(probs, share=0.5, per_class=100, min_pixels=1)
    np.testing.assert_array_equal(index, [0, 2, 4, 6])
    np.testing.assert_array_equal(column, [0, 0, 1, 1])


def test_pseudo_labels_skip_rare_classes_and_cap_the_rest():
    probs = np.zeros((30, 3))
    probs[:25, 0] = 1.0          # 25 samples of class 0
    probs[25:, 2] = 1.0          # 5 of class 2, none of class 1
    index, column = pseudo_labels(probs, share=1.0, per_class=10, min_pixels=6)
    assert set(column.tolist()) == {0}              # class 2 has fewer than 6
    assert len(index) == 10 and (index < 25).all() and len(set(index.tolist())) == 10
    index, column = pseudo_labels(probs, share=1.0, per_class=10, min_pixels=5)
    assert (column == 2).sum() == 5
    # 5 of 30 samples is under a minimum share of 20%.
    index, column = pseudo_labels(probs, share=1.0, per_class=10, min_pixels=1, min_share=0.2)
    assert set(column.tolist()) == {0}


def test_pseudo_labels_of_nothing():
    index, column = pseudo_labels(np.zeros((0, 4)))
    assert index.shape == column.shape == (0,)


def shifted_blocks(shift: float, seed: int, grid=(8, 8), block=16):
    """A photo of grey blocks, classes 1 (dark) and 2 (bright), each block's grey drawn
    around its class's level + ``shift``; returns photo and truth."""
    rng = np.random.default_rng(seed)
    classes = rng.integers(1, 3, grid)
    level = np.where(classes == 1, 100.0, 160.0) + shift + rng.uniform(-15, 15, grid)
    grey = np.kron(level, np.ones((block, block)))
    photo = np.clip(grey[:, :, None] + rng.normal(0, 2, grey.shape + (3,)), 0, 255)
    return photo.astype(np.uint8), np.kron(classes, np.ones((block, block), int)).astype(np.uint8)


def test_adaptation_follows_a_shift_of_the_classes_appearance():
    # Trained where class 1 is ~100 and class 2 ~160; the new photo is 28 brighter:
    # its brightest class-1 blocks look like class 2 to the trained forest, and the
    # forest relearned on the photo's surest blocks puts the boundary back between them.
    train, truth = shifted_blocks(0.0, seed=0)
    target, target_truth = shifted_blocks(28.0, seed=1)
    opts = SupervisedOptions()
    plain = train_classifier([(train, truth)], replace(opts, adapt=False)).predict(target)
    adapted = train_classifier([(train, truth)], opts).predict(target)
    before = (plain.labels == target_truth).mean()
    after = (adapted.labels == target_truth).mean()
    assert before < 0.97
    assert after > before + 0.02


def test_adaptation_is_on_for_masks_of_a_few_photos_and_off_for_scribbles():
    train, truth = shifted_blocks(0.0, seed=0)
    assert train_classifier([(train, truth)]).options.adapt is True
    strokes = np.zeros_like(truth)
    strokes[4:6, 4:30] = truth[4:6, 4:30]
    strokes[100:102, 60:100] = truth[100:102, 60:100]
    assert train_classifier([(train, strokes)]).options.adapt is False
    assert train_classifier([(train, truth)], SupervisedOptions(adapt=False)).options.adapt \
        is False
    # Masks of many photos train a model that carries over without adapting.
    many = [shifted_blocks(0.0, seed=s) for s in range(ADAPT_MAX_PAIRS)]
    assert train_classifier(many, SupervisedOptions(n_trees=3)).options.adapt is False
    assert train_classifier(many[:-1], SupervisedOptions(n_trees=3)).options.adapt is True


def test_kept_features_give_the_same_labels_as_computed_again(monkeypatch):
    train, truth = shifted_blocks(0.0, seed=0)
    target, _ = shifted_blocks(20.0, seed=2)
    model = train_classifier([(train, truth)])
    kept = model.predict(target)
    monkeypatch.setattr(adapt, "ADAPT_KEEP_BYTES", 0)
    again = model.predict(target)
    np.testing.assert_array_equal(kept.labels, again.labels)
    np.testing.assert_allclose(kept.confidence, again.confidence, atol=1e-6)


@pytest.mark.parametrize("tile", [48, 64])
def test_adapted_labels_do_not_depend_on_the_tiling(tile):
    train, truth = shifted_blocks(0.0, seed=0)
    target, _ = shifted_blocks(20.0, seed=3, grid=(10, 9))
    whole = train_classifier([(train, truth)]).predict(target)
    tiled = train_classifier([(train, truth)], SupervisedOptions(tile=tile)).predict(target)
    # The same pseudo-labels (photo-wide strided grid), so nearly the same forest; the
    # EDGE filter's running sums differ by float rounding, which can move a pseudo-label
    # at the confidence cut (features equal to 6e-8: 0.9969 and 0.9998 agree here).
    assert (whole.labels == tiled.labels).mean() > 0.995


def test_progress_counts_both_passes():
    train, truth = shifted_blocks(0.0, seed=0)
    target, _ = shifted_blocks(20.0, seed=3)
    calls = []
    train_classifier([(train, truth)], SupervisedOptions(tile=64)).predict(
        target, progress=lambda done, total: calls.append((done, total)))
    total = calls[-1][1]
    assert calls == [(i, total) for i in range(1, total + 1)] and total % 2 == 0
