"""The wrap methods ``make_tileable`` was chosen against (docs/decisions.md,
``TileableOptions``): Efros & Freeman minimum-error cuts, Heitz & Neyret's histogram-preserving
half-shift cross-fade ``(w G_A + (1-w) G_B) / sqrt(w^2 + (1-w)^2)``, and flattening by
division; peers in ``bench_tileable.py``."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter, uniform_filter1d
from scipy.special import ndtr
from terratheme.core.themes.histogram import gaussianise
from terratheme.core.themes.seam_cut import min_error_cut
from terratheme.core.themes.tileable import (
    FLATTEN_MIN_SIGMA,
    flatten_trend,
    periodic_component,
    seam_score,
)


def cut_wrap(img: np.ndarray, axis: int, overlap: float, feather: int) -> np.ndarray:
    """(h, w, c) float32 ``img`` made periodic along ``axis`` with two minimum-error cuts.

    ``axis`` 1: the last column continues into the first; 0: rows. ``overlap``: half-width
    of the band the cuts may run in, as a share of the side (1 texel .. n/4); ``feather``:
    texels each cut is softened over (0 hard). Periodic along the other axis stays so.
    """
    a = np.ascontiguousarray(img if axis == 1 else np.swapaxes(img, 0, 1))
    n = a.shape[1]
    b = np.roll(a, -(n // 2), axis=1)
    o = int(min(max(round(overlap * n), 1), max(n // 4, 1)))
    f = int(min(max(feather, 0), o - 1))
    err = ((a - b) ** 2).sum(axis=2)
    # Right band: A left of the cut, B from the cut on; the cut stays f texels off the edge.
    right_cols = np.arange(n - o, n - f)
    c1 = right_cols[min_error_cut(err[:, right_cols], cyclic=True)]
    # Left band: B left of the cut, A from the cut on.
    left_cols = np.arange(1 + f, o + 1)
    c2 = left_cols[min_error_cut(err[:, left_cols], cyclic=True)]
    x = np.arange(n)[None, :]
    mask = ((x >= c1[:, None]) | (x < c2[:, None])).astype(np.float32)
    if f > 0:
        mask = uniform_filter1d(mask, size=2 * f + 1, axis=1, mode="grid-wrap")
    out = mask[..., None] * b + (1.0 - mask[..., None]) * a
    return np.ascontiguousarray(out if axis == 1 else np.swapaxes(out, 0, 1))


def _ramp(n: int, band: float) -> np.ndarray:
    """(n,) weight: 0 at the borders, smoothstep up to 1 over ``band * n`` texels."""
    pos = np.arange(n) + 0.5
    t = np.clip(np.minimum(pos, n - pos) / max(band * n, 1e-9), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _crossfade(a: np.ndarray, b: np.ndarray, w: np.ndarray, hist: tuple | None) -> np.ndarray:
    """Blend ``a`` and ``b`` (float, (h, w, 3)) with weight ``w`` on ``a`` (broadcastable)."""
    if hist is None:
        return w * a + (1.0 - w) * b
    ga, gb, sorted_vals = hist
    g = (w * ga + (1.0 - w) * gb) / np.sqrt(w * w + (1.0 - w) ** 2)
    # Back through the patch's own histogram: Phi(g) -> rank -> value.
    n = sorted_vals.shape[1]
    pos = np.clip(ndtr(g) * n - 0.5, 0, n - 1)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    f = pos - lo
    out = np.empty_like(g)
    for c in range(3):
        sv = sorted_vals[c]
        out[..., c] = sv[lo[..., c]] * (1 - f[..., c]) + sv[hi[..., c]] * f[..., c]
    return out


def crossfade_wrap(cur: np.ndarray, band: float, histogram: bool) -> np.ndarray:
    """Two separable half-shift cross-fade passes (columns, then rows)."""
    h, w = cur.shape[:2]
    for axis, n in ((1, w), (0, h)):
        shifted = np.roll(cur, -(n // 2), axis=axis)
        ramp = _ramp(n, band).astype(np.float32)
        wgt = ramp[None, :, None] if axis == 1 else ramp[:, None, None]
        hist = None
        if histogram:
            ga, sorted_vals = gaussianise(np.clip(np.rint(cur), 0, 255).astype(np.uint8))
            hist = (ga, np.roll(ga, -(n // 2), axis=axis), sorted_vals)
        cur = _crossfade(cur, shifted, wgt, hist)
    return cur


def make_tileable_peer(patch: np.ndarray, method: str, *, flatten: float = 1 / 32,
                       divide: bool = False, tiles_already: float = 1.2, band: float = 0.35,
                       histogram: bool = True, overlap: float = 0.125,
                       feather: int = 2) -> np.ndarray:
    """``make_tileable`` with another wrap (``"periodic"``, ``"cut"``, ``"crossfade"``) or
    flattening by division (``img * mean / blur``)."""
    cur = patch.astype(np.float32)
    h, w = cur.shape[:2]
    if not (tiles_already > 0 and seam_score(patch) <= tiles_already):
        if method == "periodic":
            cur = periodic_component(cur)
        elif method == "cut":
            cur = cut_wrap(cut_wrap(cur, 1, overlap, feather), 0, overlap, feather)
        else:
            cur = crossfade_wrap(cur, band, histogram)
    if flatten > 0:
        sigma = max(flatten * min(h, w), FLATTEN_MIN_SIGMA)
        if divide:
            trend = gaussian_filter(cur, sigma=(sigma, sigma, 0), mode="grid-wrap")
            cur = cur * (cur.mean(axis=(0, 1), keepdims=True) / np.maximum(trend, 1.0))
        else:
            cur = flatten_trend(cur, sigma)
    return np.clip(np.rint(cur), 0, 255).astype(np.uint8)
