"""Border bands: a theme whose colour is a blend of two others, seen only along their border.

Smoothed features make a high-contrast step edge (sand | grass) look like a theme whose
colour lies between the two sides (design.md §3). :func:`relabel_bands` gives such a
pixel, with both sides within reach, the Mahalanobis-nearer side's theme by its own Lab.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from terratheme.core.classify.lab import full_lab
from terratheme.core.errors import TerrathemeError

#: The pass needs a (themes + 1) x 2^themes table; with more themes it is skipped.
MAX_BAND_THEMES = 12


@dataclass(frozen=True)
class BandOptions:
    """Options of :func:`relabel_bands`.

    Attributes
    ----------
    reach : int
        Photo pixels along each axis within which both bordering themes lie (0: off);
        about a blend band's width at 4x4 coarse pixels.
    max_distance2 : float
        Largest squared Mahalanobis distance (Lab) to the theme a pixel takes: the 99%
        point of chi-squared(3).
    min_contrast2 : float
        Smallest squared Mahalanobis distance between the bordering themes' means
        (under the sum of their variances): four standard deviations.
    """

    reach: int = 12
    max_distance2: float = 11.34
    min_contrast2: float = 16.0

    def __post_init__(self) -> None:
        if int(self.reach) != self.reach or self.reach < 0:
            raise TerrathemeError(f"band reach must be a whole number >= 0, not {self.reach}")
        if not self.max_distance2 > 0.0:
            raise TerrathemeError(f"band max_distance2 must be positive, not {self.max_distance2}")
        if not self.min_contrast2 >= 0.0:
            raise TerrathemeError(f"band min_contrast2 must be >= 0, not {self.min_contrast2}")


def lies_between(centres: np.ndarray, c: int) -> bool:
    """True if centre ``c`` lies near a segment of two others (:func:`between_pairs`)."""
    return bool(between_pairs(centres, c))


def between_pairs(centres: np.ndarray, c: int) -> list[tuple[int, int]]:
    """The pairs ``(a, b)``, ``a < b``, whose segment centre ``c`` of ``centres`` (K, D) lies
    within a quarter of its length of, strictly between its ends."""
    k, pairs = len(centres), []
    for a in range(k):
        for b in range(a + 1, k):
            if c in (a, b):
                continue
            ab = centres[b] - centres[a]
            length2 = float(ab @ ab)
            if length2 == 0.0:
                continue
            t = float(np.clip((centres[c] - centres[a]) @ ab / length2, 0.0, 1.0))
            dist = float(np.linalg.norm(centres[a] + t * ab - centres[c]))
            if 0.0 < t < 1.0 and dist < 0.25 * np.sqrt(length2):
                pairs.append((a, b))
    return pairs


def _candidate_table(means: np.ndarray, variances: np.ndarray,
                     min_contrast2: float) -> np.ndarray:
    """``table[label, near_bits]``: bit set of the themes a pixel may take (0: none).

    ``near_bits`` has bit ``c`` set when theme ``c`` (0-based, label ``c + 1``)
    lies within reach; label 0 (no data) never changes.
    """
    k = len(means)
    bits = np.arange(1 << k)
    table = np.zeros((k + 1, 1 << k), np.uint16)
    for t in range(k):
        for a, b in between_pairs(means, t):
            contrast2 = float(((means[a] - means[b]) ** 2 / (variances[a] + variances[b])).sum())
            if contrast2 < min_contrast2:
                continue
            both = ((bits >> a) & 1).astype(bool) & ((bits >> b) & 1).astype(bool)
            table[t + 1, both] |= np.uint16((1 << a) | (1 << b))
    return table


def relabel_bands(labels: np.ndarray, rgb: np.ndarray, means: np.ndarray,
                  variances: np.ndarray, options: BandOptions) -> np.ndarray:
    """Give the pixels of a blend theme along a border the colour-nearer side's theme.

    ``labels`` (H, W) uint8 holds themes 1..K (0: no data, never changed), ``rgb`` (H, W, 3)
    uint8 the photo, ``means``/``variances`` (K, 3) each theme's per-pixel Lab mean and
    (positive) variance. Returns a new (H, W) uint8 array, unchanged when ``reach`` is 0
    or there are over :data:`MAX_BAND_THEMES` themes.
    """
    means, variances = np.asarray(means, np.float64), np.asarray(variances, np.float64)
    k = len(means)
    if labels.shape != rgb.shape[:2] or means.shape != (k, 3) or variances.shape != (k, 3):
        raise TerrathemeError(f"band relabelling: labels {labels.shape}, photo {rgb.shape}, "
                              f"means {means.shape} and variances {variances.shape} do not match")
    if not (variances > 0.0).all():
        raise TerrathemeError("band relabelling needs positive colour variances")
    out = labels.copy()
    if options.reach == 0 or k < 3 or k > MAX_BAND_THEMES:
        return out
    table = _candidate_table(means, variances, options.min_contrast2)
    if not table.any():
        return out
    # Which themes lie within reach of each pixel, as a bit set (a square window: a
    # dilation with a rectangle is separable, unlike a distance transform).
    window = np.ones((2 * options.reach + 1, 2 * options.reach + 1), np.uint8)
    near = np.zeros(labels.shape, np.uint16)
    for c in range(k):
        near |= cv2.dilate((labels == c + 1).astype(np.uint8), window).astype(np.uint16) << c
    candidates = table[labels, near]
    rows, cols = np.nonzero(candidates)
    if len(rows) == 0:
        return out
    # Each band pixel's own colour against the themes it may take.
    lab = full_lab(np.ascontiguousarray(rgb[rows, cols])[:, None, :])[:, 0].astype(np.float64)
    d2 = (((lab[:, None, :] - means[None]) ** 2) / variances[None]).sum(2)
    allowed = ((candidates[rows, cols, None] >> np.arange(k)[None]) & 1).astype(bool)
    d2[~allowed] = np.inf
    best = d2.argmin(1)
    take = d2[np.arange(len(best)), best] <= options.max_distance2
    out[rows[take], cols[take]] = (best[take] + 1).astype(np.uint8)
    return out
