"""Extremely randomised trees as flat node arrays: trained by scikit-learn, read by numba.

Extra-Trees (Geurts, Ernst & Wehenkel 2006) split at random thresholds: smoother
boundaries from the few hundred samples scribbles give. Kept as plain arrays, a model
file holds numbers only (no pickle); the numba kernel walks ``PREDICT_BLOCK`` samples
through a tree, four in lockstep, with thresholds rounded down to float32 (for a
float32 ``x``, ``x <= t`` exactly when ``x <= floor32(t)``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numba
import numpy as np
from terratheme.core.errors import TerrathemeError

#: the arrays of an :class:`ExtraTreesForest`, in file order
ARRAY_NAMES = ("classes", "roots", "feature", "threshold", "left", "right", "value")
#: ceilings :meth:`ExtraTreesForest.from_arrays` holds a forest to (50 trees of depth 12
#: have at most 409,550 nodes)
MAX_TREES = 1024
MAX_NODES = 1 << 24
MAX_CLASSES = 256
MAX_DEPTH = 64
MAX_FEATURES = 4096
#: samples each parallel job of the prediction kernel takes through a tree before the next
PREDICT_BLOCK = 1024


@dataclass(frozen=True, eq=False)
class ExtraTreesForest:
    """A trained forest as flat arrays over all trees' nodes.

    Attributes
    ----------
    classes : (C,) int64 ndarray
        Class value of each probability column, ascending.
    roots : (T,) int32 ndarray
        Node index of each tree's root.
    feature : (N,) int32 ndarray
        Feature a node splits on; -1 for a leaf.
    threshold : (N,) float64 ndarray
        A sample goes left when ``x[feature] <= threshold``.
    left, right : (N,) int32 ndarrays
        Children (node indices); -1 for a leaf.
    value : (N, C) float32 ndarray
        A leaf's class distribution (rows sum to 1); zeros for inner nodes.
    """

    classes: np.ndarray
    roots: np.ndarray
    feature: np.ndarray
    threshold: np.ndarray
    left: np.ndarray
    right: np.ndarray
    value: np.ndarray

    @property
    def n_trees(self) -> int:
        return int(self.roots.size)

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """Mean class distribution (n, C) float32 of the leaves samples ``x`` (n, F) fall in,
        columns in ``classes`` order."""
        x = np.ascontiguousarray(x, np.float32)
        need = int(self.feature.max()) + 1
        if x.ndim != 2 or x.shape[1] < need:
            raise TerrathemeError(f"samples of shape {x.shape} for a forest that reads "
                                  f"{need} features")
        out = np.zeros((x.shape[0], self.classes.size), np.float64)
        _predict(x, *self.walk_arrays, self.value, out, PREDICT_BLOCK)
        return out.astype(np.float32)

    @cached_property
    def walk_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The node arrays as the prediction kernel walks them (computed once): ``roots``,
        each tree's depth, ``feature`` (0 at a leaf), ``threshold`` as the largest float32
        below it (+inf at a leaf) and ``child`` (2N,) with n's children at 2n and 2n + 1
        (a leaf's are itself)."""
        leaf = self.left < 0
        nodes = np.arange(self.feature.size, dtype=np.int32)
        thr = self.threshold.astype(np.float32)
        up = thr.astype(np.float64) > self.threshold
        thr[up] = np.nextafter(thr[up], np.float32(-np.inf))
        thr[leaf] = np.inf
        child = np.empty(2 * nodes.size, np.int32)
        child[0::2] = np.where(leaf, nodes, self.left)
        child[1::2] = np.where(leaf, nodes, self.right)
        depths = _tree_depths(self.roots, self.left, self.right)
        return (self.roots, depths, np.where(leaf, 0, self.feature).astype(np.int32), thr,
                child)

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays by name (for a file)."""
        return {name: getattr(self, name) for name in ARRAY_NAMES}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray],
                    n_features: int | None = None) -> ExtraTreesForest:
        """Check and wrap :data:`ARRAY_NAMES` read from a file (TerrathemeError if they
        do not form a forest within the ``MAX_*`` ceilings and ``n_features``).

        Indices are range-checked before narrowing, children follow parents and depth is
        bounded, so a forest that passes cannot make the kernel read out of bounds or loop.
        """
        missing = [n for n in ARRAY_NAMES if n not in arrays]
        if missing:
            raise TerrathemeError(f"forest arrays missing: {', '.join(missing)}")
        a = {n: np.asarray(arrays[n]) for n in ARRAY_NAMES}
        for name in ARRAY_NAMES:
            kind = "f" if name in ("threshold", "value") else "iu"
            if a[name].dtype.kind not in kind:
                raise TerrathemeError(f"forest arrays do not form a forest: {name} has dtype "
                                  f"{a[name].dtype}")
        n_nodes, n_classes = a["feature"].shape[0], a["classes"].shape[0]
        shapes_ok = (a["classes"].ndim == 1 and 1 <= n_classes <= MAX_CLASSES
                     and a["roots"].ndim == 1 and 1 <= a["roots"].size <= MAX_TREES
                     and 1 <= n_nodes <= MAX_NODES
                     and all(a[k].shape == (n_nodes,)
                             for k in ("feature", "threshold", "left", "right"))
                     and a["value"].shape == (n_nodes, n_classes))
        if not shapes_ok:
            raise TerrathemeError("forest arrays do not form a forest: shapes "
                                  + ", ".join(f"{n} {a[n].shape}" for n in ARRAY_NAMES))
        # Ranges in Python integers / int64 before any narrowing cast.
        limit = MAX_FEATURES if n_features is None else n_features
        classes = a["classes"]
        if int(classes.min()) < 0 or int(classes.max()) > 255 or (np.diff(
                classes.astype(np.int64)) <= 0).any():
            raise TerrathemeError("forest arrays do not form a forest: classes must be "
                                  "distinct ascending values 0..255")
        for name, low, high in (("roots", 0, n_nodes - 1), ("left", -1, n_nodes - 1),
                                ("right", -1, n_nodes - 1), ("feature", -1, limit - 1)):
            lo, hi = int(a[name].min()), int(a[name].max())
            if lo < low or hi > high:
                raise TerrathemeError(f"forest arrays do not form a forest: {name} holds "
                                      f"{lo if lo < low else hi}, outside {low}..{high}")
        left, right, feature = (a[k].astype(np.int64) for k in ("left", "right", "feature"))
        leaf = left < 0
        nodes = np.arange(n_nodes)
        # Children come after their parent (scikit-learn's depth-first order), so a walk ends.
        if not (((left > nodes) | leaf).all() and ((right > nodes) | leaf).all()
                and ((right < 0) == leaf).all() and ((feature >= 0) != leaf).all()):
            raise TerrathemeError("forest arrays do not form a forest: children, leaves and "
                                  "features disagree")
        if not (np.isfinite(a["threshold"]).all() and np.isfinite(a["value"]).all()):
            raise TerrathemeError("forest arrays do not form a forest: thresholds or leaf "
                                  "values are not finite")
        values = a["value"][leaf].astype(np.float64)
        if (values < 0).any() or (np.abs(values.sum(1) - 1.0) > 1e-3).any():
            raise TerrathemeError("forest arrays do not form a forest: a leaf's class "
                                  "distribution is not shares summing to 1")
        _check_depth(a["roots"].astype(np.int64), left, right)
        return cls(classes.astype(np.int64), a["roots"].astype(np.int32),
                   feature.astype(np.int32), a["threshold"].astype(np.float64),
                   left.astype(np.int32), right.astype(np.int32),
                   a["value"].astype(np.float32))


def _check_depth(roots: np.ndarray, left: np.ndarray, right: np.ndarray) -> None:
    """Refuse trees deeper than MAX_DEPTH (walks level by level, at most MAX_DEPTH + 1 steps)."""
    level = np.unique(roots)
    for _ in range(MAX_DEPTH + 1):
        inner = level[left[level] >= 0]
        if inner.size == 0:
            return
        level = np.unique(np.concatenate([left[inner], right[inner]]))
    raise TerrathemeError(f"forest arrays do not form a forest: a tree is deeper than "
                          f"{MAX_DEPTH} levels")


def from_sklearn(model) -> ExtraTreesForest:
    """Flatten a fitted scikit-learn tree ensemble (single output) into arrays."""
    offsets, parts = 0, {n: [] for n in ARRAY_NAMES[1:]}
    for est in model.estimators_:
        t = est.tree_
        leaf = t.children_left < 0
        parts["roots"].append(offsets)
        parts["feature"].append(np.where(leaf, -1, t.feature))
        parts["threshold"].append(t.threshold)
        parts["left"].append(np.where(leaf, -1, t.children_left + offsets))
        parts["right"].append(np.where(leaf, -1, t.children_right + offsets))
        # Leaf distributions normalised here (older scikit-learn stores weighted counts).
        v = t.value[:, 0, :].astype(np.float64)
        v = np.where(leaf[:, None], v / np.maximum(v.sum(1, keepdims=True), 1e-300), 0.0)
        parts["value"].append(v)
        offsets += t.node_count
    arrays = {n: np.concatenate(p) if n != "roots" else np.asarray(p)
              for n, p in parts.items()}
    arrays["classes"] = np.asarray(model.classes_)
    return ExtraTreesForest.from_arrays(arrays, n_features=int(model.n_features_in_))


class ForestOptions(Protocol):
    """The fields of ``SupervisedOptions`` a forest is trained with."""

    n_trees: int
    max_depth: int
    min_samples: int
    balance: bool
    seed: int


def build_forest(x: np.ndarray, y: np.ndarray, options: ForestOptions,
                 n_jobs: int | None = None) -> ExtraTreesForest:
    """Extra-Trees (scikit-learn's) on samples ``x`` (n, F) with class values ``y`` (n,).

    ``options.balance``: classes weighed inversely to their counts. ``n_jobs``: fitting
    threads, default one per core and tree (a small fit is faster with 1).
    """
    import sklearn
    from sklearn.ensemble import ExtraTreesClassifier

    n_trees = options.n_trees
    model = ExtraTreesClassifier(n_estimators=n_trees, max_depth=options.max_depth,
                                 min_samples_split=max(2, options.min_samples),
                                 class_weight="balanced" if options.balance else None,
                                 n_jobs=min(os.cpu_count() or 1, n_trees) if n_jobs is None
                                 else n_jobs, random_state=options.seed)
    # Skip scikit-learn's parameter validation per tree (SupervisedOptions checks them).
    with sklearn.config_context(skip_parameter_validation=True):
        model.fit(np.asarray(x, np.float32), np.asarray(y))
    return from_sklearn(model)


def forest_scores(forest: ExtraTreesForest, x: np.ndarray, classes: Sequence[int]) -> np.ndarray:
    """Scores (n, C) float32 of samples ``x`` (n, F), columns in ``classes`` order.

    ``forest``: anything with ``classes`` and ``predict_proba`` (the benchmarks' peers too).
    """
    x = np.ascontiguousarray(x, np.float32)
    out = np.zeros((x.shape[0], len(classes)), np.float32)
    counts = forest.predict_proba(x)
    for col, value in enumerate(forest.classes):
        out[:, list(classes).index(int(value))] = counts[:, col]
    return out


def forest_probabilities(forest: ExtraTreesForest, feats: np.ndarray, classes: Sequence[int],
                         weights: Sequence[float] | None = None) -> np.ndarray:
    """Vote shares (h, w, C) float32 of a coarse feature stack (h, w, F), columns in
    ``classes`` order; ``weights`` (C,) (a prior correction) scale them before they are
    renormalised."""
    h, w, f = feats.shape
    probs = forest_scores(forest, feats.reshape(-1, f), classes)
    if weights is not None:
        probs *= np.asarray(weights, np.float32)[None, :]
    probs /= np.maximum(probs.sum(1, keepdims=True), 1e-12)
    return probs.reshape(h, w, len(classes))


@numba.njit(cache=True, nogil=True)
def _tree_depths(roots, left, right):  # pragma: no cover
    """Depth of each tree: children come after their parent (checked in from_arrays)."""
    depth = np.zeros(left.size, np.int32)
    out = np.zeros(roots.size, np.int32)
    for t in range(roots.size):
        stack = [roots[t]]
        depth[roots[t]] = 0
        while stack:
            node = stack.pop()
            out[t] = max(out[t], depth[node])
            if left[node] >= 0:
                depth[left[node]] = depth[node] + 1
                depth[right[node]] = depth[node] + 1
                stack.append(left[node])
                stack.append(right[node])
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _step(x, i, node, feature, threshold, child):  # pragma: no cover
    return child[2 * node + (0 if x[i, feature[node]] <= threshold[node] else 1)]


@numba.njit(cache=True, nogil=True, parallel=True)
def _predict(x, roots, depths, feature, threshold, child, value, out, block):  # pragma: no cover
    n_trees, n = roots.size, x.shape[0]
    for b in numba.prange((n + block - 1) // block):
        i0, i1 = b * block, min(n, (b + 1) * block)
        for t in range(n_trees):
            root, steps = roots[t], depths[t]
            i = i0
            # Four walks in lockstep (independent load chains), then the rest one by one.
            while i + 4 <= i1:
                a0 = a1 = a2 = a3 = root
                for _ in range(steps):
                    a0 = _step(x, i, a0, feature, threshold, child)
                    a1 = _step(x, i + 1, a1, feature, threshold, child)
                    a2 = _step(x, i + 2, a2, feature, threshold, child)
                    a3 = _step(x, i + 3, a3, feature, threshold, child)
                for c in range(out.shape[1]):
                    out[i, c] += value[a0, c]
                    out[i + 1, c] += value[a1, c]
                    out[i + 2, c] += value[a2, c]
                    out[i + 3, c] += value[a3, c]
                i += 4
            for k in range(i, i1):
                a0 = root
                for _ in range(steps):
                    a0 = _step(x, k, a0, feature, threshold, child)
                for c in range(out.shape[1]):
                    out[k, c] += value[a0, c]
    for i in numba.prange(n):
        for c in range(out.shape[1]):
            out[i, c] /= n_trees
