"""The block plan of a whole-image scan along a curve (used by :mod:`core.curves.scan`).

The scan (texel order along the curve) is cut into ``2^b x 2^b`` blocks: the
coarse curve orders the blocks, and each block is walked with one of four
precomputed local patterns. Every aligned ``2^g x 2^g`` square (``g >= b``) is
a contiguous stretch of blocks, hence of curve steps: windows of a scan are
stretches of the plan (:func:`window_blocks`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from terratheme.core.curves.square import Curve, curve_order, hilbert_transposed
from terratheme.core.curves.steps import hilbert_d2xy, hilbert_xy2d, morton_d2xy, morton_xy2d

#: log2 of the scan block side (64 x 64 texels per block, 4 Hilbert patterns).
BLOCK_BITS = 6

@dataclass(frozen=True)
class BlockPlan:
    """The blocks of ``2^b x 2^b`` texels that cover an image, in curve order.

    ``n, b``: curve levels of the square and of a block; ``bx, by`` (nb,) int32 block
    column and row, ``by`` counted **up**; ``state`` (nb,) uint8 each block's local
    pattern; ``first_step`` (nb,) uint64 its first step (``c * 4^b``); ``patterns``
    (4, 4^b) uint16: entry ``i`` is ``(ly << b) | lx`` of local step ``i``, y up.
    """

    n: int
    b: int
    bx: np.ndarray
    by: np.ndarray
    state: np.ndarray
    first_step: np.ndarray
    patterns: np.ndarray


@lru_cache(maxsize=8)
def _patterns(b: int, curve: Curve) -> np.ndarray:
    """(4, 4^b) uint16: ``(ly << b) | lx`` (y up) of each local step, per Hilbert state."""
    i = np.arange(4**b, dtype=np.uint64)
    if curve is Curve.MORTON:
        x, y = morton_d2xy(i, b)
        one = ((y << b) | x).astype(np.uint16)
        out = np.ascontiguousarray(np.broadcast_to(one, (4, one.size)))
        out.setflags(write=False)
        return out
    x, y = hilbert_d2xy(i, b)
    out = np.empty((4, i.size), dtype=np.uint16)
    side = (1 << b) - 1
    for state in range(4):
        # A block in state (swap, flip) is walked by T(d2xy(i)), T = swap^s o flip^f (self-inverse).
        px, py = (side - x, side - y) if state & 2 else (x, y)
        if state & 1:
            px, py = py, px
        out[state] = (py << b) | px
    out.setflags(write=False)
    return out


def block_plan(width: int, height: int, curve: str | Curve) -> BlockPlan:
    """Blocks of the enclosing square that meet the image, in curve order (cached)."""
    return _block_plan(int(width), int(height), Curve.parse(curve))


def block_grid(width: int, height: int, curve: str | Curve, b: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Coarse curve step and local pattern of every ``2^b`` block meeting the image.

    ``coarse`` (ceil(H / 2^b), ceil(W / 2^b)) uint64: block ``[by, bx]`` (y up) covers
    steps ``coarse << 2b`` to ``((coarse + 1) << 2b) - 1``; ``state`` uint8 its pattern.
    """
    curve = Curve.parse(curve)
    n = curve_order(width, height)
    b = min(int(b), n)
    nbx, nby = -(-width // (1 << b)), -(-height // (1 << b))
    by, bx = np.mgrid[0:nby, 0:nbx]
    bx = bx.ravel().astype(np.int64)
    by = by.ravel().astype(np.int64)
    if curve is Curve.HILBERT:
        c, state = hilbert_xy2d(*((by, bx) if hilbert_transposed(n) else (bx, by)), n - b)
        if hilbert_transposed(n):
            # Transposed image curve: the local pattern is transposed too (swap bit).
            state = state ^ np.uint8(1)
    else:
        c, state = morton_xy2d(bx, by, n - b), np.zeros(bx.shape, np.uint8)
    return c.reshape(nby, nbx), state.reshape(nby, nbx)


@lru_cache(maxsize=16)
def _block_plan(width: int, height: int, curve: Curve) -> BlockPlan:
    n = curve_order(width, height)
    b = min(n, BLOCK_BITS)
    nbx = -(-width // (1 << b))
    # Coarse grid of blocks meeting the image (y up), then its coarse curve steps.
    c, state = (a.ravel() for a in block_grid(width, height, curve, b))
    bx = np.arange(c.size, dtype=np.int64) % nbx
    by = np.arange(c.size, dtype=np.int64) // nbx
    order = np.argsort(c, kind="stable")
    arrays = dict(
        bx=bx[order].astype(np.int32), by=by[order].astype(np.int32),
        state=state[order].astype(np.uint8), first_step=c[order] << np.uint64(2 * b),
    )
    for a in arrays.values():
        a.setflags(write=False)
    return BlockPlan(n=n, b=b, patterns=_patterns(b, curve), **arrays)


@dataclass(frozen=True)
class CurveSquares:
    """The aligned ``2^g x 2^g`` squares of an image's curve, in curve order.

    Each is a contiguous stretch of curve steps (Hilbert and Morton alike), hence of
    plan blocks ``j0 .. j1 - 1``, so it can be scanned or filled alone. ``sx, sy``
    (m,) int64 square coordinates, y up; ``first_step`` (m,) uint64.
    """

    g: int
    sx: np.ndarray
    sy: np.ndarray
    j0: np.ndarray
    j1: np.ndarray
    first_step: np.ndarray

    def rect(self, k: int, width: int, height: int) -> tuple[int, int, int, int]:
        """``(x, y, w, h)`` of square ``k`` in image coordinates (row 0 = top), clipped."""
        side = 1 << self.g
        x0, y0 = int(self.sx[k]) * side, int(self.sy[k]) * side
        x1, y1 = min(width, x0 + side), min(height, y0 + side)
        return x0, height - y1, x1 - x0, y1 - y0


def curve_squares(width: int, height: int, curve: str | Curve, g: int) -> CurveSquares:
    """The squares of side ``2^g`` that meet a ``width x height`` image, in curve order."""
    plan = block_plan(width, height, curve)
    g = max(plan.b, min(int(g), plan.n))
    k = g - plan.b
    sx = plan.bx.astype(np.int64) >> k
    sy = plan.by.astype(np.int64) >> k
    # Squares are contiguous in plan order: a new square starts where the key changes.
    key = sy * (1 << 32) + sx
    starts = np.flatnonzero(np.diff(key, prepend=-1) != 0)
    ends = np.append(starts[1:], key.size)
    first = (plan.first_step[starts] >> np.uint64(2 * g)) << np.uint64(2 * g)
    return CurveSquares(g, sx[starts], sy[starts], starts.astype(np.int64),
                        ends.astype(np.int64), first)


def plan_args(plan: BlockPlan) -> tuple:
    """The plan as kernels take it: ``(b, bx, by, state, first_step, patterns)``."""
    return (plan.b, plan.bx, plan.by, plan.state, plan.first_step, plan.patterns)
