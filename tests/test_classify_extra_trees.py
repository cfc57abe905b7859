"""core.classify.extra_trees / forest: Extra-Trees as flat arrays, and their model files."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from sklearn.ensemble import ExtraTreesClassifier
from terratheme.core.classify import Classifier, SupervisedOptions, train_classifier
from terratheme.core.classify.extra_trees import (
    ExtraTreesForest,
    build_forest,
    forest_scores,
    from_sklearn,
)
from terratheme.core.errors import CorruptFileError, TerrathemeError


def _stump_and_leaf() -> dict[str, np.ndarray]:
    # Tree 0: x[1] <= 0.5 -> leaf [1, 0], else leaf [0, 1]. Tree 1: one leaf [0.25, 0.75].
    return {
        "classes": np.array([3, 7]),
        "roots": np.array([0, 3]),
        "feature": np.array([1, -1, -1, -1]),
        "threshold": np.array([0.5, 0.0, 0.0, 0.0]),
        "left": np.array([1, -1, -1, -1]),
        "right": np.array([2, -1, -1, -1]),
        "value": np.array([[0, 0], [1, 0], [0, 1], [0.25, 0.75]], np.float32),
    }


def test_predict_by_hand() -> None:
    forest = ExtraTreesForest.from_arrays(_stump_and_leaf())
    x = np.array([[9.0, 0.2], [9.0, 0.9], [-9.0, 0.5]], np.float32)
    # Mean of the two trees' leaves; 0.5 itself goes left (<=).
    expect = np.array([[0.625, 0.375], [0.125, 0.875], [0.625, 0.375]], np.float32)
    np.testing.assert_array_equal(forest.predict_proba(x), expect)
    assert forest.n_trees == 2
    # Columns follow the classifier's class order, whatever the forest's.
    np.testing.assert_array_equal(forest_scores(forest, x, (7, 3)), expect[:, ::-1])


def test_flat_arrays_give_sklearns_probabilities() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, 6)).astype(np.float32)
    y = np.where(x[:, 0] + 0.5 * x[:, 3] > 0, 5, 2) + (x[:, 1] > 1.2)
    model = ExtraTreesClassifier(n_estimators=20, max_depth=8, random_state=1).fit(x, y)
    forest = from_sklearn(model)
    test = rng.normal(size=(300, 6)).astype(np.float32)
    np.testing.assert_allclose(forest.predict_proba(test), model.predict_proba(test),
                               atol=1e-6)
    np.testing.assert_array_equal(forest.classes, [2, 3, 5, 6])


def test_walk_is_the_float64_comparison_at_every_threshold() -> None:
    # Samples on, just below and just above each float64 threshold in float32 (the
    # kernel's thresholds are rounded down to float32), in counts that leave partial
    # lanes and blocks; the reference is a numpy walk comparing in float64.
    rng = np.random.default_rng(4)
    x = rng.normal(size=(600, 5)).astype(np.float32)
    y = (x[:, 0] > 0).astype(int) + 2 * (x[:, 2] > 0.5)
    forest = build_forest(x, y, SupervisedOptions(n_trees=7, max_depth=9, min_samples=2, seed=2))
    inner = np.flatnonzero(forest.feature >= 0)
    pick = rng.choice(inner, 500)
    test = rng.normal(size=(3 * pick.size + 3, 5)).astype(np.float32)
    near = forest.threshold[pick].astype(np.float32)
    for k, v in enumerate((near, np.nextafter(near, np.float32(-np.inf)),
                           np.nextafter(near, np.float32(np.inf)))):
        test[k * pick.size + np.arange(pick.size), forest.feature[pick]] = v
    node = np.repeat(forest.roots[None, :].astype(np.int64), len(test), 0)
    for _ in range(10):
        go_left = test[np.arange(len(test))[:, None], np.maximum(forest.feature[node], 0)
                       ].astype(np.float64) <= forest.threshold[node]
        node = np.where(forest.left[node] < 0, node,
                        np.where(go_left, forest.left[node], forest.right[node]))
    expect = forest.value[node].astype(np.float64).mean(1)
    for n in (len(test), 1, 5, 1027):
        np.testing.assert_allclose(forest.predict_proba(test[:n]), expect[:n], atol=1e-6)


def test_training_is_seeded_and_balanced() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(200, 4))
    y = (x[:, 0] > 1.0).astype(int) + 1  # class 2 is rare
    a = build_forest(x, y, SupervisedOptions(n_trees=8, min_samples=2, seed=3))
    b = build_forest(x, y, SupervisedOptions(n_trees=8, min_samples=2, seed=3))
    for name in ("feature", "threshold", "left", "value"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # Balanced weights lift the rare class's leaf shares above its sample share.
    p = a.predict_proba(x.astype(np.float32))
    assert p[y == 2, 1].mean() > 0.5 and p[y == 1, 0].mean() > 0.5


def test_bad_arrays_are_refused() -> None:
    arrays = _stump_and_leaf()
    with pytest.raises(TerrathemeError, match="missing: value"):
        ExtraTreesForest.from_arrays({k: v for k, v in arrays.items() if k != "value"})
    # A child pointing back up the tree would make a walk loop forever.
    loop = dict(arrays, left=np.array([0, -1, -1, -1]))
    with pytest.raises(TerrathemeError, match="do not form a forest"):
        ExtraTreesForest.from_arrays(loop)
    with pytest.raises(TerrathemeError, match="do not form a forest"):
        ExtraTreesForest.from_arrays(dict(arrays, value=np.zeros((4, 3), np.float32)))
    with pytest.raises(TerrathemeError, match="do not form a forest"):
        ExtraTreesForest.from_arrays(dict(arrays, roots=np.array([0, 9])))
    forest = ExtraTreesForest.from_arrays(arrays)
    with pytest.raises(TerrathemeError, match="reads 2 features"):
        forest.predict_proba(np.zeros((3, 1), np.float32))


def _stripes() -> tuple[np.ndarray, np.ndarray]:
    img = np.zeros((64, 64, 3), np.uint8)
    img[:, :32] = (200, 180, 120)
    img[:, 32:] = (40, 90, 40)
    mask = np.zeros((64, 64), np.uint8)
    mask[10:50, 12] = 1
    mask[10:50, 50] = 2
    return img, mask


def test_model_file_round_trip_and_damage(tmp_path) -> None:
    img, mask = _stripes()
    model = train_classifier([(img, mask)])
    assert isinstance(model.forest, ExtraTreesForest)
    labels = model.predict(img).labels
    assert (labels[:, :28] == 1).all() and (labels[:, 36:] == 2).all()
    model.save(tmp_path / "m.model")
    back = Classifier.load(tmp_path / "m.model")
    assert back.options == model.options
    res, res_back = model.predict(img), back.predict(img)
    np.testing.assert_array_equal(res_back.labels, res.labels)
    np.testing.assert_array_equal(res_back.confidence, res.confidence)
    with zipfile.ZipFile(tmp_path / "m.model") as zf:
        meta = json.loads(zf.read("meta.json"))
        npz = zf.read("forest.npz")
    assert meta["version"] == 2

    def write(name: str, forest_bytes: bytes) -> str:
        with zipfile.ZipFile(tmp_path / name, "w") as zf:
            zf.writestr("meta.json", json.dumps(meta))
            zf.writestr("forest.npz", forest_bytes)
        return str(tmp_path / name)

    with pytest.raises(CorruptFileError, match="damaged forest"):
        Classifier.load(write("cut.model", npz[: len(npz) // 2]))
    # Object arrays (pickles) are never loaded.
    buf = io.BytesIO()
    np.savez(buf, **{**model.forest.arrays(), "value": np.array([object()], dtype=object)})
    with pytest.raises(CorruptFileError, match="damaged forest"):
        Classifier.load(write("pickle.model", buf.getvalue()))
    # A forest whose classes are not the file's.
    buf = io.BytesIO()
    np.savez(buf, **{**model.forest.arrays(), "classes": np.array([1, 5])})
    with pytest.raises(CorruptFileError, match="do not match"):
        Classifier.load(write("classes.model", buf.getvalue()))
