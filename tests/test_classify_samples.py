"""Training samples: scribble recognition and growing strokes by colour (core.classify.samples)."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from terratheme.core.classify import (
    Classifier,
    Regularisation,
    SupervisedOptions,
    train_classifier,
)
from terratheme.core.classify.samples import (
    GROW_COLOUR,
    check_class_image,
    grow_labels,
    looks_like_scribbles,
)
from terratheme.core.classify.supervised import collect_samples
from terratheme.core.errors import TerrathemeError


def test_grow_labels_by_hand():
    coarse = np.zeros((5, 5), np.uint8)
    coarse[2, 2] = 3
    lab = np.zeros((5, 5, 3), np.float32)
    lab[1, 2] = (4.0, 0.5, 0.0)   # difference 4.5 < 5: grown
    lab[3, 2] = (3.0, 1.0, 1.0)   # difference 5.0, not under 5: left out
    grown = grow_labels(coarse, lab, 5.0)
    expect = np.zeros((5, 5), np.uint8)
    expect[2, 2] = expect[1, 2] = expect[2, 1] = expect[2, 3] = 3
    np.testing.assert_array_equal(grown, expect)


def test_a_pixel_between_two_classes_stays_unlabelled():
    coarse = np.array([[1, 0, 2, 0]], np.uint8)
    lab = np.zeros((1, 4, 3), np.float32)
    np.testing.assert_array_equal(grow_labels(coarse, lab, 5.0), [[1, 0, 2, 2]])


def test_labelled_pixels_keep_their_class():
    coarse = np.array([[1, 2], [0, 0]], np.uint8)
    lab = np.zeros((2, 2, 3), np.float32)
    np.testing.assert_array_equal(grow_labels(coarse, lab, 5.0), [[1, 2], [1, 2]])


def test_looks_like_scribbles():
    photo = np.zeros((10, 10, 3), np.uint8)
    strokes = np.zeros((10, 10), np.uint8)
    strokes[5, 2:8] = 1
    full = np.ones((10, 10), np.uint8)
    assert looks_like_scribbles([(photo, strokes)])
    assert not looks_like_scribbles([(photo, full)])
    assert not looks_like_scribbles([(photo, strokes), (photo, strokes)])
    # A mask that is mostly an ignored class is scribbles all the same.
    assert looks_like_scribbles([(photo, np.where(strokes > 0, 1, 6))], ignore_classes=(6,))


def test_scribble_samples_grow_by_one_ring_on_a_flat_photo():
    photo = np.full((64, 64, 3), (120, 100, 80), np.uint8)
    mask = np.zeros((64, 64), np.uint8)
    # One stroke covering coarse row 2, coarse columns 2..4 (8x8 coarse pixels).
    mask[20:23, 16:40] = 1
    x0, _ = collect_samples([(photo, mask)], SupervisedOptions(grow_colour=0.0))
    x1, y1 = collect_samples([(photo, mask)], SupervisedOptions())
    assert len(x0) == 3
    # 3 stroke pixels + 3 above + 3 below + one at each end.
    assert len(x1) == 3 + 3 + 3 + 2 and (y1 == 1).all()


def test_full_masks_are_not_grown():
    photo = np.full((32, 32, 3), 90, np.uint8)
    mask = np.zeros((32, 32), np.uint8)
    mask[:, :12] = 1
    mask[:, 24:] = 2  # 62% labelled: a full mask; coarse column 2 is unlabelled
    pairs = [(photo, mask)]
    x_auto, _ = collect_samples(pairs, SupervisedOptions())
    x_off, _ = collect_samples(pairs, SupervisedOptions(grow_colour=0.0))
    x_forced, _ = collect_samples(pairs, SupervisedOptions(grow_colour=GROW_COLOUR))
    assert len(x_auto) == len(x_off) == 3 * 4
    # Asked for explicitly, growing fills nothing here: column 2 touches both classes.
    assert len(x_forced) == len(x_off)
    mask[:, 24:] = 0
    x_forced, _ = collect_samples(pairs, SupervisedOptions(grow_colour=GROW_COLOUR))
    assert len(x_forced) == 2 * 4 + 4


def test_bad_grow_colour_is_a_clear_error():
    with pytest.raises(TerrathemeError, match="grow_colour"):
        SupervisedOptions(grow_colour=-1.0)


def test_a_model_file_from_before_edge_and_growing_still_loads(tmp_path):
    photo = np.zeros((32, 32, 3), np.uint8)
    photo[:, 16:] = (200, 180, 150)
    mask = np.zeros((32, 32), np.uint8)
    mask[8, 2:10], mask[8, 20:30] = 1, 2
    train_classifier([(photo, mask)]).save(tmp_path / "new.model")
    with zipfile.ZipFile(tmp_path / "new.model") as zf:
        meta = json.loads(zf.read("meta.json"))
        forest = zf.read("forest.npz")
    # The options as an earlier version 2 wrote them: no grow_colour, no edge sigmas, and
    # the options of removed methods at their "off" values.
    del meta["options"]["grow_colour"]
    reg = meta["options"]["regularisation"]
    del reg["edge_sigma_spatial"], reg["edge_sigma_colour"]
    reg.update(method="smooth", region_size=6, ruler=10.0)
    meta["options"].update(forest="extra-trees", active_vars=0, target_prior_power=0.0)
    meta["options"]["features"].update(normalise="none", skimage_sigma_max=16.0,
                                       profile_radii=[])
    with zipfile.ZipFile(tmp_path / "old.model", "w") as zf:
        zf.writestr("meta.json", json.dumps(meta))
        zf.writestr("forest.npz", forest)
    old = Classifier.load(tmp_path / "old.model")
    assert old.options.regularisation.method is Regularisation.SMOOTH
    assert old.options.grow_colour is None
    labels = old.predict(photo).labels
    assert (labels[:, :12] == 1).all() and (labels[:, 20:] == 2).all()


def test_a_class_image_comes_back_as_two_dimensional_uint8():
    grey = np.array([[[0], [3]], [[255], [7]]], np.uint8)
    out = check_class_image(grey, "label mask 0", (2, 2))
    assert out.shape == (2, 2) and out.dtype == np.uint8 and out.tolist() == [[0, 3], [255, 7]]
    assert np.shares_memory(out, grey)
    wide = check_class_image(np.array([[1, 200]], np.int64), "label image")
    assert wide.dtype == np.uint8 and wide.tolist() == [[1, 200]]
    assert check_class_image(np.array([[True, False]]), "label image").tolist() == [[1, 0]]


@pytest.mark.parametrize(
    ("image", "shape", "match"),
    [
        (np.zeros((2, 2, 3), np.uint8), None, r"^mask 4: shape \(2, 2, 3\) is not single-channel"),
        (np.zeros(5, np.uint8), None, r"^mask 4: shape \(5,\) is not single-channel"),
        (np.zeros((3, 2), np.uint8), (2, 2),
         r"^mask 4 is 2 x 3 pixels but its photo is 2 x 2: a mask must have the photo's size"),
        (np.zeros((0, 4), np.uint8), None, r"^mask 4 has no pixels \(shape \(0, 4\)\)"),
        (np.zeros((2, 2), np.float32), None, "^mask 4: values must be integers, not float32"),
        (np.array([[-1, 2]]), None, r"^mask 4: class values must be 0\.\.255, got -1\.\.2"),
        (np.array([[0, 256]]), None, r"^mask 4: class values must be 0\.\.255, got 0\.\.256"),
    ],
)
def test_a_bad_class_image_is_one_clear_error(image, shape, match):
    with pytest.raises(TerrathemeError, match=match):
        check_class_image(image, "mask 4", shape)
