"""Unsupervised themes: k-means on colour + texture, K chosen from the data (design.md §3).

With ``W_K`` the mean squared distance of the weighted samples (Delta-E-like units,
:mod:`core.classify.features`) to the nearest of K OpenCV k-means++ centres:

1. a photo with ``sqrt(W_1) < min_separation / 2`` is flat: K = 1;
2. else K grows while ``(W_{K-1} - W_K) / W_1 >= min_gain``, the two closest centres
   stay ``min_separation`` apart, and no theme under ``transition_share`` of the photo
   lies between two others (a border blend of smoothed features, not a theme);
3. a theme whose samples form two chroma groups at least ``min_hue_separation`` apart
   (the smaller over ``min_hue_share``) is split if the split passes 2's tests: the
   variance gain misses a small region of another hue in a textured theme;
4. K never exceeds ``max_themes`` nor the number of distinct samples.

Themes are numbered 1..K by decreasing area; confidence is the winning theme's
posterior in a Gaussian mixture (:mod:`core.classify.mixture`). Fitting a reusable
model and classifying with it: :mod:`core.classify.unsupervised_model`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from terratheme.core.classify.bands import BandOptions, lies_between
from terratheme.core.classify.features import FeatureOptions, FeatureSet
from terratheme.core.classify.mixture import fit_diagonal_mixture, isotropic_variances
from terratheme.core.classify.regularise import RegulariseOptions
from terratheme.core.classify.tiled import iter_tile_features, sampling_stride, strided_pixels
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import TileWindow


@dataclass(frozen=True)
class UnsupervisedOptions:
    """Options of :func:`classify_unsupervised`.

    ``features``: 4x4 coarse pixels, one smoothing sigma of 1 (larger scales blur class
    borders into bands that k-means would take for themes); ``bands``: border bands
    relabelled by pixel colour (DEFAULT feature set only); ``max_themes`` ... ``min_hue_share``:
    the criteria of the module docstring (``min_hue_separation=inf``: no split by hue);
    ``max_samples``, ``attempts``, ``seed``: coarse pixels sampled, k-means restarts, RNG seed;
    ``tile``: tile core size in photo pixels.
    """

    features: FeatureOptions = field(
        default_factory=lambda: FeatureOptions(scale=4, sigmas=(1.0,), hessian=False)
    )
    regularisation: RegulariseOptions = field(default_factory=RegulariseOptions)
    bands: BandOptions = field(default_factory=BandOptions)
    max_themes: int = 8
    min_gain: float = 0.03
    min_separation: float = 6.0
    transition_share: float = 0.15
    min_hue_separation: float = 8.0
    min_hue_share: float = 0.02
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
    """Per-feature weights (F,) float32: each sigma's smoothed features weigh
    ``1 / sqrt(len(sigmas))``, so two flat colours Delta-E ``d`` apart are ``d`` apart."""
    f = options.n_features
    if options.feature_set is not FeatureSet.DEFAULT:
        # Position features (if any) never count: themes are colours, not places.
        return (np.arange(f) < options.n_image_features).astype(np.float32)
    # The unsmoothed coarse-pixel features (Lab, block std) are noisy on texture: weight 0.
    w = np.zeros(f, np.float32)
    start = 3 + (1 if options.scale > 1 else 0)
    w[start : options.n_image_features] = 1.0 / np.sqrt(len(options.sigmas))
    return w


def window_samples(feats: np.ndarray, win, valid: np.ndarray | None, width: int,
                   stride: int, options: UnsupervisedOptions) -> tuple[np.ndarray, np.ndarray]:
    """One window's weighted samples (:func:`.tiled.strided_pixels`) and their photo-wide
    row-major coarse index: any tiling gives the whole photo's samples."""
    scale = options.features.scale
    iy, ix, rows, cols = strided_pixels(win, scale, stride, valid)
    return feats[iy, ix] * feature_weights(options.features), rows * (-(-width // scale)) + cols


def sample_features(
    rgb: np.ndarray, valid: np.ndarray | None, options: UnsupervisedOptions,
    tiles: Sequence[tuple[TileWindow, np.ndarray]] | None = None,
) -> np.ndarray:
    """Weighted feature vectors (n, F) float32 of at most ``max_samples`` coarse pixels.

    ``tiles``: ``(window, features)`` of a tiling already computed (halo at least
    ``options.features.halo``), else the features are computed here.
    """
    fo = options.features
    h, w = rgb.shape[:2]

    def each_tile() -> Iterable[tuple[TileWindow, np.ndarray]]:
        if tiles is not None:
            return tiles
        return ((win, feats) for win, _lab, feats in
                iter_tile_features(rgb, fo, options.tile, fo.halo))

    # The opaque pixels may fall between the sampling grid's rows/columns: then take them all.
    for stride in (sampling_stride(h, w, fo.scale, options.max_samples), 1):
        chunks, order = [], []
        for win, feats in each_tile():
            part = None if valid is None else valid[win.y : win.y1, win.x : win.x1]
            got, where = window_samples(feats, win, part, w, stride, options)
            chunks.append(got)
            order.append(where)
        samples = np.concatenate(chunks).astype(np.float32)
        if len(samples):
            break
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
    start = 3 + (1 if options.scale > 1 else 0)
    per_sigma = 7 if options.hessian else 5
    return np.concatenate([start + per_sigma * i + np.arange(3)
                           for i in range(len(options.sigmas))])


def _has_transition_theme(centres: np.ndarray, labels: np.ndarray, max_share: float,
                          *columns: np.ndarray) -> bool:
    """True if a theme under ``max_share`` of the photo lies between two others
    (:func:`lies_between`) in each set of ``columns``: the blend band smoothed
    features make along a border, not a theme of the scene."""
    shares = np.bincount(labels, minlength=len(centres)) / len(labels)
    return any(shares[c] < max_share and all(lies_between(centres[:, cols], c)
                                             for cols in columns)
               for c in range(len(centres)))


def _rejects(fit, options: UnsupervisedOptions) -> bool:
    """True if a fit's themes fail the separation or the transition test (criterion 2)."""
    return (_min_centre_distance(fit[2]) < options.min_separation
            or _has_transition_theme(fit[2], fit[1], options.transition_share,
                                     colour_columns(options.features)))


def _hue_split(samples: np.ndarray, labels: np.ndarray, options: UnsupervisedOptions):
    """The themes with one split by chroma (criterion 3), or None if no split qualifies.

    Each theme's samples are split by 2-means on smoothed a*b*; from the largest chroma
    gap down, a split seeds a diagonal Gaussian mixture of K + 1 themes, kept if the
    new theme still passes the share, chroma and separation tests, its chroma is not
    between two others' and no small theme is a blend in both Lab and a*b*.

    Returns
    -------
    None or (labels (n,), centres (K+1, F), sizes (K+1,), variances (K+1, F))
    """
    k, n = int(labels.max()) + 1, len(samples)
    colour = colour_columns(options.features)
    chroma = colour[1:3]
    candidates = []
    for c in range(k):
        members = np.flatnonzero(labels == c)
        if len(members) < max(2.0, 2 * options.min_hue_share * n):
            continue
        # Two chroma groups of the theme's samples; the smaller one may become a theme.
        _, groups, means = _kmeans(np.ascontiguousarray(samples[members][:, chroma]), 2,
                                   options)
        smaller = int(np.count_nonzero(groups) * 2 < len(groups))
        separation = float(np.linalg.norm(means[0] - means[1]))
        if (separation >= options.min_hue_separation
                and np.count_nonzero(groups == smaller) >= options.min_hue_share * n):
            candidates.append((separation, c, members[groups == smaller]))
    # The splits from the largest chroma distance down: the first that holds.
    for _, c, group in sorted(candidates, key=lambda cand: -cand[0]):
        start = labels.astype(np.int64).copy()
        start[group] = k
        split = fit_diagonal_mixture(samples, start)
        split_labels, centres = split[0], split[1]
        hue_gap = float(np.linalg.norm(centres[k, chroma] - centres[c, chroma]))
        if (np.count_nonzero(split_labels == k) >= options.min_hue_share * n
                and hue_gap >= options.min_hue_separation
                and _min_centre_distance(centres) >= options.min_separation
                and not lies_between(centres[:, chroma], k)
                and not _has_transition_theme(centres, split_labels, options.transition_share,
                                              colour, chroma)):
            return split
    return None


def _distinct_rows(samples: np.ndarray, enough: int) -> int:
    """``min(number of distinct rows, enough)``; the first column alone often settles it."""
    if len(np.unique(samples[:, 0])) >= enough:
        return enough
    return min(len(np.unique(samples, axis=0)), enough)


def choose_themes(samples: np.ndarray, options: UnsupervisedOptions, themes: str | int = "auto"):
    """Fit k-means with K from the criterion in the module docstring (or fixed K).

    Returns, from weighted ``samples`` (n, F) float32, by decreasing size: ``centres``
    (K, F) float32, ``sizes`` (K,) float64 sample shares and ``variances`` (K, F)
    float32 (the pooled k-means spread, or the mixture's after a split by hue).
    """
    wanted = options.max_themes if themes == "auto" else int(themes)
    n_distinct = _distinct_rows(samples, wanted) if len(samples) <= 50000 else len(samples)
    # One theme: the mean.
    w1 = float(((samples - samples.mean(0)) ** 2).sum(1).mean())
    best = (w1, np.zeros(len(samples), np.int32), samples.mean(0, keepdims=True))
    # Noise floor: a photo whose spread is under half the separation is flat.
    grows = themes == "auto" and np.sqrt(w1) >= options.min_separation / 2.0
    if grows:
        for k in range(2, min(options.max_themes, n_distinct) + 1):
            fit = _kmeans(samples, k, options)
            gain = (best[0] - fit[0]) / w1
            if gain < options.min_gain or _rejects(fit, options):
                break
            best = fit
    elif themes != "auto":
        k = min(int(themes), n_distinct)
        if k > 1:
            best = _kmeans(samples, k, options)
    within, labels, centres = best
    sizes = np.bincount(labels, minlength=len(centres)) / len(labels)
    variances = isotropic_variances(within, centres)
    if grows:
        # Themes of another hue inside a theme (criterion 3).
        while len(centres) < min(options.max_themes, n_distinct):
            split = _hue_split(samples, labels, options)
            if split is None:
                break
            labels, centres, sizes, variances = split
    order = np.argsort(-sizes, kind="stable")
    return centres[order].astype(np.float32), sizes[order], variances[order]
