"""Shipped classifiers by name (core.classify.shipped) and the ``aerial`` model itself."""

from __future__ import annotations

import json

import numpy as np
import pytest
from terratheme.core.classify import (
    SupervisedOptions,
    load_model,
    resolve_model,
    shipped_models,
    train_classifier,
)
from terratheme.core.classify.shipped import MODELS_INDEX, SHIPPED_MODELS_DIR
from terratheme.core.errors import CorruptFileError, TerrathemeError


def two_class_model():
    photo = np.zeros((32, 64, 3), np.uint8)
    photo[:, 32:] = 200
    mask = np.ones((32, 64), np.uint8)
    mask[:, 32:] = 2
    return train_classifier([(photo, mask)], SupervisedOptions(n_trees=3)), photo


@pytest.fixture
def folder(tmp_path):
    model, _photo = two_class_model()
    model.save(tmp_path / "dark_bright.model")
    index = {"models": {"shade": {"file": "dark_bright.model",
                                  "classes": {"1": "dark", "2": "bright"},
                                  "description": "test"}}}
    (tmp_path / MODELS_INDEX).write_text(json.dumps(index))
    return tmp_path


def test_a_name_resolves_to_its_file_and_class_names(folder):
    path, names = resolve_model("shade", folder)
    assert path == folder / "dark_bright.model" and names == {1: "dark", 2: "bright"}
    model = load_model("shade", folder)
    assert model.class_names == {1: "dark", 2: "bright"}
    assert set(shipped_models(folder)) == {"shade"}


def test_an_existing_path_wins_and_has_no_names(folder, tmp_path):
    path, names = resolve_model(folder / "dark_bright.model", folder)
    assert names is None and path == folder / "dark_bright.model"
    assert load_model(path, folder).class_names is None


def test_an_unknown_name_lists_the_shipped_ones(folder):
    with pytest.raises(TerrathemeError, match=r"nosuch: no such model file, nor a shipped "
                                              r"model \(shipped: shade\)"):
        resolve_model("nosuch", folder)


def test_a_shipped_file_that_is_missing(folder):
    (folder / "dark_bright.model").unlink()
    with pytest.raises(TerrathemeError, match="shipped model shade: .* is missing"):
        resolve_model("shade", folder)


@pytest.mark.parametrize("text", ["{", "[]", '{"models": {"a": {"classes": {}}}}',
                                  '{"models": {"a": {"file": "x", "classes": {"900": "y"}}}}',
                                  '{"models": {"a": {"file": "x", "classes": {"one": "y"}}}}'])
def test_a_damaged_index_is_one_clear_error(tmp_path, text):
    (tmp_path / MODELS_INDEX).write_text(text)
    with pytest.raises(CorruptFileError, match="not a model index"):
        shipped_models(tmp_path)


def test_no_index_means_no_shipped_models(tmp_path):
    assert shipped_models(tmp_path) == {}
    with pytest.raises(TerrathemeError, match=r"shipped: none"):
        resolve_model("aerial", tmp_path)


def test_the_aerial_forest_names_the_legends_classes():
    if not (SHIPPED_MODELS_DIR / MODELS_INDEX).is_file():
        pytest.skip("no shipped models (models/models.json absent)")
    # The forest --model aerial was before the network (tests/test_classify_network.py).
    model = load_model("aerial-forest")
    assert model.classes == (1, 2, 3, 4, 5)
    assert model.class_names == {1: "building", 2: "land", 3: "road", 4: "vegetation",
                                 5: "water"}
    # Trained on 54 photos: no test-time adaptation (SupervisedOptions.adapt).
    assert model.options.adapt is False and model.options.ignore_classes == (6, 7)
    # Dark still water and bright bare sand, the two easiest classes of the legend.
    photo = np.zeros((64, 128, 3), np.uint8)
    photo[:, :64] = (20, 35, 40)
    photo[:, 64:] = (215, 200, 175)
    labels = model.predict(photo).labels
    assert (labels[8:-8, 8:56] == 5).mean() > 0.9
    assert (labels[8:-8, 72:-8] == 2).mean() > 0.9
