"""Training samples of photo/mask pairs kept by content, so retraining skips their features.

A user who labels a handful of photos trains on them again and again (one
more labelled photo, another photo to convert). Computing the features of
every training photo is most of the cost of training, and they do not change:
:class:`SampleCache` keeps each pair's labelled coarse feature vectors (before
the per-class cap, so the result is the same as without the cache) under a
key made of everything they depend on: the photo's and the mask's bytes,
shapes and types, the classes sampled, the feature options, the tile size and
the growing threshold (:func:`sample_key`, SHA-256).

Entries live in memory and, when a folder is given, in one ``.npz`` file per
key there (numbers only, read with ``allow_pickle=False``, written
atomically). A file that does not read back as the samples of its key
(damaged, truncated, written by another version) is a miss: the samples are
computed again and the file replaced. The folder is bounded (``max_bytes``,
2 GiB by default, the least recently used entries removed first:
:mod:`core.classify.cache_bound`).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict

import numpy as np
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.keyed_store import StoreFront

#: entries kept in memory (least recently used dropped first)
MEMORY_ENTRIES = 64
#: bumped when the samples of a key change meaning
CACHE_VERSION = 1

Samples = tuple[np.ndarray, np.ndarray]


def sample_key(photo: np.ndarray, mask: np.ndarray, classes: Sequence[int],
               features: FeatureOptions, tile: int, grow: float) -> str:
    """Hex SHA-256 of everything a pair's samples depend on.

    Parameters
    ----------
    photo : (H, W, C) ndarray
    mask : (H, W) integer ndarray
    classes : sequence of int
        The classes sampled (over all pairs of the training set).
    features : FeatureOptions
    tile : int
    grow : float
        Colour threshold of the label growing (0 = off).
    """
    h = hashlib.sha256()
    options = {"version": CACHE_VERSION, "classes": [int(c) for c in classes],
               "features": _plain(asdict(features)), "tile": int(tile), "grow": float(grow)}
    h.update(json.dumps(options, sort_keys=True).encode())
    for arr in (np.asarray(photo), np.asarray(mask)):
        h.update(f"{arr.shape}{arr.dtype.str}".encode())
        h.update(np.ascontiguousarray(arr).data)
    return h.hexdigest()


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return getattr(value, "value", value)


class SampleCache(StoreFront):
    """Per-pair training samples by :func:`sample_key`, in memory and optionally on disk.

    Parameters as :class:`~core.classify.keyed_store.StoreFront` (entries ``.npz``);
    ``max_bytes`` below 1 raises TerrathemeError, and :meth:`samples` does when the
    folder cannot be made or written.
    """

    SUFFIX = ".npz"
    MEMORY_ENTRIES = MEMORY_ENTRIES
    WHAT = "training samples"

    def samples(self, key: str, n_features: int, compute: Callable[[], Samples]) -> Samples:
        """The samples of ``key``: cached, or ``compute()`` then kept.

        Parameters
        ----------
        key : str
            :func:`sample_key` of the pair.
        n_features : int
            Columns the samples must have (an entry that differs is a miss).
        compute : callable
            ``() -> (features (n, F) float32, labels (n,) uint8)``.
        """
        def computed() -> Samples:
            x, y = compute()
            return np.ascontiguousarray(x, np.float32), np.ascontiguousarray(y, np.uint8)

        return self._store.fetch(key, ("features", "labels"),
                                 lambda arrays: _samples(arrays, n_features), computed,
                                 lambda xy: {"features": xy[0], "labels": xy[1]})


def _samples(arrays: dict[str, np.ndarray], n_features: int) -> Samples | None:
    """The samples of an entry's arrays, if they have the shapes and types of samples."""
    x, y = arrays["features"], arrays["labels"]
    if (x.dtype != np.float32 or y.dtype != np.uint8 or x.ndim != 2
            or x.shape[1] != n_features or y.shape != (x.shape[0],)):
        return None
    return x, y
