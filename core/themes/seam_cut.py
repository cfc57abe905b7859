"""Minimum-error boundary cuts across a texture's wrap edge (image quilting).

Efros & Freeman, SIGGRAPH 2001, §2.1: where two blocks overlap, each texel comes from
one of them, split along the least-error path by dynamic programming,
``E[i, j] = e[i, j] + min(E[i-1, j-1], E[i-1, j], E[i-1, j+1])``: no averaged ghost.
:func:`cut_wrap` makes a patch ``A`` wrap by taking its half-period shift ``B`` in a
band around the wrap edge, between two such cuts.
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
    """(h,) int64 column of the least-error 8-connected top-to-bottom cut through (h, k) ``err``.

    ``cyclic``: re-solved from the free path's end so the last row ends within one column
    of it (the cut closes up when the texture wraps vertically).
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
    """(h, w, c) float32 ``img`` made periodic along ``axis`` with two minimum-error cuts.

    ``axis`` 1: the last column continues into the first; 0: rows. ``overlap``: half-width
    of the band the cuts may run in, as a share of the side (1 texel .. n/4); ``feather``:
    texels each cut is softened over (0 hard). Periodic along the other axis stays so.
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
