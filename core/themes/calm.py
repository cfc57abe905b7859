"""Calm twins: the calm part of a class as a second theme of the same texture (issue 34).

A detail theme's gain fits its class on the whole (:func:`.detail.detail_themes`). A class
that holds calm shallow water and textured weed, or a town's empty lots and its
buildings, then gets the same grain everywhere: too much where the photo is calm, too
little where it is busy. Where the photo's local detail energy within a class is bimodal,
its calm part becomes a twin theme: the same texture, with its own gain. So does a calm
area far under the class's typical energy that is too small to make it bimodal (still
shallows in a sea of waves): without a twin it shows as a patch of the sea's grain.

The energy is measured inside the class alone (normalised convolutions over its own
pixels), so the step at its border with another class does not count; it reaches
:data:`ENERGY_REACH` pixels, the context a tile needs to split as the whole photo does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter
from skimage.filters import threshold_otsu
from terratheme.core.themes.detail import DETAIL_SIGMA, luminance
from terratheme.core.themes.library import ThemeLibrary, distinct_names

#: Gaussian sigma (pixels) over which a pixel's detail energy is averaged
ENERGY_SIGMA = 32.0
#: the energy is averaged on blocks of this many pixels a side, aligned to the photo's
#: origin, so a tile has the whole photo's blocks
ENERGY_BLOCK = 4
#: a class splits only where its calm and busy parts' mean log2 energies are this far
#: apart, or its calm tail this far under its median (:func:`calm_threshold`)
TWIN_SEPARATION = 1.5
#: each part of a bimodal split holds at least this share of its class's pixels
TWIN_SHARE = 0.1
#: and at least this many pixels (a 64 px square: narrower parts are edges, not areas)
TWIN_MIN_PIXELS = 4096
#: pixels within this distance of a class's border weigh little in its energy
BORDER_PIXELS = 3
#: border pixels' weight
BORDER_WEIGHT = 1e-4
#: pixels of context the energy reaches (scipy's Gaussians stop at 4 sigma)
ENERGY_REACH = BORDER_PIXELS + int(np.ceil(4 * DETAIL_SIGMA + 4 * ENERGY_SIGMA)) + 2 * ENERGY_BLOCK
#: a twin's name: its theme's, then this
TWIN_SUFFIX = " calm"


@dataclass(frozen=True)
class CalmTwin:
    """Pixels of theme ``theme`` whose :func:`log_energy` is under ``threshold`` are
    theme ``twin`` instead."""

    theme: int
    twin: int
    threshold: float


def log_energy(photo: np.ndarray, mask: np.ndarray,
               origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """(H, W) float32: log2 of the local detail energy inside ``mask``, as the detail themes
    measure contrast (``y / blur(y) - 1`` at ``DETAIL_SIGMA``), both blurs over the
    mask's own pixels, those within ``BORDER_PIXELS`` of its border weighing
    ``BORDER_WEIGHT`` (a classifier's border pixels are often the neighbour's colour).

    The energy's wide blur runs on ``ENERGY_BLOCK`` blocks aligned to the photo's pixel
    (0, 0); ``origin``: the (x, y) of ``photo``'s first pixel in the photo (a tile's).
    ``photo``: (H, W, 3) uint8; ``mask``: (H, W) bool. Outside the mask the values mean
    nothing.
    """
    return _log_energy(luminance(photo), mask, origin)


def _log_energy(y: np.ndarray, mask: np.ndarray, origin: tuple[int, int]) -> np.ndarray:
    """:func:`log_energy` of the photo's (H, W) float32 :func:`.detail.luminance` ``y``."""
    inner = cv2.erode(np.asarray(mask, np.uint8), np.ones((2 * BORDER_PIXELS + 1,) * 2, np.uint8))
    m = np.where(inner > 0, 1.0, BORDER_WEIGHT * np.asarray(mask)).astype(np.float32)
    # Relative contrast against the class's own local mean (a normalised convolution).
    local = gaussian_filter(y * m, DETAIL_SIGMA, mode="reflect") / np.maximum(
        gaussian_filter(m, DETAIL_SIGMA, mode="reflect"), 1e-12)
    relative = y / np.maximum(local, 1.0) - 1.0
    # Its local mean energy over the class's pixels, on blocks aligned to the photo.
    b = ENERGY_BLOCK
    (h, w), (top, left) = y.shape, (origin[1] % b, origin[0] % b)
    shape = (-(-(h + top) // b) * b, -(-(w + left) // b) * b)

    def blocks(values: np.ndarray) -> np.ndarray:
        padded = np.zeros(shape, np.float32)
        padded[top:top + h, left:left + w] = values
        return padded.reshape(shape[0] // b, b, shape[1] // b, b).sum(axis=(1, 3))

    sigma = ENERGY_SIGMA / b
    energy = gaussian_filter(blocks(relative * relative * m), sigma, mode="reflect") / np.maximum(
        gaussian_filter(blocks(m), sigma, mode="reflect"), 1e-12)
    full = np.repeat(np.repeat(np.log2(energy + 1e-6), b, axis=0), b, axis=1)
    return full[top:top + h, left:left + w].astype(np.float32)


def class_log_energy(photo: np.ndarray, theme_labels: np.ndarray, themes: Sequence[int],
                     origin: tuple[int, int] = (0, 0), *, min_pixels: int = 1) -> np.ndarray:
    """(H, W) float32: each pixel of one of ``themes`` its :func:`log_energy` inside its
    theme's pixels, NaN at the others and at themes of fewer than ``min_pixels`` pixels.

    Measured once per photo (or tile) for both :func:`fit_calm_twins` and
    :func:`split_calm`. ``photo``: (H, W, 3) uint8; ``theme_labels``: (H, W) uint8;
    ``origin`` as :func:`log_energy`'s.
    """
    labels = np.asarray(theme_labels)
    out = np.full(labels.shape, np.nan, np.float32)
    y = None
    for k in sorted({int(t) for t in themes}):
        mask = labels == k
        if int(np.count_nonzero(mask)) >= max(min_pixels, 1):
            # The photo's luminance once for all its classes.
            y = luminance(photo) if y is None else y
            out[mask] = _log_energy(y, mask, origin)[mask]
    return out


def fit_calm_twins(energy: np.ndarray, theme_labels: np.ndarray,
                   themes: Sequence[int], first_twin: int) -> tuple[CalmTwin, ...]:
    """The twins of ``themes`` whose pixels' :func:`log_energy` is bimodal or has a calm tail
    (:func:`calm_threshold`). Twins are numbered from ``first_twin`` in theme order.
    ``energy``: (H, W) float32 :func:`class_log_energy` of ``themes``; ``theme_labels``:
    (H, W) uint8.
    """
    labels = np.asarray(theme_labels)
    twins: list[CalmTwin] = []
    for k in themes:
        values = energy[labels == k]
        if values.size < 2 * TWIN_MIN_PIXELS or np.isnan(values).any():
            continue
        threshold = calm_threshold(values)
        if threshold is not None:
            twins.append(CalmTwin(int(k), first_twin + len(twins), threshold))
    return tuple(twins)


def calm_threshold(values: np.ndarray) -> float | None:
    """The log2 energy under which a class's pixels are its calm twin's, or None.

    Otsu's threshold when it splits ``values`` (a class's :func:`log_energy`) into parts
    holding ``TWIN_SHARE`` of them and ``TWIN_MIN_PIXELS`` each, whose means are
    ``TWIN_SEPARATION`` apart; else ``TWIN_SEPARATION`` under their median when at least
    ``TWIN_MIN_PIXELS`` lie there (a calm area too small for the split).
    """
    values = np.asarray(values, np.float32).ravel()
    least = max(TWIN_MIN_PIXELS, TWIN_SHARE * values.size)
    if values.size >= 2 * least and float(values.max() - values.min()) >= TWIN_SEPARATION:
        threshold = float(threshold_otsu(values))
        calm, busy = values[values < threshold], values[values >= threshold]
        if (min(calm.size, busy.size) >= least
                and float(busy.mean()) - float(calm.mean()) >= TWIN_SEPARATION):
            return threshold
    tail = float(np.median(values)) - TWIN_SEPARATION
    if int(np.count_nonzero(values < tail)) >= TWIN_MIN_PIXELS:
        return tail
    return None


def renumbered(twins: Sequence[CalmTwin], first_twin: int) -> tuple[CalmTwin, ...]:
    """``twins`` numbered from ``first_twin`` in their order (their themes and thresholds
    kept): the twins of a library whose themes before them changed in number."""
    return tuple(CalmTwin(t.theme, first_twin + i, t.threshold) for i, t in enumerate(twins))


def split_calm(theme_labels: np.ndarray, twins: Sequence[CalmTwin],
               energy: np.ndarray) -> np.ndarray:
    """(H, W) uint8: ``theme_labels`` with each twin's calm pixels moved to it; ``energy``:
    the (H, W) :func:`class_log_energy` of (at least) the twins' themes."""
    labels = np.asarray(theme_labels)
    out = labels.copy()
    for twin in twins:
        out[(labels == twin.theme) & (energy < twin.threshold)] = twin.twin
    return out


def twin_vertices(indices: np.ndarray, split_indices: np.ndarray,
                  twins: Sequence[CalmTwin]) -> np.ndarray:
    """(rows, cols) uint8: a grid voted from theme labels, each vertex of a twinned theme
    taking its twin where the vote of the :func:`split_calm` labels chose the twin.

    The class grid (its cell, agreement and cleaning) stays as it was; only which of a
    class's two themes a vertex shows is added.
    """
    out = np.array(indices, np.uint8, copy=True)
    for twin in twins:
        out[(indices == twin.theme) & (split_indices == twin.twin)] = twin.twin
    return out


def with_twins(library: ThemeLibrary, twins: Sequence[CalmTwin]) -> ThemeLibrary:
    """``library`` with each twin appended: its theme's texture, named "<theme> calm"
    (distinct), its display colour halfway to white (the index map tells them apart)."""
    if not twins:
        return library
    names = distinct_names([*library.names, *(library[t.theme].name + TWIN_SUFFIX
                                              for t in twins)])

    def twin(theme: CalmTwin, name: str):
        parent = library[theme.theme]
        return parent.with_(name=name, colour=tuple(c + (255 - c) // 2 for c in parent.colour))

    return ThemeLibrary([*library, *(twin(t, name) for t, name in
                                     zip(twins, names[len(library):], strict=True))])


def twin_parents(n_themes: int, twins: Sequence[CalmTwin]) -> np.ndarray:
    """(n_themes,) int64: each theme's class theme (a twin's is the theme it splits)."""
    parents = np.arange(n_themes)
    for twin in twins:
        parents[twin.twin] = twin.theme
    return parents
