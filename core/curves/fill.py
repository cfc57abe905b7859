"""Images back from runs: the whole image, a window of it, or one curve square (numba).

Only the curve blocks meeting the output are walked; a block one run covers is filled
as a rectangle at once.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from terratheme.core.curves.plan import CurveSquares, block_plan, plan_args
from terratheme.core.curves.square import Curve
from terratheme.core.errors import TerrathemeError


@numba.njit(cache=True, nogil=True)
def fill_kernel(out, ox, oy, width, height, steps, values, b, bx, by, state, first_step,
                 patterns, blocks, starts):  # pragma: no cover - numba
    # The texels of blocks ``blocks`` that fall in ``out``, a window of a width x height
    # image with its top-left texel at column ox, row oy; starts[k] = first run that ends
    # at or after the first step of block blocks[k].
    wh, ww = out.shape
    side = 1 << b
    mask = side - 1
    for k in range(blocks.size):
        j = blocks[k]
        r = starts[k]
        x0 = np.int64(bx[j]) * side
        y0 = np.int64(by[j]) * side
        st = state[j]
        base = np.uint64(first_step[j])
        # The block's rows from the top are height - y0 - side .. height - y0 - 1.
        top = height - y0 - side - oy
        left = x0 - ox
        inside = (x0 + side <= width and y0 + side <= height and top >= 0 and left >= 0
                  and top + side <= wh and left + side <= ww)
        if inside and np.uint64(steps[r]) >= base + np.uint64(side * side - 1):
            # One run covers the whole block: fill its rectangle at once.
            out[top: top + side, left: left + side] = values[r]
            continue
        for i in range(side * side):
            p = np.int64(patterns[st, i])
            x = x0 + (p & mask)
            y = y0 + (p >> b)
            row = height - 1 - y - oy
            col = x - ox
            if not inside and (x >= width or y >= height or row < 0 or row >= wh
                               or col < 0 or col >= ww):
                continue
            # Advance to the run whose last step is at or after this texel's step.
            s = base + np.uint64(i)
            while np.uint64(steps[r]) < s:
                r += 1
            out[row, col] = values[r]


def fill_runs(
    steps: np.ndarray, values: np.ndarray, width: int, height: int, curve: str | Curve,
    *, threads: int = 2,
) -> np.ndarray:
    """Inverse of :func:`scan_runs`: the (height, width) image of the runs' values."""
    return fill_window(steps, values, width, height, curve, 0, 0, width, height,
                       threads=threads)


def fill_window(
    steps: np.ndarray, values: np.ndarray, width: int, height: int, curve: str | Curve,
    x: int, y: int, w: int, h: int, *, out: np.ndarray | None = None, threads: int = 1,
) -> np.ndarray:
    """The ``(h, w)`` window at column ``x``, row ``y`` (row 0 = top) of the runs' image.

    ``steps, values`` as :func:`scan_runs` returns them; ``out`` a reused band
    buffer of ``values.dtype``; ``threads`` stretches of blocks filled at once.
    """
    if not (0 <= x and 0 <= y and w >= 1 and h >= 1 and x + w <= width and y + h <= height):
        raise TerrathemeError(
            f"window x={x} y={y} w={w} h={h} is outside the {width} x {height} image")
    plan = block_plan(width, height, curve)
    if out is None:
        out = np.empty((h, w), dtype=values.dtype)
    side = 1 << plan.b
    # Blocks (y up) whose square meets the window's rows and columns.
    y_lo, y_hi = height - (y + h), height - 1 - y
    hit = ((plan.bx.astype(np.int64) * side < x + w) & ((plan.bx.astype(np.int64) + 1) * side > x)
           & (plan.by.astype(np.int64) * side <= y_hi)
           & ((plan.by.astype(np.int64) + 1) * side > y_lo))
    blocks = np.flatnonzero(hit)
    starts = np.searchsorted(steps, plan.first_step[blocks]).astype(np.int64)
    parts = np.array_split(np.arange(blocks.size), max(1, min(int(threads), blocks.size)))

    def one(part: np.ndarray) -> None:
        fill_kernel(out, int(x), int(y), int(width), int(height), steps, values,
                     *plan_args(plan), blocks[part], starts[part])

    if len(parts) == 1:
        one(parts[0])
    else:
        with ThreadPoolExecutor(len(parts)) as pool:
            list(pool.map(one, parts))
    return out


def fill_square(
    steps: np.ndarray, values: np.ndarray, width: int, height: int, curve: str | Curve,
    squares: CurveSquares, k: int, *, out: np.ndarray | None = None,
) -> np.ndarray:
    """Square ``k``'s ``(h, w)`` window (:meth:`CurveSquares.rect`) of the runs' image."""
    plan = block_plan(width, height, curve)
    x, y, w, h = squares.rect(k, width, height)
    out = np.empty((h, w), values.dtype) if out is None else out
    blocks = np.arange(squares.j0[k], squares.j1[k], dtype=np.int64)
    starts = np.searchsorted(steps, plan.first_step[blocks]).astype(np.int64)
    fill_kernel(out, x, y, width, height, steps, values, *plan_args(plan), blocks, starts)
    return out
