"""Detail themes: a theme's fine texture as a ratio around mid-grey, for the terrain engines' split.

With a fine colour map (:mod:`core.convert.colour_fit`) the map carries
everything above a few texels, roads and blocks where the photo has them,
and a theme only the detail finer than that (issue 34): a town theme's own
road pieces at 4-16 texels, quilted at random angles, would lay a
kaleidoscope over the map's streets. A detail theme is the texture over its
own wrap-around Gaussian blur, times :data:`NEUTRAL` (128): mid-grey with the
fine contrast, as engines' detail textures are, so the map's stored gain is
the photo's colour itself (a coloured theme's dark class needed gains past
the map's x1.99 and clipped: dE8 2.0 against 1.15 on a lake photo). The
fine contrast is scaled to the photo's own in the theme's class
(:func:`detail_gains`), so the render is as sharp as the photo.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter
from skimage.feature import structure_tensor
from terratheme.core.themes.library import ThemeLibrary

#: Gaussian sigma (texels) above which a detail theme is flat
DETAIL_SIGMA = 3.0
#: the value of a detail theme's mean (the colour map's neutral gain)
NEUTRAL = 128
#: range of the contrast gain of :func:`detail_gains`
GAIN_RANGE = (0.25, 4.0)
#: Gaussian sigma (texels) of the local contrast strength :func:`even_detail` evens out
EVEN_SIGMA = 4.0
#: range of :func:`even_detail`'s factor
EVEN_RANGE = (0.25, 4.0)
#: :func:`edge_coherence` above which a theme's detail is made of fragments (:func:`theme_detail`)
FRAGMENT_COHERENCE = 0.55
#: Gaussian sigma (texels) of a fragment theme's detail (:func:`theme_detail`)
CALM_SIGMA = 2.5
#: the seed of :func:`theme_detail`'s random phases (the same themes every run)
PHASE_SEED = 0


def _relative(image: np.ndarray, sigma: float, wrap: bool) -> np.ndarray:
    """``image / blur(image) - 1`` (float32), the blur wrapping around or reflecting."""
    t = np.asarray(image, np.float32)
    axes = (sigma, sigma, 0) if t.ndim == 3 else sigma
    low = gaussian_filter(t, axes, mode="wrap" if wrap else "reflect")
    return t / np.maximum(low, 1.0) - 1.0


def even_detail(texture: np.ndarray, sigma: float = DETAIL_SIGMA) -> np.ndarray:
    """A tileable texture's relative fine contrast, its local strength made even.

    ``t / blur(t) - 1`` divided by its local RMS (a wrap-around Gaussian of
    :data:`EVEN_SIGMA` texels) over the whole texture's, the factor within
    :data:`EVEN_RANGE`: a flat strip left by making a theme tileable does not
    repeat as a band every period, and a theme's few strong edges (road
    pieces in a town theme) do not stand out of its texture.

    Returns
    -------
    (h, w, 3) float32 ndarray
    """
    rel = _relative(texture, sigma, wrap=True)
    power = rel.mean(axis=2) ** 2
    local = gaussian_filter(power, EVEN_SIGMA, mode="wrap")
    total = float(power.mean())
    if total <= 1e-12:
        return rel
    factor = np.clip(np.sqrt(total / np.maximum(local, 1e-12)), *EVEN_RANGE)
    return rel * factor[:, :, None].astype(np.float32)


def edge_coherence(texture: np.ndarray, sigma: float = DETAIL_SIGMA) -> float:
    """How much of a tileable texture's fine contrast lies along oriented edges, 0..1.

    The structure tensor (smoothed over 2 texels, wrapping around) of the
    luminance's ``t / blur(t) - 1``: the sum of ``lambda1 - lambda2`` over the
    sum of ``lambda1 + lambda2``. Stripes give 1, isotropic grain little; a
    town theme quilted from road and building pieces about 0.55.
    """
    rel = _relative(np.asarray(texture, np.float32).mean(axis=2), sigma, wrap=True)
    arr, arc, acc = structure_tensor(rel, sigma=2.0, mode="wrap")
    trace = float((arr + acc).sum())
    if trace <= 1e-12:
        return 0.0
    return float(np.sqrt((arr - acc) ** 2 + 4.0 * arc ** 2).sum() / trace)


def theme_detail(texture: np.ndarray, sigma: float = DETAIL_SIGMA) -> tuple[np.ndarray, float]:
    """A theme's relative fine contrast (:func:`even_detail`) and the sigma it was taken at.

    A theme made of oriented fragments (:func:`edge_coherence` above
    :data:`FRAGMENT_COHERENCE`: a town theme's road and building pieces) keeps
    only its contrast finer than :data:`CALM_SIGMA`, its phases randomised
    (the same random phases for the three channels, seeded): the same power
    spectrum without its edges, so the colour map's own streets read through
    instead of a kaleidoscope of pieces at random angles (issue 34).

    Returns
    -------
    ((h, w, 3) float32 ndarray, float)
    """
    if edge_coherence(texture, sigma) <= FRAGMENT_COHERENCE:
        return even_detail(texture, sigma), sigma
    sigma = min(sigma, CALM_SIGMA)
    rel = even_detail(texture, sigma)
    noise = np.random.default_rng(PHASE_SEED).standard_normal(rel.shape[:2])
    phases = np.exp(1j * np.angle(np.fft.fft2(noise)))
    phases[0, 0] = 1.0  # the mean stays
    phases = phases[:, :, None]
    out = np.fft.ifft2(np.fft.fft2(rel, axes=(0, 1)) * phases, axes=(0, 1)).real
    return out.astype(np.float32), sigma


def detail_texture(texture: np.ndarray, sigma: float = DETAIL_SIGMA,
                   gain: float = 1.0) -> np.ndarray:
    """A tileable texture's fine contrast around mid-grey: ``128 (1 + gain theme_detail(t))``.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray
        Tileable (the blur wraps around its edges, so the result is too).
    sigma : float
        Gaussian sigma in texels.
    gain : float
        Contrast multiplier.

    Returns
    -------
    (h, w, 3) uint8 ndarray
        Clipped to 0..255.
    """
    out = NEUTRAL * (1.0 + gain * theme_detail(texture, sigma)[0])
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def detail_energy(image: np.ndarray, sigma: float = DETAIL_SIGMA, *, wrap: bool = False,
                  valid: np.ndarray | None = None) -> float:
    """Mean square of the relative fine contrast ``Y / blur(Y) - 1`` of an image's luminance.

    ``Y`` is the mean of the channels; ``wrap``: a tileable texture.
    ``valid``: (H, W) bool, the pixels to average over (default all).
    """
    y = np.asarray(image, np.float32).mean(axis=2)
    rel = _relative(y, sigma, wrap) ** 2
    return float(rel.mean() if valid is None else rel[valid].mean())


def detail_gains(photo: np.ndarray, theme_labels: np.ndarray, library: ThemeLibrary,
                 sigma: float = DETAIL_SIGMA) -> list[float]:
    """Per theme, the contrast gain that gives its detail the photo's in its class.

    ``sqrt(photo energy over the theme's pixels / theme energy)``, both at the
    sigma :func:`theme_detail` takes the theme's at (:func:`detail_energy`;
    the theme's of :func:`theme_detail`), clipped to
    :data:`GAIN_RANGE`; 1 for a theme no pixel takes or a flat theme.

    Parameters
    ----------
    photo : (H, W, 3) uint8 ndarray
    theme_labels : (H, W) uint8 ndarray
        Theme index per pixel.
    library : ThemeLibrary
    """
    y = np.asarray(photo, np.float32).mean(axis=2)
    labels = np.asarray(theme_labels).ravel()
    counts = np.bincount(labels, minlength=len(library))
    sums: dict[float, np.ndarray] = {}
    gains = []
    for k, theme in enumerate(library):
        rel, s = theme_detail(theme.texture, sigma)
        own = float((rel.mean(axis=2) ** 2).mean())
        if counts[k] == 0 or own <= 1e-12:
            gains.append(1.0)
            continue
        if s not in sums:
            sums[s] = np.bincount(labels, (_relative(y, s, wrap=False) ** 2).ravel(),
                                  minlength=len(library))
        gains.append(float(np.clip(np.sqrt(sums[s][k] / counts[k] / own), *GAIN_RANGE)))
    return gains


def detail_library(library: ThemeLibrary, sigma: float = DETAIL_SIGMA,
                   gains: Sequence[float] | None = None) -> ThemeLibrary:
    """Every theme of ``library`` as its :func:`detail_texture` (names and colours kept)."""
    gains = [1.0] * len(library) if gains is None else list(gains)
    return ThemeLibrary(t.with_(texture=detail_texture(t.texture, sigma, g))
                        for t, g in zip(library, gains, strict=True))
