"""Border bands: a theme whose colour is a blend of two others, seen only along their border.

Features smoothed over a coarse pixel's neighbourhood make a step edge look
like texture: along a high-contrast border (bright sand beside dark grass)
the blurred colour lies between the two sides and the lightness spread and
gradient are high, so a band of a few coarse pixels takes a textured theme
whose colour lies between the two (town) although no photo pixel there
looks like it (issue 13).

:func:`relabel_bands` undoes this at photo pixels. A pixel of theme ``T`` is
in a *band* of two other themes ``A`` and ``B`` when both lie within
``reach`` photo pixels of it along each axis (a square window) and ``T``'s
colour lies between theme colours ``A`` and ``B`` (:func:`lies_between`).
Its own Lab then decides: it takes the nearer of ``A`` and ``B`` (squared
Mahalanobis distance under their per-pixel colour spread) if that distance
is at most ``max_distance2``, and keeps ``T`` otherwise. Only a
high-contrast border makes such a band: ``A`` and ``B`` must differ by at
least ``min_contrast2`` (squared Mahalanobis distance of their means under
the sum of their variances); in a photo whose themes differ by a few
standard deviations of lightness each, every middle theme lies between
two others and the pixel colours cannot tell them apart. A road of town
inside town has town all round and is untouched; a thin road or channel of
its own colour between two themes is far from both in colour and keeps its
theme; only the blend pixels, which look like one side or the other, change.
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
        Photo pixels, along each axis, within which both bordering themes
        must lie (0 turns the pass off); about the width of a blend band at 4x4
        coarse pixels.
    max_distance2 : float
        Largest squared Mahalanobis distance (Lab, 3 degrees of freedom) to a
        bordering theme's colour for a pixel to take it. Default 11.34, the 99%
        quantile of chi-squared with 3 degrees of freedom.
    min_contrast2 : float
        Smallest squared Mahalanobis distance between the two bordering
        themes' means (under the sum of their variances). Default 16: four
        standard deviations apart (only a high-contrast border makes a band).
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

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        Themes ``1..K``, 0 where there is no data (never changed).
    rgb : (H, W, 3) uint8 ndarray
        The photo.
    means, variances : (K, 3) ndarrays
        Per-pixel Lab mean and variance of each theme (L 0..100, a, b about
        -128..127); variances positive.
    options : BandOptions

    Returns
    -------
    labels : (H, W) uint8 ndarray
        A new array (the input is not modified); the same values when
        ``options.reach`` is 0 or there are more than :data:`MAX_BAND_THEMES`
        themes.

    Raises
    ------
    TerrathemeError
        Shapes that do not match, or variances that are not positive.
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
    # dilation with a rectangle is separable, 14x faster than a distance transform).
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
