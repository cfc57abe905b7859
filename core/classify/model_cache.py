"""Fitted classifiers kept by content, so training on pairs seen before skips the fit.

Once the training photos' samples are cached
(:class:`core.classify.sample_cache.SampleCache`), fitting the forest is most
of what is left of training (0.35 s CPU of 50 trees on 12,000 samples, about
a prediction of a 1.5 Mpx photo). :class:`ModelCache` keeps the fitted model
under a key made of everything the fit depends on (:func:`model_key`): the
sample keys of the training pairs in order (each covers the pair's photo and
mask, the classes sampled, the feature options), the classes, all the
(resolved) supervised options -- forest, trees, caps, seed, prior and
prediction options, which the model carries --, the class weights given to
:func:`core.classify.supervised.train_classifier`, the versions of
scikit-learn (which fits the trees) and NumPy (which draws the capped
samples), and :data:`CACHE_VERSION`. The same key gives the very model the
fit would: predictions are bit-identical.

Entries live in memory (:data:`MEMORY_ENTRIES`, least recently used dropped
first) and, with a folder (the sample cache's folder fits: the names do not
clash), as ``<key>.model.npz``: the key and the model file's bytes
(:mod:`core.classify.model_file`, numbers only, every array checked on
reading), read with ``allow_pickle=False``, written atomically. A file that
does not read back as a model of its key and options (damaged, truncated,
written by another version) is a miss: the model is fitted again and the
file replaced. The folder is bounded (``max_bytes``, 2 GiB by default, the
least recently used entries of the folder removed first:
:mod:`core.classify.cache_bound`). Only Extra-Trees models are kept (OpenCV's forest reads back
from a model file as the equivalent node arrays, not the same object), and
on disk only those a model file can hold (options within its bounds).

The pairs stay keyed by their decoded pixels, not by their files' bytes or
(path, size, mtime): on six Dubai pairs (0.5-1.2 Mpx) a warm training costs
reading them 0.036 s CPU, checking them and finding the classes 0.012 s,
their keys 0.009 s and the model's file 0.015 s, against 0.19 s for
predicting the 1.5 Mpx target; a file key would save about 0.06 s (the
warm path 1.5x -> about 1.2x predict) but would go stale with a decoder's
or the reading code's change, and (path, size, mtime) with a file edited in
place within the clock's resolution.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from importlib.metadata import version

import numpy as np
from terratheme.core.classify.keyed_store import StoreFront
from terratheme.core.classify.model_file import ModelParts, model_bytes, read_model_bytes
from terratheme.core.classify.model_options import options_to_json
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.errors import TerrathemeError

#: models kept in memory (a 50-tree model of 63,000 nodes is about 3 MB there)
MEMORY_ENTRIES = 8
#: bumped when the model of a key changes meaning (a change in the training code)
CACHE_VERSION = 1
SUFFIX = ".model.npz"


def model_key(sample_keys: Sequence[str], classes: Sequence[int], options: SupervisedOptions,
              class_weights: Mapping[int, float] | None = None) -> str:
    """Hex SHA-256 of everything a fitted model depends on.

    Parameters
    ----------
    sample_keys : sequence of str
        :func:`core.classify.sample_cache.sample_key` of each training pair, in order.
    classes : sequence of int
        The classes sampled.
    options : SupervisedOptions
        As trained with (resolved: ``adapt`` decided).
    class_weights : mapping of class value -> float, optional
        As given to ``train_classifier``.
    """
    weights = None if class_weights is None else sorted(
        (int(k), float(v)) for k, v in class_weights.items())
    ingredients = {"version": CACHE_VERSION, "samples": [str(k) for k in sample_keys],
                   "classes": [int(c) for c in classes], "options": options_to_json(options),
                   "class_weights": weights, "scikit-learn": version("scikit-learn"),
                   "numpy": np.__version__}
    return hashlib.sha256(json.dumps(ingredients, sort_keys=True).encode()).hexdigest()


class ModelCache(StoreFront):
    """Fitted models by :func:`model_key`, in memory and optionally on disk.

    Parameters as :class:`~core.classify.keyed_store.StoreFront` (entries ``<key>.model.npz``);
    ``max_bytes`` below 1 raises TerrathemeError, and :meth:`model` does when the
    folder cannot be made or written.
    """

    SUFFIX = SUFFIX
    MEMORY_ENTRIES = MEMORY_ENTRIES
    WHAT = "trained models"

    def model(self, key: str, options: SupervisedOptions,
              fit: Callable[[], ModelParts]) -> ModelParts:
        """The model of ``key``: cached, or ``fit()`` then kept.

        Parameters
        ----------
        key : str
            :func:`model_key` of the training.
        options : SupervisedOptions
            The options the model must carry (an entry with others is a miss).
        fit : callable
            ``() -> ModelParts``.
        """
        return self._store.fetch(key, ("model",),
                                 lambda arrays: self._parse(arrays, key, options), fit,
                                 _model_arrays)

    def _parse(self, arrays: dict[str, np.ndarray], key: str,
               options: SupervisedOptions) -> ModelParts | None:
        """The model of an entry's arrays, if they hold a model file of ``options``."""
        if arrays["model"].dtype != np.uint8 or arrays["model"].ndim != 1:
            return None
        try:
            parts = read_model_bytes(arrays["model"].tobytes(), str(self._store.path(key)))
        except TerrathemeError:
            return None
        return parts if parts.options == options else None


def _model_arrays(parts: ModelParts) -> dict[str, np.ndarray] | None:
    """What an entry's file holds: the model file's bytes; None for options a model file
    cannot hold (e.g. trees deeper than it allows), kept in memory only, as a model of
    them cannot be saved either."""
    try:
        return {"model": np.frombuffer(model_bytes(parts), np.uint8)}
    except TerrathemeError:
        return None
