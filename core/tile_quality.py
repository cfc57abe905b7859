"""How obviously a tileable texture repeats: low-frequency banding and ghosting.

Two measures on the luminance of a texture tiled periodically (both use the
FFT, which treats the texture as one period of an infinite tiling):

* :func:`lowfreq_score` -- the share of the texture's contrast carried by
  waves of at most ``cycles`` periods per tile. When a tile is repeated,
  such waves (a dark band, a bright corner) become a regular grid that the
  eye picks out at once, while finer texture does not line up visibly.
* :func:`repeat_score` -- the highest normalised circular autocorrelation of
  the texture's fine detail at any non-trivial shift. A texture made
  tileable by mixing it with a shifted copy of itself (a cross-fade ghost,
  or a copied strip) correlates with itself at that shift; a texture whose
  detail never repeats within the tile scores near ``3 / sqrt(h * w)``.

Neither needs the source patch, so they also rate shipped texture files.
"""

from __future__ import annotations

import numpy as np

from core.errors import TerrathemeError
from core.themes import validate_texture

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
