"""Training kept by content in a :class:`~core.io.disk_cache.DiskCache`: a pair's samples, the fit.

Features and the fit are most of a training's cost. A pair's samples (before the
per-class cap) are kept under :func:`sample_key`, the fitted model under
:func:`model_key` (SHA-256 of everything each depends on: bit-identical results). An
entry is checked against what its key stands for before use; else it is a miss.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from importlib.metadata import version

import numpy as np
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.model_file import ModelParts, model_bytes, read_model_bytes
from terratheme.core.classify.model_options import options_to_json
from terratheme.core.classify.photo import PreparedPhoto
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.disk_cache import Arrays, DiskCache

#: bumped when the entry of a key changes meaning (a change in the training code)
CACHE_VERSION = 2
Samples = tuple[np.ndarray, np.ndarray]


def sample_key(photo: np.ndarray | PreparedPhoto, mask: np.ndarray, classes: Sequence[int],
               features: FeatureOptions, tile: int, grow: float) -> str:
    """Hex SHA-256 of what a pair's samples depend on: pixels, classes sampled (over all
    pairs), feature options, tile and the label growing's colour threshold (0 = off)."""
    h = hashlib.sha256()
    options = {"version": CACHE_VERSION, "classes": [int(c) for c in classes],
               "features": _plain(asdict(features)), "tile": int(tile), "grow": float(grow)}
    h.update(json.dumps(options, sort_keys=True).encode())
    # A prepared photo: its pixels and its mask of pixels with data (what the samples see).
    pixels = [a for a in photo if a is not None] if isinstance(photo, PreparedPhoto) else [photo]
    for arr in (*map(np.asarray, pixels), np.asarray(mask)):
        h.update(f"{arr.shape}{arr.dtype.str}".encode())
        h.update(np.ascontiguousarray(arr).data)
    return h.hexdigest()


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return getattr(value, "value", value)


def model_key(sample_keys: Sequence[str], classes: Sequence[int], options: SupervisedOptions,
              class_weights: Mapping[int, float] | None = None) -> str:
    """Hex SHA-256 of what a fit depends on: the pairs' sample keys in order, the classes,
    the resolved options, the class weights given, the scikit-learn and NumPy versions."""
    weights = None if class_weights is None else sorted(
        (int(k), float(v)) for k, v in class_weights.items())
    ingredients = {"version": CACHE_VERSION, "samples": [str(k) for k in sample_keys],
                   "classes": [int(c) for c in classes], "options": options_to_json(options),
                   "class_weights": weights, "scikit-learn": version("scikit-learn"),
                   "numpy": np.__version__}
    return hashlib.sha256(json.dumps(ingredients, sort_keys=True).encode()).hexdigest()


def cached_samples(cache: DiskCache, key: str, n_features: int, classes: Sequence[int],
                   compute: Callable[[], Samples]) -> Samples:
    """A pair's samples ``(features (n, F) float32, labels (n,) uint8)``: the entry of
    ``key`` if it holds samples of ``n_features`` columns and ``classes``, else ``compute()``."""
    def parse(arrays: Arrays) -> Samples | None:
        x, y = arrays.get("features"), arrays.get("labels")
        if (set(arrays) != {"features", "labels"} or x.dtype != np.float32 or x.ndim != 2
                or x.shape[1] != n_features or y.dtype != np.uint8 or y.shape != (len(x),)
                or not np.isfinite(x).all() or not np.isin(y, classes).all()):
            return None
        return x, y

    def computed() -> Samples:
        x, y = compute()
        return np.ascontiguousarray(x, np.float32), np.ascontiguousarray(y, np.uint8)

    return cache.fetch(key, "samples", parse, computed,
                       lambda xy: {"features": xy[0], "labels": xy[1]})


def cached_model(cache: DiskCache, key: str, options: SupervisedOptions,
                 fit: Callable[[], ModelParts]) -> ModelParts:
    """The fitted model: the entry of ``key`` if it is a model file of ``options``, else
    ``fit()`` (kept unless a model file cannot hold it, e.g. trees deeper than it allows)."""
    def parse(arrays: Arrays) -> ModelParts | None:
        data = arrays.get("model")
        if set(arrays) != {"model"} or data.dtype != np.uint8 or data.ndim != 1:
            return None
        try:
            parts = read_model_bytes(data.tobytes(), "cached model")
        except TerrathemeError:
            return None
        return parts if parts.options == options else None

    def arrays_of(parts: ModelParts) -> Arrays | None:
        try:
            return {"model": np.frombuffer(model_bytes(parts), np.uint8)}
        except TerrathemeError:
            return None

    return cache.fetch(key, "model", parse, fit, arrays_of)
