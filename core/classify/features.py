"""Per-pixel colour and texture features on a downscaled copy of the photo.

The output is a coarse grid of themes, so features are computed on ``scale x scale``
block means (*coarse pixels*), in fixed perceptual units (CIE Lab, L 0..100), not
standardised per photo: the unsupervised criterion needs Delta-E distances so that a
flat photo stays flat (design.md §3). Columns, in order:

``COLOUR``  : Lab (3).
``DEFAULT`` : Lab, block L std (if ``scale > 1``), then per sigma (coarse pixels) the
              smoothed Lab, the local L std ``sqrt(G*L^2 - (G*L)^2)``, the gradient
              magnitude of the smoothed L and (``hessian``) its two Hessian eigenvalues
              times sigma^2; then, if set: fine ridges (``ridge_sigmas``,
              :mod:`core.classify.ridges`), structure (:mod:`core.classify.texture`), and the
              position (2, :mod:`core.classify.position`).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import cv2
import numpy as np
from terratheme.core.classify.lab import block_lab, full_lab
from terratheme.core.classify.position import position_features
from terratheme.core.classify.ridges import block_ridges, hessian_eigenvalues, ridge_halo
from terratheme.core.classify.texture import context_blur, texture_count, texture_features
from terratheme.core.errors import TerrathemeError


class FeatureSet(enum.Enum):
    """Which features describe a coarse pixel."""

    COLOUR = "colour"
    DEFAULT = "default"


@dataclass(frozen=True)
class FeatureOptions:
    """How features are computed (the columns: module docstring): ``scale`` photo pixels per
    coarse pixel, ``sigmas`` Gaussian scales in coarse pixels, ``ridge_sigmas`` fine ridge
    scales in photo pixels (two features each), and the optional groups ``hessian``,
    ``structure``, ``position``.
    """

    feature_set: FeatureSet = FeatureSet.DEFAULT
    scale: int = 8
    sigmas: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)
    hessian: bool = False
    position: bool = False
    ridge_sigmas: tuple[float, ...] = ()
    structure: bool = False

    def __post_init__(self) -> None:
        if int(self.scale) != self.scale or self.scale < 1:
            raise TerrathemeError(f"feature scale must be a whole number >= 1, not {self.scale}")
        if any(s <= 0 for s in (*self.sigmas, *self.ridge_sigmas)):
            raise TerrathemeError(f"feature sigmas must be positive, not {self.sigmas} / "
                                  f"{self.ridge_sigmas}")

    @property
    def n_features(self) -> int:
        """Length F of a feature vector (position features included)."""
        return self.n_image_features + (2 if self.position else 0)

    @property
    def n_image_features(self) -> int:
        """Features computed from the pixels (all but the position)."""
        if self.feature_set is FeatureSet.COLOUR:
            return 3
        per_sigma = 7 if self.hessian else 5
        return (3 + (1 if self.scale > 1 else 0) + per_sigma * len(self.sigmas)
                + 2 * len(self.ridge_sigmas)
                + texture_count(self.sigmas, self.structure))

    @property
    def halo(self) -> int:
        """Coarse pixels of context a feature needs on each side (tile overlap)."""
        if self.feature_set is FeatureSet.COLOUR:
            return 0
        fine = -(-ridge_halo(self.ridge_sigmas) // self.scale)
        return max(_radius(max(self.sigmas, default=0.0)) + 1, fine + 1)


def _radius(sigma: float) -> int:
    return int(math.ceil(3.0 * sigma))


def features_from_lab(
    lab: np.ndarray, block_std: np.ndarray, options: FeatureOptions,
    ridges: np.ndarray | None = None, texture: np.ndarray | None = None,
) -> np.ndarray:
    """Feature stack (h, w, ``n_image_features``) float32 of a coarse Lab image (h, w, 3)
    and its block L std (h, w), all float32. ``ridges`` (:func:`block_ridges`) and
    ``texture`` (:func:`texture_features`) of the same pixels are required when the
    options ask for them.
    """
    if options.feature_set is FeatureSet.COLOUR:
        return np.ascontiguousarray(lab, dtype=np.float32)
    h, w = lab.shape[:2]
    out = np.empty((h, w, options.n_image_features), np.float32)
    out[:, :, :3] = lab
    i = 3
    if options.scale > 1:
        out[:, :, i] = block_std
        i += 1
    lum = np.ascontiguousarray(lab[:, :, 0])
    # Second moment of the photo's lightness per block: block variance + block mean^2.
    lum_sq = block_std * block_std + lum * lum
    for sigma in options.sigmas:
        # Context colour: Lab smoothed at this scale.
        smooth = context_blur(lab, sigma)
        out[:, :, i : i + 3] = smooth
        # Local lightness std of the photo pixels: sqrt(G*L^2 - (G*L)^2).
        mean_sq = context_blur(lum_sq, sigma)
        out[:, :, i + 3] = np.sqrt(np.maximum(mean_sq - smooth[:, :, 0] ** 2, 0.0))
        # Edge strength: gradient magnitude of the smoothed lightness (Sobel, 1/8 normalised).
        gx = cv2.Sobel(smooth[:, :, 0], cv2.CV_32F, 1, 0, ksize=3, scale=0.125,
                       borderType=cv2.BORDER_REFLECT_101)
        gy = cv2.Sobel(smooth[:, :, 0], cv2.CV_32F, 0, 1, ksize=3, scale=0.125,
                       borderType=cv2.BORDER_REFLECT_101)
        out[:, :, i + 4] = cv2.magnitude(gx, gy)
        i += 5
        if options.hessian:
            # Ridges and blobs (roads, buildings): Hessian eigenvalues, scale-normalised by sigma^2.
            s2 = np.float32(sigma * sigma)
            larger, smaller = hessian_eigenvalues(smooth[:, :, 0])
            out[:, :, i] = s2 * larger
            out[:, :, i + 1] = s2 * smaller
            i += 2
    if options.ridge_sigmas:
        if ridges is None or ridges.shape != (h, w, 2 * len(options.ridge_sigmas)):
            raise TerrathemeError("ridge_sigmas needs the block_ridges of the same pixels")
        out[:, :, i : i + ridges.shape[2]] = ridges
        i += ridges.shape[2]
    n_texture = texture_count(options.sigmas, options.structure)
    if n_texture:
        if texture is None or texture.shape != (h, w, n_texture):
            raise TerrathemeError("structure needs the texture_features of the same pixels")
        out[:, :, i : i + n_texture] = texture
    return out


def image_features(rgb: np.ndarray, options: FeatureOptions
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coarse Lab (h, w, 3), block lightness std (h, w) and features without the
    position (h, w, ``n_image_features``), all float32, of photo pixels."""
    full = full_lab(rgb)
    lab, block_std = block_lab(full, options.scale)
    ridges = (block_ridges(full[:, :, 0], options.scale, options.ridge_sigmas)
              if options.ridge_sigmas and options.feature_set is FeatureSet.DEFAULT else None)
    texture = (texture_features(full, lab, options.scale, options.sigmas)
               if options.structure and options.feature_set is FeatureSet.DEFAULT else None)
    return lab, block_std, features_from_lab(lab, block_std, options, ridges, texture)


def with_position(feats: np.ndarray, origin: tuple[int, int], photo_size: tuple[int, int],
                  options: FeatureOptions) -> np.ndarray:
    """Append :func:`position_features` when ``options.position`` (else return ``feats``)."""
    if not options.position:
        return feats
    pos = position_features(feats.shape[:2], origin, photo_size, options.scale)
    return np.concatenate([feats, pos], axis=2)
