"""The supervised classifier's tree ensemble: Extra-Trees (:mod:`core.classify.extra_trees`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from terratheme.core.classify.extra_trees import ExtraTreesForest, fit_extra_trees


class ForestOptions(Protocol):
    """The fields of ``SupervisedOptions`` a forest is trained with."""

    n_trees: int
    max_depth: int
    min_samples: int
    balance: bool
    seed: int


Forest = ExtraTreesForest


def build_forest(x: np.ndarray, y: np.ndarray, options: ForestOptions,
                 n_jobs: int | None = None) -> Forest:
    """Train a forest on samples ``x`` (n, F), class values ``y`` (n,).

    ``n_jobs``: fitting threads (:func:`core.classify.extra_trees.fit_extra_trees`).
    """
    return fit_extra_trees(x, y, n_trees=options.n_trees, max_depth=options.max_depth,
                           min_samples_split=options.min_samples, balance=options.balance,
                           seed=options.seed, n_jobs=n_jobs)


def forest_scores(forest: Forest, x: np.ndarray, classes: Sequence[int]) -> np.ndarray:
    """Per-class scores of samples ``x`` (n, F): the trees' mean leaf distributions.

    ``forest`` may be any object with ``classes`` (C,) and ``predict_proba(x) -> (n, C)``
    (the benchmarks' peers use it so).

    Returns
    -------
    scores : (n, C) float32 ndarray, columns in ``classes`` order
    """
    x = np.ascontiguousarray(x, np.float32)
    out = np.zeros((x.shape[0], len(classes)), np.float32)
    counts = forest.predict_proba(x)
    for col, value in enumerate(forest.classes):
        out[:, list(classes).index(int(value))] = counts[:, col]
    return out
