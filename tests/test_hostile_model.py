"""Hostile classifier files: each loads and predicts, or is one line naming the file, quickly.

Regression tests for issue 16's model-file items (a feature index of 2^31
crashed the numba kernel; NaN or huge sigmas and scales failed inside
OpenCV at predict time; inf or zero class weights and NaN thresholds were
accepted; a flipped byte gave a zlib traceback), then fuzzing through
:class:`test_hostile_harness.BoundedReader`: a model that loads must also
predict a small photo within 256 MiB and 2 s.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from hostile_fuzz import (
    EDITS,
    ZIP_DIRECTORY_FIELDS,
    campaign,
    hostile_directory,
    run_bytes,
    run_edited,
    run_truncations,
)
from hypothesis import strategies as st
from terratheme.core.classify import Classifier, SupervisedOptions, train_classifier
from terratheme.core.classify.extra_trees import MAX_FEATURES, ExtraTreesForest
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from test_hostile_harness import ZipMember, craft_zip, shared_reader

#: features of the default model (an index of N is the first out of range)
N = SupervisedOptions().features.n_features


def _photo_and_scribbles():
    photo = np.zeros((48, 48, 3), np.uint8)
    photo[:, 24:] = (200, 180, 120)
    mask = np.zeros((48, 48), np.uint8)
    mask[10, 3:20], mask[30, 28:45] = 1, 2
    return photo, mask


@pytest.fixture(scope="module")
def model_parts(tmp_path_factory):
    """(meta dict, forest arrays, path) of a small trained Extra-Trees model."""
    photo, mask = _photo_and_scribbles()
    path = tmp_path_factory.mktemp("model") / "m.ttc"
    train_classifier([(photo, mask)], SupervisedOptions(n_trees=3)).save(path)
    with zipfile.ZipFile(path) as zf:
        meta = json.loads(zf.read("meta.json"))
        with np.load(io.BytesIO(zf.read("forest.npz"))) as npz:
            arrays = {k: npz[k] for k in npz.files}
    return meta, arrays, path


def _model_file(tmp_path, meta: dict, arrays: dict | None, name: str = "h.ttc"):
    members = [ZipMember.of("meta.json", json.dumps(meta).encode())]
    if arrays is not None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        members.append(ZipMember.of("forest.npz", buf.getvalue()))
    path = tmp_path / name
    path.write_bytes(craft_zip(members))
    return path


def test_the_rebuilt_model_loads_and_predicts(model_parts, tmp_path):
    meta, arrays, _ = model_parts
    model = Classifier.load(_model_file(tmp_path, meta, arrays))
    labels = model.predict(_photo_and_scribbles()[0]).labels
    assert (labels[:, :20] == 1).all() and (labels[:, 28:] == 2).all()


def _inner_node(arrays) -> int:
    return int(np.flatnonzero(arrays["left"] >= 0)[0])


@pytest.mark.parametrize("value", [1 << 31, (1 << 31) + 5, MAX_FEATURES, N, -2])
def test_a_feature_index_out_of_range_is_refused_at_load(model_parts, tmp_path, value):
    meta, arrays, _ = model_parts
    feature = arrays["feature"].astype(np.int64)
    feature[_inner_node(arrays)] = value
    path = _model_file(tmp_path, meta, dict(arrays, feature=feature))
    with pytest.raises(CorruptFileError, match=r"h.ttc: damaged forest .*feature holds"):
        Classifier.load(path)


@pytest.mark.parametrize(("change", "match"), [
    ({"threshold": "nan"}, "thresholds or leaf values are not finite"),
    ({"left": 1 << 32}, "left holds"),
    ({"roots": -1}, "roots holds"),
    ({"value": -1.0}, "not finite|not shares"),
    ({"classes": 300}, "classes must be distinct ascending values 0..255"),
])
def test_bad_forest_arrays_are_refused(model_parts, tmp_path, change, match):
    meta, arrays, _ = model_parts
    (name, value), = change.items()
    arr = arrays[name].astype(np.float64 if name in ("threshold", "value") else np.int64)
    if name == "value":
        arr[np.flatnonzero(arrays["left"] < 0)[0], 0] = value
    elif name in ("left", "classes", "roots"):
        arr.flat[_inner_node(arrays) if name == "left" else 0] = value
    else:
        arr[_inner_node(arrays)] = float(value)
    with pytest.raises(CorruptFileError, match=match):
        Classifier.load(_model_file(tmp_path, meta, dict(arrays, **{name: arr})))


def test_a_flipped_byte_in_a_deflated_member_is_one_line(model_parts, tmp_path):
    data = bytearray(model_parts[2].read_bytes())
    with zipfile.ZipFile(model_parts[2]) as zf:
        info = zf.getinfo("forest.npz")
    start = info.header_offset + 30 + len(info.filename)
    data[start + info.compress_size // 2] ^= 0x55  # inside the deflate stream
    (tmp_path / "flip.ttc").write_bytes(bytes(data))
    with pytest.raises(CorruptFileError, match=r"flip.ttc: forest.npz is damaged") as exc:
        Classifier.load(tmp_path / "flip.ttc")
    assert "\n" not in str(exc.value)


def test_index_arrays_of_float_type_are_refused(model_parts, tmp_path):
    meta, arrays, _ = model_parts
    path = _model_file(tmp_path, meta, dict(arrays, left=arrays["left"].astype(np.float64)))
    with pytest.raises(CorruptFileError, match="left.npy holds float64"):
        Classifier.load(path)


def test_a_chain_deeper_than_the_limit_is_refused():
    n = 70
    feature = np.r_[np.zeros(n - 1, np.int64), -1, -1]
    left = np.r_[np.arange(1, n), -1, -1]
    right = np.r_[np.full(n - 1, n), -1, -1]  # every inner node's right child is the leaf n
    arrays = {"classes": np.array([1, 2]), "roots": np.array([0]), "feature": feature,
              "threshold": np.zeros(n + 1), "left": left, "right": right,
              "value": np.tile([0.5, 0.5], (n + 1, 1))}
    with pytest.raises(TerrathemeError, match="deeper than 64 levels"):
        ExtraTreesForest.from_arrays(arrays)


@pytest.mark.parametrize(("path", "value", "match"), [
    (("features", "sigmas"), [1e6], r"options.features.sigmas must be a number in 0.001..64"),
    (("features", "scale"), 10**9, r"options.features.scale must be a whole number in 1..64"),
    (("features", "scale"), 2.5, "options.features.scale must be a whole number"),
    (("features", "normalise"), "lab", "options.features.normalise 'lab' is no longer supported"),
    (("features", "relative"), True, "options.features.relative True is no longer supported"),
    (("features", "feature_set"), "nope", "feature_set must be one of"),
    (("regularisation", "edge_sigma_spatial"), 1e9, "edge_sigma_spatial"),
    (("n_trees",), 10**6, "options.n_trees"),
    (("tile",), 8, "options.tile"),
    (("balance",), "yes", "options.balance must be true or false"),
    (("nonsense",), 1, "unknown option options.nonsense"),
])
def test_options_out_of_range_are_refused(model_parts, tmp_path, path, value, match):
    meta, arrays, _ = model_parts
    meta = json.loads(json.dumps(meta))
    node = meta["options"]
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(CorruptFileError, match=match):
        Classifier.load(_model_file(tmp_path, meta, arrays))


@pytest.mark.parametrize("weights", [[0.0, 1.0], [1e300, 1.0], [1.0], "x", [True, 1.0]])
def test_class_weights_must_be_finite_and_positive(model_parts, tmp_path, weights):
    meta, arrays, _ = model_parts
    with pytest.raises(CorruptFileError, match="class weight"):
        Classifier.load(_model_file(tmp_path, dict(meta, class_weights=weights), arrays))


@pytest.mark.parametrize("text", ['{"class_weights": [Infinity, 1]}', '{"x": NaN}'])
def test_non_finite_json_is_refused(model_parts, tmp_path, text):
    path = tmp_path / "nan.ttc"
    path.write_bytes(craft_zip([ZipMember.of("meta.json", text.encode())]))
    with pytest.raises(CorruptFileError, match="meta.json is not valid JSON"):
        Classifier.load(path)


def test_saving_refuses_what_loading_refuses(tmp_path):
    photo, mask = _photo_and_scribbles()
    model = train_classifier([(photo, mask)], SupervisedOptions(n_trees=2))
    model.class_weights = (0.0, 1.0)
    with pytest.raises(TerrathemeError, match="cannot save the classifier: class weight"):
        model.save(tmp_path / "m.ttc")
    assert not (tmp_path / "m.ttc").exists()


# -- fuzzing within the time and memory bound ---------------------------------

@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@campaign
def test_truncations_of_a_model_file(budget, bounded, model_parts, tmp_path):
    data = model_parts[2].read_bytes()
    assert len(data) < 4000
    kinds = run_truncations(bounded, "model", data, tmp_path / "cut.ttc", budget,
                            quick_cases=len(data) // 7)
    assert kinds == {"error"}


def _stored_model(model_parts) -> bytes:
    """The model with stored (uncompressed) members: flips land in the JSON and arrays."""
    meta, npz = _stored_members(model_parts)
    return craft_zip([ZipMember.of("meta.json", meta, method=0),
                      ZipMember.of("forest.npz", npz, method=0)])


@campaign
def test_flips_and_insertions(budget, bounded, model_parts, tmp_path):
    files = [model_parts[2].read_bytes(), _stored_model(model_parts)]
    budget.explore(lambda edits, stored: run_edited(bounded, "model", files[stored],
                                                    tmp_path / "mut.ttc", edits),
                   edits=EDITS, stored=st.booleans())


WILD = (st.none() | st.booleans() | st.integers(-(1 << 40), 1 << 40)
        | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=5)
        | st.lists(st.floats(-1e9, 1e9), max_size=20))
OPTION_PATHS = st.sampled_from([
    ("features", k) for k in ("feature_set", "normalise", "scale", "sigmas",
                              "skimage_sigma_max", "hessian", "position", "ridge_sigmas",
                              "relative")
] + [("regularisation", k) for k in ("method", "sigma", "region_size", "ruler",
                                      "edge_sigma_spatial", "edge_sigma_colour")]
  + [(k,) for k in ("ignore_classes", "forest", "n_trees", "max_depth", "tile", "prior_power",
                    "grow_colour", "balance", "min_samples", "active_vars",
                    "max_samples_per_class", "seed", "samples_per_pair", "adapt",
                    "target_prior_power")] + [("classes",), ("class_weights",)])


def _run_option(bounded, model_parts, tmp_path, changes):
    meta, arrays, _ = model_parts
    meta = json.loads(json.dumps(meta))
    for path, value in changes:
        node = meta if path[0] in ("classes", "class_weights") else meta["options"]
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    target = _model_file(tmp_path, meta, arrays, "opt.ttc")
    run_bytes(bounded, "model", target, target.read_bytes())


@campaign
def test_hostile_option_values(budget, bounded, model_parts, tmp_path):
    budget.explore(lambda changes: _run_option(bounded, model_parts, tmp_path, changes),
                   changes=st.lists(st.tuples(OPTION_PATHS, WILD), min_size=1, max_size=3))


def test_extreme_allowed_options_still_predict_within_the_bound(bounded, model_parts, tmp_path):
    changes = [(("features", "scale"), 64), (("features", "sigmas"), [64.0] * 16),
               (("features", "ridge_sigmas"), [64.0] * 16),
               (("regularisation", "edge_sigma_spatial"), 256.0), (("tile",), 1 << 16)]
    _run_option(bounded, model_parts, tmp_path, changes)


ARRAY_EDITS = st.lists(st.tuples(
    st.sampled_from(["classes", "roots", "feature", "threshold", "left", "right", "value"]),
    st.integers(0, 100),
    st.sampled_from([-1, 0, 1, 2, N - 1, N, 1 << 31, -(1 << 31), 1 << 40, float("nan"),
                     float("inf"), 0.5, -0.5, 1e300])), min_size=1, max_size=3)


def _run_arrays(bounded, model_parts, tmp_path, edits):
    meta, arrays, _ = model_parts
    arrays = {k: v.astype(np.float64 if k in ("threshold", "value") else np.int64)
              for k, v in arrays.items()}
    for name, index, value in edits:
        arr = arrays[name]
        if arr.dtype.kind == "i" and not (float(value).is_integer() and abs(value) < 2**62):
            continue
        arr.flat[index % arr.size] = value
    target = _model_file(tmp_path, meta, arrays, "arr.ttc")
    run_bytes(bounded, "model", target, target.read_bytes())


@campaign
def test_hostile_forest_arrays(budget, bounded, model_parts, tmp_path):
    budget.explore(lambda edits: _run_arrays(bounded, model_parts, tmp_path, edits),
                   edits=ARRAY_EDITS)


@pytest.mark.parametrize(("version", "error", "match"), [
    (3, UnsupportedVersionError, "classifier file version 3 is newer than this terratheme "
                                 r"reads \(2\)"),
    (2**63, UnsupportedVersionError, "is newer than this terratheme"),
    (0, CorruptFileError, "bad classifier file version 0"),
    ("2", CorruptFileError, "bad classifier file version '2'"),
    (2.0, CorruptFileError, "bad classifier file version 2.0"),
])
def test_version_bumps_are_named(model_parts, tmp_path, version, error, match):
    meta, arrays, _ = model_parts
    with pytest.raises(error, match=match):
        Classifier.load(_model_file(tmp_path, dict(meta, version=version), arrays))


def _stored_members(model_parts) -> tuple[bytes, bytes]:
    """(meta.json, forest.npz) bytes of the model, the arrays stored (not deflated)."""
    meta, arrays, _ = model_parts
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return json.dumps(meta).encode(), buf.getvalue()


def _directory_forged(model_parts, inner: bool, member: int, fields) -> bytes:
    meta, npz = _stored_members(model_parts)
    if inner:
        # forest.npz is a ZIP of .npy members itself: forge its directory instead
        npz = hostile_directory(npz, member, fields)
        return craft_zip([ZipMember.of("meta.json", meta), ZipMember.of("forest.npz", npz)])
    return hostile_directory(model_parts[2].read_bytes(), member, fields)


@campaign
def test_hostile_zip_directory_fields(budget, bounded, model_parts, tmp_path):
    budget.explore(lambda inner, member, fields: run_bytes(
        bounded, "model", tmp_path / "dir.ttc",
        _directory_forged(model_parts, inner, member, fields)),
        inner=st.booleans(), member=st.integers(0, 8), fields=ZIP_DIRECTORY_FIELDS)


def test_an_earlier_file_with_a_removed_option_at_its_off_value_still_loads():
    from terratheme.core.classify.model_options import options_from_json, options_to_json

    d = json.loads(json.dumps(options_to_json(SupervisedOptions())))
    d["features"].update({"relative": False, "normalise": "none"})
    assert options_from_json(d) == SupervisedOptions()
