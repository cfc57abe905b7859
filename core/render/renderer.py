"""The thematic-texture renderer (Vyatkin & Romanyuk, design.md §1).

``render_cells`` turns a vertex index grid and a theme list into the full texture,
or any ``region`` of it (exactly the crop of the full render); ``render_labels``
gives the theme with the largest weight per texel. Conventions (texel positions,
integer weights, saddle rule): :mod:`core.render.rules`.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from enum import Enum

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.render import kernels as rk
from terratheme.core.render.boundary import BoundaryOptions, shaped_rows
from terratheme.core.render.colour_map import RegionGain
from terratheme.core.render.inputs import prepare_grid, theme_textures, validate_region
from terratheme.core.render.rules import SaddleRule, region_splits
from terratheme.core.render.theme_pack import LUT_RANGE, pack_themes
from terratheme.core.themes.library import Theme

Progress = Callable[[int, int], None]


class BlendMode(Enum):
    """How the three themes of a triangle are mixed."""

    #: the paper's weighted sum, exact integer weights rounded half up
    LINEAR = "linear"
    #: Heitz & Neyret (HPG 2018): variance-preserving blend of Gaussianised themes
    HISTOGRAM = "histogram"


@dataclass(frozen=True)
class RenderOptions:
    """Options of :func:`render_cells`.

    ``saddle``: how saddle cells (``A B / B A``) are split (``core.render.rules``);
    ``threads``: row bands rendered in parallel, 0 = one per CPU; ``boundary``:
    borders shaped by the themes' content and noise (:mod:`core.render.boundary`,
    linear blend only), None for the paper's barycentric ramp.
    """

    blend: BlendMode = BlendMode.LINEAR
    saddle: SaddleRule = SaddleRule.MINORITY
    threads: int = 0
    boundary: BoundaryOptions | None = None

    def __post_init__(self) -> None:
        if self.boundary is not None and self.blend is not BlendMode.LINEAR:
            raise TerrathemeError("shaped boundaries blend linearly: use BlendMode.LINEAR "
                                  "with a boundary, or no boundary with the histogram blend")


_pools: dict[int, ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def _executor(threads: int) -> ThreadPoolExecutor:
    """A pool of exactly ``threads`` workers, made once per size."""
    with _pools_lock:
        if threads not in _pools:
            _pools[threads] = ThreadPoolExecutor(max_workers=threads,
                                                 thread_name_prefix="terratheme-render")
        return _pools[threads]


def _thread_count(threads: int, pixels: int) -> int:
    """``threads`` (0 = one per CPU), one for renders too small to split."""
    if threads < 0:
        raise TerrathemeError(f"threads must be >= 0 (0 = one per CPU), got {threads}")
    if pixels < 1 << 16:
        return 1
    return threads or (os.cpu_count() or 1)


def _bands(h: int, threads: int) -> list[tuple[int, int]]:
    """Split ``h`` rows into bands: up to eight per thread (load balance), at least 8 rows each."""
    n = max(1, min(threads * 8, h // 8))
    edges = np.linspace(0, h, n + 1).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def render_cells(
    grid: object,
    themes: Sequence[np.ndarray] | Sequence[Theme],
    cell: tuple[int, int] | None = None,
    region: tuple[int, int, int, int] | None = None,
    *,
    options: RenderOptions = RenderOptions(),
    progress: Progress | None = None,
    out: np.ndarray | None = None,
    colour_map: ColourMap | None = None,
    origin: tuple[int, int] = (0, 0),
) -> np.ndarray:
    """Render a thematic texture (design.md §1, steps 1-3).

    Parameters
    ----------
    grid : (gh+1, gw+1) integer array-like or IndexGrid
        Theme index at every grid vertex (row 0 at the top).
    themes : sequence of (h, w, 3) uint8 arrays (or Theme objects)
        ``themes[k]`` for index ``k``, any size, sampled at global coordinates, wrapping.
    cell : (N, M)
        Texel columns and rows per cell (default: the IndexGrid's).
    region : (x, y, w, h), optional
        Window of the full ``(gw*N, gh*M)`` texture; equals that crop of the full render.
    out : (h, w, 3) uint8 C-contiguous ndarray, optional
        Render into this array (a reused buffer skips a fresh allocation's page faults).
    origin : (row, col), optional
        ``grid`` is the block of a larger grid starting at vertex ``(row, col)`` and
        ``region`` is in its texels; equals the larger render when the block has one
        vertex of margin (the saddle ring). Not with ``colour_map``.

    Returns the (h, w, 3) uint8 image, ``out`` when given.
    """
    textures = theme_textures(themes)
    indices, (n, m) = prepare_grid(grid, cell, len(textures))
    gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
    oy, ox = (int(v) for v in origin)
    if oy < 0 or ox < 0 or ((oy or ox) and colour_map is not None):
        raise TerrathemeError(f"origin must be two vertex numbers >= 0, without a colour map, "
                              f"got {origin}")
    if region is not None and (oy or ox):
        # The block's own texels from here on; the kernels get the global position.
        region = (region[0] - ox * n, region[1] - oy * m, *region[2:])
    rx, ry, rw, rh = validate_region(region, (gw * n, gh * m))
    # Only the block of cells under the region (a viewport of a huge grid stays cheap).
    cx0, cx1, cy0, cy1 = rx // n, (rx + rw - 1) // n, ry // m, (ry + rh - 1) // m
    # A copy when the region is narrower than the grid: the kernels' one signature ('C').
    sub = np.ascontiguousarray(indices[cy0 : cy1 + 2, cx0 : cx1 + 2])
    splits = region_splits(indices, None, options.saddle, (cy0, cy1, cx0, cx1))
    cx0, cy0, rx, ry = cx0 + ox, cy0 + oy, rx + ox * n, ry + oy * m
    hist = options.blend is BlendMode.HISTOGRAM
    packed = pack_themes(textures, n, gaussian=hist)
    if out is None:
        out = np.empty((rh, rw, 3), dtype=np.uint8)
    elif (not isinstance(out, np.ndarray) or out.shape != (rh, rw, 3) or out.dtype != np.uint8
          or not out.flags.c_contiguous or not out.flags.writeable):
        raise TerrathemeError(f"out must be a writeable C-contiguous ({rh}, {rw}, 3) uint8 array")
    out2 = out.reshape(rh, rw * 3)
    block = rk.RegionBlock(sub, splits, cx0, cy0, rx, ry, n, m)
    rows = rk.ThemeRows(packed.flat, packed.off, packed.stride, packed.th, packed.tw)
    mag, sh = rk.division_magic(n * m)
    small_table = 96 * n * m <= 8 << 20
    shaped = None if options.boundary is None else options.boundary.parameters(n, m)
    gain = None
    if colour_map is not None:
        colour_map.check_covers((gw * n, gh * m))
        gain = RegionGain(colour_map, (rx, ry, rw, rh))

    def tables(r0: int, r1: int) -> tuple[np.ndarray, np.ndarray]:
        # Weight tables: cached for ordinary cells, only this band's rows for huge ones.
        if small_table:
            return rk.weight_tables(n, m)
        return rk.weight_tables(n, m, np.unique((ry + np.arange(r0, r1)) % m))

    def band(r0: int, r1: int) -> None:
        # One row band; the kernels release the GIL so bands run in parallel.
        if hist:
            gauss = rk.GaussianThemes(packed.gflat, packed.inv_lut, LUT_RANGE)
            rk.histogram_rows(out2, r0, r1, block, rows, gauss)
        elif shaped is not None:
            shaped_rows(out2, r0, r1, block, rows, shaped)
        else:
            rk.linear_rows(out2, r0, r1, block, rows, rk.LinearWeights(*tables(r0, r1), mag, sh))
        if gain is not None:
            # The colour map multiplies the blend, band by band on the same thread.
            gain.apply(out2, r0, r1)

    threads = _thread_count(options.threads, rw * rh)
    bands = _bands(rh, threads)
    if threads == 1 or len(bands) == 1:
        for i, (r0, r1) in enumerate(bands):
            band(r0, r1)
            if progress:
                progress(i + 1, len(bands))
        return out
    futures = [_executor(threads).submit(band, r0, r1) for r0, r1 in bands]
    for i, fut in enumerate(futures):
        fut.result()
        if progress:
            progress(i + 1, len(futures))
    return out


def render_labels(
    grid: object,
    cell: tuple[int, int] | None = None,
    region: tuple[int, int, int, int] | None = None,
    *,
    n_themes: int | None = None,
    saddle: SaddleRule = SaddleRule.MINORITY,
    threads: int = 0,
) -> np.ndarray:
    """The ``(h, w)`` uint8 theme with the largest total weight at every texel.

    Corners carrying the same theme add their weights; ties go to the lower
    theme index. Same texel convention and splits as :func:`render_cells`.
    """
    indices, (n, m) = prepare_grid(grid, cell, n_themes)
    gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
    rx, ry, rw, rh = validate_region(region, (gw * n, gh * m))
    cx0, cx1, cy0, cy1 = rx // n, (rx + rw - 1) // n, ry // m, (ry + rh - 1) // m
    sub = np.ascontiguousarray(indices[cy0 : cy1 + 2, cx0 : cx1 + 2])
    splits = region_splits(indices, None, saddle, (cy0, cy1, cx0, cx1))
    out = np.empty((rh, rw), dtype=np.uint8)
    block = rk.RegionBlock(sub, splits, cx0, cy0, rx, ry, n, m)
    small_table = 96 * n * m <= 8 << 20

    def band(r0: int, r1: int) -> None:
        rows = None if small_table else np.unique((ry + np.arange(r0, r1)) % m)
        rk.label_rows(out, r0, r1, block, *rk.weight_tables(n, m, rows))

    threads = _thread_count(threads, rw * rh)
    bands = _bands(rh, threads)
    if threads == 1 or len(bands) == 1:
        for r0, r1 in bands:
            band(r0, r1)
    else:
        for fut in [_executor(threads).submit(band, r0, r1) for r0, r1 in bands]:
            fut.result()
    return out
