"""The peers of ``bench_classify.py``: the ilastik recipe and k-means baselines (not a test module).

* ilastik recipe: OpenCV's random forest (:class:`RandomForest`) on Lab +
  scikit-image ``multiscale_basic_features`` per pixel (:func:`ilastik_features`),
  no regularisation, scored on ``ILASTIK_TEST_PIXELS`` random labelled pixels per photo;
* k-means on colour: OpenCV k-means on per-pixel Lab, clusters named by the
  majority class of the training labels.
"""

from __future__ import annotations

import time

import cv2
import numpy as np
from classify_eval import confusion
from terratheme.core import classify
from terratheme.core.classify.lab import block_lab, full_lab
from terratheme.core.classify.photo import prepare_photo

RNG_SEED = 0
ILASTIK_TEST_PIXELS = 50_000
#: the ilastik recipe's forest and the largest scale of its features (smallest 1 px)
ILASTIK_TREES = 24
ILASTIK_SIGMA_MAX = 16.0

#: the options the ilastik recipe's Classifier carries (only its regularisation counts)
ILASTIK = classify.SupervisedOptions(
    regularisation=classify.RegulariseOptions(method=classify.Regularisation.NONE))
KMEANS = classify.UnsupervisedOptions(
    features=classify.FeatureOptions(feature_set=classify.FeatureSet.COLOUR, scale=1),
    regularisation=classify.RegulariseOptions(method=classify.Regularisation.NONE),
)


def ilastik_features(photo):
    """Per-pixel Lab intensity, edges and Hessian texture at sigma 1..16 -> (feats, seconds)."""
    from skimage.feature import multiscale_basic_features

    rgb, _ = prepare_photo(photo)
    t = time.perf_counter()
    lab, _ = block_lab(full_lab(rgb), 1)
    feats = multiscale_basic_features(lab, channel_axis=-1, sigma_min=1.0,
                                      sigma_max=ILASTIK_SIGMA_MAX)
    return np.ascontiguousarray(feats, np.float32), time.perf_counter() - t


class RandomForest:
    """OpenCV's random forest (``cv2.ml.RTrees``, hard votes, balanced class priors).

    Has ``classes`` and ``predict_proba`` as ``ExtraTreesForest``, so a
    ``Classifier`` predicts with it.
    """

    def __init__(self, x, y, n_trees=ILASTIK_TREES, max_depth=12, min_samples=4, seed=0):
        self.classes, counts = np.unique(y, return_counts=True)
        self.n_trees = n_trees
        self.rt = cv2.ml.RTrees_create()
        self.rt.setMaxDepth(max_depth)
        self.rt.setMinSampleCount(min_samples)
        self.rt.setCalculateVarImportance(False)
        self.rt.setTermCriteria((cv2.TERM_CRITERIA_MAX_ITER, n_trees, 0))
        # Priors in ascending class order: each class's total weight becomes equal.
        self.rt.setPriors((counts.max() / counts).astype(np.float32).reshape(1, -1))
        cv2.setRNGSeed(seed)
        self.rt.train(np.ascontiguousarray(x, np.float32), cv2.ml.ROW_SAMPLE,
                      np.asarray(y, np.int32))

    def predict_proba(self, x):
        """Vote shares (n, C), columns in ``classes`` order."""
        votes = self.rt.getVotes(np.ascontiguousarray(x, np.float32), 0)
        # Row 0 of getVotes holds the class value of each column.
        order = [list(votes[0]).index(c) for c in self.classes]
        return votes[1:, order].astype(np.float32) / self.n_trees


def ilastik_model(x, y):
    """The ilastik recipe's classifier trained on per-pixel samples ``x`` (n, F), ``y`` (n,)."""
    return classify.Classifier(RandomForest(x, y), tuple(np.unique(y)), ILASTIK)


def labelled_pixels(truth, classes, count, rng):
    """Flat indices of at most ``count`` random pixels of ``truth`` of a class in ``classes``."""
    cand = np.flatnonzero(np.isin(truth.ravel(), classes))
    return rng.choice(cand, min(count, len(cand)), replace=False)


def timed_votes(model, x):
    """The forest's class of every row of ``x`` ((n, F) float32) -> (uint8 classes, seconds)."""
    t = time.perf_counter()
    probs = model.probabilities(x[None])[0]
    dt = time.perf_counter() - t
    return np.asarray(model.classes, np.uint8)[probs.argmax(1)], dt


def ilastik_predict(model, feats, truth, classes, rng, seconds_feat):
    """Votes on random labelled pixels -> (confusion, Mpx/s of features + votes)."""
    pick = labelled_pixels(truth, classes, ILASTIK_TEST_PIXELS, rng)
    pred, dt = timed_votes(model, feats.reshape(-1, feats.shape[2])[pick])
    per_px = seconds_feat / truth.size + dt / len(pick)
    return confusion(truth.ravel()[pick], pred, classes), 1e-6 / per_px


def kmeans_predict(photo, truth, classes, mapping_mask):
    """k-means on colour, clusters -> classes by majority of ``mapping_mask`` (0 = unlabelled)."""
    t = time.perf_counter()
    res = classify.classify_unsupervised(photo, themes=len(classes), options=KMEANS)
    dt = time.perf_counter() - t
    lut = np.zeros(256, np.uint8)
    fallback = np.bincount(mapping_mask[np.isin(mapping_mask, classes)], minlength=256).argmax()
    for c in res.classes:
        hit = mapping_mask[(res.labels == c) & np.isin(mapping_mask, classes)]
        lut[c] = np.bincount(hit, minlength=256).argmax() if hit.size else fallback
    return confusion(truth, lut[res.labels], classes), truth.size / dt / 1e6


class ColourKMeans:
    """k-means on Lab fitted to training samples, each cluster named by its majority class."""

    def __init__(self, lab, labels, k):
        cv2.setRNGSeed(RNG_SEED)
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
        _, assign, self.centres = cv2.kmeans(lab.astype(np.float32), k, None, criteria, 3,
                                              cv2.KMEANS_PP_CENTERS)
        assign = assign.ravel()
        self.lut = np.array([np.bincount(labels[assign == c], minlength=256).argmax()
                             if (assign == c).any() else 0 for c in range(k)], np.uint8)

    def classify(self, photo, truth, classes):
        """Per-pixel nearest centre -> (confusion, seconds)."""
        t = time.perf_counter()
        rgb, _ = prepare_photo(photo)
        lab, _ = block_lab(full_lab(rgb), 1)
        flat = lab.reshape(-1, 3)
        c = self.centres
        d2 = (flat * flat).sum(1)[:, None] - 2.0 * flat @ c.T + (c * c).sum(1)[None]
        pred = self.lut[d2.argmin(1)].reshape(truth.shape)
        return confusion(truth, pred, classes), time.perf_counter() - t
