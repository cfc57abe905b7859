"""Spatial regularisation of class probabilities on the coarse grid.

A pixel's class should agree with its neighbours unless the photo shows an
edge. Two ways, both acting on the per-class probability maps before the
final arg-max (a soft majority vote):

``SMOOTH``     : Gaussian-weighted average of each class's probability over
                 ``sigma`` coarse pixels (a soft majority filter).
``SUPERPIXEL`` : average of the probabilities over each manifold-SLIC superpixel
                 (``cv2.ximgproc`` MSLIC, Liu et al. 2016) of the coarse Lab image,
                 so regions follow the photo's edges.
``NONE``       : per-pixel decisions.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import TerrathemeError


class Regularisation(enum.Enum):
    """How the coarse probability maps are regularised."""

    NONE = "none"
    SMOOTH = "smooth"
    SUPERPIXEL = "superpixel"


@dataclass(frozen=True)
class RegulariseOptions:
    """Options of :func:`regularise`.

    Attributes
    ----------
    method : Regularisation
    sigma : float
        SMOOTH: Gaussian sigma in coarse pixels.
    region_size : int
        SUPERPIXEL: SLIC region size in coarse pixels.
    ruler : float
        SUPERPIXEL: SLIC compactness (higher = squarer superpixels).
    """

    method: Regularisation = Regularisation.SMOOTH
    sigma: float = 1.0
    region_size: int = 6
    ruler: float = 10.0

    def __post_init__(self) -> None:
        if self.sigma <= 0 or self.region_size < 2:
            raise TerrathemeError(
                f"regularisation sigma must be > 0 and region size >= 2 "
                f"(got {self.sigma}, {self.region_size})"
            )

    @property
    def halo(self) -> int:
        """Coarse pixels of context the regularisation needs on each side."""
        if self.method is Regularisation.SMOOTH:
            return int(math.ceil(3.0 * self.sigma))
        if self.method is Regularisation.SUPERPIXEL:
            return 2 * self.region_size
        return 0


def smooth_probabilities(probs: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian-average each class's probability map.

    Parameters
    ----------
    probs : (h, w, C) float32 ndarray
    sigma : float
        In coarse pixels.

    Returns
    -------
    smoothed : (h, w, C) float32 ndarray (rows still sum to 1)
    """
    k = 2 * int(math.ceil(3.0 * sigma)) + 1
    out = cv2.GaussianBlur(probs, (k, k), sigma, borderType=cv2.BORDER_REFLECT_101)
    return out.reshape(probs.shape)


def superpixel_labels(lab: np.ndarray, region_size: int, ruler: float) -> np.ndarray:
    """SLIC superpixels of a coarse Lab image.

    Parameters
    ----------
    lab : (h, w, 3) float32 ndarray
    region_size, ruler : SLIC parameters (cv2.ximgproc.createSuperpixelSLIC)

    Returns
    -------
    segments : (h, w) int32 ndarray, values 0..S-1
    """
    h, w = lab.shape[:2]
    if min(h, w) < 2:
        return np.arange(h * w, dtype=np.int32).reshape(h, w)
    slic = cv2.ximgproc.createSuperpixelSLIC(
        np.ascontiguousarray(lab, np.float32), cv2.ximgproc.MSLIC, region_size, ruler
    )
    slic.iterate(10)
    slic.enforceLabelConnectivity(25)
    return slic.getLabels().astype(np.int32)


def average_over_segments(probs: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Replace each pixel's probabilities by its segment's mean.

    Parameters
    ----------
    probs : (h, w, C) float32 ndarray
    segments : (h, w) int ndarray

    Returns
    -------
    averaged : (h, w, C) float32 ndarray
    """
    h, w, c = probs.shape
    seg = segments.ravel()
    n = int(seg.max()) + 1
    counts = np.bincount(seg, minlength=n).astype(np.float32)
    flat = probs.reshape(-1, c)
    sums = np.stack([np.bincount(seg, weights=flat[:, k], minlength=n) for k in range(c)], 1)
    means = (sums / np.maximum(counts, 1.0)[:, None]).astype(np.float32)
    return means[seg].reshape(h, w, c)


def regularise(probs: np.ndarray, lab: np.ndarray, options: RegulariseOptions) -> np.ndarray:
    """Apply the chosen regularisation to coarse probability maps.

    Parameters
    ----------
    probs : (h, w, C) float32 ndarray
    lab : (h, w, 3) float32 ndarray
        The coarse Lab image (used by SUPERPIXEL).
    options : RegulariseOptions

    Returns
    -------
    probs : (h, w, C) float32 ndarray
    """
    if options.method is Regularisation.SMOOTH:
        return smooth_probabilities(probs, options.sigma)
    if options.method is Regularisation.SUPERPIXEL:
        segments = superpixel_labels(lab, options.region_size, options.ruler)
        return average_over_segments(probs, segments)
    return probs
