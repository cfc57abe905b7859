"""Boundaries shaped by the themes' content and deterministic noise (beyond the paper's ramp).

A border is a narrow, irregular edge instead of the paper's whole-cell ramp, decided per
texel of a mixed cell in integers (1/1024 of a weight) so every renderer and region agrees
exactly: barycentric weight, plus value noise and the theme's own luminance, then a
transition of width ``W``. Equations and the continuity argument: docs/design.md §1.4.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.render.kernels import (
    RegionBlock,
    ThemeRows,
    cell_columns,
    cell_corners,
    cell_span,
    merged_weights,
)
from terratheme.core.render.theme_pack import pack_themes

_M32 = np.uint64(0xFFFFFFFF)
#: widest border, in 1/1024 of a weight
MAX_WIDTH = 409
#: widest noise lattice, in texels (beyond a texture's side the noise is one value anyway)
MAX_LATTICE = 1 << 31


@dataclass(frozen=True)
class BoundaryOptions:
    """How borders between themes are drawn (see the module docstring).

    ``width``: border width in texels (the paper's ramp is a whole cell); ``noise``,
    ``height``: amplitudes of the noise and of the themes' own luminance, in 1/256
    of a weight (0..255); ``features``: noise features per cell side (the lattice is
    ``(N + M) / 2 / features`` texels, >= 2); ``seed``: 0 .. 2^31 - 1.
    """

    width: float = 3.0
    noise: int = 90
    height: int = 40
    features: float = 2.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("noise", "height", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise TerrathemeError(f"boundary {name} must be a whole number, got "
                                      f"{str(value)[:40]!r}")
        for name in ("width", "features"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise TerrathemeError(f"boundary {name} must be a number, got "
                                      f"{str(value)[:40]!r}")
        if not 0.0 <= self.width <= 4096:
            raise TerrathemeError(f"boundary width must be in 0..4096 texels, got {self.width}")
        if not (0 <= self.noise <= 255 and 0 <= self.height <= 255):
            raise TerrathemeError("boundary noise and height must be 0..255 (1/256 of a weight)")
        if not 0.0 < self.features <= 1024:
            raise TerrathemeError(f"noise features per cell must be in (0, 1024], "
                                  f"got {self.features}")
        if not 0 <= self.seed < 2**31:
            raise TerrathemeError(f"boundary seed must be in 0 .. 2^31-1, got {self.seed}")

    def parameters(self, n: int, m: int) -> BoundaryParams:
        """The integer parameters of the kernel for cells of ``n x m`` texels.

        The width is capped at 0.4 of a weight; noise and height are scaled
        down together so that ``2 * (noise + height) <= 512 - width`` (in the
        kernel's units), the budget that keeps borders continuous.
        """
        half_cell = (n + m) / 2.0
        w1024 = int(round(1024 * self.width / half_cell)) if self.width > 0 else 0
        w1024 = max(1, min(w1024, MAX_WIDTH))
        noise, height = self.noise, self.height
        budget = (512 - w1024) // 2
        if noise + height > budget:
            f = budget / (noise + height)
            noise, height = int(noise * f), int(height * f)
        lattice = max(2, int(round(min(half_cell / self.features, MAX_LATTICE))))
        return BoundaryParams(w1024, noise, height, lattice, self.seed)


class BoundaryParams(NamedTuple):
    """The kernel's integers: width (1/1024), noise and height (1/256), lattice, seed."""

    width: int
    noise: int
    height: int
    lattice: int
    seed: int


@nb.njit(cache=True, nogil=True, inline="always")
def lattice_value(ix, iy, theme, seed):  # pragma: no cover - numba
    """Hash of a lattice point to 0..255 (a 32-bit integer mix; same on every platform)."""
    h = ((np.uint64(ix & 0xFFFFFFFF) * np.uint64(0x8DA6B343))
         ^ (np.uint64(iy & 0xFFFFFFFF) * np.uint64(0xD8163841))
         ^ (np.uint64(theme) * np.uint64(0xCB1AB31F)) ^ np.uint64(seed)) & _M32
    h ^= h >> np.uint64(16)
    h = (h * np.uint64(0x7FEB352D)) & _M32
    h ^= h >> np.uint64(15)
    h = (h * np.uint64(0x846CA68B)) & _M32
    h ^= h >> np.uint64(16)
    return np.int64(h >> np.uint64(24))


@nb.njit(cache=True, nogil=True, inline="always")
def noise_value(x, y, theme, lattice, seed):  # pragma: no cover - numba
    """Value noise of ``theme`` at global texel ``(x, y)``, in -512 .. 508."""
    ix = x // lattice
    iy = y // lattice
    fx = x - ix * lattice
    fy = y - iy * lattice
    gx = lattice - fx
    gy = lattice - fy
    v = (gx * gy * lattice_value(ix, iy, theme, seed)
         + fx * gy * lattice_value(ix + 1, iy, theme, seed)
         + gx * fy * lattice_value(ix, iy + 1, theme, seed)
         + fx * fy * lattice_value(ix + 1, iy + 1, theme, seed))
    return (v * 4) // (lattice * lattice) - 512


@nb.njit(cache=True, nogil=True, inline="always")
def border_weights(ks, ws, bs, o, flat, x, gy, d, params, sc):  # pragma: no cover - numba
    """Steps 2-3 at texel ``(x, gy)``: ``sc[a] = v_t`` of every corner slot; returns their sum.

    ``ks, ws`` the corner themes and merged weights (:func:`core.render.kernels.merged_weights`),
    ``bs[a] + o`` each theme's texel in ``flat``; slots of zero weight get 0.
    """
    width, noise, height, lattice, seed = params
    # Step 2: the score of every theme of non-zero weight.
    best = np.int64(-(1 << 40))
    for a in range(4):
        if ws[a] == 0:
            continue
        p = bs[a] + o
        luma = (77 * np.int64(flat[p]) + 150 * np.int64(flat[p + 1])
                + 29 * np.int64(flat[p + 2])) >> 8
        s = ((ws[a] * 1024) // d
             + (noise * noise_value(x, gy, ks[a], lattice, seed)) // 256
             + (height * (luma - 128) * 4) // 256)
        sc[a] = s
        best = max(best, s)
    # Step 3: the border of the given width around the best score.
    total = np.int64(0)
    for a in range(4):
        if ws[a] == 0:
            sc[a] = 0
        else:
            sc[a] = max(np.int64(0), sc[a] - best + width)
            total += sc[a]
    return total


@nb.njit(cache=True, nogil=True)
def shaped_rows(out, r0, r1, block, themes, params):  # pragma: no cover - numba
    """Fill ``out[r0:r1]`` with the shaped-boundary blend (the module docstring's steps).

    ``block`` a :class:`core.render.kernels.RegionBlock`, ``themes``
    :class:`core.render.kernels.ThemeRows`, ``params`` :class:`BoundaryParams`.
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat, off, stride, th, tw = themes
    rw = out.shape[1] // 3
    d = n * m
    cx0, cx1 = cell_columns(rx, rw, n)
    ks = np.zeros(4, np.int64)
    ws = np.zeros(4, np.int64)
    bs = np.zeros(4, np.int64)
    sc = np.zeros(4, np.int64)
    for r in range(r0, r1):
        gy = ry + r
        cy = gy // m
        yi = (gy - cy * m) * n
        for cx in range(cx0, cx1 + 1):
            xa, xb = cell_span(cx, n, rx, rw)
            sp = cell_corners(block, themes, cx, gy, xa, ks, bs)
            if sp == 0:
                # A uniform cell: one contiguous copy, as the paper's rule.
                length = (xb - xa) * 3
                dst = (xa - rx) * 3
                out[r, dst : dst + length] = flat[bs[0] : bs[0] + length]
                continue
            for x in range(xa, xb):
                o = (x - xa) * 3
                # Step 1: the barycentric weights, corners of one theme merged.
                merged_weights(sp, (x - cx * n) * m, yi, d, ks, ws)
                # Steps 2-3: scores, and the weights v_t of the border around the best.
                total = border_weights(ks, ws, bs, o, flat, x, gy, d, params, sc)
                for c in range(3):
                    acc = np.int64(0)
                    for a in range(4):
                        if sc[a] != 0:
                            acc += sc[a] * np.int64(flat[bs[a] + o + c])
                    out[r, (x - rx) * 3 + c] = (2 * acc + total) // (2 * total)


@nb.njit(cache=True, nogil=True)
def shaped_weight_rows(ids, weights, denom, xs, ys, block, edge, themes, params
                       ):  # pragma: no cover - numba
    """Fill the slots of pixels at texel columns ``xs`` and rows ``ys`` with the ``v_t``.

    ``ids`` (4, h, w) uint8 and ``weights`` (4, h, w) int64 get every pixel's corner
    themes and their ``v_t`` (0 for a corner merged into an earlier one of its theme
    or out of the border), ``denom`` (h, w) int64 their sum; ``edge`` is ``block``
    offset by one cell row (for the far edge row).
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat = themes[0]
    gh, gw = splits.shape[0], splits.shape[1]
    d = n * m
    ks = np.zeros(4, np.int64)
    ws = np.zeros(4, np.int64)
    bs = np.zeros(4, np.int64)
    sc = np.zeros(4, np.int64)
    for r in range(ys.size):
        gy = ys[r]
        cy = min(gy // m, gh - 1)
        rows = edge if gy == gh * m else block
        yi = (gy - cy * m) * n
        for c in range(xs.size):
            x = xs[c]
            cx = min(x // n, gw - 1)
            # The cell's corner themes, and each theme's texel at (x, gy).
            sp = cell_corners(rows, themes, cx, gy, x, ks, bs)
            for a in range(4):
                ids[a, r, c] = ks[a]
                weights[a, r, c] = 0
            if sp == 0:
                # A uniform cell: its one theme at full weight.
                weights[0, r, c] = 1
                denom[r, c] = 1
                continue
            # Step 1: the barycentric weights, corners of one theme merged.
            merged_weights(sp, (x - cx * n) * m, yi, d, ks, ws)
            # Steps 2-3 of the boundary blend: the v_t are the weights.
            total = border_weights(ks, ws, bs, 0, flat, x, gy, d, params, sc)
            for a in range(4):
                weights[a, r, c] = sc[a]
            denom[r, c] = total


def shaped_weights(indices: np.ndarray, splits: np.ndarray, textures: list[np.ndarray],
                   cell: tuple[int, int], xs: np.ndarray, ys: np.ndarray,
                   params: BoundaryParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The shaped blend's weights at texels ``xs`` (columns) x ``ys`` (rows) of the whole grid.

    ``xs``, ``ys`` int64 in ``0..gw*N`` and ``0..gh*M`` (far edge included); ``splits``
    is ``cell_splits(indices, saddle)``. Returns ``ids, weights`` ``(4, len(ys),
    len(xs))`` uint8 / int64 (corner themes and their ``v_t``) and ``denom`` int64
    ``sum(v_t)``: slot ``a`` weighs ``weights[a] / denom``.
    """
    n, m = (int(v) for v in cell)
    gh = indices.shape[0] - 1
    # Writeable C arrays: one kernel signature (numba types read-only arrays apart).
    indices = np.require(indices, np.uint8, ("C", "W"))
    splits = np.require(splits, np.uint8, ("C", "W"))
    packed = pack_themes(textures, n)
    rows = ThemeRows(packed.flat, packed.off, packed.stride, packed.th, packed.tw)
    block = RegionBlock(indices, splits, 0, 0, 0, 0, n, m)
    # The far edge row: the same grid one cell row on, so cell_corners finds the last row.
    edge = RegionBlock(indices[gh - 1:], splits[gh - 1:], 0, gh, 0, 0, n, m)
    xs = np.ascontiguousarray(xs, np.int64)
    ys = np.ascontiguousarray(ys, np.int64)
    ids = np.empty((4, ys.size, xs.size), np.uint8)
    weights = np.empty((4, ys.size, xs.size), np.int64)
    denom = np.empty((ys.size, xs.size), np.int64)
    shaped_weight_rows(ids, weights, denom, xs, ys, block, edge, rows, params)
    return ids, weights, denom
