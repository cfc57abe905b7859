"""Tile-by-tile prediction with overlap: memory bounded by the tile, no seams.

Each ``tile x tile`` core is read with a halo as wide as the features and the
regularisation reach, so results equal the whole photo's. Coarse probabilities are
upsampled bilinearly (coarse centre ``i`` at photo ``(i + 0.5) * scale - 0.5``); the
arg-max gives the label.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import cv2
import numba
import numpy as np
from terratheme.core.classify.features import FeatureOptions, image_features, with_position
from terratheme.core.classify.regularise import RegulariseOptions, regularise
from terratheme.core.classify.result import Classification
from terratheme.core.classify.texture import CV_MAX_CHANNELS, block_mean
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import TileWindow, tile_windows

ProgressFn = Callable[[int, int], None]
#: maps a coarse feature stack (h, w, F) float32 to class probabilities (h, w, C) float32
ProbabilityFn = Callable[[np.ndarray], np.ndarray]
#: a window's coarse Lab (h, w, 3), block lightness std (h, w) and features (h, w, F)
TileArrays = tuple[np.ndarray, np.ndarray, np.ndarray]
#: a window's coarse Lab (h, w, 3), block lightness std (h, w) and class probabilities (h, w, C)
TileProbabilitiesFn = Callable[[TileWindow], tuple[np.ndarray, np.ndarray, np.ndarray]]


def feature_windows(height: int, width: int, tile: int, scale: int,
                    halo: int) -> list[TileWindow]:
    """Row-major tiles: cores of whole coarse pixels, ``halo`` coarse pixels of overlap."""
    return tile_windows(width, height, max(scale, (tile // scale) * scale), halo * scale)


def prediction_windows(height: int, width: int, features: FeatureOptions,
                       regularisation: RegulariseOptions, tile: int) -> list[TileWindow]:
    """The tiles :func:`predict_tiled` cuts a photo into: the overlap covers the features'
    and the regularisation's reach, plus one coarse pixel for the upsampling."""
    halo = features.halo + regularisation.halo + 1
    return feature_windows(height, width, tile, features.scale, halo)


def tile_arrays(rgb: np.ndarray, win: TileWindow, options: FeatureOptions) -> TileArrays:
    """Coarse Lab (h, w, 3), block lightness std (h, w) and features (h, w, F), all
    float32, of a window's outer rectangle."""
    lab, block_std, feats = image_features(rgb[win.ry : win.ry1, win.rx : win.rx1], options)
    return lab, block_std, with_position(feats, (win.ry, win.rx), rgb.shape[:2], options)


def iter_tile_features(
    rgb: np.ndarray, options: FeatureOptions, tile: int, halo: int
) -> Iterator[tuple[TileWindow, np.ndarray, np.ndarray]]:
    """Yield ``(window, lab, features)`` for every tile of a photo."""
    for win in feature_windows(rgb.shape[0], rgb.shape[1], tile, options.scale, halo):
        lab, _block_std, feats = tile_arrays(rgb, win, options)
        yield win, lab, feats


def sampling_stride(height: int, width: int, scale: int, max_samples: int) -> int:
    """The smallest stride (coarse pixels) whose photo-wide grid keeps to ``max_samples``."""
    n_coarse = (-(-height // scale)) * (-(-width // scale))
    return max(1, math.ceil(math.sqrt(n_coarse / max_samples)))


def strided_pixels(
    win: TileWindow, scale: int, stride: int, valid: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A tile's core coarse pixels on the photo-wide grid of every ``stride``-th row and
    column, those with data (any pixel of ``valid`` (win.h, win.w), or all if None).

    Returns ``(iy, ix)`` (n,) int64 into the read window's coarse arrays and ``(rows, cols)``
    photo-wide: the same samples whatever the tiling.
    """
    gy0, gx0 = win.y // scale, win.x // scale
    ch, cw = -(-(win.y1 - win.y) // scale), -(-(win.x1 - win.x) // scale)
    iy, ix = np.meshgrid(np.arange((-gy0) % stride, ch, stride, dtype=np.int64),
                         np.arange((-gx0) % stride, cw, stride, dtype=np.int64), indexing="ij")
    if valid is None:
        iy, ix = iy.ravel(), ix.ravel()
    else:
        keep = (block_mean(valid.astype(np.float32), scale) > 0.0)[iy, ix]
        iy, ix = iy[keep], ix[keep]
    cy, cx = gy0 - win.ry // scale, gx0 - win.rx // scale
    return cy + iy, cx + ix, gy0 + iy, gx0 + ix


def _upsampled(probs: np.ndarray, win: TileWindow, scale: int) -> tuple[np.ndarray, int, int]:
    """A window's coarse probabilities (h, w, C) float32 bilinearly upsampled to
    (h * scale, w * scale, C), C-contiguous, and the row, column ``oy, ox`` where the
    core starts in it."""
    offsets = win.y - win.ry, win.x - win.rx
    if scale == 1:
        return np.ascontiguousarray(probs), *offsets
    h, w, c = probs.shape
    size = (w * scale, h * scale)
    if c <= CV_MAX_CHANNELS:
        up = cv2.resize(probs, size, interpolation=cv2.INTER_LINEAR)
        return up.reshape(h * scale, w * scale, c), *offsets
    # cv2.resize takes at most CV_MAX_CHANNELS channels at once: more classes go in parts.
    up = np.empty((h * scale, w * scale, c), np.float32)
    for k in range(0, c, CV_MAX_CHANNELS):
        part = np.ascontiguousarray(probs[:, :, k : k + CV_MAX_CHANNELS])
        up[:, :, k : k + CV_MAX_CHANNELS] = cv2.resize(
            part, size, interpolation=cv2.INTER_LINEAR).reshape(h * scale, w * scale, -1)
    return up, *offsets


def predict_tiled(
    rgb: np.ndarray,
    valid: np.ndarray | None,
    probability_fn: ProbabilityFn,
    classes: tuple[int, ...],
    features: FeatureOptions,
    regularisation: RegulariseOptions,
    tile: int,
    progress: ProgressFn | None = None,
    tile_fn: TileProbabilitiesFn | None = None,
) -> Classification:
    """Classify a (H, W, 3) uint8 photo tile by tile (``tile``: core size in photo pixels).

    ``valid`` (H, W) bool: pixels with data, others get label 0 and confidence 0;
    ``classes``: class value of each channel of ``probability_fn``'s output;
    ``tile_fn(window) -> (lab, block_std, probabilities)`` replaces :func:`tile_arrays`
    and ``probability_fn`` (probabilities made from an earlier pass's).
    """
    if len(classes) == 0:
        raise TerrathemeError("a classifier needs at least one class")
    height, width = rgb.shape[:2]
    scale = features.scale
    windows = prediction_windows(height, width, features, regularisation, tile)
    if tile_fn is None:
        def tile_fn(win: TileWindow) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            lab, block_std, feats = tile_arrays(rgb, win, features)
            return lab, block_std, probability_fn(feats)
    lut = np.asarray(classes, np.uint8)
    labels = np.zeros((height, width), np.uint8)
    confidence = np.zeros((height, width), np.float32)
    for done, win in enumerate(windows, 1):
        # Features over the tile and its halo, then per-coarse-pixel probabilities.
        lab, block_std, probs = tile_fn(win)
        probs = probs.astype(np.float32, copy=False)
        # Spatial regularisation on the coarse grid.
        probs = regularise(probs, lab, regularisation, texture=block_std)
        # Back to photo pixels: arg-max class and its probability.
        # The whole arrays and offsets, not views: every photo size calls the kernel with
        # the same C-contiguous types, the one signature the warm-up compiles.
        up, oy, ox = _upsampled(probs, win, scale)
        _arg_max(up, oy, ox, lut, labels, confidence, win.y, win.x, win.y1 - win.y,
                 win.x1 - win.x)
        if progress is not None:
            progress(done, len(windows))
    np.clip(confidence, 0.0, 1.0, out=confidence)
    if valid is not None:
        labels[~valid] = 0
        confidence[~valid] = 0.0
    return Classification(labels=labels, confidence=confidence, classes=tuple(classes))


@numba.njit(cache=True, nogil=True, parallel=True)
def _arg_max(probs, oy, ox, lut, labels, confidence, y0, x0, h, w):  # pragma: no cover
    """Over an ``h x w`` block: ``labels[y0 + y, x0 + x] = lut[argmax(probs[oy + y, ox + x])]``
    (first of equal maxima, as numpy's ``argmax``) and ``confidence`` = that maximum; rows
    in parallel."""
    c = probs.shape[2]
    for y in numba.prange(h):
        for x in range(w):
            best, top = 0, probs[oy + y, ox + x, 0]
            for k in range(1, c):
                if probs[oy + y, ox + x, k] > top:
                    best, top = k, probs[oy + y, ox + x, k]
            labels[y0 + y, x0 + x] = lut[best]
            confidence[y0 + y, x0 + x] = top
