"""Unsupervised themes as a reusable model: fit on a sample, predict any tile.

:func:`fit_unsupervised` samples features of a photo -- or of several pieces
of one photo too large for memory -- and fits k-means with K chosen by the
criterion of :mod:`core.classify.unsupervised`. The resulting
:class:`UnsupervisedModel` classifies any photo or tile with the same centres,
so a colour gets the same theme number in every tile (the tiled converter,
:mod:`core.convert.tiled`, relies on it). :func:`classify_unsupervised` is
fit-then-predict on one photo.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from terratheme.core.classify.bands import relabel_bands
from terratheme.core.classify.features import FeatureSet
from terratheme.core.classify.mixture import posterior_fn
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.classify.result import Classification
from terratheme.core.classify.tiled import predict_tiled
from terratheme.core.classify.unsupervised import (
    UnsupervisedOptions,
    choose_themes,
    colour_columns,
    feature_weights,
    sample_features,
)
from terratheme.core.errors import TerrathemeError


@dataclass(frozen=True)
class UnsupervisedModel:
    """k-means themes fitted to a sample, applicable to any photo or tile.

    Attributes
    ----------
    centres : (K, F) float32 ndarray
        Theme centres in weighted feature space, theme 1 first (largest).
    sizes : (K,) float64 ndarray
        Share of the sample in each theme (the mixture weights).
    variances : (K, F) float32 ndarray
        Per-theme, per-feature variances of the mixture
        (:func:`core.classify.unsupervised.choose_themes`).
    options : UnsupervisedOptions
    """

    centres: np.ndarray
    sizes: np.ndarray
    variances: np.ndarray
    options: UnsupervisedOptions

    @property
    def classes(self) -> tuple[int, ...]:
        """Theme values ``1..K``."""
        return tuple(range(1, len(self.centres) + 1))

    @property
    def context_pixels(self) -> int:
        """Photo pixels of context a label needs on each side.

        A tile read with at least this overlap, starting at a multiple of
        ``options.features.scale``, gets the labels of the whole photo there.
        """
        fo, reg = self.options.features, self.options.regularisation
        return (fo.halo + reg.halo + 1) * fo.scale + self.options.bands.reach

    def pixel_colours(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Each theme's Lab mean and variance over photo pixels, for :mod:`core.classify.bands`.

        The mean is the centre's smoothed Lab at the smallest sigma; the
        variance its spread across the theme's coarse pixels plus, for the
        lightness, the squared local lightness std of the centre (the spread
        of photo pixels around a smoothed value).

        Returns
        -------
        None (feature sets other than DEFAULT, or no sigma), or
        means, variances : (K, 3) float64 ndarrays
        """
        fo = self.options.features
        if fo.feature_set is not FeatureSet.DEFAULT or not fo.sigmas:
            return None
        weights = feature_weights(fo).astype(np.float64)
        cols = colour_columns(fo)[:3]
        means = self.centres[:, cols] / weights[cols]
        variances = self.variances[:, cols] / weights[cols] ** 2
        local_std = self.centres[:, cols[0] + 3] / weights[cols[0] + 3]
        variances[:, 0] += local_std * local_std
        return means, variances

    def predict(self, photo: np.ndarray,
                progress: Callable[[int, int], None] | None = None) -> Classification:
        """Classify a photo or a tile of one with the fitted themes.

        Parameters
        ----------
        photo : (H, W, 3) or (H, W, 4) uint8/uint16 ndarray
            Transparent pixels (alpha 0) get label 0.
        progress : callable, optional
            ``(done, total)`` over the prediction tiles.

        Returns
        -------
        Classification
            labels (H, W) uint8 in 1..K, confidence (H, W) float32 (the
            mixture posterior, module docstring of ``unsupervised``; a pixel
            relabelled in a border band, :mod:`core.classify.bands`, keeps
            its posterior's confidence).
        """
        rgb, valid = prepare_photo(photo)
        opts = self.options
        fn = posterior_fn(self.centres, self.sizes, self.variances, feature_weights(opts.features))
        result = predict_tiled(rgb, valid, fn, self.classes, opts.features,
                               opts.regularisation, opts.tile, progress)
        colours = self.pixel_colours()
        if colours is None or opts.bands.reach == 0:
            return result
        # Border bands of a blend theme: each pixel's own colour decides (module bands).
        labels = relabel_bands(result.labels, rgb, *colours, opts.bands)
        return replace(result, labels=labels)


def _check_themes(themes) -> None:
    if themes == "auto":
        return
    if isinstance(themes, bool) or not isinstance(themes, int | np.integer) or not (
        1 <= int(themes) <= 255
    ):
        raise TerrathemeError(f"themes must be 'auto' or a number 1..255, not {themes!r}")


def fit_unsupervised(
    sample_photo: np.ndarray | Sequence[np.ndarray],
    *,
    themes: str | int = "auto",
    options: UnsupervisedOptions | None = None,
) -> UnsupervisedModel:
    """Fit k-means themes to a photo, or to pieces of a photo too large for memory.

    Parameters
    ----------
    sample_photo : (H, W, 3|4) uint8/uint16 ndarray, or a sequence of them
        The photo, or windows of it read at full resolution (e.g. spread
        over a big photo). Pieces share the sample budget
        (``options.max_samples``) in proportion to their area; each piece's
        features see only that piece (no context across pieces).
    themes : "auto" or int
        "auto": K from the data (criterion of
        :mod:`core.classify.unsupervised`); an int: that many themes (fewer
        if the sample has fewer distinct pixels).
    options : UnsupervisedOptions, optional

    Returns
    -------
    UnsupervisedModel

    Raises
    ------
    TerrathemeError
        Bad ``themes``, no pieces, or a piece that is not a photo.
    """
    opts = options or UnsupervisedOptions()
    _check_themes(themes)
    pieces = [sample_photo] if isinstance(sample_photo, np.ndarray) else list(sample_photo)
    if not pieces:
        raise TerrathemeError("fit_unsupervised needs a photo or at least one piece of one")
    prepared = [prepare_photo(p) for p in pieces]
    total = sum(rgb.shape[0] * rgb.shape[1] for rgb, _ in prepared)
    # Sample each piece's features, the budget shared by area, then fit k-means with K.
    chunks = []
    for rgb, valid in prepared:
        share = rgb.shape[0] * rgb.shape[1] / total
        budget = max(1, int(round(opts.max_samples * share)))
        chunks.append(sample_features(rgb, valid, replace(opts, max_samples=budget)))
    samples = np.concatenate(chunks).astype(np.float32)
    centres, sizes, variances = choose_themes(samples, opts, themes)
    return UnsupervisedModel(centres, sizes, variances, opts)


def classify_unsupervised(
    photo: np.ndarray,
    *,
    themes: str | int = "auto",
    options: UnsupervisedOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Classification:
    """Split a photo into themes without training data.

    Parameters
    ----------
    photo : (H, W, 3) or (H, W, 4) uint8/uint16 ndarray
        Transparent pixels (alpha 0) get label 0.
    themes : "auto" or int
        "auto": K from the data (module docstring of ``unsupervised``); an
        int: that many themes (fewer if the photo has fewer distinct pixels).
    options : UnsupervisedOptions, optional
    progress : callable, optional
        ``(done, total)`` over the prediction tiles.

    Returns
    -------
    Classification
        labels (H, W) uint8 in 1..K (1 = largest theme), confidence (H, W) float32.
    """
    _check_themes(themes)
    # Fit on the whole photo, then predict every pixel tile by tile.
    return fit_unsupervised(photo, themes=themes, options=options).predict(photo, progress)
