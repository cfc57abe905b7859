"""Where to cut a class's theme from its photo: the window whose texture matches the class.

A theme stands for every pixel of its class, so its patch must carry the class's
texture, not its calmest corner (design.md §3). Windows mostly inside the class are
scored against the class on:

* luma band-pass energy ``(G_0.7 - G_3.0)^2``, as ``ln(E_window / E_class)^2``;
* each Lab channel's spread about its local mean, relative to the class's;
* the mean Lab colour in units of that spread (small weight);

plus ``size_weight`` per halving of the side. Window statistics are box filters of
class-independent per-pixel maps, area-averaged on large photos to bound the search.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import cv2
import numba
import numpy as np
from terratheme.core.errors import TerrathemeError

#: Gaussian sigmas of the detail band (as core.fidelity.metrics.DETAIL_SIGMAS)
BAND_SIGMAS = (0.7, 3.0)
#: a class's texture is measured this many pixels inside its border
INTERIOR = 4
#: window positions searched at most (the lattice is coarsened above this)
SEARCH_POSITIONS = 1 << 18
#: strips a side whose band energies a window's evenness compares (:meth:`ClassWindows.scores`)
EVEN_STRIPS = 8


@dataclass(frozen=True)
class PatchOptions:
    """How theme patches are searched.

    ``size``, ``min_size``: largest and smallest patch side (pixels), below ``min_size`` a flat
    theme; ``inside``: share of the patch that must carry the class (the rest is filled);
    ``size_weight``: score per halving of the side; ``colour_weight``: the mean-colour term's
    weight; ``highpass_sigma``: the local mean the Lab spread is measured about (pixels);
    ``quilt``: quilt from small blocks (:mod:`.quilt`) when no window tiles unseen;
    ``even_weight``: the weight of a window's unevenness (:meth:`ClassWindows.scores`).
    """

    size: int = 256
    min_size: int = 24
    inside: float = 0.85
    size_weight: float = 0.15
    colour_weight: float = 0.25
    highpass_sigma: float = 16.0
    quilt: bool = True
    even_weight: float = 2.0

    def __post_init__(self) -> None:
        if not 4 <= self.min_size <= self.size:
            raise TerrathemeError(
                f"patch sizes must satisfy 4 <= min_size <= size, got {self.min_size}, {self.size}"
            )
        if not 0.0 < self.inside <= 1.0:
            raise TerrathemeError(f"inside must be in (0, 1], got {self.inside}")

    def sizes(self, h: int, w: int) -> list[int]:
        """Sides tried on an ``h x w`` photo: from the largest that fits down by 3/4."""
        size = min(self.size, h, w)
        out = []
        while size >= self.min_size:
            out.append(size)
            size = size * 3 // 4
        return out


@dataclass(frozen=True)
class TextureStats:
    """Per-pixel maps of a photo that window and class statistics are taken from.

    ``lab``: (H, W, 3) float32 CIE Lab (OpenCV); ``detail``: (H, W, 3) float32 ``lab``
    minus its Gaussian blur; ``band``: (H, W) float32 luma band-pass energy in [0, 1].
    """

    lab: np.ndarray
    detail: np.ndarray
    band: np.ndarray


def texture_stats(rgb: np.ndarray, options: PatchOptions = PatchOptions()) -> TextureStats:
    """The per-pixel maps of an ``(H, W, 3)`` uint8 photo (see :class:`TextureStats`)."""
    lab = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)
    local = cv2.GaussianBlur(lab, (0, 0), options.highpass_sigma, borderType=cv2.BORDER_REFLECT)
    lum = lab[:, :, 0] / 100.0
    fine = cv2.GaussianBlur(lum, (0, 0), BAND_SIGMAS[0], borderType=cv2.BORDER_REFLECT)
    coarse = cv2.GaussianBlur(lum, (0, 0), BAND_SIGMAS[1], borderType=cv2.BORDER_REFLECT)
    return TextureStats(lab, lab - local, (fine - coarse) ** 2)


@dataclass(frozen=True)
class ClassTarget:
    """The statistics a class's patch should have: band energy, Lab spread and mean."""

    energy: float
    spread: np.ndarray
    mean: np.ndarray


def class_means(labels: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-label means of (H, W) or (H, W, k) values over (H, W) uint8 labels, in one pass.

    Returns (256, k) float64 means (0 where no pixel) and (256,) int64 counts.
    """
    flat = np.ascontiguousarray(labels, np.uint8).ravel()
    cols = np.ascontiguousarray(values).reshape(flat.size, -1)
    counts = np.zeros(256, np.int64)
    sums = np.zeros((256, cols.shape[1]), np.float64)
    _label_sums(flat, cols, counts, sums)
    return sums / np.maximum(counts, 1)[:, None], counts


@numba.njit(cache=True, nogil=True)
def _label_sums(flat, cols, counts, sums):  # pragma: no cover
    """Per label ``c``, its pixel count and float64 value sums, in pixel order (as bincount)."""
    for i in range(flat.size):
        c = flat[i]
        counts[c] += 1
        for k in range(cols.shape[1]):
            sums[c, k] += cols[i, k]


@dataclass(frozen=True)
class ClassStats:
    """Every class's statistics of a photo, taken once (:func:`class_stats`).

    ``texture``: the photo's :class:`TextureStats` and ``windows`` its
    :class:`WindowStats`; ``counts``: (256,) int64 pixels per class value; ``colour``,
    ``lab``: (256, 3) float64 mean RGB and Lab; ``band``: (256,) mean band energy (0
    where no pixel); ``interior``: the labels' :func:`interior_labels`; ``targets``:
    :class:`ClassTarget` of each present class but 0 (no data).
    """

    texture: TextureStats
    windows: WindowStats
    counts: np.ndarray
    colour: np.ndarray
    lab: np.ndarray
    band: np.ndarray
    interior: np.ndarray
    targets: Mapping[int, ClassTarget]


def class_stats(rgb: np.ndarray, labels: np.ndarray,
                options: PatchOptions = PatchOptions()) -> ClassStats:
    """The :class:`ClassStats` of an (H, W, 3) uint8 photo's (H, W) uint8 class labels."""
    texture = texture_stats(rgb, options)
    colour, counts = class_means(labels, rgb)
    # One stack of per-pixel statistics: the classes' means, their interiors', the windows'.
    stack = _stack(texture)
    whole, _ = class_means(labels, stack)
    inner = interior_labels(labels)
    targets = _targets(stack, inner, whole, [int(c) for c in np.flatnonzero(counts[1:]) + 1])
    return ClassStats(texture, WindowStats(stack), counts, colour, whole[:, 1:4],
                      whole[:, 0], inner, targets)


def interior_labels(labels: np.ndarray) -> np.ndarray:
    """(H, W) uint8: a pixel's class where all within ``INTERIOR`` px share it, else 0.

    The labels go on beyond the image (replicated border): its edge is no class border.
    """
    # Every label within the disc is the pixel's own: a min and a max filter.
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * INTERIOR + 1, 2 * INTERIOR + 1))
    lo = cv2.erode(labels, kernel, borderType=cv2.BORDER_REPLICATE)
    hi = cv2.dilate(labels, kernel, borderType=cv2.BORDER_REPLICATE)
    return np.where((lo == labels) & (hi == labels), labels, 0).astype(np.uint8)


def _stack(stats: TextureStats) -> np.ndarray:
    """(H, W, 10) float32: band, Lab (3), detail (3), detail^2 (3) (as :meth:`WindowStats.at`)."""
    return np.concatenate([stats.band[:, :, None], stats.lab, stats.detail,
                           stats.detail * stats.detail], axis=2)


def _targets(stack: np.ndarray, inner: np.ndarray, whole: np.ndarray,
             classes: Sequence[int]) -> dict[int, ClassTarget]:
    """{class: ClassTarget} from the :func:`_stack`, its :func:`interior_labels` and means.

    Energy and spread come from pixels ``INTERIOR`` px inside the border (all pixels when
    none): the render draws the border, a theme carrying it would double it. The colour is
    the whole class's mean.
    """
    inside, n_inside = class_means(inner, stack)
    out = {}
    for c in (int(c) for c in classes):
        # A class with no interior pixel is measured on all its pixels.
        band, det, sq = (inside[c, 0], inside[c, 4:7], inside[c, 7:10]) if n_inside[c] else (
            whole[c, 0], whole[c, 4:7], whole[c, 7:10])
        out[c] = ClassTarget(float(band), np.sqrt(np.maximum(sq - det * det, 0.0)),
                             whole[c, 1:4])
    return out


def _coarsen(arr: np.ndarray, f: int) -> np.ndarray:
    """Area average over ``f x f`` blocks (the last partial blocks dropped)."""
    if f == 1:
        return arr
    h, w = arr.shape[0] // f, arr.shape[1] // f
    return cv2.resize(arr[: h * f, : w * f], (w, h), interpolation=cv2.INTER_AREA)


class WindowStats:
    """Box-filtered window statistics of a photo at every lattice position, per side (cached).

    The lattice step ``factor`` grows so that at most ``SEARCH_POSITIONS`` are searched.
    """

    def __init__(self, stack: np.ndarray) -> None:
        """``stack``: the photo's :func:`_stack`."""
        h, w = stack.shape[:2]
        self.factor = max(1, int(np.ceil(np.sqrt(h * w / SEARCH_POSITIONS))))
        self._stack = _coarsen(stack, self.factor)
        self._by_size: dict[int, np.ndarray] = {}
        self._strips: dict[int, tuple[np.ndarray, np.ndarray, int]] = {}

    def at(self, size: int) -> np.ndarray:
        """(h, w, 10) float32: mean band, Lab mean (3), detail mean (3), detail^2 mean (3).

        ``[j, i]``: the window at ``(i * factor, j * factor)`` of side ``size`` (on the lattice).
        """
        if size not in self._by_size:
            k = max(1, size // self.factor)
            self._by_size[size] = cv2.boxFilter(self._stack, -1, (k, k), anchor=(0, 0),
                                                borderType=cv2.BORDER_CONSTANT)
        return self._by_size[size]

    def strips(self, size: int) -> tuple[np.ndarray, np.ndarray, int]:
        """Mean band energy of the column strips and of the row strips of windows of side
        ``size`` (``EVEN_STRIPS`` a side; lattice arrays as :meth:`at`), and the strips'
        width on the lattice."""
        if size not in self._strips:
            k = max(1, size // self.factor)
            w = max(1, k // EVEN_STRIPS)
            band = np.ascontiguousarray(self._stack[:, :, 0])
            self._strips[size] = (
                cv2.boxFilter(band, -1, (w, k), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT),
                cv2.boxFilter(band, -1, (k, w), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT),
                w)
        return self._strips[size]


def patch_scores(window: np.ndarray, target: ClassTarget, size: int,
                 options: PatchOptions) -> np.ndarray:
    """(n,) float32 score of windows of one side against a class (lower is closer).

    ``window`` is ``(n, 10)``: rows of :meth:`WindowStats.at`.
    """
    eps = 1e-6
    energy = window[:, 0]
    mean, dmean, dsq = window[:, 1:4], window[:, 4:7], window[:, 7:10]
    spread = np.sqrt(np.maximum(dsq - dmean * dmean, 0.0))
    # Band-pass energy as a log ratio (texture a viewer sees at texel scale).
    score = np.log((energy + eps) / (target.energy + eps)) ** 2
    # Lab spread about the local mean, relative to the class's.
    score += (((spread - target.spread) / (target.spread + 1.0)) ** 2).mean(axis=1)
    # Mean colour, in units of the class's spread.
    score += options.colour_weight * (((mean - target.mean) / (target.spread + 3.0)) ** 2).mean(
        axis=1)
    # Smaller windows repeat more when tiled.
    return score + options.size_weight * np.log2(options.size / size)


@dataclass(frozen=True)
class ClassWindows:
    """One class region on a :class:`WindowStats` lattice, its windows scored once.

    ``coarse``: the class mask area-averaged to the lattice; ``sides``: per side tried,
    ``(size, at, score)``: flat lattice indices of the windows inside the photo with at
    least ``options.inside`` of class pixels, and their :func:`patch_scores`. Every try
    of :func:`find_patch` and :func:`best_windows` takes them from here.
    """

    windows: WindowStats
    shape: tuple[int, int]
    target: ClassTarget
    options: PatchOptions
    coarse: np.ndarray
    sides: tuple[tuple[int, np.ndarray, np.ndarray], ...]

    def admissible(self, size: int, step: int = 1) -> np.ndarray:
        """Flat lattice indices of windows of side ``size`` mostly in the class, every ``step``."""
        h, w = self.shape
        f = self.windows.factor
        k = max(1, size // f)
        cover = cv2.boxFilter(self.coarse, -1, (k, k), anchor=(0, 0),
                              borderType=cv2.BORDER_CONSTANT)
        # Only windows inside the photo whose pixels are mostly in the class.
        ok = np.zeros(cover.shape, bool)
        ok[: (h - size) // f + 1 : step, : (w - size) // f + 1 : step] = True
        ok &= cover >= self.options.inside - 1e-6
        return np.flatnonzero(ok)

    def scores(self, size: int, at: np.ndarray) -> np.ndarray:
        """:func:`patch_scores` of the windows of side ``size`` at lattice indices ``at``,
        plus ``options.even_weight`` times the variances of the log band energy over their
        ``EVEN_STRIPS`` column strips and over their row strips: a window partly of
        another texture tiles into bands of it (a sea's black, JPEG-blocked deep beside
        its lit ripples; a calm strip along one edge)."""
        score = patch_scores(self.windows.at(size).reshape(-1, 10)[at], self.target, size,
                             self.options)
        if self.options.even_weight <= 0.0:
            return score
        cols, rows, step = self.windows.strips(size)
        j, i = np.divmod(at, cols.shape[1])
        offsets = np.arange(EVEN_STRIPS) * step
        by_col = np.log(cols[j[:, None], np.minimum(i[:, None] + offsets, cols.shape[1] - 1)]
                        + 1e-6)
        by_row = np.log(rows[np.minimum(j[:, None] + offsets, rows.shape[0] - 1), i[:, None]]
                        + 1e-6)
        return score + self.options.even_weight * (by_col.var(axis=1) + by_row.var(axis=1))


def class_windows(windows: WindowStats, mask: np.ndarray, options: PatchOptions,
                  target: ClassTarget) -> ClassWindows:
    """The :class:`ClassWindows` of a class region ``mask`` ((H, W) bool) of ``target``."""
    found = ClassWindows(windows, mask.shape, target, options,
                         _coarsen(mask.astype(np.float32), windows.factor), ())
    sides = []
    for size in options.sizes(*mask.shape):
        at = found.admissible(size)
        sides.append((size, at, found.scores(size, at)))
    return replace(found, sides=tuple(sides))


def find_patch(found: ClassWindows, *, exclude: Sequence[tuple[int, int, int]] = ()
               ) -> tuple[int, int, int] | None:
    """``(x, y, size)`` of the window closest to a class region, or None when none fits.

    Windows overlapping an ``exclude`` one by more than half are skipped.
    """
    f = found.windows.factor
    best: tuple[float, int, int, int] | None = None
    for size, at, score in found.sides:
        j, i = np.divmod(at, found.coarse.shape[1])
        keep = np.ones(at.size, bool)
        for ex, ey, es in exclude:
            half = max(size, es) // 2
            keep &= ~((j >= max(0, (ey - half) // f)) & (j < (ey + half) // f + 1)
                      & (i >= max(0, (ex - half) // f)) & (i < (ex + half) // f + 1))
        if not keep.any():
            continue
        kept = score[keep]
        k = int(np.argmin(kept))
        if best is None or kept[k] < best[0]:
            best = (float(kept[k]), int(i[keep][k]) * f, int(j[keep][k]) * f,
                    max(1, size // f) * f)
    return None if best is None else best[1:]


def best_windows(found: ClassWindows, size: int, count: int, *, spacing: int = 1) -> np.ndarray:
    """(n, 2) int64 ``(x, y)`` corners of the ``n <= count`` windows closest to the class.

    Best first; windows of side ``size`` on a lattice of step ``spacing`` (no near-copies),
    at least ``options.inside`` in the class.
    """
    f = found.windows.factor
    at = found.admissible(size, max(1, spacing // f))
    if at.size == 0:
        return np.zeros((0, 2), np.int64)
    best = at[np.argsort(found.scores(size, at), kind="stable")[:count]]
    j, i = np.divmod(best, found.coarse.shape[1])
    return np.stack([i * f, j * f], axis=1).astype(np.int64)
