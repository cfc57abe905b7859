"""Minimum-error boundary cuts across a texture's wrap edge (image quilting).

Efros & Freeman, "Image Quilting for Texture Synthesis and Transfer",
SIGGRAPH 2001, section 2.1: where two overlapping blocks meet, each output
texel is taken from one block or the other, split along the path of least
overlap error found by dynamic programming (their cumulative minimum error
``E[i, j] = e[i, j] + min(E[i-1, j-1], E[i-1, j], E[i-1, j+1])``). Unlike a
cross-fade, no texel is an average of two unrelated texels, so the
transition region shows no doubled ("ghost") features.

:func:`cut_wrap` uses it to make a patch wrap along one axis: ``A`` is the
patch, ``B`` its copy shifted by half a period (``B`` is continuous across
the wrap edge, where it shows ``A``'s interior). The output takes ``B`` in a
narrow band around the wrap edge and ``A`` elsewhere, switching along two
minimum-error cuts (one each side of the edge), then softens each cut over a
few texels (``feather``).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d


def _dp_path(err: np.ndarray, start: int | None) -> tuple[np.ndarray, float]:
    """Least-cost 8-connected top-to-bottom path through ``err`` (h, k); optional fixed start."""
    h, k = err.shape
    cost = err[0].copy()
    if start is not None:
        cost = np.where(np.arange(k) == start, cost, np.inf)
    back = np.zeros((h, k), np.int64)
    pad = np.full(k + 2, np.inf)
    left, mid, right = pad[:-2], pad[1:-1], pad[2:]
    cols = np.arange(k)
    for i in range(1, h):
        # E[i, j] = e[i, j] + min(E[i-1, j-1 .. j+1]) (Efros & Freeman 2001, §2.1);
        # ties go to the leftmost of the three, as argmin does.
        mid[:] = cost
        arg = np.where((left <= mid) & (left <= right), -1, np.where(mid <= right, 0, 1))
        back[i] = cols + arg
        cost = err[i] + np.minimum(np.minimum(left, mid), right)
    return back, cost


def min_error_cut(err: np.ndarray, *, cyclic: bool = False) -> np.ndarray:
    """Column of the least-error top-to-bottom cut through an error surface.

    Parameters
    ----------
    err : (h, k) float ndarray
        Overlap error per texel (non-negative), ``k >= 1``.
    cyclic : bool
        Make the path's last row within one column of its first (the path
        then closes up when the texture wraps vertically): the path is
        re-solved starting from the end of the unconstrained one and must
        end next to that start.

    Returns
    -------
    path : (h,) int64 ndarray
        ``path[i]`` in ``[0, k)``; consecutive entries differ by at most 1.
    """
    err = np.asarray(err, dtype=np.float64)
    h, k = err.shape
    back, cost = _dp_path(err, None)
    end = int(np.argmin(cost))
    if cyclic and h > 1:
        # Second pass: start where the free path ended, end within one column of it.
        back, cost = _dp_path(err, end)
        near = np.full(k, np.inf)
        lo, hi = max(end - 1, 0), min(end + 2, k)
        near[lo:hi] = cost[lo:hi]
        end = int(np.argmin(near))
    path = np.empty(h, np.int64)
    path[-1] = end
    # Backtrack the stored predecessors.
    for i in range(h - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path


def cut_wrap(img: np.ndarray, axis: int, overlap: float, feather: int) -> np.ndarray:
    """Make ``img`` wrap along ``axis`` with two minimum-error cuts (no cross-fade).

    Parameters
    ----------
    img : (h, w, c) float32 ndarray
    axis : int
        1: make the last column continue into the first; 0: rows.
    overlap : float
        Half-width of the band around the wrap edge where the cuts may run,
        as a fraction of the size along ``axis`` (clamped to [1 texel, n/4]).
    feather : int
        Texels over which each cut is softened (a box-filtered mask); 0 is a
        hard cut.

    Returns
    -------
    out : (h, w, c) float32 ndarray
        Periodic along ``axis``; if ``img`` was periodic along the other
        axis, so is ``out`` (the cuts close up cyclically).
    """
    # Work on columns: for rows, transpose so the wrap edge is between columns n-1 and 0.
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
        # Soften the cuts: a periodic box filter across them (width 2f + 1).
        mask = uniform_filter1d(mask, size=2 * f + 1, axis=1, mode="grid-wrap")
    out = mask[..., None] * b + (1.0 - mask[..., None]) * a
    return np.ascontiguousarray(out if axis == 1 else np.swapaxes(out, 0, 1))
