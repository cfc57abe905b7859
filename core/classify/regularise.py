"""Spatial regularisation of class probabilities on the coarse grid.

A pixel's class should agree with its neighbours unless the photo shows an edge, so
the per-class probability maps are averaged before the arg-max: ``SMOOTH`` with a
Gaussian, ``EDGE`` among neighbours of similar colour weighted by the forest's
confidence (:func:`edge_aware_probabilities`, a cheap stand-in for a dense CRF), or
not at all (``NONE``).
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import cv2
import numpy as np
from terratheme.core.classify.texture import context_blur
from terratheme.core.errors import TerrathemeError


class Regularisation(enum.Enum):
    """How the coarse probability maps are regularised."""

    NONE = "none"
    SMOOTH = "smooth"
    EDGE = "edge"


#: EDGE: weight of a pixel the forest is torn on (margin 0), against 1 + this for a sure one
EDGE_WEIGHT_FLOOR = 0.05
#: EDGE: iterations of the domain-transform filter (Gastal & Oliveira 2011 use 3)
EDGE_ITERATIONS = 3
#: EDGE: weight of the block lightness std (texture, L units) in the guide, beside L, a, b
EDGE_TEXTURE_WEIGHT = 1.0


@dataclass(frozen=True)
class RegulariseOptions:
    """Options of :func:`regularise`: SMOOTH's Gaussian ``sigma`` (coarse pixels); EDGE's
    ``edge_sigma_spatial`` (coarse pixels, the filter's sigma_s) and ``edge_sigma_colour``
    (Lab difference summed over L, a, b across which averaging fades, its sigma_r).
    """

    method: Regularisation = Regularisation.SMOOTH
    sigma: float = 1.0
    edge_sigma_spatial: float = 8.0
    edge_sigma_colour: float = 10.0

    def __post_init__(self) -> None:
        if self.sigma <= 0:
            raise TerrathemeError(f"regularisation sigma must be > 0, not {self.sigma}")
        if self.edge_sigma_spatial <= 0 or self.edge_sigma_colour <= 0:
            raise TerrathemeError(
                f"edge regularisation sigmas must be > 0 "
                f"(got {self.edge_sigma_spatial}, {self.edge_sigma_colour})"
            )

    @property
    def halo(self) -> int:
        """Coarse pixels of context the regularisation needs on each side."""
        if self.method is Regularisation.SMOOTH:
            return int(math.ceil(3.0 * self.sigma))
        if self.method is Regularisation.EDGE:
            return edge_reach(self.edge_sigma_spatial) + 1
        return 0


def edge_reach(sigma_spatial: float, iterations: int = EDGE_ITERATIONS) -> int:
    """Farthest a coarse pixel's value travels along one axis in the EDGE filter.

    Gastal & Oliveira (2011, section 4 and eq. 14): iteration ``i`` of ``N``
    is a box filter of radius ``sqrt(3) * sigma_i`` in the transformed domain,
    ``sigma_i = sigma_s * sqrt(3) * 2**(N - i) / sqrt(4**N - 1)``; transformed
    distances are never shorter than pixel distances (eq. 11), so the sum of
    the radii bounds the reach in pixels (21.2 for ``sigma_s = 8``).
    """
    radii = [3.0 * sigma_spatial * 2.0 ** (iterations - i) / math.sqrt(4.0**iterations - 1.0)
             for i in range(1, iterations + 1)]
    return int(math.ceil(sum(radii)))


def smooth_probabilities(probs: np.ndarray, sigma: float) -> np.ndarray:
    """Each class's probability map (h, w, C) Gaussian-averaged over ``sigma`` coarse px."""
    return context_blur(probs, sigma).reshape(probs.shape)


def edge_aware_probabilities(probs: np.ndarray, lab: np.ndarray, sigma_spatial: float,
                             sigma_colour: float, texture: np.ndarray | None = None) -> np.ndarray:
    """Confidence-weighted, edge-aware average of the class probability maps.

    ``out_k = DT(w * p_k) / DT(w)`` (normalised convolution), where ``DT`` is
    the domain-transform filter guided by ``lab`` (Gastal & Oliveira 2011,
    NC mode) and ``w`` = the margin between a pixel's two most probable
    classes + ``EDGE_WEIGHT_FLOOR``; rows are renormalised to sum to 1.

    ``probs`` (h, w, C) float32 rows sum to 1; ``lab`` (h, w, 3) float32 is the guide;
    ``texture`` (h, w) float32 block lightness std (optional), a fourth guide channel
    times ``EDGE_TEXTURE_WEIGHT``, keeps regions of equal colour but different texture
    apart. Returns (h, w, C) float32, rows summing to 1.
    """
    h, w, c = probs.shape
    if c == 1 or h * w == 1:
        return probs
    # Confidence of each coarse pixel: the forest's margin between its best two classes.
    top2 = np.partition(probs, c - 2, axis=2)[:, :, c - 2 :]
    weight = (top2[:, :, 1] - top2[:, :, 0] + EDGE_WEIGHT_FLOOR).astype(np.float32)
    # Guide: Lab, plus texture when given.
    guide = np.ascontiguousarray(lab, np.float32)
    if texture is not None:
        guide = np.ascontiguousarray(np.dstack([guide, texture * EDGE_TEXTURE_WEIGHT]),
                                     np.float32)
    # One domain transform of the guide, applied to the weight and each weighted class map.
    flt = cv2.ximgproc.createDTFilter(guide, sigma_spatial,
                                      sigma_colour, cv2.ximgproc.DTF_NC, EDGE_ITERATIONS)
    den = flt.filter(weight).reshape(h, w)
    out = np.empty_like(probs, dtype=np.float32)
    for k in range(c):
        out[:, :, k] = flt.filter(np.ascontiguousarray(probs[:, :, k] * weight)).reshape(h, w)
    out /= np.maximum(den, 1e-12)[:, :, None]
    # Keep the rows on the simplex (rounding).
    np.maximum(out, 0.0, out=out)
    out /= np.maximum(out.sum(2, keepdims=True), 1e-12)
    return out


def regularise(probs: np.ndarray, lab: np.ndarray, options: RegulariseOptions,
               texture: np.ndarray | None = None) -> np.ndarray:
    """Coarse probability maps (h, w, C) float32 regularised by ``options.method``; EDGE is
    guided by the coarse Lab ``lab`` (h, w, 3) and the block lightness std ``texture``."""
    if options.method is Regularisation.SMOOTH:
        return smooth_probabilities(probs, options.sigma)
    if options.method is Regularisation.EDGE:
        return edge_aware_probabilities(probs, lab, options.edge_sigma_spatial,
                                        options.edge_sigma_colour, texture)
    return probs
