"""Unsupervised themes as a reusable model: fit on a sample, predict any tile.

:func:`fit_unsupervised` fits the themes to a photo or to pieces of one too large for
memory; :class:`UnsupervisedModel` then gives a colour the same theme in every tile
(:mod:`core.convert.tiled` relies on it).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from terratheme.core.classify.bands import relabel_bands
from terratheme.core.classify.features import FeatureSet
from terratheme.core.classify.mixture import posterior_fn
from terratheme.core.classify.photo import PreparedPhoto, prepare_photo
from terratheme.core.classify.result import Classification
from terratheme.core.classify.tiled import (
    TileArrays,
    predict_tiled,
    prediction_windows,
    tile_arrays,
)
from terratheme.core.classify.unsupervised import (
    UnsupervisedOptions,
    choose_themes,
    colour_columns,
    feature_weights,
    sample_features,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import TileWindow


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
        Per-theme, per-feature variances of the mixture.
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
        """Photo pixels of context a label needs on each side: a tile read with this overlap,
        starting at a multiple of ``options.features.scale``, gets the whole photo's labels."""
        fo, reg = self.options.features, self.options.regularisation
        return (fo.halo + reg.halo + 1) * fo.scale + self.options.bands.reach

    def pixel_colours(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Each theme's Lab mean and variance (K, 3) over photo pixels, for
        :mod:`core.classify.bands`; None outside the DEFAULT set or without a sigma.

        The mean is the centre's smoothed Lab at the smallest sigma; the variance
        its spread across coarse pixels plus, for L, the squared local lightness std.
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

    def predict(self, photo: np.ndarray | PreparedPhoto,
                progress: Callable[[int, int], None] | None = None,
                tiles: Mapping[TileWindow, TileArrays] | None = None) -> Classification:
        """Themes 1..K of a (H, W, 3|4) uint8/uint16 photo or tile (0 where transparent).

        Confidence is the mixture posterior (a pixel relabelled in a border band keeps
        it); ``progress(done, total)`` is called over the tiles; ``tiles``: the
        :func:`.tiled.tile_arrays` of every :func:`.tiled.prediction_windows` window,
        when already computed.
        """
        rgb, valid = prepare_photo(photo)
        opts = self.options
        fn = posterior_fn(self.centres, self.sizes, self.variances, feature_weights(opts.features))
        tile_fn = None
        if tiles is not None:
            def tile_fn(win: TileWindow) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                lab, block_std, feats = tiles[win]
                return lab, block_std, fn(feats)
        result = predict_tiled(rgb, valid, fn, self.classes, opts.features,
                               opts.regularisation, opts.tile, progress, tile_fn)
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
    sample_photo: np.ndarray | PreparedPhoto | Sequence[np.ndarray],
    *,
    themes: str | int = "auto",
    options: UnsupervisedOptions | None = None,
    tiles: Mapping[TileWindow, TileArrays] | None = None,
) -> UnsupervisedModel:
    """Fit themes to a (H, W, 3|4) photo, or to full-resolution pieces of one too large
    for memory (they share ``options.max_samples`` by area; no context across pieces).

    ``themes``: "auto" (K by the criterion of :mod:`core.classify.unsupervised`) or
    at most that many; ``tiles``: a single photo's features as for
    :meth:`UnsupervisedModel.predict`. ``TerrathemeError`` for bad ``themes``, no piece,
    or a piece that is not a photo.
    """
    opts = options or UnsupervisedOptions()
    _check_themes(themes)
    single = isinstance(sample_photo, np.ndarray | PreparedPhoto)
    pieces = [sample_photo] if single else list(sample_photo)
    if not pieces:
        raise TerrathemeError("fit_unsupervised needs a photo or at least one piece of one")
    if tiles is not None and not single:
        raise TerrathemeError("fit_unsupervised takes tile features of a single photo only")
    prepared = [prepare_photo(p) for p in pieces]
    total = sum(rgb.shape[0] * rgb.shape[1] for rgb, _ in prepared)
    # Sample each piece's features, the budget shared by area, then fit k-means with K.
    given = None if tiles is None else [(win, feats) for win, (_, _, feats) in tiles.items()]
    chunks = []
    for rgb, valid in prepared:
        share = rgb.shape[0] * rgb.shape[1] / total
        budget = max(1, int(round(opts.max_samples * share)))
        chunks.append(sample_features(rgb, valid, replace(opts, max_samples=budget), given))
    samples = np.concatenate(chunks).astype(np.float32)
    centres, sizes, variances = choose_themes(samples, opts, themes)
    return UnsupervisedModel(centres, sizes, variances, opts)


def classify_unsupervised(
    photo: np.ndarray | PreparedPhoto,
    *,
    themes: str | int = "auto",
    options: UnsupervisedOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Classification:
    """Themes of a photo without training data: :func:`fit_unsupervised`, then
    :meth:`UnsupervisedModel.predict` (1 = largest theme), the photo prepared and its
    features computed once for both."""
    _check_themes(themes)
    opts = options or UnsupervisedOptions()
    prepared = prepare_photo(photo)
    rgb, fo = prepared.rgb, opts.features
    windows = prediction_windows(*rgb.shape[:2], fo, opts.regularisation, opts.tile)
    tiles = {win: tile_arrays(rgb, win, fo) for win in windows}
    model = fit_unsupervised(prepared, themes=themes, options=opts, tiles=tiles)
    return model.predict(prepared, progress, tiles)
