"""The trained-classifier file: a zip holding ``meta.json`` and the forest.

``meta.json`` : ``{"format": "terratheme-classifier", "version": 2,
"classes": [...], "options": {...}, "class_weights": [...], "class_names": {...}}``
(options as plain JSON, enums by value; class weights only when the model has
a prior correction; class names, ``{"value": name}``, only when it was
trained with a legend, :mod:`core.io.legend`).
The forest (absent when the model has a single class): ``forest.npz``, the
Extra-Trees node arrays (:class:`core.classify.extra_trees.ExtraTreesForest`,
read with ``allow_pickle=False``: numbers only), or ``forest.yml``, an OpenCV
random forest as OpenCV's own YAML. Version 1 files (OpenCV forests, written
before Extra-Trees) still load. Written atomically; a newer version raises
UnsupportedVersionError, a damaged file CorruptFileError.

A model file may come from anyone, so reading bounds its work
(:mod:`core.io.archive`: sizes checked before reading, a capped inflate) and
checks every number: each option against a type and range (:mod:`core.classify.model_options`:
feature scale 1..64, sigmas up to 64, at most ``MAX_TREES`` trees of depth
``MAX_DEPTH``, ...), class values 0..255, class weights finite and positive,
and the forest's arrays (:meth:`ExtraTreesForest.from_arrays`) against the
options' feature count, so prediction never fails or reads out of bounds.
:func:`write_model` refuses what :func:`read_model` would refuse.
"""

from __future__ import annotations

import io
import json
import math
import os
import zipfile
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np
from terratheme.core.classify.extra_trees import (
    ARRAY_NAMES,
    MAX_CLASSES,
    MAX_FEATURES,
    MAX_NODES,
    MAX_TREES,
    ExtraTreesForest,
)
from terratheme.core.classify.model_options import number_rule, options_from_json, options_to_json
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.archive import open_archive, read_json_member, read_member, read_npy_member
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.legend import parse_legend

FORMAT = "terratheme-classifier"
VERSION = 2
META, FOREST_NPZ, FOREST_YML = "meta.json", "forest.npz", "forest.yml"
#: ceilings on what a model file may declare
MAX_META_BYTES = 1 << 20
MAX_FOREST_BYTES = 256 << 20
MAX_MEMBERS = 16
_INT_DTYPES = [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64]
_FLOAT_DTYPES = [np.float32, np.float64]


class ModelParts(NamedTuple):
    """What a model file holds: the forest (None for one class), classes, options, weights,
    and the classes' names (None when it has none)."""

    forest: object
    classes: tuple[int, ...]
    options: SupervisedOptions
    class_weights: tuple[float, ...] | None
    class_names: dict[int, str] | None = None


def write_model(path: str | os.PathLike, model: ModelParts) -> None:
    """Write a model to ``path`` (atomic).

    Raises
    ------
    TerrathemeError
        Options or class weights :func:`read_model` would refuse (nothing is written).
    """
    write_bytes_atomic(path, model_bytes(model))


def model_bytes(model: ModelParts) -> bytes:
    """The bytes of the model file of ``model`` (what :func:`write_model` writes).

    Raises
    ------
    TerrathemeError
        Options or class weights :func:`read_model` would refuse.
    """
    options = options_to_json(model.options)
    try:
        options_from_json(json.loads(json.dumps(options)))
        _class_weights(list(model.class_weights) if model.class_weights is not None else None,
                       list(model.classes))
        names = _class_names(_names_json(model.class_names), list(model.classes), "")
    except ValueError as exc:
        raise TerrathemeError(f"cannot save the classifier: {exc}") from None
    meta = {"format": FORMAT, "version": VERSION, "classes": list(model.classes),
            "options": options}
    if model.class_weights is not None:
        meta["class_weights"] = list(model.class_weights)
    if names is not None:
        meta["class_names"] = _names_json(names)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(META, json.dumps(meta, indent=1, allow_nan=False))
        if isinstance(model.forest, ExtraTreesForest):
            arrays = io.BytesIO()
            np.savez_compressed(arrays, **model.forest.arrays())
            zf.writestr(FOREST_NPZ, arrays.getvalue())
        elif model.forest is not None:
            fs = cv2.FileStorage(".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
            model.forest.write(fs)
            zf.writestr(FOREST_YML, fs.releaseAndGetString())
    return buf.getvalue()


def _class_weights(weights: object, classes: list) -> list[float] | None:
    if weights is None:
        return None
    if not isinstance(weights, list) or len(weights) != len(classes):
        count = len(weights) if isinstance(weights, list) else "no list of"
        raise ValueError(f"{count} class weights for {len(classes)} classes")
    return [float(number_rule(1e-12, 1e12)(v, "class weight")) for v in weights]


def _names_json(names: dict[int, str] | None) -> dict[str, str] | None:
    return None if names is None else {str(k): v for k, v in names.items()}


def _class_names(value: object, classes: list, label: str) -> dict[int, str] | None:
    """The stored names, checked as a legend is (:func:`core.io.legend.parse_legend`)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise ValueError("class names must be an object of class value -> name")
    try:
        names = parse_legend(json.dumps(value).encode(), label or "class names")
    except CorruptFileError as exc:
        raise ValueError(str(exc)) from None
    if not set(names) <= set(classes):
        raise ValueError(f"class names for {sorted(set(names) - set(classes))}, which the "
                         f"model does not have")
    return names


def _classes(value: object) -> list[int]:
    if not isinstance(value, list) or not 1 <= len(value) <= MAX_CLASSES:
        raise ValueError(f"classes must be a list of 1..{MAX_CLASSES} class values")
    classes = [number_rule(0, 255, whole=True)(c, "class") for c in value]
    if len(set(classes)) != len(classes):
        raise ValueError(f"classes {classes} repeat a value")
    return classes


def _read_extra_trees(data: bytes, label: str, n_features: int) -> ExtraTreesForest:
    """The Extra-Trees arrays of ``forest.npz`` (itself a ZIP of ``.npy`` members)."""
    arrays = {}
    try:
        with open_archive(data, FOREST_NPZ, kind="forest array archive",
                          max_members=len(ARRAY_NAMES) + 4) as npz:
            for name in ARRAY_NAMES:
                floats = name in ("threshold", "value")
                arrays[name] = read_npy_member(
                    npz, f"{name}.npy", FOREST_NPZ, max_bytes=MAX_NODES * MAX_CLASSES * 8 if
                    name == "value" else MAX_NODES * 8,
                    dtypes=_FLOAT_DTYPES if floats else _INT_DTYPES,
                    ndims=[2] if name == "value" else [1])
    except CorruptFileError as exc:
        raise CorruptFileError(f"{label}: damaged forest ({exc})") from None
    try:
        return ExtraTreesForest.from_arrays(arrays, n_features=n_features)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{label}: damaged forest ({exc})") from None


def _whole_field(node, name: str, lo: int, hi: int) -> int:
    field = node.getNode(name)
    if not field.isInt() or not lo <= field.real() <= hi:
        raise ValueError(f"{name} is not a whole number in {lo}..{hi}")
    return int(field.real())


def _opencv_trees(root, n_features: int, classes: list[int]) -> dict[str, np.ndarray]:
    """The node arrays of an OpenCV RTrees file node (format 3, ordered features only)."""
    if _whole_field(root, "var_count", 0, MAX_FEATURES) != n_features:
        raise ValueError(f"not trained for {n_features} features")
    _whole_field(root, "is_classifier", 1, 1)
    var_idx, labels = root.getNode("var_idx"), root.getNode("class_labels")
    if not var_idx.empty() and [int(var_idx.at(i).real()) for i in range(
            min(var_idx.size(), MAX_FEATURES + 1))] != list(range(n_features)):
        raise ValueError("var_idx picks features this version does not read")
    labels = [int(labels.at(i).real()) for i in range(min(labels.size(), MAX_CLASSES + 1))]
    if sorted(labels) != sorted(classes):
        raise ValueError(f"classes {labels[:8]} are not the file's {classes}")
    column = [sorted(classes).index(c) for c in labels]
    trees = root.getNode("trees")
    if not trees.isSeq() or not 1 <= trees.size() <= MAX_TREES:
        raise ValueError(f"trees must be a list of 1..{MAX_TREES}")
    feature, threshold, left, right, leaf_class, roots = [], [], [], [], [], []
    inverted = []
    for t in range(trees.size()):
        nodes = trees.at(t).getNode("nodes")
        if not nodes.isSeq() or not 1 <= nodes.size() <= MAX_NODES - len(feature):
            raise ValueError(f"tree {t} has no nodes or too many")
        # Pre-order, linked as OpenCV's readTree does: a split node's children follow it.
        parent, pending = {}, -1
        roots.append(len(feature))
        for i in range(nodes.size()):
            node, k = nodes.at(i), len(feature)
            if pending < 0 and k != roots[-1]:
                raise ValueError(f"tree {t} has nodes after its last leaf")
            parent[k] = pending
            if pending >= 0:
                (left if left[pending] < 0 else right)[pending] = k
            leaf_class.append(column[_whole_field(node, "norm_class_idx", 0, len(labels) - 1)])
            left.append(-1)
            right.append(-1)
            splits = node.getNode("splits")
            if splits.empty():
                feature.append(-1)
                threshold.append(0.0)
                while pending >= 0 and right[pending] >= 0:
                    pending = parent[pending]
                continue
            split = splits.at(0)
            # "ge" marks an inverted split: x <= c goes right (its children are swapped below).
            if split.getNode("le").empty():
                inverted.append(k)
            cut = split.getNode("ge" if inverted and inverted[-1] == k else "le")
            if not (cut.isReal() or cut.isInt()) or not math.isfinite(cut.real()):
                raise ValueError(f"tree {t} has a split that is not on an ordered feature")
            feature.append(_whole_field(split, "var", 0, n_features - 1))
            threshold.append(float(np.float32(cut.real())))
            pending = k
        if pending >= 0:
            raise ValueError(f"tree {t} ends before every split has two children")
    left, right = np.array(left), np.array(right)
    left[inverted], right[inverted] = right[inverted], left[inverted].copy()
    is_leaf = np.array(feature) < 0
    value = np.zeros((len(feature), len(classes)))
    value[np.flatnonzero(is_leaf), np.array(leaf_class)[is_leaf]] = 1.0
    return {"classes": np.array(sorted(classes)), "roots": np.array(roots),
            "feature": np.array(feature), "threshold": np.array(threshold), "left": left,
            "right": right, "value": value}


def _read_opencv_forest(text: str, label: str, n_features: int,
                        classes: list[int]) -> ExtraTreesForest:
    """An OpenCV random forest (``forest.yml``) as checked node arrays.

    OpenCV's own reader trusts the file (a split on feature ``var_count``
    reads out of bounds, a split without children crashes prediction), so
    the trees are read here, node by node, and predicted by the checked
    kernel of :mod:`core.classify.extra_trees`: a leaf's distribution is its
    class, one vote per tree, which is what ``RTrees.getVotes`` counts.
    """
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        arrays = _opencv_trees(fs.root(), n_features, classes)
        return ExtraTreesForest.from_arrays(arrays, n_features=n_features)
    except (cv2.error, SystemError, ValueError, TerrathemeError) as exc:
        # OpenCV's bindings report some YAML parse errors as SystemError.
        raise CorruptFileError(f"{label}: damaged forest "
                               f"({' '.join(str(exc).split())[:120]})") from None


def read_model(path: str | os.PathLike) -> ModelParts:
    """Read a model written by :func:`write_model`.

    Work is bounded by the file: members and arrays are checked before they
    are read (:mod:`core.io.archive`), every option is type- and
    range-checked, and the forest is checked so prediction cannot fail or
    read out of bounds.

    Raises
    ------
    TerrathemeError
        Missing file.
    CorruptFileError
        Not a classifier file, or damaged: a member, an option out of range,
        class weights that are not finite and positive, a forest that does
        not fit the options or the classes.
    UnsupportedVersionError
        Written by a newer version.
    """
    p = Path(path)
    if not p.is_file():
        raise TerrathemeError(f"{p}: no such model file")
    return read_model_bytes(p, str(p))


def read_model_bytes(source: str | os.PathLike | bytes, label: str) -> ModelParts:
    """Read a model file's bytes (or the file at a path), checked as :func:`read_model` does.

    ``label`` names the source in messages.

    Raises
    ------
    CorruptFileError
        Not a classifier file, or damaged (see :func:`read_model`).
    UnsupportedVersionError
        Written by a newer version.
    """
    with open_archive(source, label, kind="terratheme classifier file",
                      max_members=MAX_MEMBERS) as zf:
        names = zf.namelist()
        if META not in names:
            raise CorruptFileError(f"{label}: not a terratheme classifier file (no {META})")
        meta = read_json_member(zf, META, label, max_bytes=MAX_META_BYTES)
        forest_npz = (read_member(zf, FOREST_NPZ, label, max_bytes=MAX_FOREST_BYTES)
                      if FOREST_NPZ in names else None)
        forest_yml = (read_member(zf, FOREST_YML, label, max_bytes=MAX_FOREST_BYTES)
                      if FOREST_YML in names else None)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CorruptFileError(f"{label}: not a terratheme classifier file")
    version = meta.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise CorruptFileError(f"{label}: bad classifier file version {repr(version)[:20]}")
    if version > VERSION:
        raise UnsupportedVersionError(
            f"{label}: classifier file version {version} is newer than this "
            f"terratheme reads ({VERSION})"
        )
    try:
        options = options_from_json(meta.get("options"))
        classes = _classes(meta.get("classes"))
        weights = _class_weights(meta.get("class_weights"), classes)
        names = _class_names(meta.get("class_names"), classes, "class names")
    except (ValueError, TerrathemeError) as exc:
        raise CorruptFileError(f"{label}: damaged classifier metadata ({exc})") from None
    n_features = options.features.n_features
    forest: object = None
    if forest_npz is not None:
        forest = _read_extra_trees(forest_npz, label, n_features)
        if [int(c) for c in forest.classes] != sorted(classes):
            raise CorruptFileError(f"{label}: classes {classes} do not match the stored forest")
    elif forest_yml is not None:
        try:
            text = forest_yml.decode("utf-8")
        except UnicodeDecodeError:
            raise CorruptFileError(f"{label}: damaged forest (not UTF-8 text)") from None
        forest = _read_opencv_forest(text, label, n_features, classes)
    if (forest is None) != (len(classes) == 1):
        raise CorruptFileError(f"{label}: classes {classes} do not match the stored forest")
    return ModelParts(forest, tuple(classes), options,
                      None if weights is None else tuple(weights), names)
