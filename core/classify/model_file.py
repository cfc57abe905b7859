"""The trained-classifier file: a zip holding ``meta.json`` and the forest.

``meta.json`` : ``{"format": "terratheme-classifier", "version": 2,
"classes": [...], "options": {...}, "class_weights": [...]}`` (options as plain
JSON, enums by value; class weights only when the model has a prior correction).
The forest (absent when the model has a single class): ``forest.npz``, the
Extra-Trees node arrays (:class:`core.classify.extra_trees.ExtraTreesForest`,
read with ``allow_pickle=False``: numbers only), or ``forest.yml``, an OpenCV
random forest as OpenCV's own YAML. Version 1 files (OpenCV forests, written
before Extra-Trees) still load. Written atomically; a newer version raises
UnsupportedVersionError, a damaged file CorruptFileError.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import asdict
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from core.classify.extra_trees import ExtraTreesForest
from core.classify.features import FeatureOptions, FeatureSet, Normalise
from core.classify.forest import ForestKind
from core.classify.regularise import Regularisation, RegulariseOptions
from core.classify.supervised_options import SupervisedOptions
from core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from core.io.atomic import write_bytes_atomic

FORMAT = "terratheme-classifier"
VERSION = 2


class ModelParts(NamedTuple):
    """What a model file holds: the forest (None for one class), classes, options, weights."""

    forest: object
    classes: tuple[int, ...]
    options: SupervisedOptions
    class_weights: tuple[float, ...] | None


def _options_to_json(options: SupervisedOptions) -> dict:
    d = asdict(options)
    d["features"]["feature_set"] = options.features.feature_set.value
    d["features"]["normalise"] = options.features.normalise.value
    d["regularisation"]["method"] = options.regularisation.method.value
    d["forest"] = options.forest.value
    return d


def _options_from_json(d: dict) -> SupervisedOptions:
    f = dict(d["features"])
    f["feature_set"] = FeatureSet(f["feature_set"])
    f["normalise"] = Normalise(f.get("normalise", "none"))
    f["sigmas"] = tuple(f["sigmas"])
    f["ridge_sigmas"] = tuple(f.get("ridge_sigmas", ()))
    r = dict(d["regularisation"])
    r["method"] = Regularisation(r["method"])
    rest = {k: v for k, v in d.items() if k not in ("features", "regularisation")}
    rest["ignore_classes"] = tuple(rest.get("ignore_classes", ()))
    # Version 1 files predate Extra-Trees: their forests are OpenCV's.
    rest["forest"] = ForestKind(rest.get("forest", ForestKind.RANDOM_FOREST.value))
    return SupervisedOptions(features=FeatureOptions(**f),
                             regularisation=RegulariseOptions(**r), **rest)


def write_model(path: str | os.PathLike, model: ModelParts) -> None:
    """Write a model to ``path`` (atomic)."""
    meta = {"format": FORMAT, "version": VERSION, "classes": list(model.classes),
            "options": _options_to_json(model.options)}
    if model.class_weights is not None:
        meta["class_weights"] = list(model.class_weights)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.json", json.dumps(meta, indent=1))
        if isinstance(model.forest, ExtraTreesForest):
            arrays = io.BytesIO()
            np.savez_compressed(arrays, **model.forest.arrays())
            zf.writestr("forest.npz", arrays.getvalue())
        elif model.forest is not None:
            fs = cv2.FileStorage(".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
            model.forest.write(fs)
            zf.writestr("forest.yml", fs.releaseAndGetString())
    write_bytes_atomic(path, buf.getvalue())


def read_model(path: str | os.PathLike) -> ModelParts:
    """Read a model written by :func:`write_model`.

    Raises
    ------
    TerrathemeError
        Missing file.
    CorruptFileError
        Not a classifier file, or damaged.
    UnsupportedVersionError
        Written by a newer version.
    """
    p = Path(path)
    if not p.is_file():
        raise TerrathemeError(f"{p}: no such model file")
    try:
        with zipfile.ZipFile(p) as zf:
            meta = json.loads(zf.read("meta.json"))
            forest_text = zf.read("forest.yml").decode() if "forest.yml" in zf.namelist() else None
            forest_npz = zf.read("forest.npz") if "forest.npz" in zf.namelist() else None
    except (zipfile.BadZipFile, KeyError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CorruptFileError(f"{p}: not a terratheme classifier file ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CorruptFileError(f"{p}: not a terratheme classifier file")
    if not isinstance(meta.get("version"), int) or meta["version"] > VERSION:
        raise UnsupportedVersionError(
            f"{p}: classifier file version {meta.get('version')} is newer than this "
            f"terratheme reads ({VERSION})"
        )
    try:
        options = _options_from_json(meta["options"])
        classes = [int(c) for c in meta["classes"]]
        weights = meta.get("class_weights")
        weights = None if weights is None else [float(v) for v in weights]
        if weights is not None and (len(weights) != len(classes)
                                    or not all(v >= 0 for v in weights)):
            raise ValueError(f"{len(weights)} class weights for {len(classes)} classes")
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptFileError(f"{p}: damaged classifier metadata ({exc})") from None
    forest = None
    if forest_npz is not None:
        try:
            with np.load(io.BytesIO(forest_npz), allow_pickle=False) as npz:
                forest = ExtraTreesForest.from_arrays({k: npz[k] for k in npz.files})
        except (OSError, ValueError, zipfile.BadZipFile, TerrathemeError) as exc:
            raise CorruptFileError(f"{p}: damaged forest ({str(exc).strip()[:80]})") from None
        if [int(c) for c in forest.classes] != sorted(classes):
            raise CorruptFileError(f"{p}: classes {classes} do not match the stored forest")
    elif forest_text is not None:
        try:
            fs = cv2.FileStorage(forest_text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
            forest = cv2.ml.RTrees_create()
            forest.read(fs.root())
        except cv2.error as exc:
            raise CorruptFileError(f"{p}: damaged forest ({str(exc).strip()[:80]})") from None
        if not forest.isTrained():
            raise CorruptFileError(f"{p}: damaged forest (not trained)")
    if (forest is None) != (len(classes) == 1) or not classes:
        raise CorruptFileError(f"{p}: classes {classes} do not match the stored forest")
    return ModelParts(forest, tuple(classes), options,
                      None if weights is None else tuple(weights))
