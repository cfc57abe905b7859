"""Texel <-> curve step in image coordinates (row 0 on top), a test oracle built on
core.curves.steps' square-curve functions; the packer never needs steps of single texels."""

from __future__ import annotations

import numpy as np
from terratheme.core.curves.square import Curve, curve_order, hilbert_transposed
from terratheme.core.curves.steps import hilbert_d2xy, hilbert_xy2d, morton_d2xy, morton_xy2d


def _upward(x: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return (y, x) if hilbert_transposed(n) else (x, y)


def steps_of(cols, rows, width: int, height: int, curve: str | Curve) -> np.ndarray:
    """0-based curve steps of texels ``image[rows, cols]`` of a ``width x height`` image."""
    curve = Curve.parse(curve)
    n = curve_order(width, height)
    cols, rows = np.asarray(cols, dtype=np.int64), np.asarray(rows, dtype=np.int64)
    yup = (height - 1) - rows
    if curve is Curve.HILBERT:
        return hilbert_xy2d(*_upward(cols, yup, n), n)[0]
    return morton_xy2d(cols, yup, n)


def texels_of(steps, width: int, height: int, curve: str | Curve):
    """Texel ``(cols, rows)`` of 0-based curve steps, and ``inside`` (False for steps of
    the enclosing square the image does not cover)."""
    curve = Curve.parse(curve)
    n = curve_order(width, height)
    d = np.asarray(steps, dtype=np.int64)
    if curve is Curve.HILBERT:
        x, yup = _upward(*hilbert_d2xy(d, n), n)
    else:
        x, yup = morton_d2xy(d, n)
    return x, (height - 1) - yup, (x < width) & (yup < height)


def step_table(width: int, height: int, curve: str | Curve, *, one_based: bool = True
               ) -> np.ndarray:
    """(height, width) int64 step of every texel, 1-based (the seed's numbers) by default."""
    rows, cols = np.mgrid[0:height, 0:width]
    return steps_of(cols, rows, width, height, curve).astype(np.int64) + int(one_based)
