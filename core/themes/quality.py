"""How obviously a tileable texture repeats: banding, ghosting and landmarks.

Three measures on the luminance of a texture tiled periodically (the first
two use the FFT, which treats the texture as one period of an infinite tiling):

* :func:`lowfreq_score` -- the share of the texture's contrast carried by
  waves of at most ``cycles`` periods per tile. When a tile is repeated,
  such waves (a dark band, a bright corner) become a regular grid that the
  eye picks out at once, while finer texture does not line up visibly.
* :func:`repeat_score` -- the highest normalised circular autocorrelation of
  the texture's fine detail at any non-trivial shift. A texture made
  tileable by mixing it with a shifted copy of itself (a cross-fade ghost,
  or a copied strip) correlates with itself at that shift; a texture whose
  detail never repeats within the tile scores near ``3 / sqrt(h * w)``.
* :func:`landmark_score` -- the area of the largest dark or bright feature
  that stands out from the texture's grain (a channel, a path, a lone
  building), as a share of the tile: tiled, such a landmark repeats once per tile and
  the eye finds the grid through it. :func:`landmark_mask` gives the pixels.

None needs the source patch, so they also rate shipped texture files.
"""

from __future__ import annotations

import cv2
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import validate_texture

#: Rec. 601 luma weights
_LUMA = np.array([0.299, 0.587, 0.114], np.float64)


def _luma(texture: np.ndarray, name: str) -> np.ndarray:
    img = validate_texture(texture, name=name)
    h, w = img.shape[:2]
    if h < 4 or w < 4:
        raise TerrathemeError(f"{name} {w} x {h} is too small to rate (need 4 x 4)")
    return img.astype(np.float64) @ _LUMA


def _cycles(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) signed frequencies in cycles per tile along y and x."""
    return np.fft.fftfreq(h)[:, None] * h, np.fft.fftfreq(w)[None, :] * w


def lowfreq_score(texture: np.ndarray, cycles: float = 2.0) -> float:
    """RMS of the luminance waves of at most ``cycles`` per tile over the RMS of all of it.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray (at least 4 x 4)
    cycles : float
        Radial frequency bound, in periods per tile (per axis, scaled so a
        non-square tile counts periods along each side).

    Returns
    -------
    score : float
        In [0, 1]: 0 for a texture with no variation slower than ``cycles``
        per tile (or a flat one); 1 for a single smooth gradient.
    """
    lum = _luma(texture, "texture")
    spec = np.abs(np.fft.fft2(lum - lum.mean())) ** 2
    ky, kx = _cycles(*lum.shape)
    low = (np.hypot(ky, kx) <= cycles) & ((ky != 0) | (kx != 0))
    total = float(spec.sum())
    return 0.0 if total <= 1e-9 else float(np.sqrt(spec[low].sum() / total))


def repeat_score(texture: np.ndarray, detail: float = 3.0, exclude: int = 4) -> float:
    """Largest normalised circular autocorrelation of the texture's fine detail.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray (at least 4 x 4)
    detail : float
        The detail is the luminance minus its periodic Gaussian blur of this
        sigma (texels), computed in the Fourier domain.
    exclude : int
        Shifts within this many texels of zero (circularly, on both axes)
        are ignored: there every texture correlates with itself.

    Returns
    -------
    score : float
        In [-1, 1]; about 1 when a part of the tile is a copy of another
        part, near 0 when the detail never repeats. 0 for a flat texture.
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
    """Dark and bright features narrower than ``size`` that stand out by ``contrast``.

    Morphological black-hat (dark features) and top-hat (bright features)
    with an elliptic structuring element of diameter ``size`` on the luminance
    blurred by ``LANDMARK_SIGMA`` texels; a pixel is part of a feature where
    the response exceeds ``contrast``.

    Parameters
    ----------
    image : (h, w, 3) uint8 ndarray (at least 4 x 4)
    periodic : bool
        Treat the image as one period of a tiling (wrap at the edges), as for
        a tileable texture; else replicate its border (a photo window).
    size : int
        Structuring element diameter in texels (odd, at least 3).
    contrast : float
        Luma difference, 0..255.

    Returns
    -------
    dark, bright : (h, w) bool ndarrays
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
    """Area of the largest landmark of a tileable texture, as a share of the tile.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray (at least 4 x 4)
    size, contrast : see :func:`landmark_mask`

    Returns
    -------
    score : float
        0 when no feature stands out; the share of the tile covered by the
        largest connected dark or bright feature (8-connected, across the
        wrap edges). A feature network that runs on into the neighbouring
        tiles, like streets, can score above 1.
    """
    best = 0
    for mask in landmark_mask(texture, size=size, contrast=contrast):
        # Tile 3 x 3 so a feature crossing the wrap edge is one component.
        tiled = np.tile(mask.astype(np.uint8), (3, 3))
        n, _labels, stats, _ = cv2.connectedComponentsWithStats(tiled, connectivity=8)
        if n > 1:
            best = max(best, int(stats[1:, cv2.CC_STAT_AREA].max()))
    return best / mask.size
