"""Structure features (``FeatureOptions.structure``): texture that carries across photos.

The DEFAULT set's texture features are in L units and scale with contrast.
``structure`` adds ``1 + len(sigmas)``, within ``FeatureOptions.halo``:

* edge density: the block mean of the full-resolution lightness gradient magnitude
  (many small edges against one large step);
* per sigma, the coherence ``((mu_1 - mu_2) / (mu_1 + mu_2 + eps))^2`` of the structure
  tensor ``G_sigma * (grad L grad L^T)`` of the coarse lightness (Bigun & Granlund
  1987; Weickert 1999): 1 along parallel lines, 0 for isotropic or flat areas,
  whatever the contrast.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

#: most channels one OpenCV filter or resize call takes
CV_MAX_CHANNELS = 128
#: structure-tensor coherence: added to the trace (L units^2) so flat areas stay finite
COHERENCE_FLOOR = 1e-2


def texture_count(sigmas: Sequence[float], structure: bool) -> int:
    """Number of features :func:`texture_features` gives."""
    return 1 + len(sigmas) if structure else 0


def context_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur with an explicit 3-sigma kernel (so a tile overlap of ``ceil(3 sigma)``
    pixels is exact), reflected at the border; any number of channels."""
    k = 2 * int(math.ceil(3.0 * sigma)) + 1
    channels = img.shape[2] if img.ndim == 3 else 1
    if channels <= CV_MAX_CHANNELS:
        return cv2.GaussianBlur(img, (k, k), sigma, borderType=cv2.BORDER_REFLECT_101)
    # OpenCV filters at most 128 channels at once: blur them in parts.
    return np.dstack([cv2.GaussianBlur(np.ascontiguousarray(img[:, :, i : i + CV_MAX_CHANNELS]),
                                       (k, k), sigma, borderType=cv2.BORDER_REFLECT_101)
                      for i in range(0, channels, CV_MAX_CHANNELS)])


def block_mean(img: np.ndarray, scale: int) -> np.ndarray:
    """Means of ``scale x scale`` blocks, block (i, j) covering rows ``i*scale..i*scale+scale-1``;
    the photo is edge-replicated to whole blocks (INTER_AREA at an integer factor is an
    exact block mean)."""
    h, w = img.shape[:2]
    ph, pw = -h % scale, -w % scale
    if ph or pw:
        img = cv2.copyMakeBorder(img, 0, ph, 0, pw, cv2.BORDER_REPLICATE)
    return cv2.resize(img, ((w + pw) // scale, (h + ph) // scale), interpolation=cv2.INTER_AREA)


def texture_features(full: np.ndarray, lab: np.ndarray, scale: int,
                     sigmas: Sequence[float]) -> np.ndarray:
    """Edge density, then the coherence at each of ``sigmas`` (coarse pixels): (h, w,
    1 + len(sigmas)) float32 (module docstring), from the photo's full-resolution Lab
    ``full`` (H, W, 3) and its block means ``lab`` (h, w, 3)."""
    h, w = lab.shape[:2]
    out = np.empty((h, w, texture_count(sigmas, True)), np.float32)
    gx, gy = _gradient(np.ascontiguousarray(full[:, :, 0]))
    magnitude = cv2.magnitude(gx, gy)
    out[:, :, 0] = block_mean(magnitude, scale) if scale > 1 else magnitude
    cx, cy = _gradient(np.ascontiguousarray(lab[:, :, 0]))
    products = np.dstack([cx * cx, cy * cy, cx * cy])
    for i, sigma in enumerate(sigmas, 1):
        jxx, jyy, jxy = np.moveaxis(context_blur(products, sigma), 2, 0)
        # (mu_1 - mu_2)^2 = (jxx - jyy)^2 + 4 jxy^2; mu_1 + mu_2 = trace.
        spread = (jxx - jyy) ** 2 + 4.0 * jxy * jxy
        out[:, :, i] = spread / (jxx + jyy + np.float32(COHERENCE_FLOOR)) ** 2
    return out


def _gradient(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sobel 3 x 3 derivatives along x and y, 1/8 normalised, reflected at the border."""
    return tuple(cv2.Sobel(image, cv2.CV_32F, dx, 1 - dx, ksize=3, scale=0.125,
                           borderType=cv2.BORDER_REFLECT_101) for dx in (1, 0))
