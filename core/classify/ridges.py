"""Fine ridge features: lines narrower than a block, found before the block average.

A track or channel a few pixels wide barely moves a block's mean lightness, so the
lightness is filtered at full resolution: the Hessian eigenvalues at scale ``sigma``
(scale-normalised by ``sigma^2``, Lindeberg 1998), then per block the largest larger
eigenvalue (a dark line) and the smallest smaller one (a bright line): two features
per sigma. Sigmas of 2 px and more run on 2 x 2 block means (a quarter of the work).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
from terratheme.core.classify.texture import context_blur


def ridge_halo(sigmas: Sequence[float]) -> int:
    """Photo pixels of context the filters need on each side (3-sigma kernel + Sobel)."""
    return int(math.ceil(3.0 * max(sigmas, default=0.0))) + 1 if len(sigmas) else 0


def hessian_eigenvalues(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hessian eigenvalues ``(xx + yy) / 2 +/- sqrt(((xx - yy) / 2)^2 + xy^2)`` (larger,
    smaller; (H, W) float32, not scale-normalised) of a smoothed (H, W) float32 image,
    derivatives by 3 x 3 Sobel, 1/4 normalised, reflected at the border."""
    img = np.ascontiguousarray(image, dtype=np.float32)
    lxx, lyy, lxy = (cv2.Sobel(img, cv2.CV_32F, dx, dy, ksize=3, scale=0.25,
                               borderType=cv2.BORDER_REFLECT_101)
                     for dx, dy in ((2, 0), (0, 2), (1, 1)))
    # Half trace +/- root: one new buffer, the results written over the derivatives.
    half_diff = cv2.addWeighted(lxx, 0.5, lyy, -0.5, 0.0)
    root = cv2.magnitude(half_diff, lxy, lxy)
    half_trace = cv2.addWeighted(lxx, 0.5, lyy, 0.5, 0.0, dst=half_diff)
    return cv2.add(half_trace, root, dst=lxx), cv2.subtract(half_trace, root, dst=lyy)


def block_ridges(lightness: np.ndarray, scale: int, sigmas: Sequence[float]) -> np.ndarray:
    """Per-block extremes of the lightness Hessian's eigenvalues at each sigma.

    ``lightness`` (H, W) float32 is the photo's L* at full resolution; blocks are
    ``scale`` pixels a side (edge-replicated past the photo); ``sigmas`` in photo pixels.
    Returns (ceil(H/scale), ceil(W/scale), 2 * len(sigmas)) float32: per sigma the
    block's largest ``sigma^2 * lambda_1`` and smallest ``sigma^2 * lambda_2``.
    """
    h, w = lightness.shape
    hc, wc = -(-h // scale), -(-w // scale)
    out = np.empty((hc, wc, 2 * len(sigmas)), np.float32)
    full = np.ascontiguousarray(lightness, dtype=np.float32)
    half = None
    for n, sigma in enumerate(sigmas):
        # Sigmas of 2 pixels and more on the 2 x 2 block means: a quarter of the work,
        # the same blocks (scale-normalised eigenvalues do not depend on the pixel size).
        lum, step = full, scale
        if sigma >= 2.0 and scale % 2 == 0:
            if half is None:
                even = cv2.copyMakeBorder(full, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
                half = cv2.resize(even, ((w + 1) // 2, (h + 1) // 2),
                                  interpolation=cv2.INTER_AREA)
            lum, step, sigma = half, scale // 2, sigma / 2.0
        block = np.ones((step, step), np.uint8)
        # An explicit 3-sigma kernel: the tile overlap covers it exactly.
        g = context_blur(lum, sigma)
        larger, smaller = hessian_eigenvalues(g)
        # Block extremes: max/min filter over each block anchored at its top-left pixel,
        # read at the block corners; past the photo the border is replicated.
        top = cv2.dilate(larger, block, dst=g, anchor=(0, 0), borderType=cv2.BORDER_REPLICATE)
        bottom = cv2.erode(smaller, block, dst=larger, anchor=(0, 0),
                           borderType=cv2.BORDER_REPLICATE)
        s2 = np.float32(sigma * sigma)
        out[:, :, 2 * n] = s2 * top[::step, ::step]
        out[:, :, 2 * n + 1] = s2 * bottom[::step, ::step]
    return out
