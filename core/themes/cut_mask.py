"""What a theme cut keeps of its photo window, and how the rest is filled.

Other classes' pixels, the class's border rim, lone objects and faint lone marks would
repeat once per tile; :func:`cut_window` fills them with shifted pieces of the class's
own pixels before the patch is made tileable.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.fft import irfft2, next_fast_len, rfft2
from scipy.ndimage import maximum
from skimage.filters import apply_hysteresis_threshold
from terratheme.core.themes.quality import LANDMARK_CONTRAST, LANDMARK_SIZE, LUMA, landmark_mask

#: Rec. 601 luma weights
_LUMA = LUMA.astype(np.float32)


#: a filled hole copies the class's pixels whose low-pass luma lies within this many
#: robust spreads of their median first (not a dark channel next to the hole)
TYPICAL_SPREADS = 2.5
#: Gaussian sigma (texels) of that low-pass
TYPICAL_SIGMA = 6.0
#: copies laid at most per fill (each the shift covering the most of what is left)
FILL_COPIES = 32


def _fft_size(shape: tuple[int, ...]) -> tuple[int, int]:
    """A fast FFT size of at least twice each side: shifts by it never wrap a patch onto itself."""
    return next_fast_len(2 * shape[0], real=True), next_fast_len(2 * shape[1], real=True)


def _coverage(hole: np.ndarray, source: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(size) float32: per shift ``d`` (mod ``size``), the hole pixels with ``source[p - d]``."""
    return irfft2(rfft2(hole.astype(np.float32), size) * np.conj(source), size)


def _shifted(image: np.ndarray, dy: int, dx: int, size: tuple[int, int]) -> np.ndarray:
    """``image`` moved by ``(dy, dx)`` (modulo ``size``), zero where it moved in."""
    h, w = image.shape[:2]
    pad = np.zeros((*size, *image.shape[2:]), image.dtype)
    pad[:h, :w] = image
    return np.roll(pad, (dy, dx), axis=(0, 1))[:h, :w]


def _typical(patch: np.ndarray, pixels: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(s, t) bool: ``pixels`` whose low-pass luma is near the median of the ``reference`` ones."""
    low = cv2.GaussianBlur(patch.astype(np.float32) @ _LUMA, (0, 0), TYPICAL_SIGMA)
    mid = float(np.median(low[reference]))
    spread = 1.4826 * float(np.median(np.abs(low[reference] - mid))) + 1.0
    return pixels & (np.abs(low - mid) <= TYPICAL_SPREADS * spread)


def fill_from_class(patch: np.ndarray, keep: np.ndarray, hole: np.ndarray | None = None, *,
                    first: np.ndarray | None = None) -> np.ndarray:
    """Fill the holes of a (s, t, 3) uint8 ``patch`` with shifted copies of its kept pixels.

    Each copy is the shift covering the most of the open hole (never wrapping), taken from
    ``first``'s typical pixels, then all ``first``, then the same of ``keep`` (the class's
    own pixels, at least one): a hole gets a few coherent pieces, not onion shells of its
    rim. ``hole`` defaults to all but ``keep``; masks are (s, t) bool.
    """
    out = patch.copy()
    hole = ~keep if hole is None else hole & ~keep
    # Typical is measured on the patch's own kept pixels (a window's, not those around it).
    own = keep if first is None or not (keep & ~first).any() else keep & ~first
    sources = [] if first is None or not first.any() else [_typical(patch, first, own), first]
    size = _fft_size(keep.shape)
    for source in (*sources, _typical(patch, keep, own), keep):
        spectrum = rfft2(source.astype(np.float32), size)
        for _ in range(FILL_COPIES):
            if not hole.any():
                return out
            # The shift whose copy of the source covers the most of the hole still open.
            coverage = _coverage(hole, spectrum, size)
            dy, dx = np.unravel_index(int(np.argmax(coverage)), size)
            take = hole & _shifted(source, dy, dx, size)
            if not take.any():
                break
            out[take] = _shifted(patch, dy, dx, size)[take]
            hole &= ~take
    if hole.any():
        out[hole] = patch[keep].reshape(-1, 3).mean(axis=0).astype(np.uint8)
    return out


#: an object stands out of its texture when it passes this many luma spreads (and 20 levels)
OBJECT_SPREADS = 4.0
#: the band marks are searched in: luma Gaussian sigmas (texels), thin strokes to small blobs
MARK_SIGMAS = (1.5, 6.0)
#: the local band energy is the squared band averaged over this Gaussian sigma (texels)
MARK_REACH = 4.0
#: a mark's local band energy passes this many times the window's median somewhere ...
MARK_RATIO = 12.0
#: ... and the mark reaches as far as it passes this many times
MARK_EXTENT = 6.0
#: band amplitude (luma levels) under which nothing is a mark
MARK_FLOOR = 2.0
#: a mark spans at most this share of the window's side (longer: a region's edge)
MARK_SPAN = 0.75
#: band amplitude (luma levels) from which a feature is no faint mark (landmark_mask rates it)
MARK_CEILING = 60.0
#: a mark's pixels are those where its band reaches this share of its peak
MARK_CORE = 0.25
#: marks carrying over this share of the window's band energy are its texture's own grain
MARK_SHARE = 0.25


def band_marks(window: np.ndarray, inside: np.ndarray | None = None,
               span: float | None = None) -> np.ndarray:
    """(s, t) bool: lone marks of a window, spots of band-pass energy far above its own.

    A faint thin stroke on sand passes (the sand's grain is fainter still); ripples, grass
    or streets, whose energy is much the same everywhere, do not, nor does a region's edge.
    Thresholds: the ``MARK_*`` constants. ``inside``: the pixels the median energy is
    taken over (default all); ``span``: longest mark side in texels (default
    ``MARK_SPAN`` of the shorter side).
    """
    lum = window.astype(np.float32) @ _LUMA
    # Band-pass of the luma: strokes and blobs, not the window's shading.
    band = (cv2.GaussianBlur(lum, (0, 0), MARK_SIGMAS[0])
            - cv2.GaussianBlur(lum, (0, 0), MARK_SIGMAS[1]))
    # Local band energy against the window's typical (median) energy.
    energy = cv2.GaussianBlur(band * band, (0, 0), MARK_REACH)
    typical = float(np.median(energy if inside is None or not inside.any() else energy[inside]))
    high = max(MARK_RATIO * typical, MARK_FLOOR**2)
    # The band clipped at twice a seed's amplitude: a strong mark's energy reaches no farther
    # than a faint one's.
    reach = 2.0 * np.sqrt(high)
    energy = cv2.GaussianBlur(np.clip(band, -reach, reach) ** 2, (0, 0), MARK_REACH)
    marks = apply_hysteresis_threshold(energy, high * MARK_EXTENT / MARK_RATIO, high)
    # Lone marks only: a feature spanning most of the window is a region's edge.
    n, labels, stats, _ = cv2.connectedComponentsWithStats(marks.astype(np.uint8), connectivity=8)
    extent = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    longest = MARK_SPAN * min(lum.shape) if span is None else span
    lone = (extent <= longest) & (np.arange(n) > 0)
    # A mark's pixels: where its band reaches MARK_CORE of its own peak (not the energy's halo).
    strength = np.abs(band)
    peak = np.zeros(n, np.float32)
    peak[1:] = maximum(strength, labels, np.arange(1, n))
    # Faint marks only: a stronger feature is the landmark test's, whose contrast rises with
    # the texture's spread (so a town keeps its houses).
    lone &= peak < MARK_CEILING
    marks = lone[labels] & (strength >= MARK_CORE * peak[labels])
    # Marks carrying much of the band energy are the texture's own grain (scattered stones).
    energy_in = band[marks] ** 2
    total = float((band[inside] ** 2).sum() if inside is not None else (band**2).sum())
    return marks if energy_in.sum() <= MARK_SHARE * total else np.zeros_like(marks)


def lone_objects(window: np.ndarray, inside: np.ndarray | None = None,
                 span: float | None = None) -> np.ndarray:
    """(s, s) bool: objects standing out of a patch's texture (a lone building in water).

    Features narrower than ``LANDMARK_SIZE`` above ``OBJECT_SPREADS`` luma spreads
    (:func:`landmark_mask`) and faint marks (:func:`band_marks`), grown by 2 px.
    """
    lum = window.astype(np.float32) @ _LUMA
    spread = float(np.std(lum - cv2.GaussianBlur(lum, (0, 0), LANDMARK_SIZE / 4)))
    dark, bright = landmark_mask(window, periodic=False,
                                 contrast=max(LANDMARK_CONTRAST, OBJECT_SPREADS * spread))
    found = dark | bright | band_marks(window, inside, span)
    grown = cv2.dilate(found.astype(np.uint8), np.ones((5, 5), np.uint8))
    return grown.astype(bool)


def cut_window(rgb: np.ndarray, mask: np.ndarray, x: int, y: int, s: int,
               interior: np.ndarray) -> np.ndarray:
    """(s, s, 3) uint8: the window at ``(x, y)`` with all but the class's plain texture filled.

    Other classes, the border rim and lone objects are filled from the class's pixels
    within half a side around the window first (no second copy of the tile in itself).
    ``interior``: (H, W) bool, the class's pixels in its :func:`interior_labels`.
    """
    h, w = mask.shape
    window = rgb[y : y + s, x : x + s]
    # The window and up to half a side around it (the class's texture the holes are filled from).
    m = s // 2
    x0, y0, x1, y1 = max(0, x - m), max(0, y - m), min(w, x + s + m), min(h, y + s + m)
    around = rgb[y0:y1, x0:x1]
    inner = interior[y0:y1, x0:x1].copy()
    at = (slice(y - y0, y - y0 + s), slice(x - x0, x - x0 + s))
    if not inner[at].any():
        inner[at] = mask[y : y + s, x : x + s]
    # Objects are found with the other classes painted in the class's median colour:
    # a dark rim left along a shore is then a line on sand, not the edge of the water.
    seen = around.copy()
    seen[~inner] = np.median(around[inner], axis=0).astype(np.uint8)
    keep = inner & ~lone_objects(seen, inner, span=MARK_SPAN * s)
    if keep[at].all():
        return window
    if not keep[at].any():
        keep[at] = inner[at]
    # The holes are the window's; the class's pixels around it are copied first.
    hole = np.zeros_like(keep)
    hole[at] = ~keep[at]
    outside = keep.copy()
    outside[at] = False
    filled = fill_from_class(around, keep, hole, first=outside)
    return match_surroundings(filled, around, keep, hole)[at]


def _masked_lowpass(image: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s, t, 3) Gaussian low-pass of ``pixels`` only and the (s, t, 1) share they reach."""
    weight = cv2.GaussianBlur(pixels.astype(np.float32), (0, 0), TYPICAL_SIGMA)
    values = np.where(pixels[..., None], image, 0).astype(np.float32)
    low = cv2.GaussianBlur(values, (0, 0), TYPICAL_SIGMA) / np.maximum(weight, 1e-6)[..., None]
    return low, np.minimum(weight / 0.05, 1.0)[..., None]


def match_surroundings(filled: np.ndarray, patch: np.ndarray, keep: np.ndarray,
                       hole: np.ndarray) -> np.ndarray:
    """(s, t, 3) uint8: the filled pixels given the low-pass colour of the kept pixels around.

    A piece copied from shade into sun keeps its grain but not its dark blob.
    """
    around, reach = _masked_lowpass(patch, keep)
    # Far inside a large hole no kept pixel reaches: the kept pixels' mean colour there.
    mean = patch[keep].reshape(-1, 3).mean(axis=0).astype(np.float32)
    around = reach * around + (1.0 - reach) * mean
    own, _ = _masked_lowpass(filled, hole)
    out = filled.copy()
    out[hole] = np.clip(np.rint(filled[hole] - own[hole] + around[hole]), 0, 255).astype(np.uint8)
    return out
