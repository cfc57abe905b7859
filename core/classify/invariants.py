"""Optional features meant to carry over between photos (issue 17), each off by default.

The DEFAULT set (:mod:`core.classify.features`) is mostly in Lab units, which
change with a photo's exposure and contrast. These are measured in
``benchmarks/classify_tune_tiles.py`` one by one (``FeatureOptions`` fields):

* ``profile_radii`` -- a morphological profile by reconstruction (Pesaresi &
  Benediktsson 2001) of the coarse lightness: for each disk radius r (coarse
  pixels) the lightness minus its opening by reconstruction (bright objects
  narrower than the disk: buildings) and its closing by reconstruction minus
  the lightness (dark ones: roads, shadows). The reconstruction is a geodesic
  dilation (erosion) of at most ``RECONSTRUCTION_STEPS`` 3 x 3 steps, so a
  feature reaches ``r + RECONSTRUCTION_STEPS`` coarse pixels and tiles stay
  exact (``FeatureOptions.halo``); 2 features per radius.
* ``ratios`` -- colour ratios of the coarse pixel's sRGB (from its Lab):
  chromaticity r / (r + g + b), g / (r + g + b), (g - r) / (g + r), and the
  Lab hue angle and chroma over lightness; a change of exposure (a common
  gain) leaves them as they are; 5 features.
* ``lbp`` -- local binary patterns (Ojala et al. 2002; rotation-invariant
  uniform, 8 neighbours at radius 1) of the photo's lightness at half
  resolution, as each code's share of the coarse pixel's block, smoothed
  over one coarse pixel (sigma 1); unchanged by a change of gain and offset
  (by other monotonic changes too but for skimage's interpolation of the
  diagonal neighbours); 10 features.
* ``rank_radii`` -- the coarse pixel's lightness rank in the disk of each
  radius around it (local histogram equalisation, 0..1): a percentile
  normalisation by the neighbourhood, unchanged by monotonic brightness
  changes; 1 feature per radius.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np
from skimage.feature import local_binary_pattern
from skimage.filters.rank import equalize
from skimage.morphology import disk

from core.classify.texture import block_mean, context_blur
from core.errors import TerrathemeError

if TYPE_CHECKING:
    from core.classify.features import FeatureOptions

#: geodesic 3 x 3 steps of the bounded reconstruction (its reach beyond the disk)
RECONSTRUCTION_STEPS = 8
#: rotation-invariant uniform LBP with 8 neighbours: codes 0..9
LBP_POINTS = 8
LBP_CODES = LBP_POINTS + 2
#: lightness offset (L units) of the chroma over lightness ratio, so black stays finite
CHROMA_FLOOR = 5.0
#: ratio features from the coarse pixel's colour
RATIO_COUNT = 5
_STEP = np.ones((3, 3), np.uint8)


def invariant_count(options: FeatureOptions) -> int:
    """Number of features :func:`invariant_features` gives."""
    return (2 * len(options.profile_radii) + (RATIO_COUNT if options.ratios else 0)
            + (LBP_CODES if options.lbp else 0) + len(options.rank_radii))


def invariant_halo(options: FeatureOptions) -> int:
    """Coarse pixels of context the invariant features need on each side."""
    reach = [max(options.profile_radii, default=0) + RECONSTRUCTION_STEPS
             if options.profile_radii else 0,
             max(options.rank_radii, default=0), 4 if options.lbp else 0]
    return max(reach) + 1


def reconstruction_profile(lum: np.ndarray, radii: tuple[int, ...],
                           steps: int = RECONSTRUCTION_STEPS) -> np.ndarray:
    """Bright and dark residues of opening / closing by (bounded) reconstruction.

    Parameters
    ----------
    lum : (h, w) float32 ndarray
        Coarse lightness.
    radii : tuple of int
        Disk radii in coarse pixels.
    steps : int
        Geodesic 3 x 3 steps of the reconstruction.

    Returns
    -------
    profile : (h, w, 2 * len(radii)) float32 ndarray
        For each radius: ``lum - opening_by_reconstruction`` (>= 0) and
        ``closing_by_reconstruction - lum`` (>= 0).
    """
    lum = np.ascontiguousarray(lum, dtype=np.float32)
    out = np.empty((*lum.shape, 2 * len(radii)), np.float32)
    for n, r in enumerate(radii):
        se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        # Opening by reconstruction: erode, then dilate geodesically under the lightness.
        marker = cv2.erode(lum, se, borderType=cv2.BORDER_REFLECT_101)
        for _ in range(steps):
            marker = np.minimum(cv2.dilate(marker, _STEP, borderType=cv2.BORDER_REFLECT_101),
                                lum)
        out[:, :, 2 * n] = lum - marker
        # Closing by reconstruction: dilate, then erode geodesically above the lightness.
        marker = cv2.dilate(lum, se, borderType=cv2.BORDER_REFLECT_101)
        for _ in range(steps):
            marker = np.maximum(cv2.erode(marker, _STEP, borderType=cv2.BORDER_REFLECT_101),
                                lum)
        out[:, :, 2 * n + 1] = marker - lum
    return out


def colour_ratios(lab: np.ndarray) -> np.ndarray:
    """Exposure-free colour ratios of coarse Lab pixels (module docstring).

    Parameters
    ----------
    lab : (h, w, 3) float32 ndarray, L in 0..100

    Returns
    -------
    ratios : (h, w, 5) float32 ndarray
        r / (r + g + b), g / (r + g + b), (g - r) / (g + r) of the sRGB
        values (0 for black), hue angle ``atan2(b*, a*)`` in radians and
        chroma / (L + ``CHROMA_FLOOR``).
    """
    rgb = cv2.cvtColor(np.ascontiguousarray(lab, dtype=np.float32), cv2.COLOR_Lab2RGB)
    r, g, b = np.moveaxis(np.maximum(rgb, 0.0), 2, 0)
    out = np.empty((*lab.shape[:2], RATIO_COUNT), np.float32)
    total = r + g + b
    # Chromaticity: each channel's share of the sum.
    np.divide(r, total, out=out[:, :, 0], where=total > 0)
    out[:, :, 0][total <= 0] = 0.0
    np.divide(g, total, out=out[:, :, 1], where=total > 0)
    out[:, :, 1][total <= 0] = 0.0
    # Normalised green-red difference.
    green_red = g + r
    np.divide(g - r, green_red, out=out[:, :, 2], where=green_red > 0)
    out[:, :, 2][green_red <= 0] = 0.0
    # Hue angle and saturation-like chroma over lightness, from Lab.
    out[:, :, 3] = np.arctan2(lab[:, :, 2], lab[:, :, 1])
    out[:, :, 4] = np.hypot(lab[:, :, 1], lab[:, :, 2]) / (lab[:, :, 0] + CHROMA_FLOOR)
    return out


def lbp_shares(lightness: np.ndarray, scale: int) -> np.ndarray:
    """Each uniform LBP code's smoothed share of every coarse block.

    Parameters
    ----------
    lightness : (H, W) float32 ndarray
        The photo's L* (0..100) at full resolution.
    scale : int
        Block size in photo pixels (even, >= 2).

    Returns
    -------
    shares : (ceil(H/scale), ceil(W/scale), 10) float32 ndarray
        Shares sum to 1 over the last axis.

    Raises
    ------
    TerrathemeError
        An odd block size (the codes are taken at half resolution).
    """
    if scale < 2 or scale % 2:
        raise TerrathemeError(f"LBP features need an even feature scale, not {scale}")
    # Half resolution, as 8-bit codes (ties between neighbours count as brighter).
    half = block_mean(np.ascontiguousarray(lightness, dtype=np.float32), 2)
    lum8 = np.rint(np.clip(half, 0.0, 100.0) * np.float32(2.55)).astype(np.uint8)
    # Codes of the photo reflected by one pixel (skimage reads zeros past the border).
    padded = cv2.copyMakeBorder(lum8, 1, 1, 1, 1, cv2.BORDER_REFLECT_101)
    codes = local_binary_pattern(padded, LBP_POINTS, 1, method="uniform")[1:-1, 1:-1]
    codes = codes.astype(np.uint8)
    # One share per code and block, then smoothed over one coarse pixel.
    onehot = (codes[:, :, None] == np.arange(LBP_CODES, dtype=np.uint8)).astype(np.float32)
    return context_blur(block_mean(onehot, scale // 2), 1.0)


def local_rank(lum: np.ndarray, radii: tuple[int, ...]) -> np.ndarray:
    """Rank of each coarse pixel's lightness in the disk around it, for each radius.

    Parameters
    ----------
    lum : (h, w) float32 ndarray, L in 0..100
    radii : tuple of int

    Returns
    -------
    ranks : (h, w, len(radii)) float32 ndarray in 0..1
        skimage's local histogram equalisation of the 8-bit lightness.
    """
    lum8 = np.rint(np.clip(lum, 0.0, 100.0) * np.float32(2.55)).astype(np.uint8)
    out = np.empty((*lum.shape, len(radii)), np.float32)
    for n, r in enumerate(radii):
        out[:, :, n] = equalize(lum8, disk(r)) / np.float32(255.0)
    return out


def invariant_features(lab: np.ndarray, lbp: np.ndarray | None,
                       options: FeatureOptions) -> np.ndarray:
    """The invariant features the options ask for, in the module docstring's order.

    Parameters
    ----------
    lab : (h, w, 3) float32 ndarray
        Coarse Lab.
    lbp : (h, w, 10) float32 ndarray or None
        :func:`lbp_shares` of the same photo pixels, required with ``options.lbp``.
    options : FeatureOptions

    Returns
    -------
    features : (h, w, invariant_count(options)) float32 ndarray
    """
    h, w = lab.shape[:2]
    parts = []
    lum = np.ascontiguousarray(lab[:, :, 0])
    if options.profile_radii:
        parts.append(reconstruction_profile(lum, options.profile_radii))
    if options.ratios:
        parts.append(colour_ratios(lab))
    if options.lbp:
        if lbp is None or lbp.shape != (h, w, LBP_CODES):
            raise TerrathemeError("lbp needs the lbp_shares of the same pixels")
        parts.append(lbp)
    if options.rank_radii:
        parts.append(local_rank(lum, options.rank_radii))
    if not parts:
        return np.empty((h, w, 0), np.float32)
    return np.concatenate(parts, axis=2)
