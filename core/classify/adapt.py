"""Test-time adaptation: relearn the classes on the photo being classified.

A forest trained on other photos is right on most pixels of a class and unsure on the
rest. Self-training (Yarowsky 1995; Lee 2013): classify the photo (regularised), keep
each class's ``ADAPT_SHARE`` surest coarse pixels (:func:`pseudo_labels`, strided),
fit a small balanced forest of ``ADAPT_TREES`` on them, and classify again with the
mean of both forests' probabilities. Pass-1 features are kept for pass 2 up to
``ADAPT_KEEP_BYTES``; a class pass 1 barely predicts is not relearned.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial

import numpy as np
from terratheme.core.classify.extra_trees import ForestOptions, build_forest, forest_probabilities
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.regularise import RegulariseOptions, regularise
from terratheme.core.classify.result import Classification
from terratheme.core.classify.tiled import (
    ProbabilityFn,
    ProgressFn,
    predict_tiled,
    prediction_windows,
    sampling_stride,
    strided_pixels,
    tile_arrays,
)
from terratheme.core.io.tiles import TileWindow

#: share of each predicted class's coarse pixels (the most confident) taken as pseudo-labels
ADAPT_SHARE = 0.7
#: trees of the forest trained on the pseudo-labels
ADAPT_TREES = 10
#: pseudo-labels per class (random among the confident ones)
ADAPT_SAMPLES_PER_CLASS = 2000
#: coarse pixels of the photo pass 1 looks at (strided, at most)
ADAPT_SAMPLES = 200_000
#: a class predicted on fewer coarse pixels than this is not relearned
ADAPT_MIN_PIXELS = 20
#: ... nor one predicted on less than this share of the photo's coarse pixels
ADAPT_MIN_SHARE = 0.02
#: pass-1 features kept for pass 2 up to this many bytes (else computed again)
ADAPT_KEEP_BYTES = 256 << 20


def pseudo_labels(probs: np.ndarray, share: float = ADAPT_SHARE,
                  per_class: int = ADAPT_SAMPLES_PER_CLASS,
                  min_pixels: int = ADAPT_MIN_PIXELS, min_share: float = ADAPT_MIN_SHARE,
                  rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The samples of ``probs`` (n, C) a classification is surest of, per predicted class.

    Of the samples whose arg-max is class ``c``, the ``share`` most probable (ties at
    the cut kept), at most ``per_class`` (random, ``rng``); none for a class that is
    the arg-max of fewer than ``min_pixels`` samples or ``min_share`` of them.
    Returns the kept rows (m,) int64, ascending within each class, and their class
    column (m,) int64.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    best = np.argmax(probs, axis=1)
    conf = probs[np.arange(len(probs)), best]
    index, column = [], []
    for c in range(probs.shape[1]):
        rows = np.flatnonzero(best == c)
        if len(rows) < max(min_pixels, 1, min_share * len(probs)):
            continue
        # The most confident share of the class, then a random subset if too many.
        cut = np.quantile(conf[rows], 1.0 - share)
        rows = rows[conf[rows] >= cut]
        if len(rows) > per_class:
            rows = np.sort(rng.choice(rows, per_class, replace=False))
        index.append(rows)
        column.append(np.full(len(rows), c, np.int64))
    if not index:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(index).astype(np.int64), np.concatenate(column)


def predict_adapted(
    rgb: np.ndarray, valid: np.ndarray | None, probability_fn: ProbabilityFn,
    classes: tuple[int, ...], features: FeatureOptions, regularisation: RegulariseOptions,
    forest_options: ForestOptions, tile: int, progress: ProgressFn | None = None,
) -> Classification:
    """Classify a photo, relearn its classes from the surest pixels, classify again.

    Arguments as :func:`core.classify.tiled.predict_tiled`; ``forest_options`` gives the
    adapted forest's depth, split size and seed; ``progress`` spans both passes. Pass 1's
    result when it finds fewer than two classes.
    """
    h, w = rgb.shape[:2]
    scale = features.scale
    windows = prediction_windows(h, w, features, regularisation, tile)
    n_coarse = (-(-h // scale)) * (-(-w // scale))
    stride = sampling_stride(h, w, scale, ADAPT_SAMPLES)
    keep = n_coarse * (features.n_features + len(classes) + 4) * 4 * 1.5 <= ADAPT_KEEP_BYTES
    kept: dict = {}
    feats_seen, probs_seen = [], []
    for done, win in enumerate(windows, 1):
        # Pass 1: the trained model's regularised probabilities on this tile.
        lab, block_std, feats = tile_arrays(rgb, win, features)
        raw = probability_fn(feats).astype(np.float32, copy=False)
        if keep:
            kept[win] = (lab, block_std, feats, raw)
        probs = regularise(raw, lab, regularisation, texture=block_std)
        # Its core coarse pixels on the photo-wide strided grid (only those with data).
        part = None if valid is None else valid[win.y : win.y1, win.x : win.x1]
        iy, ix, _, _ = strided_pixels(win, scale, stride, part)
        feats_seen.append(feats[iy, ix])
        probs_seen.append(probs[iy, ix])
        if progress is not None:
            progress(done, 2 * len(windows))
    x, p = np.concatenate(feats_seen), np.concatenate(probs_seen)
    # The surest coarse pixels of each class as this photo's own training samples.
    index, column = pseudo_labels(p, rng=np.random.default_rng(forest_options.seed))
    if len(np.unique(column)) < 2:
        adapted_fn = None
    else:
        adapt_opts = replace(forest_options, n_trees=ADAPT_TREES, balance=True)
        labels = np.asarray(classes, np.int64)[column]
        adapted_fn = partial(forest_probabilities,
                             build_forest(x[index], labels, adapt_opts, n_jobs=1), classes=classes)

    def tile_fn(win: TileWindow) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # Pass 2: the mean of the trained and the photo's own forests' probabilities.
        if keep:
            lab, block_std, feats, raw = kept.pop(win)
        else:
            lab, block_std, feats = tile_arrays(rgb, win, features)
            raw = probability_fn(feats)
        if adapted_fn is None:
            return lab, block_std, raw
        return lab, block_std, 0.5 * (raw + adapted_fn(feats))

    def pass_two(done: int, total: int) -> None:
        if progress is not None:
            progress(len(windows) + done, 2 * len(windows))

    return predict_tiled(rgb, valid, probability_fn, classes, features, regularisation, tile,
                         pass_two, tile_fn=tile_fn)
