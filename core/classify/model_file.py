"""The trained-classifier file: a ZIP of ``meta.json`` and ``forest.npz`` (docs/formats.md).

A model file may come from anyone: reading bounds its work (:mod:`core.io.archive`)
and checks every number (options by :mod:`core.classify.model_options`, classes,
weights, the forest's arrays against the options' feature count), so prediction never
fails or reads out of bounds. A newer version or a terratheme 0.x OpenCV forest raises
UnsupportedVersionError. :func:`write_model` refuses what :func:`read_model` would.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path
from typing import NamedTuple

import numpy as np
from terratheme.core.classify.extra_trees import (
    ARRAY_NAMES,
    MAX_CLASSES,
    MAX_NODES,
    ExtraTreesForest,
)
from terratheme.core.classify.model_options import number_rule, options_from_json, options_to_json
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.archive import (
    DEFLATE_SLACK,
    MAX_DEFLATE_RATIO,
    open_archive,
    read_json_member,
    read_member,
    read_npy_member,
)
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
    """Write a model to ``path`` (atomic); refuses what :func:`read_model` would refuse."""
    write_bytes_atomic(path, model_bytes(model))


def model_bytes(model: ModelParts) -> bytes:
    """The bytes :func:`write_model` writes; TerrathemeError for what a reader refuses."""
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
        if model.forest is not None:
            arrays = io.BytesIO()
            np.savez_compressed(arrays, **model.forest.arrays())
            zf.writestr(FOREST_NPZ, arrays.getvalue())
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


def _read_extra_trees(data: bytes, label: str, n_features: int,
                      file_bytes: int) -> ExtraTreesForest:
    """The Extra-Trees arrays of ``forest.npz`` (itself a ZIP of ``.npy`` members).

    The arrays may declare at most what one deflate could pack into the model file's
    ``file_bytes``: a ZIP inside a ZIP would otherwise multiply the ratios (a 5 KB file
    declaring gigabytes).
    """
    arrays = {}
    budget = MAX_DEFLATE_RATIO * file_bytes + DEFLATE_SLACK
    try:
        with open_archive(data, FOREST_NPZ, kind="forest array archive",
                          max_members=len(ARRAY_NAMES) + 4) as npz:
            declared = sum(info.file_size for info in npz.infolist())
            if declared > budget:
                raise CorruptFileError(f"its arrays declare {declared:,} bytes, more than "
                                       f"{MAX_DEFLATE_RATIO} times the {file_bytes:,}-byte "
                                       "model file can hold")
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


def read_model(path: str | os.PathLike) -> ModelParts:
    """Read a model written by :func:`write_model`, checked as the module docstring says
    (``CorruptFileError``, ``UnsupportedVersionError``; a missing file ``TerrathemeError``)."""
    p = Path(path)
    if not p.is_file():
        raise TerrathemeError(f"{p}: no such model file")
    return read_model_bytes(p, str(p))


def read_model_bytes(source: str | os.PathLike | bytes, label: str) -> ModelParts:
    """:func:`read_model` of a file's bytes (or path), named ``label`` in messages."""
    with open_archive(source, label, kind="terratheme classifier file",
                      max_members=MAX_MEMBERS) as zf:
        names = zf.namelist()
        if META not in names:
            raise CorruptFileError(f"{label}: not a terratheme classifier file (no {META})")
        meta = read_json_member(zf, META, label, max_bytes=MAX_META_BYTES)
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise CorruptFileError(f"{label}: not a terratheme classifier file")
        version = meta.get("version")
        if not isinstance(version, int) or isinstance(version, bool) or version < 1:
            raise CorruptFileError(f"{label}: bad classifier file version {repr(version)[:20]}")
        if version > VERSION:
            raise UnsupportedVersionError(
                f"{label}: classifier file version {version} is newer than this "
                f"terratheme reads ({VERSION})")
        if version < VERSION or FOREST_YML in names:
            # Terratheme 0.x: an OpenCV random forest as OpenCV's YAML (never parsed).
            raise UnsupportedVersionError(
                f"{label}: unsupported model format version {version} (an OpenCV forest of "
                f"terratheme 0.x): train the model again")
        forest_npz = (read_member(zf, FOREST_NPZ, label, max_bytes=MAX_FOREST_BYTES)
                      if FOREST_NPZ in names else None)
    try:
        options = options_from_json(meta.get("options"))
        classes = _classes(meta.get("classes"))
        weights = _class_weights(meta.get("class_weights"), classes)
        names = _class_names(meta.get("class_names"), classes, "class names")
    except (ValueError, TerrathemeError) as exc:
        raise CorruptFileError(f"{label}: damaged classifier metadata ({exc})") from None
    n_features = options.features.n_features
    forest: ExtraTreesForest | None = None
    if forest_npz is not None:
        file_bytes = len(source) if isinstance(source, bytes) else os.path.getsize(source)
        forest = _read_extra_trees(forest_npz, label, n_features, file_bytes)
        if [int(c) for c in forest.classes] != sorted(classes):
            raise CorruptFileError(f"{label}: classes {classes} do not match the stored forest")
    if (forest is None) != (len(classes) == 1):
        raise CorruptFileError(f"{label}: classes {classes} do not match the stored forest")
    return ModelParts(forest, tuple(classes), options,
                      None if weights is None else tuple(weights), names)
