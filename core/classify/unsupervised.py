"""Unsupervised themes: k-means on colour + texture, K chosen from the data.

Criterion for the number of themes K ("model no more than the scene needs",
design.md §3). With ``W_K`` the mean squared distance of the sampled
feature vectors to their nearest of K k-means centres (OpenCV k-means++,
features in fixed Delta-E-like units, see :mod:`core.classify.features`):

1. noise floor: if the photo's RMS spread ``sqrt(W_1)`` is below
   ``min_separation / 2``, the photo is flat: K = 1;
2. otherwise K grows from 1 while the next split explains at least
   ``min_gain`` of the photo's variance, ``(W_{K-1} - W_K) / W_1 >= min_gain``,
   **and** its two closest centres stay at least ``min_separation`` apart
   (themes a viewer could not tell apart are not made), **and** no theme
   covering under ``transition_share`` of the photo has its centre near the
   segment between two other centres (that is the blend that smoothed
   features make along a border, not a theme of the scene);
3. K never exceeds ``max_themes`` nor the number of distinct samples.

Themes are numbered 1..K by decreasing area. Confidence is the winning
theme's posterior under an isotropic Gaussian mixture with the centres as
means, the theme areas as weights and the pooled within-theme variance.

This module holds the options, the sampling and the choice of K; fitting a
reusable model and classifying with it is :mod:`core.classify.unsupervised_model`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from core.classify.features import FeatureOptions, FeatureSet
from core.classify.regularise import RegulariseOptions
from core.classify.tiled import iter_tile_features, strided_core
from core.errors import TerrathemeError


@dataclass(frozen=True)
class UnsupervisedOptions:
    """Options of :func:`classify_unsupervised`.

    Attributes
    ----------
    features : FeatureOptions
        Default: 4x4 coarse pixels and one smoothing scale (sigma 1 coarse
        pixel). Larger scales blur class borders into bands that k-means
        would take for themes.
    regularisation : RegulariseOptions
    max_themes : int
        Upper bound on K for ``themes="auto"``.
    min_gain : float
        Smallest share of the photo's variance a new theme must explain.
    min_separation : float
        Smallest distance between two theme centres, in Delta-E-like units
        (weighted feature space).
    transition_share : float
        A theme smaller than this share of the photo whose centre lies
        between two others is a border blend, not a theme (criterion 2).
    max_samples : int
        Coarse pixels sampled for k-means.
    attempts : int
        k-means restarts (best compactness kept).
    seed : int
        OpenCV RNG seed (results are deterministic).
    tile : int
        Tile core size in photo pixels.
    """

    features: FeatureOptions = field(
        default_factory=lambda: FeatureOptions(scale=4, sigmas=(1.0,), hessian=False)
    )
    regularisation: RegulariseOptions = field(default_factory=RegulariseOptions)
    max_themes: int = 8
    min_gain: float = 0.03
    min_separation: float = 6.0
    transition_share: float = 0.15
    max_samples: int = 20000
    attempts: int = 3
    seed: int = 0
    tile: int = 1024

    def __post_init__(self) -> None:
        if not 1 <= self.max_themes <= 255:
            raise TerrathemeError(f"max_themes must be 1..255, not {self.max_themes}")
        if self.tile < 16:
            raise TerrathemeError(f"tile must be at least 16 pixels, not {self.tile}")


def feature_weights(options: FeatureOptions) -> np.ndarray:
    """Per-feature weights so each kind of feature counts about once in a distance.

    For the DEFAULT set only the smoothed features count (the unsmoothed
    coarse Lab and block std are noisy on texture, weight 0), each sigma's copy
    weighted ``1 / sqrt(len(sigmas))``, so that two flat colours Delta-E ``d``
    apart are ``d`` apart in feature space.

    Returns
    -------
    weights : (F,) float32 ndarray
    """
    f = options.n_features
    if options.feature_set is not FeatureSet.DEFAULT:
        # Position features (if any) never count: themes are colours, not places.
        return (np.arange(f) < options.n_image_features).astype(np.float32)
    # The unsmoothed coarse-pixel features (Lab, block std) are noisy on texture: weight 0.
    w = np.zeros(f, np.float32)
    start = 3 + (1 if options.scale > 1 else 0)
    w[start : options.n_image_features] = 1.0 / np.sqrt(len(options.sigmas))
    return w


def _valid_coarse(valid: np.ndarray | None, win, scale: int) -> np.ndarray | None:
    if valid is None:
        return None
    block = valid[win.y : win.y1, win.x : win.x1].astype(np.float32)
    h, w = -(-block.shape[0] // scale), -(-block.shape[1] // scale)
    ph, pw = h * scale - block.shape[0], w * scale - block.shape[1]
    block = np.pad(block, ((0, ph), (0, pw)), mode="edge")
    return cv2.resize(block, (w, h), interpolation=cv2.INTER_AREA) > 0.0


def sample_features(
    rgb: np.ndarray, valid: np.ndarray | None, options: UnsupervisedOptions
) -> np.ndarray:
    """Weighted feature vectors of (at most ``max_samples``) coarse pixels.

    Returns
    -------
    samples : (n, F) float32 ndarray
    """
    fo, scale = options.features, options.features.scale
    h, w = rgb.shape[:2]
    n_coarse = (-(-h // scale)) * (-(-w // scale))
    # The smallest stride whose grid keeps to the budget.
    stride = max(1, math.ceil(math.sqrt(n_coarse / options.max_samples)))
    weights = feature_weights(fo)
    wc = -(-w // scale)
    chunks, order = [], []
    for win, _lab, feats in iter_tile_features(rgb, fo, options.tile, fo.halo):
        # Core of the tile in coarse pixels, on a global grid of every stride-th row/column
        # (the same samples whatever the tile size).
        core, rows, cols = strided_core(feats, win, scale, stride)
        keep = _valid_coarse(valid, win, scale)
        if keep is None:
            keep = np.ones(core.shape[:2], bool)
        else:
            ry, rx = (-(win.y // scale)) % stride, (-(win.x // scale)) % stride
            keep = keep[ry::stride, rx::stride]
        chunks.append(core[keep] * weights)
        order.append((rows[:, None] * wc + cols[None, :])[keep])
    samples = np.concatenate(chunks).astype(np.float32)
    if len(samples) == 0:
        # The opaque pixels fall between the sampling grid's rows/columns: take them all.
        return sample_features(rgb, valid, replace(options, max_samples=n_coarse))
    # Row-major order of the photo, so k-means sees the same sequence for any tiling.
    return samples[np.argsort(np.concatenate(order), kind="stable")]


def _kmeans(samples: np.ndarray, k: int, options: UnsupervisedOptions):
    """OpenCV k-means++ -> (mean squared distance, labels (n,), centres (k, F))."""
    cv2.setRNGSeed(options.seed)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
    compact, labels, centres = cv2.kmeans(
        samples, k, None, criteria, options.attempts, cv2.KMEANS_PP_CENTERS
    )
    return compact / len(samples), labels.ravel(), centres


def _min_centre_distance(centres: np.ndarray) -> float:
    d = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
    d[np.diag_indices_from(d)] = np.inf
    return float(d.min())


def colour_columns(options: FeatureOptions) -> np.ndarray:
    """Indices of the (smoothed) Lab colour features in a feature vector."""
    if options.feature_set is FeatureSet.COLOUR:
        return np.arange(3)
    if options.feature_set is FeatureSet.SKIMAGE:
        return np.arange(options.n_image_features)
    start = 3 + (1 if options.scale > 1 else 0)
    per_sigma = 7 if options.hessian else 5
    return np.concatenate([start + per_sigma * i + np.arange(3)
                           for i in range(len(options.sigmas))])


def _has_transition_theme(centres: np.ndarray, labels: np.ndarray, max_share: float,
                          colour: np.ndarray) -> bool:
    """True if a small theme's colour lies near the segment between two other themes' colours.

    Smoothed features blend across a border between two themes; k-means then
    offers the blend band (mixed colour, raised edge and texture features) as
    a theme. Such a theme is recognised by its centre's colour part lying
    within a quarter of the segment's length of the segment joining two other
    centres' colours, and by covering less than ``max_share`` of the photo.
    """
    centres = centres[:, colour]
    k = len(centres)
    shares = np.bincount(labels, minlength=k) / len(labels)
    for c in range(k):
        if shares[c] >= max_share:
            continue
        for a in range(k):
            for b in range(a + 1, k):
                if c in (a, b):
                    continue
                ab = centres[b] - centres[a]
                length2 = float(ab @ ab)
                if length2 == 0.0:
                    continue
                t = float(np.clip((centres[c] - centres[a]) @ ab / length2, 0.0, 1.0))
                dist = float(np.linalg.norm(centres[a] + t * ab - centres[c]))
                if 0.0 < t < 1.0 and dist < 0.25 * np.sqrt(length2):
                    return True
    return False


def _distinct_rows(samples: np.ndarray, enough: int) -> int:
    """``min(number of distinct rows, enough)``; the first column alone often settles it."""
    if len(np.unique(samples[:, 0])) >= enough:
        return enough
    return min(len(np.unique(samples, axis=0)), enough)


def choose_themes(samples: np.ndarray, options: UnsupervisedOptions, themes: str | int = "auto"):
    """Fit k-means with K from the criterion in the module docstring (or fixed K).

    Parameters
    ----------
    samples : (n, F) float32 ndarray
        Weighted features.
    themes : "auto" or int

    Returns
    -------
    centres : (K, F) float32 ndarray, ordered by decreasing cluster size
    sizes : (K,) float64 ndarray, share of samples per theme
    within : float
        Pooled mean squared distance to the nearest centre, ``W_K``.
    """
    wanted = options.max_themes if themes == "auto" else int(themes)
    n_distinct = _distinct_rows(samples, wanted) if len(samples) <= 50000 else len(samples)
    # One theme: the mean.
    w1 = float(((samples - samples.mean(0)) ** 2).sum(1).mean())
    best = (w1, np.zeros(len(samples), np.int32), samples.mean(0, keepdims=True))
    if themes == "auto":
        # Noise floor: a photo whose spread is under half the separation is flat.
        if np.sqrt(w1) >= options.min_separation / 2.0:
            for k in range(2, min(options.max_themes, n_distinct) + 1):
                fit = _kmeans(samples, k, options)
                gain = (best[0] - fit[0]) / w1
                if (
                    gain < options.min_gain
                    or _min_centre_distance(fit[2]) < options.min_separation
                    or _has_transition_theme(fit[2], fit[1], options.transition_share,
                                          colour_columns(options.features))
                ):
                    break
                best = fit
    else:
        k = min(int(themes), n_distinct)
        if k > 1:
            best = _kmeans(samples, k, options)
    within, labels, centres = best
    sizes = np.bincount(labels, minlength=len(centres)) / len(labels)
    order = np.argsort(-sizes, kind="stable")
    return centres[order].astype(np.float32), sizes[order], float(within)


def posterior_fn(centres: np.ndarray, sizes: np.ndarray, within: float,
                  weights: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Gaussian-mixture posterior of each theme for a coarse feature stack."""
    k, f = centres.shape
    # Pooled per-dimension variance, floored at 1 Delta-E^2 so flat themes stay sharp.
    var = max(within / f, 1.0)
    log_prior = np.log(np.maximum(sizes, 1e-6)).astype(np.float32)

    def probs(feats: np.ndarray) -> np.ndarray:
        h, w, _ = feats.shape
        x = feats.reshape(-1, f) * weights
        # Squared distances via |x|^2 - 2 x.c + |c|^2.
        d2 = (x * x).sum(1)[:, None] - 2.0 * x @ centres.T + (centres * centres).sum(1)[None]
        logit = log_prior[None] - np.maximum(d2, 0.0) / (2.0 * var)
        logit -= logit.max(1, keepdims=True)
        p = np.exp(logit)
        p /= p.sum(1, keepdims=True)
        return p.reshape(h, w, k).astype(np.float32)

    return probs
