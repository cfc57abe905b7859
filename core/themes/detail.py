"""Detail themes: a theme's fine texture around its mean colour, for the terrain engines' split.

With a fine colour map (:mod:`core.convert.colour_fit`) the map carries
everything above a few texels, roads and blocks where the photo has them,
and a theme only the detail finer than that (issue 34): a town theme's own
road pieces at 4-16 texels, quilted at random angles, would lay a
kaleidoscope over the map's streets. :func:`detail_texture` keeps the
high-pass of a tileable texture (minus a wrap-around Gaussian blur) plus its
mean colour, so the theme stays tileable and keeps its colour.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter
from terratheme.core.themes.library import ThemeLibrary

#: Gaussian sigma (texels) above which a detail theme is flat
DETAIL_SIGMA = 3.0


def detail_texture(texture: np.ndarray, sigma: float = DETAIL_SIGMA) -> np.ndarray:
    """A tileable texture's detail finer than ``sigma`` around its mean colour.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray
        Tileable (the blur wraps around its edges, so the result is too).
    sigma : float
        Gaussian sigma in texels.

    Returns
    -------
    (h, w, 3) uint8 ndarray
        ``texture - blur(texture) + mean``, clipped to 0..255.
    """
    t = np.asarray(texture, np.float32)
    low = gaussian_filter(t, (sigma, sigma, 0), mode="wrap")
    out = t - low + t.mean(axis=(0, 1))
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def detail_library(library: ThemeLibrary, sigma: float = DETAIL_SIGMA) -> ThemeLibrary:
    """Every theme of ``library`` as its :func:`detail_texture` (names and colours kept)."""
    return ThemeLibrary(t.with_(texture=detail_texture(t.texture, sigma)) for t in library)
