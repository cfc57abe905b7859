"""The supervised classifier's tree ensemble: Extra-Trees (default) or OpenCV's random forest.

``ForestKind.EXTRA_TREES`` (:mod:`core.classify.extra_trees`, scikit-learn
training, soft votes) is the default; ``ForestKind.RANDOM_FOREST`` is OpenCV's
``cv2.ml.RTrees`` (hard votes), the default of earlier versions, kept for
their model files and as the benchmark's peer (``bench_classify.py`` row
``rf-cv2``).
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from typing import Protocol

import cv2
import numpy as np
from terratheme.core.classify.extra_trees import ExtraTreesForest, fit_extra_trees


class ForestKind(enum.Enum):
    """Which tree ensemble :func:`build_forest` trains."""

    EXTRA_TREES = "extra-trees"
    RANDOM_FOREST = "random-forest"


class ForestOptions(Protocol):
    """The fields of ``SupervisedOptions`` a forest is trained with."""

    forest: ForestKind
    n_trees: int
    max_depth: int
    min_samples: int
    active_vars: int
    balance: bool
    seed: int


Forest = ExtraTreesForest | cv2.ml.RTrees


def build_forest(x: np.ndarray, y: np.ndarray, options: ForestOptions,
                 n_jobs: int | None = None) -> Forest:
    """Train the ensemble ``options.forest`` on samples ``x`` (n, F), class values ``y`` (n,).

    ``n_jobs``: Extra-Trees fitting threads (:func:`core.classify.extra_trees.fit_extra_trees`).
    """
    if options.forest is ForestKind.EXTRA_TREES:
        return fit_extra_trees(x, y, n_trees=options.n_trees, max_depth=options.max_depth,
                               min_samples_split=options.min_samples, balance=options.balance,
                               seed=options.seed, n_jobs=n_jobs)
    classes, counts = np.unique(y, return_counts=True)
    rt = cv2.ml.RTrees_create()
    rt.setMaxDepth(options.max_depth)
    rt.setMinSampleCount(options.min_samples)
    rt.setActiveVarCount(options.active_vars)
    rt.setCalculateVarImportance(False)
    rt.setTermCriteria((cv2.TERM_CRITERIA_MAX_ITER, options.n_trees, 0))
    if options.balance:
        # Priors in ascending class order: each class's total weight becomes equal.
        rt.setPriors((counts.max() / counts).astype(np.float32).reshape(1, -1))
    cv2.setRNGSeed(options.seed)
    rt.train(np.ascontiguousarray(x, np.float32), cv2.ml.ROW_SAMPLE, y.astype(np.int32))
    return rt


def forest_scores(forest: Forest, x: np.ndarray, classes: Sequence[int]) -> np.ndarray:
    """Per-class scores of samples ``x`` (n, F): mean leaf distributions or vote counts.

    Returns
    -------
    scores : (n, C) float32 ndarray, columns in ``classes`` order, not normalised
    """
    x = np.ascontiguousarray(x, np.float32)
    out = np.zeros((x.shape[0], len(classes)), np.float32)
    if isinstance(forest, ExtraTreesForest):
        order, counts = forest.classes, forest.predict_proba(x)
    else:
        votes = forest.getVotes(x, 0)
        # Row 0 of getVotes holds the class value of each column.
        order, counts = votes[0], votes[1:].astype(np.float32)
    for col, value in enumerate(order):
        out[:, list(classes).index(int(value))] = counts[:, col]
    return out
