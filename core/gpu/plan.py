"""What one GPU render draws: its checked inputs, its mode, and the geometry of each tile.

Pure data and arithmetic (no OpenGL): :class:`core.gpu.renderer.GpuRenderer`
makes a :class:`RenderPlan` before any GPU work and draws it tile by tile.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from terratheme.core.gpu.packed import PackedGrid
from terratheme.core.gpu.programs import Variant
from terratheme.core.gpu.style import Style


class RenderMode(NamedTuple):
    """The style of a render and its sampling path. A flat render's filtered path reads
    box means (``TT_BOX``: its footprints are axis-aligned), counting whole theme periods
    when ``periods`` (a footprint wider than a theme)."""

    style: Style
    filtered: bool
    periods: bool = False

    def variant(self, kind: str, lut_size: int) -> Variant:
        """The program of ``kind`` drawing this mode."""
        blend = kind == "blend"
        return Variant(kind, histogram=self.style.histogram and blend,
                       shaped=self.style.border is not None and blend, filtered=self.filtered,
                       colour_map=self.style.colour_map is not None, lut_size=lut_size,
                       box=(1 + self.periods) * (self.filtered and blend))


class RenderPlan(NamedTuple):
    """What a render draws: the checked inputs, the output size, the variant, the tile side.

    ``indices`` is the dense grid, or None when ``packed`` (the GPU reads the layer).
    """

    indices: np.ndarray | None
    packed: PackedGrid | None
    cells: tuple[int, int]
    cell: tuple[int, int]
    size: tuple[int, int]
    region: tuple[int, int, int, int]
    out_size: tuple[int, int]
    mode: RenderMode
    tile: int


def tile_geometry(plan: RenderPlan, tx: int, ty: int
                  ) -> tuple[tuple[int, int], tuple[float, float, float, float],
                             tuple[int, int, int, int]]:
    """The output tile at pixel ``(tx, ty)``: ``size`` (tw, th), ``view`` (x0, y0, w, h) in
    texel edges, and the inclusive ``cells`` (cx0, cy0, cx1, cy1) under it (one more each
    side for the filtered path, whose sub-samples reach half a texel beyond).
    """
    n, m = plan.cell
    rx, ry, rw, rh = plan.region
    ow, oh = plan.out_size
    fx, fy = rw / ow, rh / oh
    tw, th = min(plan.tile, ow - tx), min(plan.tile, oh - ty)
    x0, y0, w, h = (rx + tx * fx, ry + ty * fy, tw * fx, th * fy)
    gw, gh = plan.cells
    pad = int(plan.mode.filtered)
    cx0 = min(max(0, math.floor((x0 - pad) / n)), gw - 1)
    cy0 = min(max(0, math.floor((y0 - pad) / m)), gh - 1)
    cx1 = min(gw - 1, math.ceil((x0 + w) / n) - 1 + pad)
    cy1 = min(gh - 1, math.ceil((y0 + h) / m) - 1 + pad)
    return (tw, th), (x0, y0, w, h), (cx0, cy0, cx1, cy1)
