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
    """A forest of samples ``x`` (n, F) with classes ``y`` (n,); ``n_jobs`` fitting threads."""
    return fit_extra_trees(x, y, n_trees=options.n_trees, max_depth=options.max_depth,
                           min_samples_split=options.min_samples, balance=options.balance,
                           seed=options.seed, n_jobs=n_jobs)


def forest_scores(forest: Forest, x: np.ndarray, classes: Sequence[int]) -> np.ndarray:
    """Scores (n, C) float32 of samples ``x`` (n, F), columns in ``classes`` order.

    ``forest``: anything with ``classes`` and ``predict_proba`` (the benchmarks' peers too).
    """
    x = np.ascontiguousarray(x, np.float32)
    out = np.zeros((x.shape[0], len(classes)), np.float32)
    counts = forest.predict_proba(x)
    for col, value in enumerate(forest.classes):
        out[:, list(classes).index(int(value))] = counts[:, col]
    return out
