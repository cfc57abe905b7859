"""Small checks on a real photo from ../shared/data (skipped when absent)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import SupervisedOptions, classify_unsupervised, train_classifier
from terratheme.core.io.images import read_image

#: real photos: part of the slow suite
pytestmark = pytest.mark.slow


def test_dubai_photo_trained_on_its_mask_reproduces_it(shared_data):
    photo = read_image(shared_data / "dubai" / "images" / "image_part_004t2.jpg")
    mask = read_image(shared_data / "dubai" / "masks" / "image_part_004t2.png")[:, :, 0]
    model = train_classifier([(photo, mask)], SupervisedOptions(ignore_classes=(6, 7)))
    assert set(model.classes) <= {1, 2, 3, 4, 5}
    res = model.predict(photo)
    labelled = (mask >= 1) & (mask <= 5)
    # Labels keep the mask's values and orientation: most pixels agree with it.
    assert (res.labels[labelled] == mask[labelled]).mean() > 0.8


def test_dubai_photo_unsupervised_finds_a_few_themes(shared_data):
    photo = read_image(shared_data / "dubai" / "images" / "image_part_004t2.jpg")
    res = classify_unsupervised(photo)
    assert 2 <= res.n_classes <= 8
    assert set(np.unique(res.labels)) == set(res.classes)
