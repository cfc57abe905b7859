"""The GPU renderer: the blend rule as GLSL shaders, rendered headless (docs/gpu.md).

:class:`GpuRenderer` takes the same grid, themes, cell and region as
:func:`core.render.render_cells` and refuses them with the same messages
(:mod:`core.render.inputs`). Two sampling paths:

* ``Sampling.EXACT`` (scale 1): ``texelFetch`` with integer wrap and the
  exact integer weights rounded as the CPU does, so the render equals the
  CPU render (within one level for the histogram-preserving blend, whose
  sums run in float32 here). Runs of uniform cells are drawn with a copy
  shader and blended cells with the blend shader (``core.gpu.cover``).
* ``Sampling.FILTERED`` (any scale; ``AUTO`` picks it below scale 1):
  ``textureGrad`` with mipmaps and anisotropic filtering, weights averaged
  over ``S x S`` sub-samples per pixel; the fly-over's path.

Large outputs are rendered in tiles of ``GpuRenderOptions.tile`` pixels
(framebuffer limits), each reading only the block of the grid under it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import moderngl
import numpy as np

from core.errors import TerrathemeError
from core.gpu.context import gl_context
from core.gpu.cover import cell_rectangles
from core.gpu.pipeline import RECT, Pipeline
from core.gpu.programs import UNITS
from core.gpu.textures import ThemeTextures
from core.render.inputs import prepare_grid, theme_textures, validate_region
from core.render.renderer import BlendMode
from core.render.rules import SaddleRule, cell_splits
from core.themes.library import Theme

Progress = Callable[[int, int], None]

#: largest texel coordinate and cell area the shaders' integer arithmetic keeps exact
MAX_COORDINATE = 1 << 23
MAX_CELL_AREA = 1 << 23


class Sampling(Enum):
    """How the shaders read the themes."""

    #: exact at scale 1, filtered below
    AUTO = "auto"
    #: texelFetch with integer wrap: the CPU render's texels (scale 1 only)
    EXACT = "exact"
    #: mipmaps and anisotropic filtering at any scale (the fly-over's path)
    FILTERED = "filtered"


@dataclass(frozen=True)
class GpuRenderOptions:
    """Options of :meth:`GpuRenderer.render`.

    Attributes
    ----------
    blend : BlendMode
    saddle : SaddleRule
        How saddle cells are split (``core.render.rules``).
    sampling : Sampling
    max_anisotropy : float
        Anisotropic filtering limit of the filtered path (the driver's cap
        applies). 1 (trilinear) suits flat renders, whose footprints are
        isotropic; a fly-over at grazing angles wants 16. (Mesa's llvmpipe
        blurs isotropic footprints with anisotropy on: 4.1 levels mean
        difference at scale 1 against 0.03 with it off.)
    tile : int
        Largest framebuffer side in pixels; bigger outputs are rendered tile by tile.
    uniform_cells : bool
        Exact path: draw runs of uniform cells with the copy shader (False: the
        blend shader draws every pixel, as an engine using it alone would).
    """

    blend: BlendMode = BlendMode.LINEAR
    saddle: SaddleRule = SaddleRule.MINORITY
    sampling: Sampling = Sampling.AUTO
    max_anisotropy: float = 1.0
    tile: int = 4096
    uniform_cells: bool = True


def _block_splits(indices: np.ndarray, rule: SaddleRule,
                  cells: tuple[int, int, int, int]) -> np.ndarray:
    """Splits of cells ``cx0..cx1 x cy0..cy1``, the saddle rule seeing one vertex ring around."""
    cx0, cy0, cx1, cy1 = cells
    vy0, vx0 = max(cy0 - 1, 0), max(cx0 - 1, 0)
    part = cell_splits(indices[vy0 : cy1 + 3, vx0 : cx1 + 3], rule)
    return part[cy0 - vy0 : cy1 - vy0 + 1, cx0 - vx0 : cx1 - vx0 + 1]


def _supersample(view: tuple[float, float, float, float], pixels: tuple[int, int],
                 cell: tuple[int, int]) -> int:
    """Sub-samples per pixel side of the filtered path: two or more per cell a pixel spans."""
    fx, fy = view[2] / pixels[0], view[3] / pixels[1]
    return int(min(16, max(1, math.ceil(2 * fx / cell[0]), math.ceil(2 * fy / cell[1]))))


class _Mode(NamedTuple):
    """The shader variant of a render."""

    filtered: bool
    histogram: bool
    colour_map: bool


def _colour_map_texture(ctx: moderngl.Context,
                        colour_map: np.ndarray | None) -> moderngl.Texture | None:
    """The colour map as an RGBA8 texture (the shaders read it with texelFetch), checked."""
    if colour_map is None:
        return None
    arr = np.asarray(colour_map)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8 or 0 in arr.shape:
        raise TerrathemeError(f"colour map must be a (h, w, 3) uint8 image, "
                              f"got shape {arr.shape} dtype {arr.dtype}")
    rgba = np.concatenate([arr, np.full(arr.shape[:2] + (1,), 255, np.uint8)], axis=2)
    tex = ctx.texture((arr.shape[1], arr.shape[0]), 4, np.ascontiguousarray(rgba).tobytes())
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


def _check_out(out: np.ndarray | None, shape: tuple[int, int, int]) -> np.ndarray:
    if out is None:
        return np.empty(shape, dtype=np.uint8)
    if (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.uint8
            or not out.flags.c_contiguous or not out.flags.writeable):
        raise TerrathemeError(f"out must be a writeable C-contiguous {shape} uint8 array")
    return out


class GpuRenderer:
    """Themes on the GPU, ready to render any grid over them (the editor keeps one).

    Parameters
    ----------
    themes : sequence of (h, w, 3) uint8 arrays (or Theme objects)
        ``themes[k]`` for index ``k``; any sizes.
    context : moderngl.Context, optional
        Default: this thread's shared context (:func:`core.gpu.context.gl_context`).

    Raises
    ------
    TerrathemeError
        Bad themes; ``GpuUnavailableError`` where no OpenGL 3.3 context can be made.
    """

    def __init__(self, themes: Sequence[np.ndarray] | Sequence[Theme], *,
                 context: moderngl.Context | None = None) -> None:
        textures = theme_textures(themes)
        self.ctx = context if context is not None else gl_context()
        self.themes = ThemeTextures(self.ctx, textures)
        self.pipeline = Pipeline(self.ctx, len(textures))

    def render(
        self,
        grid: object,
        cell: tuple[int, int] | None = None,
        region: tuple[int, int, int, int] | None = None,
        *,
        scale: float = 1.0,
        options: GpuRenderOptions = GpuRenderOptions(),
        colour_map: np.ndarray | None = None,
        progress: Progress | None = None,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Render a region of the thematic texture through the shaders.

        Parameters
        ----------
        grid : (gh+1, gw+1) integer array-like or IndexGrid
            Theme index at every grid vertex (row 0 at the top).
        cell : (N, M)
            Texel columns and rows per cell (default: the IndexGrid's).
        region : (x, y, w, h), optional
            Full-resolution texels (default: the whole ``(gw*N, gh*M)`` texture).
        scale : float in (0, 1]
            Output pixels per texel (below 1 the filtered path renders an overview).
        options : GpuRenderOptions
        colour_map : (ch, cw, 3) uint8 ndarray, optional
            A low-resolution colour map over the whole texture (128 neutral):
            the render is multiplied by ``value / 128``, bilinear (texel
            centres aligned), rounded.
        progress : callable(done, total), optional
            Called after every tile.
        out : (h, w, 3) uint8 C-contiguous ndarray, optional
            Render into this array.

        Returns
        -------
        image : (h, w, 3) uint8 ndarray
            ``(max(1, round(h*scale)), max(1, round(w*scale)), 3)``; at scale 1
            with exact sampling, the CPU render's texels.

        Raises
        ------
        TerrathemeError
            Bad grid, cell, region, scale, colour map or ``out`` (checked
            before any work); a texture or cell beyond the shaders' exact
            integer range.
        """
        indices, (n, m) = prepare_grid(grid, cell, len(self.themes.textures))
        gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
        size = (gw * n, gh * m)
        rx, ry, rw, rh = validate_region(region, size)
        if not 0.0 < float(scale) <= 1.0:
            raise TerrathemeError(f"scale must be in (0, 1], got {scale}")
        if max(size) > MAX_COORDINATE or n * m > MAX_CELL_AREA:
            raise TerrathemeError(
                f"texture {size[0]} x {size[1]} with {n} x {m} cells is beyond the GPU "
                f"renderer's exact integer range (sides and cell area up to {MAX_COORDINATE})")
        if options.tile < 1:
            raise TerrathemeError(f"tile must be at least 1 pixel, got {options.tile}")
        sampling = options.sampling
        if sampling is Sampling.AUTO:
            sampling = Sampling.EXACT if float(scale) == 1.0 else Sampling.FILTERED
        if sampling is Sampling.EXACT and float(scale) != 1.0:
            raise TerrathemeError(f"exact sampling renders at scale 1 only, got scale {scale}")
        ow, oh = max(1, round(rw * scale)), max(1, round(rh * scale))
        image = _check_out(out, (oh, ow, 3))
        colours = _colour_map_texture(self.ctx, colour_map)
        mode = _Mode(sampling is Sampling.FILTERED, options.blend is BlendMode.HISTOGRAM,
                     colours is not None)
        self._bind(mode, options.max_anisotropy, colours)
        tile = min(options.tile, *self.ctx.info["GL_MAX_VIEWPORT_DIMS"])
        self.pipeline.framebuffer(min(tile, ow), min(tile, oh))
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        fx, fy = rw / ow, rh / oh
        tiles = [(tx, ty) for ty in range(0, oh, tile) for tx in range(0, ow, tile)]
        try:
            for i, (tx, ty) in enumerate(tiles):
                tw, th = min(tile, ow - tx), min(tile, oh - ty)
                # The tile's part of the texture, in texel edges.
                view = (rx + tx * fx, ry + ty * fy, tw * fx, th * fy)
                self.ctx.viewport = (0, 0, tw, th)
                self._render_tile(indices, (n, m), view, (tw, th), options, mode, size)
                self.pipeline.read(image, tx, ty, tw, th)
                if progress:
                    progress(i + 1, len(tiles))
        finally:
            if colours is not None:
                colours.release()
        return image

    def _bind(self, mode: _Mode, anisotropy: float, colours: moderngl.Texture | None) -> None:
        """Bind the theme layouts of this path and the colour map to their units."""
        self.themes.colours(mode.filtered, anisotropy).use(UNITS["tt_themes"])
        if mode.histogram:
            self.themes.gaussianised(mode.filtered, anisotropy).use(UNITS["tt_gauss"])
            self.themes.inverse_lut()[0].use(UNITS["tt_inverse_lut"])
        if colours is not None:
            colours.use(UNITS["tt_colour_map"])

    def _render_tile(self, indices: np.ndarray, cell: tuple[int, int],
                     view: tuple[float, float, float, float], pixels: tuple[int, int],
                     options: GpuRenderOptions, mode: _Mode, size: tuple[int, int]) -> None:
        n, m = cell
        gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
        x0, y0, w, h = view
        # Cells under the tile (the filtered path's sub-samples reach half a texel out).
        pad = int(mode.filtered)
        cx0 = min(max(0, math.floor((x0 - pad) / n)), gw - 1)
        cy0 = min(max(0, math.floor((y0 - pad) / m)), gh - 1)
        cx1 = min(gw - 1, math.ceil((x0 + w) / n) - 1 + pad)
        cy1 = min(gh - 1, math.ceil((y0 + h) / m) - 1 + pad)
        sub = indices[cy0 : cy1 + 2, cx0 : cx1 + 2]
        splits = _block_splits(indices, options.saddle, (cx0, cy0, cx1, cy1))
        self.pipeline.index_texture("tt_grid", sub)
        self.pipeline.index_texture("tt_splits", splits)
        # Rectangles to draw: uniform runs and blended runs, or the whole tile.
        if mode.filtered or not options.uniform_cells:
            rects = np.zeros(1, RECT)
            rects["edges"] = (x0, y0, x0 + w, y0 + h)
            rects["theme"] = -1
        else:
            cells, kinds = cell_rectangles(sub, splits)
            rects = np.zeros(len(kinds), RECT)
            rects["edges"] = (cells + (cx0, cy0, cx0, cy0)) * np.array([n, m, n, m])
            rects["theme"] = kinds
        lut_size, lut_range = 4096, 0.0
        if mode.histogram:
            _, lut_size, lut_range = self.themes.inverse_lut()
        values = {
            "tt_view": view, "tt_cell": (n, m), "tt_block_cell": (cx0, cy0),
            "tt_block_cells": (splits.shape[1], splits.shape[0]),
            "tt_theme_size": self.themes.sizes,
            "tt_texture_size": (float(size[0]), float(size[1])),
            "tt_supersample": _supersample(view, pixels, cell), "tt_lut_range": lut_range,
        }
        for kind, chosen in (("uniform", rects["theme"] >= 0), ("blend", rects["theme"] < 0)):
            if not chosen.any():
                continue
            prog = self.pipeline.program(kind, histogram=mode.histogram, filtered=mode.filtered,
                                         colour_map=mode.colour_map, lut_size=lut_size)
            self.pipeline.set_uniforms(prog, values)
            self.pipeline.draw_rects(prog, rects[chosen])

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays)."""
        self.pipeline.release()
        self.themes.release()


def render_cells_gpu(
    grid: object,
    themes: Sequence[np.ndarray] | Sequence[Theme],
    cell: tuple[int, int] | None = None,
    region: tuple[int, int, int, int] | None = None,
    *,
    scale: float = 1.0,
    options: GpuRenderOptions = GpuRenderOptions(),
    progress: Progress | None = None,
) -> np.ndarray:
    """Render a thematic texture on the GPU once (:class:`GpuRenderer` for repeated renders).

    Same inputs as :func:`core.render.render_cells` plus ``scale``; see
    :meth:`GpuRenderer.render`.

    Returns
    -------
    image : (h, w, 3) uint8 ndarray
    """
    renderer = GpuRenderer(themes)
    try:
        return renderer.render(grid, cell, region, scale=scale, options=options,
                               progress=progress)
    finally:
        renderer.release()
