"""The shipped network (core.classify.network): tiles, probabilities, bad files, the index."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from terratheme.core.classify import load_model, shipped_models
from terratheme.core.classify.network import NetworkClassifier, NetworkOptions
from terratheme.core.classify.shipped import MODELS_INDEX
from terratheme.core.errors import CorruptFileError, TerrathemeError

MODELS = shipped_models()
AERIAL = MODELS.get("aerial")
pytestmark = pytest.mark.skipif(AERIAL is None or AERIAL.path.suffix != ".onnx"
                                or not AERIAL.path.is_file(),
                                reason="the shipped aerial network is not in models/")
CLASSES = (1, 2, 3, 4, 5)
DUBAI = Path(__file__).resolve().parents[2] / "shared" / "data" / "dubai"


def network(tile: int = 768, halo: int = 48, classes=CLASSES) -> NetworkClassifier:
    return NetworkClassifier(AERIAL.path, classes, AERIAL.scale, AERIAL.multiple,
                             options=NetworkOptions(tile=tile, halo=halo))


def photo(h: int = 150, w: int = 173, seed: int = 0) -> np.ndarray:
    """Blobs of sand, water, grass and grey roofs with noise: odd sides, all classes likely."""
    rng = np.random.default_rng(seed)
    colours = np.array([[210, 190, 160], [30, 60, 70], [70, 110, 50], [150, 150, 150]], float)
    idx = cv2.resize(rng.integers(0, 4, (6, 7)).astype(np.uint8), (w, h),
                     interpolation=cv2.INTER_NEAREST)
    img = colours[idx] + rng.normal(0, 12, (h, w, 3))
    return np.clip(img, 0, 255).astype(np.uint8)


def test_tiles_give_the_whole_photo_s_probabilities():
    img = photo()
    whole = network(tile=4096).probabilities(img)
    # Tiles of 24 net pixels, far smaller than the photo, with the halo over the net's reach.
    tiled = network(tile=24, halo=64).probabilities(img)
    np.testing.assert_allclose(tiled, whole, atol=1e-5)
    # The default halo: within float-like tolerance too.
    assert np.abs(network(tile=24).probabilities(img) - whole).max() < 1e-3


def test_a_halo_too_small_does_change_the_probabilities():
    # The comparison above can fail: too little context and tiles differ from the whole.
    img = photo()
    whole = network(tile=4096).probabilities(img)
    assert np.abs(network(tile=24, halo=8).probabilities(img) - whole).max() > 1e-3


def test_probabilities_and_labels_shapes_types_and_sums():
    img = photo(37, 61, seed=1)
    net = network()
    probs = net.probabilities(img)
    assert probs.shape == (37, 61, 5) and probs.dtype == np.float32
    assert probs.min() >= 0.0 and probs.max() <= 1.0
    np.testing.assert_allclose(probs.sum(axis=2), 1.0, atol=1e-5)
    result = net.predict(img)
    assert result.labels.shape == (37, 61) and result.labels.dtype == np.uint8
    assert result.confidence.dtype == np.float32 and result.classes == CLASSES
    np.testing.assert_array_equal(result.labels, np.asarray(CLASSES)[probs.argmax(axis=2)])
    np.testing.assert_allclose(result.confidence, probs.max(axis=2), atol=1e-6)


def test_dark_water_and_bright_sand_are_water_and_land():
    # The two easiest classes of the legend, as the forest's test asks of it.
    img = np.zeros((64, 128, 3), np.uint8)
    img[:, :64] = (20, 35, 40)
    img[:, 64:] = (215, 200, 175)
    labels = network().predict(img).labels
    assert (labels[8:-8, 8:56] == 5).mean() > 0.9
    assert (labels[8:-8, 72:-8] == 2).mean() > 0.9


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (3, 2), (17, 1)])
def test_tiny_photos_are_classified(shape):
    img = np.full(shape + (3,), 120, np.uint8)
    result = network().predict(img)
    assert result.labels.shape == shape and set(np.unique(result.labels)) <= set(CLASSES)


def test_transparent_pixels_are_no_data():
    rgba = np.dstack([photo(40, 48), np.full((40, 48), 255, np.uint8)])
    rgba[:10, :, 3] = 0
    result = network().predict(rgba)
    assert (result.labels[:10] == 0).all() and (result.confidence[:10] == 0).all()
    assert (result.labels[10:] > 0).all()


def test_the_network_pickles_for_the_cluster_path():
    net = network()
    img = photo(32, 40)
    again = pickle.loads(pickle.dumps(net))
    np.testing.assert_array_equal(again.predict(img).labels, net.predict(img).labels)


@pytest.mark.parametrize("content", [b"", b"not an onnx file at all" * 50, None])
def test_a_corrupt_network_file_is_one_line_naming_it(tmp_path, content):
    bad = tmp_path / "bad.onnx"
    data = AERIAL.path.read_bytes()
    bad.write_bytes(data[: len(data) // 3] if content is None else content)
    with pytest.raises(CorruptFileError) as info:
        NetworkClassifier(bad, CLASSES, AERIAL.scale, AERIAL.multiple)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_a_network_with_other_outputs_than_its_classes_is_refused():
    with pytest.raises(CorruptFileError, match="gives shape"):
        network(classes=(1, 2, 3)).predict(photo(16, 16))


@pytest.mark.parametrize("scale", [0.3, 0.0, -1.0, 0.05])
def test_a_scale_that_is_not_one_over_an_integer_is_refused(scale):
    with pytest.raises(TerrathemeError, match="scale"):
        NetworkClassifier(AERIAL.path, CLASSES, scale, AERIAL.multiple)


def test_the_shipped_entry_is_a_small_named_network():
    assert AERIAL.size is not None and AERIAL.size <= 20 << 20
    model = load_model("aerial")
    assert isinstance(model, NetworkClassifier)
    assert model.classes == CLASSES
    assert model.class_names == {1: "building", 2: "land", 3: "road", 4: "vegetation",
                                 5: "water"}


def test_an_index_with_a_bad_scale_is_one_line_naming_it(tmp_path):
    shutil.copy(AERIAL.path, tmp_path / "n.onnx")
    entry = {"file": "n.onnx", "classes": {"1": "a", "2": "b"}, "scale": 3}
    (tmp_path / MODELS_INDEX).write_text(json.dumps({"models": {"n": entry}}))
    with pytest.raises(CorruptFileError, match="scale"):
        shipped_models(tmp_path)


@pytest.mark.slow
@pytest.mark.skipif(not (DUBAI / "images").is_dir(), reason="no Dubai photos in ../shared")
def test_the_network_classifies_a_dubai_photo():
    # The shipped model is trained on all six tiles (--holdout 0): tile 1 is seen data.
    img = cv2.imread(str(DUBAI / "images" / "image_part_001t1.jpg"))[:, :, ::-1]
    mask = cv2.imread(str(DUBAI / "masks" / "image_part_001t1.png"), cv2.IMREAD_UNCHANGED)
    mask = mask if mask.ndim == 2 else mask[:, :, 0]
    labels = load_model("aerial").predict(np.ascontiguousarray(img)).labels
    keep = (mask >= 1) & (mask <= 5)
    assert (labels[keep] == mask[keep]).mean() > 0.7
