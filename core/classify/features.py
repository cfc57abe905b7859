"""Per-pixel colour and texture features on a downscaled copy of the photo.

The product's output is a coarse grid of themes, so features are computed on
the photo area-averaged by ``scale`` (each *coarse pixel* is a ``scale x
scale`` block of photo pixels) instead of on every photo pixel: 64x fewer
samples at the default ``scale=8`` (the benchmark found no accuracy loss
against ``scale=4`` and 2.6x the speed), and the detail lost inside a block is
kept as one feature, the block's standard deviation of lightness.

Units are perceptual and fixed (CIE Lab, L in 0..100, a/b about -128..127),
not standardised per photo: the unsupervised criterion relies on distances
being in Delta-E units, so that a flat photo stays flat (design.md §3).

Feature sets
------------
``COLOUR``  : Lab of the coarse pixel (3 features).
``DEFAULT`` : Lab, block lightness std, and for each sigma in ``sigmas``
              (coarse pixels) the Gaussian-smoothed Lab (context), the local
              lightness std of the photo pixels ``sqrt(G*L^2 - (G*L)^2)``
              (L^2 from the block variance plus the squared block mean) and the gradient magnitude
              of the smoothed lightness, and (``hessian``) the two Hessian
              eigenvalues of the smoothed lightness times sigma^2
              (3 + 1 + 7 * len(sigmas) features), all with OpenCV filters.
``SKIMAGE`` : scikit-image ``multiscale_basic_features`` (intensity, edges,
              Hessian texture) on each Lab channel: the ilastik recipe.

Optional relative lightness (``relative``, DEFAULT set): the coarse pixel's
lightness and its smoothed lightness at every sigma but the largest, over the
smoothed lightness at the largest sigma (+ ``RELATIVE_FLOOR``): darker or
brighter than the surroundings, whatever the photo's exposure (``len(sigmas)``
features after the ridges; measured in SupervisedOptions).

Optional structure features (``structure``, on in the supervised default):
edge density per block and the structure-tensor coherence at every sigma,
:mod:`core.classify.texture` (``1 + len(sigmas)`` features after the relative ones), then
the optional morphological profile (``profile_radii``, off; :mod:`core.classify.profiles`).

Optional position features (``position``): the coarse pixel's centre as a
fraction of the photo's height and width (2 features, appended last). Only
for a model fitted to the one photo it classifies (scribbles): there, where
a class was painted is evidence (benchmark: scribble mIoU +0.02); on another
photo it means nothing.

Optional per-photo colour normalisation (``Normalise``) maps the photo's Lab
mean/spread to a fixed reference first (Reinhard et al. 2001 colour
transfer); it uses whole-photo statistics, so it is off by default (the
benchmark found no gain across Dubai tiles).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import cv2
import numpy as np
from terratheme.core.classify.lab import block_lab, coarse_lab, full_lab
from terratheme.core.classify.position import position_features
from terratheme.core.classify.profiles import profile_count, profile_halo, reconstruction_profile
from terratheme.core.classify.ridges import block_ridges, hessian_eigenvalues, ridge_halo
from terratheme.core.classify.texture import context_blur, texture_count, texture_features
from terratheme.core.errors import TerrathemeError


class FeatureSet(enum.Enum):
    """Which features describe a coarse pixel."""

    COLOUR = "colour"
    DEFAULT = "default"
    SKIMAGE = "skimage"


class Normalise(enum.Enum):
    """Per-photo colour normalisation before the features (for photos of other dates)."""

    NONE = "none"
    LIGHTNESS = "lightness"  # L to a fixed mean and spread; a, b untouched
    LAB = "lab"              # L, a and b each to a fixed mean and spread


#: Lab mean and spread a normalised photo is mapped to (a typical orthophoto).
REFERENCE_MEAN = np.array([50.0, 0.0, 8.0], np.float32)
REFERENCE_STD = np.array([18.0, 6.0, 10.0], np.float32)
#: relative lightness: added to the context lightness (L units) so dark context stays finite
RELATIVE_FLOOR = 5.0
@dataclass(frozen=True)
class FeatureOptions:
    """How features are computed.

    Attributes
    ----------
    feature_set : FeatureSet
    normalise : Normalise
        Map each photo's Lab statistics (:func:`photo_statistics`) to a fixed
        reference before computing features.
    scale : int
        Photo pixels per coarse pixel along each axis (1 = every pixel).
    sigmas : tuple of float
        Gaussian scales in coarse pixels for the DEFAULT set.
    skimage_sigma_max : float
        Largest scale (coarse pixels) for the SKIMAGE set (smallest is 1).
    hessian : bool
        DEFAULT set: add the two Hessian eigenvalues of the smoothed lightness
        at each sigma (ridges, blobs).
    position : bool
        Append the coarse pixel's position in the photo (row and column as
        fractions of the photo's height and width); see the module docstring.
    ridge_sigmas : tuple of float
        DEFAULT set: add fine ridge features at these scales in photo pixels
        (:mod:`core.classify.ridges`, two per sigma), computed before the block
        average. Default () here; the supervised default uses (1, 2, 4).
    relative : bool
        DEFAULT set: add the lightness relative to the context (module
        docstring), ``len(sigmas)`` features after the ridges.
    structure : bool
        DEFAULT set: add edge density and structure-tensor coherence
        (:mod:`core.classify.texture`, ``1 + len(sigmas)`` features).
    profile_radii : tuple of int
        DEFAULT set: add the morphological profile by reconstruction at these
        disk radii in coarse pixels (:mod:`core.classify.profiles`, two per
        radius), last before the position.
    """

    feature_set: FeatureSet = FeatureSet.DEFAULT
    normalise: Normalise = Normalise.NONE
    scale: int = 8
    sigmas: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)
    skimage_sigma_max: float = 16.0
    hessian: bool = False
    position: bool = False
    ridge_sigmas: tuple[float, ...] = ()
    relative: bool = False
    structure: bool = False
    profile_radii: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if int(self.scale) != self.scale or self.scale < 1:
            raise TerrathemeError(f"feature scale must be a whole number >= 1, not {self.scale}")
        if any(s <= 0 for s in (*self.sigmas, *self.ridge_sigmas)):
            raise TerrathemeError(f"feature sigmas must be positive, not {self.sigmas} / "
                                  f"{self.ridge_sigmas}")
        if self.relative and not self.sigmas:
            raise TerrathemeError("relative lightness needs at least one sigma (its context)")
        if any(int(r) != r or r < 1 for r in self.profile_radii):
            raise TerrathemeError(f"profile radii must be whole numbers >= 1, not "
                                  f"{self.profile_radii}")

    @property
    def n_features(self) -> int:
        """Length F of a feature vector (position features included)."""
        return self.n_image_features + (2 if self.position else 0)

    @property
    def n_image_features(self) -> int:
        """Features computed from the pixels (all but the position)."""
        if self.feature_set is FeatureSet.COLOUR:
            return 3
        if self.feature_set is FeatureSet.DEFAULT:
            per_sigma = 7 if self.hessian else 5
            return (3 + (1 if self.scale > 1 else 0) + per_sigma * len(self.sigmas)
                    + 2 * len(self.ridge_sigmas) + (len(self.sigmas) if self.relative else 0)
                    + texture_count(self.sigmas, self.structure)
                    + profile_count(self.profile_radii))
        # multiscale_basic_features: per channel and sigma, intensity + edges + 2 Hessian
        n_sig = int(np.floor(np.log2(self.skimage_sigma_max))) + 1
        return 3 * n_sig * 4

    @property
    def halo(self) -> int:
        """Coarse pixels of context a feature needs on each side (tile overlap)."""
        if self.feature_set is FeatureSet.COLOUR:
            return 0
        if self.feature_set is FeatureSet.DEFAULT:
            fine = -(-ridge_halo(self.ridge_sigmas) // self.scale)
            return max(_radius(max(self.sigmas, default=0.0)) + 1, fine + 1,
                       profile_halo(self.profile_radii))
        # scipy's gaussian_filter truncates at 4 sigma; Hessian adds 2 pixels
        return int(math.ceil(4.0 * self.skimage_sigma_max)) + 2


def _radius(sigma: float) -> int:
    return int(math.ceil(3.0 * sigma))


def photo_statistics(rgb: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Lab mean and standard deviation of a photo (from at most ~1 Mpx, strided).

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
    valid : (H, W) bool ndarray or None

    Returns
    -------
    stats : (2, 3) float32 ndarray, rows mean and std (std floored at 1)
    """
    step = max(1, int(np.sqrt(rgb.shape[0] * rgb.shape[1] / 1e6)))
    lab, _ = coarse_lab(rgb[::step, ::step], 1)
    pix = lab.reshape(-1, 3)
    if valid is not None:
        pix = pix[valid[::step, ::step].ravel()]
    return np.stack([pix.mean(0), np.maximum(pix.std(0), 1.0)]).astype(np.float32)


def normalise_lab(lab: np.ndarray, block_std: np.ndarray, stats: np.ndarray,
                  mode: Normalise) -> tuple[np.ndarray, np.ndarray]:
    """Map a photo's Lab statistics to the reference (Reinhard-style colour transfer)."""
    if mode is Normalise.NONE:
        return lab, block_std
    gain = REFERENCE_STD / stats[1]
    offset = REFERENCE_MEAN - stats[0] * gain
    if mode is Normalise.LIGHTNESS:
        gain[1:], offset[1:] = 1.0, 0.0
    return (lab * gain + offset).astype(np.float32), (block_std * gain[0]).astype(np.float32)


def features_from_lab(
    lab: np.ndarray, block_std: np.ndarray, options: FeatureOptions,
    stats: np.ndarray | None = None, ridges: np.ndarray | None = None,
    texture: np.ndarray | None = None,
) -> np.ndarray:
    """Feature stack of a coarse Lab image.

    Parameters
    ----------
    lab : (h, w, 3) float32 ndarray
    block_std : (h, w) float32 ndarray
    options : FeatureOptions
    stats : (2, 3) float32 ndarray, optional
        The whole photo's :func:`photo_statistics`, for ``options.normalise``.
    ridges : (h, w, 2 * len(options.ridge_sigmas)) float32 ndarray, optional
        :func:`core.classify.ridges.block_ridges` of the same photo pixels;
        required when ``options.ridge_sigmas`` is set (DEFAULT set).
    texture : (h, w, T) float32 ndarray, optional
        :func:`core.classify.texture.texture_features` of the same photo pixels;
        required when ``options.structure`` is set.

    Raises
    ------
    TerrathemeError
        Ridge sigmas without the ridges, texture options without the texture.

    Returns
    -------
    features : (h, w, F) float32 ndarray, F = ``options.n_features``
    """
    if stats is not None:
        lab, block_std = normalise_lab(lab, block_std, stats, options.normalise)
    fs = options.feature_set
    if fs is FeatureSet.COLOUR:
        return np.ascontiguousarray(lab, dtype=np.float32)
    if fs is FeatureSet.SKIMAGE:
        from skimage.feature import multiscale_basic_features

        feats = multiscale_basic_features(
            lab, channel_axis=-1, sigma_min=1.0, sigma_max=options.skimage_sigma_max,
        )
        return np.ascontiguousarray(feats, dtype=np.float32)
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
    smooth_lum = []
    for sigma in options.sigmas:
        # Context colour: Lab smoothed at this scale.
        smooth = context_blur(lab, sigma)
        out[:, :, i : i + 3] = smooth
        smooth_lum.append(out[:, :, i])
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
    if options.relative:
        # Lightness over the widest context's lightness: unchanged by the photo's exposure.
        context = smooth_lum[-1] + np.float32(RELATIVE_FLOOR)
        for j, near in enumerate([lum, *smooth_lum[:-1]]):
            out[:, :, i + j] = near / context
        i += len(options.sigmas)
    n_texture = texture_count(options.sigmas, options.structure)
    if n_texture:
        if texture is None or texture.shape != (h, w, n_texture):
            raise TerrathemeError("structure needs the texture_features of the same pixels")
        out[:, :, i : i + n_texture] = texture
        i += n_texture
    if options.profile_radii:
        # Bright and dark objects smaller than each disk (core.classify.profiles).
        out[:, :, i:] = reconstruction_profile(lum, options.profile_radii)
    return out


def image_features(rgb: np.ndarray, options: FeatureOptions, stats: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coarse Lab, block lightness std and features (no position) of photo pixels.

    Returns
    -------
    lab : (h, w, 3) float32 ndarray
    block_std : (h, w) float32 ndarray
    features : (h, w, options.n_image_features) float32 ndarray
    """
    full = full_lab(rgb)
    lab, block_std = block_lab(full, options.scale)
    ridges = (block_ridges(full[:, :, 0], options.scale, options.ridge_sigmas)
              if options.ridge_sigmas and options.feature_set is FeatureSet.DEFAULT else None)
    texture = (texture_features(full, lab, options.scale, options.sigmas)
               if options.structure and options.feature_set is FeatureSet.DEFAULT else None)
    return lab, block_std, features_from_lab(lab, block_std, options, stats, ridges, texture)


def with_position(feats: np.ndarray, origin: tuple[int, int], photo_size: tuple[int, int],
                  options: FeatureOptions) -> np.ndarray:
    """Append :func:`position_features` when ``options.position`` (else return ``feats``)."""
    if not options.position:
        return feats
    pos = position_features(feats.shape[:2], origin, photo_size, options.scale)
    return np.concatenate([feats, pos], axis=2)


def compute_features(rgb: np.ndarray, options: FeatureOptions) -> np.ndarray:
    """Features of one photo tile (whole tile, no overlap handling).

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
    options : FeatureOptions

    Returns
    -------
    features : (ceil(H/scale), ceil(W/scale), F) float32 ndarray
    """
    _lab, _block_std, feats = image_features(rgb, options)
    return with_position(feats, (0, 0), rgb.shape[:2], options)
