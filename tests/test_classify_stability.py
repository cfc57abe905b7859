"""The issue's stability list: where classifiers tend to fail."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import classify_unsupervised, train_classifier
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import read_image, write_image


def field_and_road(h=96, w=128):
    img = np.empty((h, w, 3), np.uint8)
    truth = np.full((h, w), 1, np.uint8)
    img[:] = (70, 140, 50)
    img[40:56] = (150, 150, 150)
    truth[40:56] = 2
    return img, truth


def test_one_class_photo_unsupervised_and_supervised():
    img = np.full((40, 40, 3), (90, 60, 30), np.uint8)
    res = classify_unsupervised(img)
    assert res.classes == (1,) and (res.labels == 1).all()
    mask = np.zeros((40, 40), np.uint8)
    mask[20, 10:30] = 4
    assert (train_classifier([(img, mask)]).predict(img).labels == 4).all()


def test_heavy_shadow():
    img, truth = field_and_road()
    # The right half lies in a shadow that keeps 25% of the light.
    shaded = img.astype(np.float32)
    shaded[:, 64:] *= 0.25
    shaded = shaded.astype(np.uint8)
    res = classify_unsupervised(shaded)
    assert 1 <= res.n_classes <= 4 and set(np.unique(res.labels)) <= set(res.classes)
    # Scribbles in the lit and the shaded part of each class teach both looks.
    mask = np.zeros_like(truth)
    mask[20, 10:30] = 1
    mask[20, 90:110] = 1
    mask[48, 10:30] = 2
    mask[48, 90:110] = 2
    out = train_classifier([(shaded, mask)]).predict(shaded)
    inner = np.ones(truth.shape, bool)
    inner[28:68] = False  # the road and one 8-px coarse pixel plus blur either side
    inner[:, 52:76] = False  # the shadow edge itself
    assert (out.labels[inner] == truth[inner]).all()
    assert (out.labels[44:52, :52] == 2).all() and (out.labels[44:52, 76:] == 2).all()


@pytest.mark.parametrize("size", [1, 3])
def test_tiny_photos(size):
    rng = np.random.default_rng(size)
    img = rng.integers(0, 255, (size, size, 3)).astype(np.uint8)
    res = classify_unsupervised(img)
    assert res.labels.shape == (size, size) and res.confidence.shape == (size, size)
    assert set(np.unique(res.labels)) <= set(res.classes)
    assert res.classes[0] == 1
    res3 = classify_unsupervised(img, themes=3)
    assert res3.labels.shape == (size, size)
    mask = np.zeros((size, size), np.uint8)
    mask[0, 0] = 2
    mask[-1, -1] = 3 if size > 1 else 2
    out = train_classifier([(img, mask)]).predict(img)
    assert out.labels.shape == (size, size)
    assert set(np.unique(out.labels)) <= {2, 3}


def test_alpha_channel_transparent_pixels_are_no_data():
    img, _ = field_and_road()
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    # Left quarter transparent and painted a colour that must not become a theme.
    rgba[:, :32, :3] = (255, 0, 0)
    rgba[:, :32, 3] = 0
    res = classify_unsupervised(rgba)
    assert res.n_classes == 2
    assert (res.labels[:, :32] == 0).all() and (res.confidence[:, :32] == 0).all()
    assert (res.labels[:, 32:] > 0).all()
    # Opaque alpha everywhere: same as the RGB photo.
    rgba[:, :32, :3] = img[:, :32]
    rgba[:, :, 3] = 255
    np.testing.assert_array_equal(classify_unsupervised(rgba).labels,
                                  classify_unsupervised(img).labels)


def test_fully_transparent_photo_is_a_clear_error():
    rgba = np.zeros((8, 8, 4), np.uint8)
    with pytest.raises(TerrathemeError, match="fully transparent"):
        classify_unsupervised(rgba)


def test_float_pixels_out_of_range_clip_without_warnings():
    import warnings

    from terratheme.core.classify.photo import prepare_photo

    arr = np.array([[[np.inf, -np.inf, np.nan], [0.5, 2.0, -1.0]]], np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rgb = prepare_photo(arr).rgb
    assert rgb.tolist() == [[[255, 0, 0], [128, 255, 0]]]


def test_fully_transparent_photo_is_a_clear_error_tile_by_tile(tmp_path):
    from terratheme.core.classify import load_model
    from terratheme.core.convert.tiled import convert_file_tiled

    path = tmp_path / "clear.png"
    write_image(path, np.zeros((64, 96, 4), np.uint8))
    with pytest.raises(TerrathemeError, match="clear.png: photo is fully transparent"):
        convert_file_tiled(path, load_model("aerial"), 8, tile=32)


def test_16_bit_tiff_matches_the_8_bit_photo(tmp_path):
    img, truth = field_and_road()
    path = tmp_path / "photo16.tif"
    write_image(path, img.astype(np.uint16) * 257)
    photo16 = read_image(path)
    assert photo16.dtype == np.uint16
    np.testing.assert_array_equal(classify_unsupervised(photo16).labels,
                                  classify_unsupervised(img).labels)
    mask = np.zeros_like(truth)
    mask[10, 10:40] = 1
    mask[48, 10:40] = 2
    model = train_classifier([(photo16, mask)])
    np.testing.assert_array_equal(model.predict(photo16).labels, model.predict(img).labels)


@pytest.mark.parametrize(
    ("photo", "match"),
    [
        (np.zeros((0, 5, 3), np.uint8), "no pixels"),
        (np.zeros((5, 5, 5), np.uint8), "shape"),
        (np.zeros((5, 5, 3), np.int64), "pixel type"),
    ],
)
def test_bad_photos_are_clear_errors(photo, match):
    with pytest.raises(TerrathemeError, match=match):
        classify_unsupervised(photo)
