"""Detail themes: a theme's fine texture as a ratio around mid-grey (issue 34).

With a fine colour map (:mod:`core.convert.colour_fit`) the map carries everything above
a few texels and a theme only the finer detail, ``NEUTRAL * t / blur(t)``, its contrast
scaled to the photo's in its class (:func:`detail_themes`), as engines' detail textures are,
and flat from its mip level 2 up (:func:`mip_flat`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter, zoom
from scipy.signal import resample
from skimage.feature import structure_tensor
from terratheme.core.themes.library import ThemeLibrary

#: Gaussian sigma (texels) above which a detail theme is flat
DETAIL_SIGMA = 3.0
#: a detail theme's contrast over the photo's at :data:`DETAIL_SIGMA` in its class
DETAIL_CONTRAST = 1.5
#: the value of a detail theme's mean (the colour map's neutral gain)
NEUTRAL = 128
#: range of the contrast gain of :func:`detail_themes`
GAIN_RANGE = (0.25, 4.0)
#: Gaussian sigma (texels) of the local contrast strength :func:`even_detail` evens out
EVEN_SIGMA = 4.0
#: range of :func:`even_detail`'s factor
EVEN_RANGE = (0.25, 4.0)
#: :func:`edge_coherence` above which a theme's detail is made of fragments (:func:`theme_detail`)
FRAGMENT_COHERENCE = 0.5
#: Gaussian sigma (texels) at which :func:`theme_detail` measures :func:`edge_coherence`
COHERENCE_SIGMA = 3.0
#: the most relative RMS contrast a fragment theme's detail reaches (:func:`detail_themes`)
FRAGMENT_CONTRAST = 0.12
#: a class's contrast counts at most this many times its robust amplitude, 1.4826 x the
#: median |relative| (:func:`detail_themes`)
TAIL_CAP = 1.0
#: the seed of :func:`theme_detail`'s random phases (the same themes every run)
PHASE_SEED = 0
#: a theme with a side under this many texels has its phases randomised (:func:`theme_detail`)
LATTICE_SIDE = 128
#: side (texels) of the aligned blocks a detail theme averages to neutral over (:func:`mip_flat`)
MIP_FLAT = 4


def _relative(image: np.ndarray, sigma: float, wrap: bool) -> np.ndarray:
    """``image / blur(image) - 1`` (float32), the blur wrapping around or reflecting."""
    t = np.asarray(image, np.float32)
    axes = (sigma, sigma, 0) if t.ndim == 3 else sigma
    low = gaussian_filter(t, axes, mode="wrap" if wrap else "reflect")
    return t / np.maximum(low, 1.0) - 1.0


def even_detail(texture: np.ndarray, sigma: float = DETAIL_SIGMA) -> np.ndarray:
    """(h, w, 3) float32: ``t / blur(t) - 1`` with its local RMS made even.

    Divided by its local RMS (sigma ``EVEN_SIGMA``, wrapping) over the whole texture's,
    clipped to ``EVEN_RANGE``: no flat strip or lone strong edge repeats every period.
    """
    rel = _relative(texture, sigma, wrap=True)
    power = rel.mean(axis=2) ** 2
    local = gaussian_filter(power, EVEN_SIGMA, mode="wrap")
    total = float(power.mean())
    if total <= 1e-12:
        return rel
    factor = np.clip(np.sqrt(total / np.maximum(local, 1e-12)), *EVEN_RANGE)
    return rel * factor[:, :, None].astype(np.float32)


def edge_coherence(texture: np.ndarray, sigma: float = COHERENCE_SIGMA) -> float:
    """Share of a tileable texture's fine contrast along oriented edges, 0..1.

    From the structure tensor of the luma's ``t / blur(t) - 1``:
    ``sum(lambda1 - lambda2) / sum(lambda1 + lambda2)``; stripes give 1, grain little.
    """
    rel = _relative(np.asarray(texture, np.float32).mean(axis=2), sigma, wrap=True)
    arr, arc, acc = structure_tensor(rel, sigma=2.0, mode="wrap")
    trace = float((arr + acc).sum())
    if trace <= 1e-12:
        return 0.0
    return float(np.sqrt((arr - acc) ** 2 + 4.0 * arc ** 2).sum() / trace)


def mip_flat(rel: np.ndarray, block: int = MIP_FLAT) -> np.ndarray:
    """(H, W, 3) float32: a tileable (h, w, 3) ``rel``, Fourier-resampled to sides of whole
    ``block``s, minus the smooth (bilinear, wrapping) field of its block means: its aligned
    blocks average to 0 with no edges, so a view at ``1 / block`` sees the colour map alone.
    """
    size = [max(block, round(n / block) * block) for n in rel.shape[:2]]
    for axis, n in enumerate(size):
        rel = rel if rel.shape[axis] == n else resample(rel, n, axis=axis)
    rel, (hb, wb) = np.asarray(rel, np.float64), (size[0] // block, size[1] // block)

    def means(a: np.ndarray) -> np.ndarray:
        return a.reshape(hb, block, wb, block, -1).mean(axis=(1, 3))

    def smooth(c: np.ndarray) -> np.ndarray:
        return zoom(c, (block, block, 1), order=1, mode="grid-wrap", grid_mode=True)

    # Step 1: the lattice's transfer function of smooth-then-mean, from one impulse.
    impulse = np.zeros((hb, wb, 1))
    impulse[0, 0] = 1.0
    transfer = np.fft.fft2(means(smooth(impulse)), axes=(0, 1))
    # Step 2: the block field whose smooth version has the texture's block means.
    field = np.fft.ifft2(np.fft.fft2(means(rel), axes=(0, 1)) / transfer, axes=(0, 1)).real
    return (rel - smooth(field)).astype(np.float32)


def theme_detail(texture: np.ndarray, sigma: float = DETAIL_SIGMA
                 ) -> tuple[np.ndarray, bool]:
    """((H, W, 3) float32, fragment): a theme's :func:`mip_flat` :func:`even_detail`; a
    fragment theme (coherence above ``FRAGMENT_COHERENCE``: a town's road pieces) with its
    phases randomised, so the map's streets read through, not a kaleidoscope of pieces.

    A theme with a side under ``LATTICE_SIDE`` has its phases randomised too (it stays no
    fragment): repeated every few dozen texels, its one roundabout or roof would show as a
    lattice of rings or dots.
    """
    rel = even_detail(texture, sigma)
    fragment = edge_coherence(texture) > FRAGMENT_COHERENCE
    if fragment or min(np.shape(texture)[:2]) < LATTICE_SIDE:
        rel = _random_phases(rel)
    return mip_flat(rel), fragment


def _random_phases(rel: np.ndarray) -> np.ndarray:
    """(h, w, 3) float32: ``rel`` with seeded random Fourier phases, its power spectrum kept."""
    noise = np.random.default_rng(PHASE_SEED).standard_normal(rel.shape[:2])
    phases = np.exp(1j * np.angle(np.fft.fft2(noise)))
    phases[0, 0] = 1.0  # the mean stays
    out = np.fft.ifft2(np.fft.fft2(rel, axes=(0, 1)) * phases[:, :, None], axes=(0, 1)).real
    return out.astype(np.float32)


def detail_texture(texture: np.ndarray, sigma: float = DETAIL_SIGMA,
                   gain: float = 1.0) -> np.ndarray:
    """(H, W, 3) uint8: ``128 (1 + gain theme_detail(t))`` of a tileable texture, clipped."""
    return _detail_bytes(theme_detail(texture, sigma)[0], gain)


def _detail_bytes(rel: np.ndarray, gain: float) -> np.ndarray:
    out = NEUTRAL * (1.0 + gain * rel)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def luminance(photo: np.ndarray) -> np.ndarray:
    """(H, W) float32: the mean of an (H, W, 3+) photo's first three bands."""
    return np.asarray(photo, np.float32)[..., :3].mean(axis=2)


def photo_contrast(photo: np.ndarray, sigma: float = DETAIL_SIGMA) -> np.ndarray:
    """(H, W) float32: the (H, W, 3) photo's relative :func:`luminance` contrast
    ``y / blur(y) - 1`` at ``sigma`` (reflecting at its edges), which :func:`detail_themes`
    matches."""
    return _relative(luminance(photo), sigma, wrap=False)


def detail_themes(photo: np.ndarray, theme_labels: np.ndarray, library: ThemeLibrary,
                  sigma: float = DETAIL_SIGMA, *,
                  details: Sequence[tuple[np.ndarray, bool]] | None = None,
                  contrast: np.ndarray | None = None
                  ) -> tuple[ThemeLibrary, list[float]]:
    """Every theme as its detail texture at the photo's contrast in its class; and the gains.

    Gain: ``DETAIL_CONTRAST sqrt(photo energy over the theme's pixels / theme energy)`` at
    ``sigma``, the photo's energy at most ``(TAIL_CAP x its robust amplitude)^2`` (a road
    class's cars and marks do not set the grain of its whole theme; a fragment theme's at
    most ``FRAGMENT_CONTRAST / its RMS``), clipped to ``GAIN_RANGE``; 1 for an unused or
    flat theme. ``photo``: (H, W, 3) uint8; ``theme_labels``: (H, W) uint8 theme per
    pixel. Names and colours are kept. ``details``: each theme's :func:`theme_detail` at
    ``sigma``, when the caller has them already (one per theme of ``library``);
    ``contrast``: the photo's :func:`photo_contrast` at ``sigma``, likewise.
    """
    if details is None:
        details = [theme_detail(t.texture, sigma) for t in library]
    labels = np.asarray(theme_labels).ravel()
    relative = (photo_contrast(photo, sigma) if contrast is None else contrast).ravel()
    counts = np.bincount(labels, minlength=len(details))
    sums = np.bincount(labels, relative ** 2, minlength=len(details))
    gains = []
    for k, (rel, fragment) in enumerate(details):
        own = float((rel.mean(axis=2) ** 2).mean())
        if counts[k] == 0 or own <= 1e-12:
            gains.append(1.0)
            continue
        # The class's energy, its heavy tail cut at TAIL_CAP x its robust amplitude.
        robust = 1.4826 * float(np.median(np.abs(relative[labels == k])))
        energy = min(float(sums[k] / counts[k]), (TAIL_CAP * robust) ** 2)
        gain = DETAIL_CONTRAST * np.sqrt(energy / own)
        if fragment:
            # Scrambled fragments match the photo's edges in energy only: at a town's full
            # contrast they read as dark speckle over the map's streets.
            gain = min(gain, FRAGMENT_CONTRAST / np.sqrt(own))
        gains.append(float(np.clip(gain, *GAIN_RANGE)))
    themes = ThemeLibrary(t.with_(texture=_detail_bytes(rel, g))
                          for t, (rel, _), g in zip(library, details, gains, strict=True))
    return themes, gains
