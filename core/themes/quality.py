"""How obviously a tileable texture repeats: banding, ghosting and landmarks.

Three measures on the luma of the texture as one period of a tiling, rating shipped
files as well as cut patches: slow waves (:func:`lowfreq_score`), self-copies
(:func:`repeat_score`) and lone features (:func:`landmark_score`), each of which the
eye finds as a grid once the tile repeats.
"""

from __future__ import annotations

import cv2
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import validate_texture

#: Rec. 601 luma weights
LUMA = np.array([0.299, 0.587, 0.114], np.float64)


def _luma(texture: np.ndarray, name: str) -> np.ndarray:
    img = validate_texture(texture, name=name)
    h, w = img.shape[:2]
    if h < 4 or w < 4:
        raise TerrathemeError(f"{name} {w} x {h} is too small to rate (need 4 x 4)")
    return img.astype(np.float64) @ LUMA


def _cycles(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) signed frequencies in cycles per tile along y and x."""
    return np.fft.fftfreq(h)[:, None] * h, np.fft.fftfreq(w)[None, :] * w


def lowfreq_score(texture: np.ndarray, cycles: float = 2.0) -> float:
    """RMS of the luma waves of at most ``cycles`` per tile over the RMS of all of it.

    In [0, 1]: 0 with no variation slower than ``cycles`` (or flat), 1 for one smooth
    gradient. ``cycles`` is a radial bound in periods per tile, along each side.
    """
    lum = _luma(texture, "texture")
    spec = np.abs(np.fft.fft2(lum - lum.mean())) ** 2
    ky, kx = _cycles(*lum.shape)
    low = (np.hypot(ky, kx) <= cycles) & ((ky != 0) | (kx != 0))
    total = float(spec.sum())
    return 0.0 if total <= 1e-9 else float(np.sqrt(spec[low].sum() / total))


def repeat_score(texture: np.ndarray, detail: float = 3.0, exclude: int = 4) -> float:
    """Largest normalised circular autocorrelation of the texture's fine detail, in [-1, 1].

    Detail: luma minus its periodic Gaussian blur of sigma ``detail``; shifts within
    ``exclude`` texels of zero are ignored. About 1 when part of the tile copies another
    (a cross-fade ghost), near ``3 / sqrt(h w)`` when nothing repeats, 0 when flat.
    """
    lum = _luma(texture, "texture")
    h, w = lum.shape
    ky, kx = _cycles(h, w)
    # Periodic high-pass: 1 - Gaussian transfer function exp(-2 pi^2 sigma^2 f^2).
    f2 = (ky / h) ** 2 + (kx / w) ** 2
    spec = np.fft.fft2(lum) * (1.0 - np.exp(-2.0 * np.pi**2 * detail**2 * f2))
    # Wiener-Khinchin: the circular autocorrelation is the inverse FFT of the power spectrum.
    ac = np.real(np.fft.ifft2(np.abs(spec) ** 2))
    if ac[0, 0] <= 1e-9:
        return 0.0
    ac /= ac[0, 0]
    dy = np.minimum(np.arange(h), h - np.arange(h))[:, None]
    dx = np.minimum(np.arange(w), w - np.arange(w))[None, :]
    far = (dy > exclude) | (dx > exclude)
    return float(ac[far].max()) if far.any() else 0.0


#: landmark_mask: structuring element diameter (texels) -- features narrower than this count
LANDMARK_SIZE = 21
#: landmark_mask: luma contrast (0..255) a feature needs against its surroundings
LANDMARK_CONTRAST = 20.0
#: landmark_mask: Gaussian sigma (texels) that removes the grain first
LANDMARK_SIGMA = 2.0


def landmark_mask(image: np.ndarray, *, periodic: bool = True,
                  size: int = LANDMARK_SIZE,
                  contrast: float = LANDMARK_CONTRAST) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) bool dark and bright features narrower than ``size`` standing out by ``contrast``.

    Black-hat and top-hat with an elliptic element of diameter ``size`` (odd, >= 3) on the
    luma blurred by ``LANDMARK_SIGMA``, over ``contrast`` (0..255). ``periodic``: wrap the
    edges (a tile), else replicate them (a photo window).
    """
    lum = _luma(image, "image").astype(np.float32)
    if size < 3 or size % 2 == 0:
        raise TerrathemeError(f"landmark size must be odd and at least 3, not {size}")
    # Pad by the element's reach (wrapping for a tile), then remove the grain.
    pad = np.pad(lum, size, mode="wrap" if periodic else "edge")
    pad = cv2.GaussianBlur(pad, (0, 0), LANDMARK_SIGMA)
    element = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    out = []
    for op in (cv2.MORPH_BLACKHAT, cv2.MORPH_TOPHAT):
        response = cv2.morphologyEx(pad, op, element)[size:-size, size:-size]
        out.append(response > contrast)
    return out[0], out[1]


def landmark_score(texture: np.ndarray, *, size: int = LANDMARK_SIZE,
                   contrast: float = LANDMARK_CONTRAST) -> float:
    """Area of the largest landmark of a tileable texture (:func:`landmark_mask`) over the tile's.

    8-connected across the wrap edges; a network running on into the next tiles (streets)
    can score above 1.
    """
    best = 0
    for mask in landmark_mask(texture, size=size, contrast=contrast):
        # Tile 3 x 3 so a feature crossing the wrap edge is one component.
        tiled = np.tile(mask.astype(np.uint8), (3, 3))
        n, _labels, stats, _ = cv2.connectedComponentsWithStats(tiled, connectivity=8)
        if n > 1:
            best = max(best, int(stats[1:, cv2.CC_STAT_AREA].max()))
    return best / mask.size


#: a tile repeating more than this (:func:`repeat_score`) or holding a larger landmark
#: (:func:`landmark_score`) shows its grid: a theme cut is replaced
REPEAT_LIMIT = 0.3
LANDMARK_LIMIT = 0.04


def tiles_unseen(texture: np.ndarray) -> tuple[float, bool]:
    """``(repeat_score, unseen)``: unseen when a tileable texture stays under both limits."""
    repeat = repeat_score(texture)
    return repeat, repeat <= REPEAT_LIMIT and landmark_score(texture) <= LANDMARK_LIMIT
