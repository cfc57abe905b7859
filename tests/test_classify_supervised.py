"""Supervised classification: scribbles, label masks, save/load, errors."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest
from terratheme.core.classify import Classifier, SupervisedOptions, train_classifier
from terratheme.core.classify.model_file import FORMAT
from terratheme.core.classify.supervised import coarse_mask
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError

COLOURS = {3: (40, 110, 40), 5: (60, 80, 170), 9: (200, 185, 150)}


def three_stripes(h=96, w=120, order=(3, 5, 9)):
    """Photo of three vertical stripes and its true class mask."""
    img = np.empty((h, w, 3), np.uint8)
    truth = np.empty((h, w), np.uint8)
    for i, k in enumerate(order):
        sl = slice(i * w // 3, (i + 1) * w // 3)
        img[:, sl] = COLOURS[k]
        truth[:, sl] = k
    rng = np.random.default_rng(0)
    img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    return img, truth


def strokes(truth, length=12):
    """One short horizontal stroke in the middle of each class region (< 1% of pixels)."""
    mask = np.zeros_like(truth)
    for k in np.unique(truth):
        ys, xs = np.nonzero(truth == k)
        y, x = int(np.median(ys)), int(np.median(xs))
        mask[y, x - length // 2 : x + length // 2] = k
    return mask


def test_scribbles_give_the_right_labels():
    img, truth = three_stripes()
    mask = strokes(truth)
    assert (mask > 0).mean() < 0.01
    res = train_classifier([(img, mask)]).predict(img)
    assert res.classes == (3, 5, 9)
    assert res.labels.dtype == np.uint8 and res.labels.shape == truth.shape
    # Exact away from the stripe borders.
    inner = np.ones(truth.shape, bool)
    for x in (40, 80):
        inner[:, x - 6 : x + 6] = False
    assert (res.labels[inner] == truth[inner]).all()
    assert (res.confidence[inner] > 0.5).all()


def test_full_mask_of_another_photo_transfers():
    img_a, truth_a = three_stripes(order=(3, 5, 9))
    img_b, truth_b = three_stripes(order=(9, 3, 5))
    res = train_classifier([(img_a, truth_a)]).predict(img_b)
    assert (res.labels == truth_b).mean() > 0.95


def test_texture_separates_classes_of_equal_mean_colour():
    rng = np.random.default_rng(2)
    img = np.full((96, 96, 3), 128, np.uint8)
    img[:, :48] = rng.choice(np.array([68, 188], np.uint8), size=(96, 48))[:, :, None]
    truth = np.full((96, 96), 2, np.uint8)
    truth[:, :48] = 1
    mask = np.zeros_like(truth)
    mask[10:14, 10:30] = 1
    mask[80:84, 60:90] = 2
    res = train_classifier([(img, mask)]).predict(img)
    assert (res.labels[:, :40] == 1).mean() > 0.97
    assert (res.labels[:, 56:] == 2).mean() > 0.97


def test_ignored_classes_are_never_predicted():
    img, truth = three_stripes()
    mask = truth.copy()
    mask[:10] = 6  # a strip marked "Unlabeled"
    model = train_classifier([(img, mask)], SupervisedOptions(ignore_classes=(6,)))
    assert model.classes == (3, 5, 9)
    assert set(np.unique(model.predict(img).labels)) <= {3, 5, 9}


def test_more_classes_than_one_resize_takes():
    # found: 129 classes broke the probabilities' upsampling (OpenCV takes 128 channels)
    rng = np.random.default_rng(0)
    colours = rng.integers(0, 256, (130, 3))
    truth = np.kron(np.arange(1, 131).reshape(13, 10), np.ones((16, 16), np.int64))
    img = colours[truth - 1].astype(np.uint8)
    model = train_classifier([(img, truth.astype(np.uint8))], SupervisedOptions())
    labels = model.predict(img).labels
    assert len(model.classes) == 130
    # the centres of the 16 x 16 squares keep their class
    assert (labels[8::16, 8::16] == truth[8::16, 8::16]).mean() > 0.9


def test_scribbles_naming_one_class_give_that_class_everywhere():
    img, truth = three_stripes()
    mask = np.zeros_like(truth)
    mask[40:44, 5:20] = 5
    res = train_classifier([(img, mask)]).predict(img)
    assert res.classes == (5,)
    assert (res.labels == 5).all() and np.allclose(res.confidence, 1.0)


def test_coarse_mask_takes_the_majority_class_of_labelled_pixels():
    mask = np.zeros((4, 8), np.uint8)
    mask[0, 0] = 2            # block 0: one labelled pixel -> 2
    mask[:3, 4:8] = 3         # block 1: 12 of 16 are 3 ...
    mask[3, 4:8] = 4          # ... and 4 of 16 are 4 -> 3
    np.testing.assert_array_equal(coarse_mask(mask, 4, [2, 3, 4]), [[2, 3]])
    np.testing.assert_array_equal(coarse_mask(mask, 4, [2, 4]), [[2, 4]])


def test_save_load_round_trip(tmp_path):
    img, truth = three_stripes()
    model = train_classifier([(img, strokes(truth))], SupervisedOptions(n_trees=12))
    path = tmp_path / "model.ttc"
    model.save(path)
    back = Classifier.load(path)
    assert back.classes == model.classes and back.options == model.options
    a, b = model.predict(img), back.predict(img)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.confidence, b.confidence)


def test_save_load_round_trip_one_class(tmp_path):
    img, _ = three_stripes()
    mask = np.zeros(img.shape[:2], np.uint8)
    mask[5, 5] = 7
    path = tmp_path / "one.ttc"
    train_classifier([(img, mask)]).save(path)
    assert (Classifier.load(path).predict(img).labels == 7).all()


def test_load_errors(tmp_path):
    with pytest.raises(TerrathemeError, match="no such model"):
        Classifier.load(tmp_path / "absent.ttc")
    junk = tmp_path / "junk.ttc"
    junk.write_bytes(b"not a zip at all")
    with pytest.raises(CorruptFileError, match="not a terratheme classifier"):
        Classifier.load(junk)
    newer = tmp_path / "newer.ttc"
    with zipfile.ZipFile(newer, "w") as zf:
        zf.writestr("meta.json", f'{{"format": "{FORMAT}", "version": 99}}')
    with pytest.raises(UnsupportedVersionError, match="version 99"):
        Classifier.load(newer)
    truncated = tmp_path / "truncated.ttc"
    img, truth = three_stripes()
    train_classifier([(img, strokes(truth))]).save(truncated)
    truncated.write_bytes(truncated.read_bytes()[:200])
    with pytest.raises(CorruptFileError):
        Classifier.load(truncated)


def test_mask_of_the_wrong_size_is_a_clear_error():
    img, truth = three_stripes()
    with pytest.raises(TerrathemeError, match=r"120 x 95 .* photo is 120 x 96"):
        train_classifier([(img, truth[:-1])])


@pytest.mark.parametrize(
    ("mask", "match"),
    [
        (np.zeros((96, 120), np.uint8), "name no class"),
        (np.zeros((96, 120, 3), np.uint8), "single-channel"),
        (np.full((96, 120), 1.5, np.float32), "integers"),
    ],
)
def test_bad_masks_are_clear_errors(mask, match):
    img, _ = three_stripes()
    with pytest.raises(TerrathemeError, match=match):
        train_classifier([(img, mask)])


def test_no_pairs_is_a_clear_error():
    with pytest.raises(TerrathemeError, match="no training data"):
        train_classifier([])


def test_bad_options_are_clear_errors():
    with pytest.raises(TerrathemeError, match="n_trees"):
        SupervisedOptions(n_trees=0)


def test_pieces_with_the_context_overlap_match_the_whole_photo(block_photo):
    photo, img = block_photo(np.random.default_rng(7), (8, 30), 24, 6)
    mask = np.zeros(img.shape, np.uint8)
    mask[::9, ::9] = img[::9, ::9] + 1
    model = train_classifier([(photo, mask)])
    whole = model.predict(photo).labels
    ctx = model.context_pixels
    assert ctx % model.options.features.scale == 0
    assert 0 < ctx < 360
    # Left piece: columns 0..359 read with ctx columns of context to the right.
    left = model.predict(photo[:, : 360 + ctx]).labels[:, :360]
    right = model.predict(photo[:, 360 - ctx :]).labels[:, ctx:]
    np.testing.assert_array_equal(np.hstack([left, right]), whole)


def test_samples_per_class_grow_with_the_pairs():
    opts = SupervisedOptions()
    assert [opts.samples_per_class(n) for n in (1, 5, 10, 37, 100)] == [
        2000, 2000, 4000, 14800, 15000]
    assert SupervisedOptions(max_samples_per_class=500).samples_per_class(3) == 500
    with pytest.raises(TerrathemeError, match="samples_per_pair must be at least 1"):
        SupervisedOptions(samples_per_pair=0)


def test_training_samples_are_capped_per_class():
    from terratheme.core.classify.supervised import collect_samples

    img, truth = three_stripes(h=480, w=480)
    # 60 x 60 coarse pixels, 1200 per stripe and photo: 2400 per class, two pairs cap 2000.
    x, y = collect_samples([(img, truth), (img[:, ::-1].copy(), truth[:, ::-1].copy())],
                           SupervisedOptions())
    assert np.bincount(y, minlength=10)[[3, 5, 9]].tolist() == [2000, 2000, 2000]
    assert len(x) == 6000
