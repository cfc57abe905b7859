"""Minimum-error boundary cuts between overlapping blocks (image quilting).

Efros & Freeman, SIGGRAPH 2001, §2.1: where two blocks overlap, each texel comes from
one of them, split along the least-error path by dynamic programming,
``E[i, j] = e[i, j] + min(E[i-1, j-1], E[i-1, j], E[i-1, j+1])``: no averaged ghost.
"""

from __future__ import annotations

import numpy as np


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

