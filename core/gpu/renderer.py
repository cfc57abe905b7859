"""The GPU renderer: the blend rule as GLSL shaders, rendered headless (docs/gpu.md).

Same inputs and messages as :func:`core.render.render_cells`. ``Sampling.EXACT`` (scale
1) gives the CPU render's texels (within one level for the histogram-preserving blend);
``Sampling.FILTERED`` (any scale) uses each theme's box mean over the pixel (summed-area
tables) and sub-sampled weights. Large outputs are drawn in tiles of
``GpuRenderOptions.tile`` pixels.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import moderngl
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.context import gl_context
from terratheme.core.gpu.options import GpuRenderOptions, Sampling
from terratheme.core.gpu.packed import PackedGrid, check_grid_layer
from terratheme.core.gpu.pipeline import Pipeline, rect_vertices
from terratheme.core.gpu.plan import RenderMode, RenderPlan, tile_geometry
from terratheme.core.gpu.style import StyleTextures, gpu_style
from terratheme.core.gpu.textures import ThemeTextures
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import validate_cell
from terratheme.core.packing import PackedLayer, TiledLayer
from terratheme.core.render.inputs import prepare_grid, theme_textures, validate_region
from terratheme.core.render.rules import region_splits
from terratheme.core.themes.library import Theme

Progress = Callable[[int, int], None]


def _check_out(out: np.ndarray | None, shape: tuple[int, int, int]) -> np.ndarray:
    if out is None:
        return np.empty(shape, dtype=np.uint8)
    if (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.uint8
            or not out.flags.c_contiguous or not out.flags.writeable):
        raise TerrathemeError(f"out must be a writeable C-contiguous {shape} uint8 array")
    return out


class GpuRenderer:
    """Themes on the GPU, ready to render any grid over them (an editor keeps one).

    ``themes[k]``: (h, w, 3) uint8 arrays or Themes of any sizes; ``context``: current on
    this thread, default the thread's shared one. Raises TerrathemeError for bad themes,
    GpuUnavailableError without OpenGL 3.3.
    """

    def __init__(self, themes: Sequence[np.ndarray] | Sequence[Theme], *,
                 context: moderngl.Context | None = None) -> None:
        textures = theme_textures(themes)
        self.ctx = context if context is not None else gl_context()
        self.themes = ThemeTextures(self.ctx, textures)
        self.pipeline = Pipeline(self.ctx, len(textures), self.themes.one_size)
        self._max_viewport = min(self.ctx.info["GL_MAX_VIEWPORT_DIMS"])
        self.style = StyleTextures(self.ctx, self.themes)
        self._packed: PackedGrid | None = None

    def render(
        self,
        grid: object,
        cell: tuple[int, int] | None = None,
        region: tuple[int, int, int, int] | None = None,
        *,
        scale: float = 1.0,
        options: GpuRenderOptions = GpuRenderOptions(),  # noqa: B008 (frozen)
        colour_map: ColourMap | None = None,
        progress: Progress | None = None,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Render a region of the thematic texture through the shaders.

        ``grid``: (gh+1, gw+1) theme indices (row 0 on top), an IndexGrid, or a PackedLayer
        read packed; ``cell`` (N, M) texels per cell; ``region`` (x, y, w, h) texels (default
        all); ``scale`` in (0, 1] pixels per texel; ``out``: a (h, w, 3) uint8 C-contiguous
        target. Returns the (h, w, 3) uint8 image, at scale 1 with exact sampling the CPU
        render's texels. TerrathemeError for bad inputs or sizes beyond the shaders' exact
        integers, before any work.
        """
        plan = self._plan(grid, cell, region, scale, options, colour_map)
        ow, oh = plan.out_size
        image = _check_out(out, (oh, ow, 3))
        tiles = [(tx, ty) for ty in range(0, oh, plan.tile) for tx in range(0, ow, plan.tile)]
        self._start(plan, options)
        for i, (tx, ty) in enumerate(tiles):
            tw, th = self._draw_tile(plan, options, tx, ty)
            self.pipeline.read(image, tx, ty, tw, th)
            if progress:
                progress(i + 1, len(tiles))
        return image

    def draw(
        self,
        grid: object,
        cell: tuple[int, int] | None = None,
        region: tuple[int, int, int, int] | None = None,
        *,
        scale: float = 1.0,
        options: GpuRenderOptions = GpuRenderOptions(),  # noqa: B008 (frozen)
        colour_map: ColourMap | None = None,
    ) -> moderngl.Framebuffer:
        """Draw a region (one tile at most; parameters as :meth:`render`) into the renderer's
        RGBA8 framebuffer without reading it back, row 0 the region's top; returns the
        framebuffer (the draw may still run: ``ctx.finish()`` waits).
        """
        plan = self._plan(grid, cell, region, scale, options, colour_map)
        if max(plan.out_size) > plan.tile:
            raise TerrathemeError(f"draw renders one tile of at most {plan.tile} pixels a side, "
                                  f"got {plan.out_size[0]} x {plan.out_size[1]} (use render)")
        self._start(plan, options)
        self._draw_tile(plan, options, 0, 0)
        return self.pipeline.framebuffer(*plan.out_size)

    def _plan(self, grid: object, cell: tuple[int, int] | None,
              region: tuple[int, int, int, int] | None, scale: float,
              options: GpuRenderOptions, colour_map: ColourMap | None) -> RenderPlan:
        """Check every input (before any GPU work) and fix what the tiles draw."""
        indices, packed, (n, m) = self._grid(grid, cell)
        gw, gh = (packed.layer.width - 1, packed.layer.height - 1) if packed else \
            (indices.shape[1] - 1, indices.shape[0] - 1)
        size = (gw * n, gh * m)
        region = validate_region(region, size)
        if not 0.0 < float(scale) <= 1.0:
            raise TerrathemeError(f"scale must be in (0, 1], got {scale}")
        style = gpu_style(options, (n, m), size, colour_map)
        if options.tile < 1:
            raise TerrathemeError(f"tile must be at least 1 pixel, got {options.tile}")
        sampling = options.sampling
        if sampling is Sampling.AUTO:
            sampling = Sampling.EXACT if float(scale) == 1.0 else Sampling.FILTERED
        if sampling is Sampling.EXACT and float(scale) != 1.0:
            raise TerrathemeError(f"exact sampling renders at scale 1 only, got scale {scale}")
        filtered = sampling is Sampling.FILTERED
        out_size = (max(1, round(region[2] * scale)), max(1, round(region[3] * scale)))
        footprint = (region[2] / out_size[0], region[3] / out_size[1])
        periods = bool((np.array(footprint) > self.themes.sizes[:, :2].min(axis=0)).any())
        mode = RenderMode(style, filtered, filtered and periods)
        tile = min(options.tile, self._max_viewport)
        return RenderPlan(indices, packed, (gw, gh), (n, m), size, region, out_size, mode, tile)

    def _grid(self, grid: object, cell: object) -> tuple[np.ndarray | None, PackedGrid | None,
                                                          tuple[int, int]]:
        """The checked dense indices, or the packed layer on the GPU (kept for the next render)."""
        if not isinstance(grid, PackedLayer | TiledLayer):
            indices, cell = prepare_grid(grid, cell, len(self.themes.textures))
            return indices, None, cell
        if cell is None:
            raise TerrathemeError("cell size (N, M) is required with a packed index grid")
        cell = validate_cell(cell)
        if self._packed is None or self._packed.layer is not grid:
            check_grid_layer(grid, len(self.themes.textures))
            if self._packed is not None:
                self._packed.release()
            self._packed = PackedGrid(self.ctx, grid)
        return None, self._packed, cell

    def _start(self, plan: RenderPlan, options: GpuRenderOptions) -> None:
        """Bind the textures and make the framebuffer current."""
        self.style.bind(plan.mode.style, plan.mode.filtered, options.max_anisotropy,
                        box=plan.mode.filtered)
        ow, oh = plan.out_size
        self.pipeline.framebuffer(min(plan.tile, ow), min(plan.tile, oh))
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)

    def _draw_tile(self, plan: RenderPlan, options: GpuRenderOptions, tx: int,
                   ty: int) -> tuple[int, int]:
        """Draw output pixels ``[tx, tx + tile) x [ty, ty + tile)``; returns their size."""
        (tw, th), view, (cx0, cy0, cx1, cy1) = tile_geometry(plan, tx, ty)
        x0, y0, w, h = view
        block_shape = (cy1 - cy0 + 1, cx1 - cx0 + 1)
        if plan.packed is not None:
            # The GPU decodes the block and splits its cells from the packed layer.
            plan.packed.bind_block((cx0, cy0, cx1, cy1), options.saddle)
            self.pipeline.framebuffer(tw, th)
        else:
            sub = plan.indices[cy0 : cy1 + 2, cx0 : cx1 + 2]
            splits = region_splits(plan.indices, None, options.saddle, (cy0, cy1, cx0, cx1))
            self.pipeline.index_texture("tt_grid", sub)
            self.pipeline.index_texture("tt_splits", splits)
        self.ctx.viewport = (0, 0, tw, th)
        # One rectangle over the whole tile, every pixel drawn by the blend shader.
        values = self._uniforms(plan, options, view, (cx0, cy0), block_shape)
        self._draw_tile_rect(plan.mode, (x0, y0, x0 + w, y0 + h), values)
        return tw, th

    def _uniforms(self, plan: RenderPlan, options: GpuRenderOptions,
                  view: tuple[float, float, float, float], block_cell: tuple[int, int],
                  block_shape: tuple[int, int]) -> dict[str, object]:
        """The uniform values of one tile's draws (``tt_blend.glsl`` documents each)."""
        lw, lh = self.themes.layer_size
        return {
            "tt_view": view, "tt_cell": plan.cell, "tt_block_cell": block_cell,
            "tt_block_cells": (block_shape[1], block_shape[0]),
            "tt_wrap_origin": (int(view[0]) // lw * lw, int(view[1]) // lh * lh),
            **self.style.uniforms(plan.mode.style, plan.size, options.max_supersample),
        }

    def _draw_tile_rect(self, mode: RenderMode, edges: tuple[float, float, float, float],
                        values: dict[str, object]) -> None:
        """Draw the blend shader over one rectangle of texel ``edges``."""
        self.pipeline.upload_vertices(rect_vertices(np.array([edges])))
        lut_size = self.themes.inverse_lut()[1] if mode.style.histogram else 4096
        prog = self.pipeline.program(mode.variant("blend", lut_size))
        self.pipeline.set_uniforms(prog, values)
        self.pipeline.draw(prog, 0, 6)

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays)."""
        self.pipeline.release()
        if self._packed is not None:
            self._packed.release()
            self._packed = None
        self.style.release()
        self.themes.release()
